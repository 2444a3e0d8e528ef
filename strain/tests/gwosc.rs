//! The GWOSC reader against files h5py wrote in GWOSC's layout
//! (`scripts/strain_fixtures.py`), the writer by round trip, and bad files.

use gwml_strain::gwosc::{open, read, write, WriteOptions, DQ_NAMES};
use gwml_strain::series::Series;
use std::path::{Path, PathBuf};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/strain").join(name)
}

fn npy<T: npyz::Deserialize>(name: &str) -> Vec<T> {
    let bytes = std::fs::read(fixture(name)).unwrap();
    npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap()
}

fn expected(name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(fixture("gwosc_expected.json")).unwrap();
    serde_json::from_str::<serde_json::Value>(&text).unwrap()[name].clone()
}

fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
}

#[test]
fn h5py_files_read_exactly_contiguous_and_chunked_gzip() {
    for (file, stem) in [("gwosc_contiguous.hdf5", "gwosc_contiguous"), ("gwosc_chunked_gzip.hdf5", "gwosc_chunked_gzip")] {
        let got = read(&fixture(file)).unwrap();
        let want = expected(file);
        assert_eq!(got.detector, want["detector"].as_str().unwrap(), "{file}");
        assert_eq!(got.gps_start, want["gps_start"].as_f64().unwrap(), "{file}");
        assert_eq!(got.sample_rate, want["sample_rate"].as_f64().unwrap(), "{file}");
        assert!(same_bits(&got.samples, &npy::<f64>(&format!("{stem}.strain.npy"))), "{file}: samples differ");
        assert_eq!(got.dq.as_deref(), Some(&npy::<u32>(&format!("{stem}.dq.npy"))[..]), "{file}");
        assert_eq!(open(&fixture(file)).unwrap().dq_names, DQ_NAMES.to_vec(), "{file}");
        let nan_seconds: Vec<usize> =
            (0..got.samples.len() / got.sample_rate as usize).filter(|s| got.samples[s * got.sample_rate as usize].is_nan()).collect();
        let want_nan: Vec<usize> = want["nan_seconds"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as usize).collect();
        assert_eq!(nan_seconds, want_nan, "{file}");
    }
}

#[test]
fn written_files_read_back_bit_for_bit() {
    let dir = std::env::temp_dir().join(format!("gwml-gwosc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut samples: Vec<f64> = (0..4096 * 3).map(|j| 1e-21 * ((j as f64) * 0.37).sin()).collect();
    samples[4096..4096 + 100].iter_mut().for_each(|v| *v = f64::NAN);
    let file = Series {
        detector: "V1".into(),
        gps_start: 1_187_008_866.0,
        sample_rate: 4096.0,
        samples,
        dq: Some(vec![127, 0, 63]),
        source: "test".into(),
    };
    for (name, chunk) in [("contiguous.hdf5", None), ("chunked.hdf5", Some(1000))] {
        let path = dir.join(name);
        write(&path, &file, &WriteOptions { chunk, gzip_level: 4 }).unwrap();
        let back = read(&path).unwrap();
        assert!(same_bits(&back.samples, &file.samples), "{name}");
        assert_eq!(
            (back.detector.as_str(), back.gps_start, back.sample_rate, back.dq.as_deref()),
            ("V1", file.gps_start, 4096.0, file.dq.as_deref()),
            "{name}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_files_are_errors_naming_the_file_and_the_problem() {
    let cases = [
        ("no_such_file.hdf5", "cannot read"),
        ("not_hdf5.hdf5", "not an HDF5 file"),
        ("gwosc_truncated.hdf5", "truncated"),
        ("gwosc_missing_xspacing.hdf5", "missing attribute `Xspacing` of dataset `strain/Strain`"),
    ];
    for (name, message) in cases {
        let err = read(&fixture(name)).unwrap_err().to_string();
        assert!(err.contains(name) && err.contains(message), "{name}: {err}");
    }
}
