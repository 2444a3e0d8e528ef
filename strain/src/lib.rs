//! Detector strain in, glitch triggers out.
//!
//! The scan pipeline, one module per stage: [`gwosc`] reads (and writes)
//! GWOSC HDF5 strain files, [`input`] joins inputs into runs read a block
//! at a time (decimated to the classifier's rate by [`decimate`]), [`series`] holds a stretch of strain and
//! splits it at missing data, [`psd`] estimates the noise PSD by Welch's
//! method, [`qtransform`] tiles whitened data in time, frequency and Q,
//! [`triggers`] clusters loud tiles into triggers, [`classifier`] labels
//! them with a trained gwml model, and [`scan`] runs the stages over a
//! long stretch of strain in parallel chunks, [`blocks`] cuts long inputs
//! into blocks that can be recorded, resumed and dealt out; [`record`] writes a scan's
//! report as JSON and reads it back exactly (resuming, MPI).

pub mod blocks;
pub mod classifier;
pub mod decimate;
pub mod gwosc;
pub mod input;
pub mod psd;
pub mod qimage;
pub mod qtransform;
pub mod record;
pub mod scan;
pub mod series;
pub mod triggers;
pub mod whitening;

use std::fmt;

/// What went wrong reading or processing strain. Every message names the
/// file (and the dataset or attribute) it is about.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// A file could not be read or written, or is not what it should be.
    File {
        /// The file.
        path: String,
        /// What is wrong, naming the dataset or attribute.
        message: String,
    },
    /// Data that cannot be processed (too short, bad sample rate, …).
    Data(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::File { path, message } => write!(f, "{path}: {message}"),
            Error::Data(message) => f.write_str(message),
        }
    }
}

impl std::error::Error for Error {}

impl Error {
    /// An error about `path`.
    pub fn file(path: &std::path::Path, message: impl Into<String>) -> Error {
        Error::File { path: path.display().to_string(), message: message.into() }
    }
}
