//! `gwml.scan`: GWOSC strain files in, glitch triggers out, as `gwml scan`
//! finds them (the same blocks, scanner and shipped classifier, from
//! `gwml_strain`), returned as columns instead of a CSV file.

use crate::errors::bind_error;
use gwml_strain::blocks::scan_sources;
use gwml_strain::classifier::{probability_column, Classifier};
use gwml_strain::input::{NpyInfo, Source};
use gwml_strain::scan::{ScanOptions, Scanner};
use numpy::PyArray1;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// Scans `paths` (consecutive GWOSC HDF5 files of one detector, or one
/// `.npy` with `sample_rate` and `gps_start`) and returns `(columns,
/// classes)`: a dict of the CLI's CSV columns (floats and `tiles` as NumPy
/// arrays, `ifo` and `label` as lists of str, one `p_<class>` column per
/// class) and the classifier's class names. The GIL is released while
/// scanning.
#[pyfunction]
#[pyo3(signature = (paths, *, snr_threshold=7.5, min_significance=None, fmin=10.0, fmax=2048.0, psd_stretch=128.0, fft_length=4.0, block=1024.0, threads=None, classify=true, sample_rate=None, gps_start=None, ifo="X1".to_string()))]
#[allow(clippy::too_many_arguments)]
pub fn scan<'py>(
    py: Python<'py>,
    paths: Vec<PathBuf>,
    snr_threshold: f64,
    min_significance: Option<f64>,
    fmin: f64,
    fmax: f64,
    psd_stretch: f64,
    fft_length: f64,
    block: f64,
    threads: Option<usize>,
    classify: bool,
    sample_rate: Option<f64>,
    gps_start: Option<f64>,
    ifo: String,
) -> PyResult<(Bound<'py, PyDict>, Vec<String>)> {
    let fail = |e: gwml_strain::Error| e.to_string();
    let npy = match (sample_rate, gps_start) {
        (Some(sample_rate), Some(gps_start)) => Some(NpyInfo { sample_rate, gps_start, ifo }),
        (None, None) => None,
        _ => return Err(bind_error(py, "sample_rate and gps_start go together (a .npy input needs both)".into())),
    };
    if paths.is_empty() {
        return Err(bind_error(py, "no strain files given".into()));
    }
    if !(block >= 64.0 && block.is_finite()) {
        return Err(bind_error(py, format!("block {block}: blocks of at least 64 s are needed")));
    }
    let defaults = ScanOptions::default();
    let min_significance = min_significance.unwrap_or(defaults.min_significance);
    let options = ScanOptions { snr_threshold, min_significance, f_range: (fmin, fmax), psd_stretch, fft_length, ..defaults };
    let result = py.detach(|| -> Result<_, String> {
        let sources: Vec<Source> = paths.iter().map(|p| Source::open(p, npy.as_ref())).collect::<Result<_, _>>().map_err(fail)?;
        let classifier = if classify { Some(Classifier::shipped().map_err(fail)?) } else { None };
        let scanner = Scanner::new(options, classifier).map_err(fail)?;
        let threads = threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get())).max(1);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| e.to_string())?;
        let report = scan_sources(&sources, block, (&scanner, &pool), &|_| {}).map_err(fail)?;
        let classes = scanner.classifier().map_or(Vec::new(), |c| c.manifest.classes.clone());
        Ok((report, classes))
    });
    let (report, classes) = result.map_err(|e| bind_error(py, e))?;
    let columns = PyDict::new(py);
    let rows = &report.rows;
    let floats = |f: &dyn Fn(&gwml_strain::scan::Row) -> f64| PyArray1::from_vec(py, rows.iter().map(f).collect());
    columns.set_item("gps_time", floats(&|r| r.trigger.time))?;
    columns.set_item("ifo", vec![report.ifo.clone(); rows.len()])?;
    columns.set_item("snr", floats(&|r| r.trigger.snr))?;
    columns.set_item("peak_frequency", floats(&|r| r.trigger.peak_frequency))?;
    columns.set_item("q", floats(&|r| r.trigger.q))?;
    columns.set_item("duration", floats(&|r| r.trigger.duration()))?;
    let label = |r: &gwml_strain::scan::Row| r.verdict.as_ref().map_or(String::new(), |v| classes[v.label].clone());
    columns.set_item("label", rows.iter().map(label).collect::<Vec<_>>())?;
    columns.set_item("confidence", floats(&|r| r.verdict.as_ref().map_or(f64::NAN, |v| v.probabilities[v.label])))?;
    columns.set_item("start", floats(&|r| r.trigger.start))?;
    columns.set_item("end", floats(&|r| r.trigger.end))?;
    columns.set_item("f_start", floats(&|r| r.trigger.f_start))?;
    columns.set_item("f_end", floats(&|r| r.trigger.f_end))?;
    columns.set_item("tiles", PyArray1::from_vec(py, rows.iter().map(|r| r.trigger.tiles as i64).collect()))?;
    for (k, class) in classes.iter().enumerate() {
        columns.set_item(probability_column(class), floats(&|r| r.verdict.as_ref().map_or(f64::NAN, |v| v.probabilities[k])))?;
    }
    Ok((columns, classes))
}
