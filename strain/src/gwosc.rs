//! GWOSC HDF5 strain files: reading, and writing in the same layout.
//!
//! The layout (GWOSC's "HDF5 file format" page; what gwpy's
//! `TimeSeries.read(path, format='hdf5.gwosc')` reads):
//! - `strain/Strain`: f64 samples, NaN where data are missing, with
//!   attributes `Xstart` (GPS start), `Xspacing` (1 / sample rate),
//!   `Npoints`, `Xunits` ("second"), `Yunits` ("strain");
//! - `meta/`: `Detector` ("H1"), `Observatory` ("H"), `GPSstart`,
//!   `Duration`, `Type`, `UTCstart`, `Description`;
//! - `quality/simple/`: `DQmask` (u32 per second; bit 0 data present, bits
//!   1–6 CBC and burst categories 1–3), `DQShortnames`, `DQDescriptions`;
//! - `quality/injections/`: `Injmask`, `InjShortnames`.
//!
//! Read and written with `hdf5-pure`, a pure-Rust HDF5 implementation, so no
//! system HDF5 library is needed.

use crate::series::Series;
use crate::Error;
use hdf5_pure::{AttrValue, File, FileBuilder};
use std::path::Path;

/// The names of the `DQmask` bits, in bit order (GWOSC's simple DQ).
pub const DQ_NAMES: [&str; 7] = ["DATA", "CBC_CAT1", "CBC_CAT2", "CBC_CAT3", "BURST_CAT1", "BURST_CAT2", "BURST_CAT3"];

/// What each `DQmask` bit means.
const DQ_DESCRIPTIONS: [&str; 7] = [
    "Data present",
    "Passes the CBC CAT1 test",
    "Passes the CBC CAT2 test",
    "Passes the CBC CAT3 test",
    "Passes the burst CAT1 test",
    "Passes the burst CAT2 test",
    "Passes the burst CAT3 test",
];

/// How to store the strain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WriteOptions {
    /// Samples per chunk: chunked and gzip-compressed, as GWOSC's files are;
    /// `None`: contiguous.
    pub chunk: Option<usize>,
    /// gzip level (0–9) of chunked storage.
    pub gzip_level: u8,
}

/// The largest chunk of `strain/Strain` gwml decompresses (64 MiB of f64;
/// GWOSC files use chunks of a few thousand samples).
const MAX_CHUNK_SAMPLES: u64 = 1 << 23;

/// Reads a GWOSC strain file whole, checking every field it uses.
pub fn read(path: &Path) -> Result<Series, Error> {
    let reader = open(path)?;
    let samples = reader.read_samples(0, reader.samples)?;
    let Reader { detector, gps_start, sample_rate, dq_mask, .. } = reader;
    Ok(Series { detector, gps_start, sample_rate, samples, dq: dq_mask, source: path.display().to_string() })
}

/// An open GWOSC file: its metadata, checked, and its strain read a window
/// at a time (chunks are fetched from disk on demand, so memory follows
/// the window, not the file).
pub struct Reader {
    path: std::path::PathBuf,
    file: File,
    /// `meta/Detector`.
    pub detector: String,
    /// GPS time of the first sample.
    pub gps_start: f64,
    /// Samples per second.
    pub sample_rate: f64,
    /// Samples in `strain/Strain`.
    pub samples: usize,
    /// `quality/simple/DQmask`, one word per second, if present.
    pub dq_mask: Option<Vec<u32>>,
    /// `quality/simple/DQShortnames` (empty if absent).
    pub dq_names: Vec<String>,
}

impl Reader {
    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Samples `start..start + count` of `strain/Strain` (clipped to the file).
    pub fn read_samples(&self, start: usize, count: usize) -> Result<Vec<f64>, Error> {
        let fail = |message: String| Error::file(&self.path, message);
        // Each window is read once: keep no decompressed chunks around.
        let once = hdf5_pure::DatasetAccessProperties::new().with_chunk_cache(hdf5_pure::ChunkCacheConfig::disabled());
        let strain = self.file.dataset_with_options("strain/Strain", once).map_err(|e| fail(format!("no dataset `strain/Strain`: {e}")))?;
        let count = count.min(self.samples.saturating_sub(start));
        let values = strain
            .read_f64_rows(start as u64, count as u64)
            .map_err(|e| fail(format!("cannot read samples {start}..{} of `strain/Strain` (truncated?): {e}", start + count)))?;
        if values.len() != count {
            return Err(fail(format!("`strain/Strain` gave {} of samples {start}..{}", values.len(), start + count)));
        }
        Ok(values)
    }
}

