//! Strain inputs shared by `gwml scan`, `gwml qscan` and `gwml explain`:
//! GWOSC HDF5 files (read a window at a time) or one `.npy`, joined into
//! runs of consecutive files, and the stretch around one GPS time.

use crate::commands::render;
use gwml_strain::gwosc;
use gwml_strain::series::{plan, Series, Span};
use std::path::{Path, PathBuf};

/// Where strain comes from (flattened into each command's arguments).
#[derive(clap::Args)]
pub struct StrainInput {
    /// Strain files: GWOSC HDF5 (.hdf5, .h5) of one detector, consecutive
    /// segments in any order; or one .npy with --sample-rate and --gps-start.
    #[arg(required = true, value_name = "STRAIN")]
    pub strain: Vec<PathBuf>,
    /// .npy input: samples per second.
    #[arg(long, value_name = "HZ")]
    pub sample_rate: Option<f64>,
    /// .npy input: GPS time of the first sample.
    #[arg(long, value_name = "GPS")]
    pub gps_start: Option<f64>,
    /// .npy input: detector name.
    #[arg(long, default_value = "X1")]
    pub ifo: String,
}

impl StrainInput {
    /// Opens every input (metadata only for HDF5 files).
    pub fn open(&self) -> Result<Vec<Source>, String> {
        self.strain.iter().map(|p| open_strain(p, self)).collect()
    }

    /// `seconds` of strain centred on GPS `gps` (moved inside the data when
    /// `gps` is near an end), with no missing samples: an error names what
    /// is wrong (outside the data, in a gap between files, a stretch
    /// without data, or files too short).
    pub fn around(&self, gps: f64, seconds: f64) -> Result<Series, String> {
        if !(gps.is_finite() && seconds > 0.0 && seconds.is_finite()) {
            return Err(format!("error: GPS {gps} and a span of {seconds} s must be finite (and the span positive)"));
        }
        let sources = self.open()?;
        let spans: Vec<Span> = sources.iter().map(Source::span).collect();
        let (runs, _) = plan(&spans).map_err(|e| format!("error: {e}"))?;
        let runs: Vec<StrainRun> = runs.iter().map(|r| StrainRun::new(&sources, r)).collect();
        let extent = |r: &StrainRun| (r.span.gps_start, r.span.gps_start + r.span.samples as f64 / r.span.sample_rate);
        let Some(run) = runs.iter().find(|r| (extent(r).0..extent(r).1).contains(&gps)) else {
            let covered: Vec<String> = runs.iter().map(|r| format!("{:.1}-{:.1}", extent(r).0, extent(r).1)).collect();
            return Err(format!("error: GPS {gps} is not in the data (GPS {} covered)", covered.join(", ")));
        };
        let (start, end) = extent(run);
        if end - start < seconds {
            return Err(format!(
                "error: {} s of data are needed around GPS {gps} but {} holds {:.1} s there",
                seconds,
                run.span.source,
                end - start
            ));
        }
        let fs = run.span.sample_rate;
        let from = (gps - seconds / 2.0).clamp(start, end - seconds);
        let first = ((from - start) * fs).round() as usize;
        let series = run.block(first, (seconds * fs).round() as usize)?;
        if let Some(i) = series.samples.iter().position(|v| !v.is_finite()) {
            let t = series.gps_start + i as f64 / fs;
            return Err(format!(
                "error: GPS {gps}: the {seconds} s around it reach missing data (a NaN sample at GPS {t:.3} in {}); choose a time at least {:.0} s from a gap",
                series.source,
                seconds / 2.0
            ));
        }
        if let Some(dq) = &series.dq {
            if let Some(k) = dq.iter().position(|w| w & 1 == 0) {
                return Err(format!(
                    "error: GPS {gps}: the {seconds} s around it reach a second without data (DQ bit 0 clear at GPS {:.0} in {})",
                    series.gps_start.floor() + k as f64,
                    series.source
                ));
            }
        }
        Ok(series)
    }
}

/// A strain input: an HDF5 file read a window at a time, or a `.npy` held whole.
pub enum Source {
    File(gwosc::Reader),
    Memory(Series),
}

impl Source {
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

    fn read(&self, start: usize, count: usize) -> Result<Vec<f64>, String> {
        match self {
            Source::File(r) => r.read_samples(start, count).map_err(|e| format!("error: {e}")),
            Source::Memory(s) => Ok(s.samples[start.min(s.samples.len())..(start + count).min(s.samples.len())].to_vec()),
        }
    }
}

/// Opens one strain input (an HDF5 file's metadata, or a whole `.npy`).
fn open_strain(path: &Path, a: &StrainInput) -> Result<Source, String> {
    let is_npy = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("npy"));
    if is_npy {
        let (Some(rate), Some(gps)) = (a.sample_rate, a.gps_start) else {
            return Err(format!("error: {}: a .npy file needs --sample-rate and --gps-start", path.display()));
        };
        let data = gwml::runtime::npy::read(path).map_err(render)?;
        if data.complex {
            return Err(format!("error: {}: strain must be real, the file holds complex numbers", path.display()));
        }
        return Ok(Source::Memory(Series {
            detector: a.ifo.clone(),
            gps_start: gps,
            sample_rate: rate,
            samples: data.values.iter().map(|c| c.re).collect(),
            dq: None,
            source: path.display().to_string(),
        }));
    }
    if a.sample_rate.is_some() || a.gps_start.is_some() {
        return Err(format!("error: {}: --sample-rate and --gps-start are for .npy files; an HDF5 file carries its own", path.display()));
    }
    gwosc::open(path).map(Source::File).map_err(|e| format!("error: {e}"))
}

/// Consecutive inputs read as one stretch, a block at a time.
pub struct StrainRun<'s> {
    parts: Vec<&'s Source>,
    /// The run's extent.
    pub span: Span,
    /// The DQ words of the whole run (one per second), if every part has them.
    dq: Option<Vec<u32>>,
}

impl<'s> StrainRun<'s> {
    pub fn new(sources: &'s [Source], indices: &[usize]) -> StrainRun<'s> {
        let parts: Vec<&Source> = indices.iter().map(|&i| &sources[i]).collect();
        let first = parts[0].span();
        let samples = parts.iter().map(|p| p.span().samples).sum();
        let whole = parts.iter().all(|p| {
            let s = p.span();
            (s.samples as f64 / s.sample_rate).fract() == 0.0
        });
        let dq = parts.iter().map(|p| p.dq().map(<[u32]>::to_vec)).collect::<Option<Vec<_>>>().filter(|_| whole).map(|v| v.concat());
        let source = parts.iter().map(|p| p.span().source).collect::<Vec<_>>().join(" + ");
        StrainRun { span: Span { samples, source, ..first }, parts, dq }
    }

    /// Samples `start..start + count` of the run as a series.
    pub fn block(&self, start: usize, count: usize) -> Result<Series, String> {
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
