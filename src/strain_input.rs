//! Strain input arguments shared by `gwml scan`, `gwml qscan` and `gwml
//! explain` (files, or one `.npy` with its rate and start), opened with
//! `gwml_strain::input`, and the stretch around one GPS time.

use gwml_strain::input::{self, NpyInfo, Source, StrainRun};
use gwml_strain::series::Series;
use std::path::PathBuf;

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
        let npy = match (self.sample_rate, self.gps_start) {
            (Some(sample_rate), Some(gps_start)) => Some(NpyInfo { sample_rate, gps_start, ifo: self.ifo.clone() }),
            (None, None) => None,
            _ => return Err("error: --sample-rate and --gps-start go together (a .npy input needs both)".into()),
        };
        self.strain.iter().map(|p| Source::open(p, npy.as_ref()).map_err(|e| format!("error: {e}"))).collect()
    }

    /// `seconds` of strain centred on GPS `gps` (moved inside the data when
    /// `gps` is near an end), with no missing samples: an error names what
    /// is wrong (outside the data, in a gap between files, a stretch
    /// without data, or files too short).
    /// The data are read decimated to `rate` when the files are sampled at
    /// a whole multiple of it.
    pub fn around(&self, gps: f64, seconds: f64, rate: Option<f64>) -> Result<Series, String> {
        if !(gps.is_finite() && seconds > 0.0 && seconds.is_finite()) {
            return Err(format!("error: GPS {gps} and a span of {seconds} s must be finite (and the span positive)"));
        }
        let sources = self.open()?;
        let (runs, _) = input::runs(&sources, rate).map_err(|e| format!("error: {e}"))?;
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
        let series = run.block(first, (seconds * fs).round() as usize).map_err(|e| format!("error: {e}"))?;
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