/// Opens a GWOSC strain file and checks its metadata.
pub fn open(path: &Path) -> Result<Reader, Error> {
    let fail = |message: String| Error::file(path, message);
    let is_hdf5 = hdf5_pure::is_hdf5(path).map_err(|e| fail(format!("cannot read: {e}")))?;
    if !is_hdf5 {
        return Err(fail("not an HDF5 file (no HDF5 signature)".into()));
    }
    let file = File::open_streaming(path).map_err(|e| fail(format!("not a readable HDF5 file (truncated or corrupt?): {e}")))?;
    let strain = file.dataset("strain/Strain").map_err(|e| fail(format!("no dataset `strain/Strain`: {e}")))?;
    let attrs = strain.attrs().map_err(|e| fail(format!("cannot read the attributes of `strain/Strain`: {e}")))?;
    let number = |name: &str| -> Result<f64, Error> {
        let value = attrs.get(name).ok_or_else(|| fail(format!("missing attribute `{name}` of dataset `strain/Strain`")))?;
        attr_number(value).ok_or_else(|| fail(format!("attribute `{name}` of `strain/Strain` is not a number ({value:?})")))
    };
    let gps_start = number("Xstart")?;
    let spacing = number("Xspacing")?;
    if !gps_start.is_finite() {
        return Err(fail(format!("attribute `Xstart` of `strain/Strain` is {gps_start}, not a GPS time")));
    }
    if !(spacing > 0.0 && spacing.is_finite()) {
        return Err(fail(format!("attribute `Xspacing` of `strain/Strain` is {spacing}; it must be a positive sample spacing")));
    }
    let sample_rate = 1.0 / spacing;
    // GWOSC spacings are 1/4096 or 1/16384 s exactly; round to the nearest
    // whole rate when it is within rounding of one.
    let sample_rate = if (sample_rate - sample_rate.round()).abs() < 1e-6 { sample_rate.round() } else { sample_rate };
    let shape = strain.shape().map_err(|e| fail(format!("cannot read the shape of `strain/Strain`: {e}")))?;
    let [samples] = shape[..] else {
        return Err(fail(format!("`strain/Strain` has shape {shape:?}; strain is one-dimensional")));
    };
    let samples = samples as usize;
    if samples == 0 {
        return Err(fail("`strain/Strain` is empty".into()));
    }
    // Sizes the file declares, against what it can hold, before anything
    // is allocated by them (cargo-fuzz found a 10 kB file with a chunk that
    // declared 4 GB of stored bytes, which the reader allocated): a sample
    // is 8 bytes, gzip shrinks data at most ~1,032-fold, and every chunk
    // lies inside the file.
    let file_bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(u64::MAX);
    if (samples as u64).saturating_mul(8) / 1100 > file_bytes {
        return Err(fail(format!("`strain/Strain` declares {samples} samples, more than a file of {file_bytes} bytes can hold")));
    }
    if let Some(bad) = strain.chunks().ok().and_then(|cs| cs.into_iter().find(|c| c.address.saturating_add(c.storage_size) > file_bytes)) {
        return Err(fail(format!(
            "a chunk of `strain/Strain` declares {} bytes at byte {}, past the end of the {file_bytes}-byte file (truncated or corrupt)",
            bad.storage_size, bad.address
        )));
    }
    if let Ok(Some(chunk)) = strain.chunk_shape() {
        let floats = chunk.iter().try_fold(1u64, |n, d| n.checked_mul(*d)).unwrap_or(u64::MAX);
        if floats == 0 || floats > MAX_CHUNK_SAMPLES {
            return Err(fail(format!(
                "`strain/Strain` is stored in chunks of {chunk:?} samples; gwml reads chunks of 1 to {MAX_CHUNK_SAMPLES} (the file is corrupt or unusual)"
            )));
        }
    }
    if let Some(n) = attrs.get("Npoints").and_then(attr_number) {
        if n as usize != samples {
            return Err(fail(format!("`strain/Strain` has {samples} samples but its attribute `Npoints` says {n}")));
        }
    }
    let detector = match file.dataset("meta/Detector") {
        Ok(ds) => ds.read_string().ok().and_then(|v| v.into_iter().next()).unwrap_or_default().trim().to_string(),
        Err(_) => String::new(),
    };
    if detector.is_empty() {
        return Err(fail("missing or empty dataset `meta/Detector` (the detector name, e.g. H1)".into()));
    }
    if let Ok(ds) = file.dataset("meta/GPSstart") {
        if let Some(meta_start) = ds.read_f64().ok().and_then(|v| v.first().copied()) {
            if (meta_start - gps_start).abs() >= 1.0 {
                return Err(fail(format!(
                    "`meta/GPSstart` is {meta_start} but `strain/Strain@Xstart` is {gps_start}: the file disagrees with itself"
                )));
            }
        }
    }
    let seconds = (samples as f64 / sample_rate).ceil() as usize;
    let dq_mask = match file.dataset("quality/simple/DQmask") {
        Err(_) => None,
        Ok(ds) => {
            let declared = ds.shape().map(|s| s.iter().product::<u64>()).unwrap_or(0);
            if declared != seconds as u64 {
                return Err(fail(format!(
                    "`quality/simple/DQmask` has {declared} entries but the strain spans {seconds} s (one entry per second)"
                )));
            }
            let mask = ds.read_u32().map_err(|e| fail(format!("cannot read `quality/simple/DQmask` as integers: {e}")))?;
            if mask.len() != seconds {
                return Err(fail(format!(
                    "`quality/simple/DQmask` has {} entries but the strain spans {seconds} s (one entry per second)",
                    mask.len()
                )));
            }
            Some(mask)
        }
    };
    let dq_names = match file.dataset("quality/simple/DQShortnames") {
        Ok(ds) => ds.read_string().unwrap_or_default().into_iter().map(|s| s.trim().to_string()).collect(),
        Err(_) => Vec::new(),
    };
    Ok(Reader { path: path.to_path_buf(), file, detector, gps_start, sample_rate, samples, dq_mask, dq_names })
}

