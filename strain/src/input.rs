//! Strain inputs: GWOSC HDF5 files (read a window at a time) or a `.npy`
//! held whole, joined into runs of consecutive files that are read a block
//! at a time, decimated when they are sampled at a whole multiple of the
//! rate the scan wants (a 16384 Hz file for a 4096 Hz classifier).

use crate::decimate::Decimator;
use crate::gwosc;
use crate::series::{plan, Series, Skipped, Span};
use crate::Error;
use std::path::Path;

/// What a `.npy` input lacks: where and when its samples are.
#[derive(Clone, Debug, PartialEq)]
pub struct NpyInfo {
    /// Samples per second.
    pub sample_rate: f64,
    /// GPS time of the first sample.
    pub gps_start: f64,
    /// Detector name.
    pub ifo: String,
}

/// A strain input: an HDF5 file read a window at a time, or a `.npy` held whole.
pub enum Source {
    File(gwosc::Reader),
    Memory(Series),
}

impl Source {
    /// Opens `path`: a GWOSC HDF5 file (metadata only), or a `.npy` with `npy`.
    pub fn open(path: &Path, npy: Option<&NpyInfo>) -> Result<Source, Error> {
        let is_npy = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"));
        if is_npy {
            let Some(info) = npy else {
                return Err(Error::file(path, "a .npy file needs --sample-rate and --gps-start"));
            };
            let data = gwml_runtime::npy::read(path).map_err(|e| Error::file(path, e.to_string()))?;
            if data.complex {
                return Err(Error::file(path, "strain must be real, the file holds complex numbers"));
            }
            return Ok(Source::Memory(Series {
                detector: info.ifo.clone(),
                gps_start: info.gps_start,
                sample_rate: info.sample_rate,
                samples: data.values.iter().map(|c| c.re).collect(),
                dq: None,
                source: path.display().to_string(),
            }));
        }
        if npy.is_some() {
            return Err(Error::file(path, "--sample-rate and --gps-start are for .npy files; an HDF5 file carries its own"));
        }
        gwosc::open(path).map(Source::File)
    }

    /// Where its samples lie.
    pub fn span(&self) -> Span {
        match self {
            Source::File(r) => Span {
                detector: r.detector.clone(),
                gps_start: r.gps_start,
                sample_rate: r.sample_rate,
                samples: r.samples,
                source: r.path().display().to_string(),
            },
            Source::Memory(s) => s.span(),
        }
    }

    fn dq(&self) -> Option<&[u32]> {
        match self {
            Source::File(r) => r.dq_mask.as_deref(),
            Source::Memory(s) => s.dq.as_deref(),
        }
    }

    fn read(&self, start: usize, count: usize) -> Result<Vec<f64>, Error> {
        match self {
            Source::File(r) => r.read_samples(start, count),
            Source::Memory(s) => Ok(s.samples[start.min(s.samples.len())..(start + count).min(s.samples.len())].to_vec()),
        }
    }
}

/// Inputs in time order as runs of consecutive ones, and the gaps between
/// runs (see [`plan`]). With `rate`, a run sampled at a whole multiple of
/// it is read decimated to it ([`decimation`]).
pub fn runs(sources: &[Source], rate: Option<f64>) -> Result<(Vec<StrainRun<'_>>, Vec<Skipped>), Error> {
    let spans: Vec<Span> = sources.iter().map(Source::span).collect();
    let (runs, gaps) = plan(&spans)?;
    Ok((runs.iter().map(|r| StrainRun::new(sources, r, rate)).collect(), gaps))
}

/// The factor that takes data sampled at `from` Hz to `to` Hz, when it is
/// a whole number of at least 2 (other rates are read as they are, and a
/// classifier at another rate refuses them).
pub fn decimation(from: f64, to: f64) -> Option<usize> {
    let k = from / to;
    (k >= 2.0 && k.fract() == 0.0 && k <= 1024.0).then_some(k as usize)
}

/// Consecutive inputs read as one stretch, a block at a time.
pub struct StrainRun<'s> {
    parts: Vec<&'s Source>,
    /// The run's extent (at the rate it is read at, after decimation).
    pub span: Span,
    /// Samples in the files (before decimation).
    stored: usize,
    /// The DQ words of the whole run (one per second), if every part has them.
    dq: Option<Vec<u32>>,
    /// How the files' samples are brought to `span.sample_rate`, if they are.
    decimator: Option<Decimator>,
}

impl<'s> StrainRun<'s> {
    /// The inputs `indices` of `sources`, consecutive and in time order;
    /// read decimated to `rate` if they are sampled at a whole multiple of it.
    pub fn new(sources: &'s [Source], indices: &[usize], rate: Option<f64>) -> StrainRun<'s> {
        let parts: Vec<&Source> = indices.iter().map(|&i| &sources[i]).collect();
        let first = parts[0].span();
        let stored: usize = parts.iter().map(|p| p.span().samples).sum();
        let whole = parts.iter().all(|p| {
            let s = p.span();
            (s.samples as f64 / s.sample_rate).fract() == 0.0
        });
        let dq = parts.iter().map(|p| p.dq().map(<[u32]>::to_vec)).collect::<Option<Vec<_>>>().filter(|_| whole).map(|v| v.concat());
        let source = parts.iter().map(|p| p.span().source).collect::<Vec<_>>().join(" + ");
        let decimator = rate.and_then(|r| decimation(first.sample_rate, r)).map(Decimator::new);
        let (samples, sample_rate) = match &decimator {
            Some(d) => (stored.div_ceil(d.factor), first.sample_rate / d.factor as f64),
            None => (stored, first.sample_rate),
        };
        StrainRun { span: Span { samples, source, sample_rate, ..first }, stored, parts, dq, decimator }
    }

    /// The factor the files are decimated by, if they are.
    pub fn decimation(&self) -> Option<usize> {
        self.decimator.as_ref().map(|d| d.factor)
    }

    /// Samples `start..start + count` of the files, as stored.
    fn stored_samples(&self, start: usize, count: usize) -> Result<Vec<f64>, Error> {
        let mut samples = Vec::with_capacity(count);
        let mut offset = 0;
        for part in &self.parts {
            let n = part.span().samples;
            let (a, b) = (start.max(offset), (start + count).min(offset + n));
            if a < b {
                samples.extend(part.read(a - offset, b - a)?);
            }
            offset += n;
        }
        Ok(samples)
    }

    /// Samples `start..start + count` of the run as a series (after
    /// decimation, if it is decimated: the files are read the filter's
    /// reach beyond the block's ends, so blocks join seamlessly).
    pub fn block(&self, start: usize, count: usize) -> Result<Series, Error> {
        let samples = match &self.decimator {
            None => self.stored_samples(start, count)?,
            Some(d) => {
                let count = count.min(self.span.samples.saturating_sub(start));
                let from = (start * d.factor).saturating_sub(d.reach());
                let to = ((start + count) * d.factor + d.reach()).min(self.stored);
                let stored = self.stored_samples(from, to.saturating_sub(from))?;
                d.apply(&stored, from, start, count)
            }
        };
        let fs = self.span.sample_rate;
        let (s0, s1) = ((start as f64 / fs) as usize, ((start + count) as f64 / fs).ceil() as usize);
        let aligned = (start as f64 / fs).fract() == 0.0;
        Ok(Series {
            detector: self.span.detector.clone(),
            gps_start: self.span.gps_start + start as f64 / fs,
            sample_rate: fs,
            samples,
            dq: self.dq.as_ref().filter(|_| aligned).map(|d| d[s0.min(d.len())..s1.min(d.len())].to_vec()),
            source: self.span.source.clone(),
        })
    }
}