/// The value of a numeric attribute (a scalar or a one-element array).
fn attr_number(value: &AttrValue) -> Option<f64> {
    match value {
        AttrValue::F64(v) => Some(*v),
        AttrValue::F32(v) => Some(f64::from(*v)),
        AttrValue::I64(v) => Some(*v as f64),
        AttrValue::I32(v) => Some(f64::from(*v)),
        AttrValue::U64(v) => Some(*v as f64),
        AttrValue::U32(v) => Some(f64::from(*v)),
        AttrValue::F64Array(v) if v.len() == 1 => Some(v[0]),
        AttrValue::I64Array(v) if v.len() == 1 => Some(v[0] as f64),
        _ => None,
    }
}

/// Writes a series in GWOSC's layout (its DQ mask, or every bit set
/// without one; the DQ names are [`DQ_NAMES`]).
pub fn write(path: &Path, file: &Series, options: &WriteOptions) -> Result<(), Error> {
    let fail = |message: String| Error::file(path, message);
    if file.detector.is_empty() || !(file.sample_rate > 0.0 && file.sample_rate.is_finite()) || !file.gps_start.is_finite() {
        return Err(fail(format!(
            "cannot write detector `{}`, rate {} Hz, start {}: need a name, a positive rate and a finite start",
            file.detector, file.sample_rate, file.gps_start
        )));
    }
    let duration = file.samples.len() as f64 / file.sample_rate;
    let seconds = duration.ceil() as usize;
    let dq: Vec<u32> = match &file.dq {
        Some(mask) if mask.len() == seconds => mask.clone(),
        Some(mask) => return Err(fail(format!("a DQ mask of {} entries for {seconds} s of strain", mask.len()))),
        None => vec![127; seconds],
    };
    let mut builder = FileBuilder::new();
    let mut strain = builder.create_group("strain");
    let ds = strain.create_dataset("Strain");
    ds.with_f64_data(&file.samples);
    if let Some(chunk) = options.chunk {
        ds.with_chunks(&[chunk.clamp(1, file.samples.len().max(1)) as u64]).with_deflate(u32::from(options.gzip_level.min(9)));
    }
    ds.set_attr("Xstart", AttrValue::F64(file.gps_start))
        .set_attr("Xspacing", AttrValue::F64(1.0 / file.sample_rate))
        .set_attr("Npoints", AttrValue::I64(file.samples.len() as i64))
        .set_attr("Xunits", AttrValue::AsciiString("second".into()))
        .set_attr("Yunits", AttrValue::AsciiString("strain".into()));
    builder.add_group(strain.finish());

    let ascii = |e: hdf5_pure::FormatError| fail(format!("cannot store a string: {e}"));
    let mut meta = builder.create_group("meta");
    let observatory: String = file.detector.chars().take(1).collect();
    let strings = [
        ("Detector", file.detector.as_str()),
        ("Observatory", observatory.as_str()),
        ("Type", "StrainTimeSeries"),
        ("UTCstart", ""),
        ("Description", "Strain data written by gwml"),
    ];
    for (name, value) in strings {
        // Scalars, as GWOSC's files and gwpy's reader have them.
        meta.create_dataset(name).with_ascii_strings(&[value]).map_err(ascii)?.with_shape(&[]);
    }
    meta.create_dataset("GPSstart").with_i64_data(&[file.gps_start.floor() as i64]).with_shape(&[]);
    meta.create_dataset("Duration").with_i64_data(&[duration.round() as i64]).with_shape(&[]);
    builder.add_group(meta.finish());

    let mut quality = builder.create_group("quality");
    let mut simple = quality.create_group("simple");
    simple.create_dataset("DQmask").with_u32_data(&dq);
    simple.create_dataset("DQShortnames").with_ascii_strings(&DQ_NAMES).map_err(ascii)?;
    simple.create_dataset("DQDescriptions").with_ascii_strings(&DQ_DESCRIPTIONS).map_err(ascii)?;
    quality.add_group(simple.finish());
    let mut injections = quality.create_group("injections");
    injections.create_dataset("Injmask").with_u32_data(&vec![0; seconds]);
    injections
        .create_dataset("InjShortnames")
        .with_ascii_strings(&["NO_CBC_HW_INJ", "NO_BURST_HW_INJ", "NO_DETCHAR_HW_INJ", "NO_CW_HW_INJ", "NO_STOCH_HW_INJ"])
        .map_err(ascii)?;
    quality.add_group(injections.finish());
    builder.add_group(quality.finish());
    builder.write(path).map_err(|e| fail(format!("cannot write: {e}")))
}
