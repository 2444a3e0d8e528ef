//! The Q tiling against gwpy's `QTiling` on the same data (fixtures from
//! `scripts/strain_fixtures.py`): the same planes, frequency rows and tile
//! counts, and in every plane the same peak tile (time, frequency) with the
//! same median-normalised energy.

use gwml_strain::qtransform::{QOptions, QTiling};
use realfft::RealFftPlanner;
use std::path::Path;

#[test]
fn tiles_and_peaks_match_gwpy() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/strain");
    let bytes = std::fs::read(dir.join("qscan_input.npy")).unwrap();
    let x: Vec<f64> = npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap();
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("qscan_expected.json")).unwrap()).unwrap();
    let fs = doc["fs"].as_f64().unwrap();
    let duration = x.len() as f64 / fs;
    let options = QOptions { q_range: (4.0, 64.0), f_range: (20.0, 400.0), mismatch: 0.2, smooth_sizes: false, plane_nyquist: false };
    let tiling = QTiling::new(duration, fs, &options).unwrap();
    let want_range: Vec<f64> = doc["frange"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    assert!((tiling.f_range.0 - want_range[0]).abs() < 1e-9 && (tiling.f_range.1 - want_range[1]).abs() < 1e-9);
    let mut input = x.clone();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(x.len());
    let mut spectrum = fft.make_output_vec();
    fft.process(&mut input, &mut spectrum).unwrap();
    let planes = doc["planes"].as_array().unwrap();
    assert_eq!(tiling.planes.len(), planes.len());
    for (plane, want) in tiling.planes.iter().zip(planes) {
        assert!((plane.q - want["q"].as_f64().unwrap()).abs() < 1e-9);
        let freqs: Vec<f64> = want["frequencies"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        let tiles: Vec<usize> = want["ntiles"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as usize).collect();
        assert_eq!(plane.rows.len(), freqs.len(), "Q {}", plane.q);
        for ((row, f), n) in plane.rows.iter().zip(&freqs).zip(&tiles) {
            assert!((row.frequency - f).abs() < 1e-9, "Q {}: row {} Hz vs gwpy {f} Hz", plane.q, row.frequency);
            assert_eq!(row.tiles, *n, "Q {} at {f} Hz", plane.q);
        }
        let (mut energy, mut time, mut frequency) = (0.0, 0.0, 0.0);
        for row in &plane.rows {
            for (j, e) in row.energies(&spectrum).iter().enumerate() {
                if *e > energy {
                    (energy, time, frequency) = (*e, j as f64 * duration / row.tiles as f64, row.frequency);
                }
            }
        }
        let want_energy = want["peak_energy"].as_f64().unwrap();
        assert_eq!(time, want["peak_time"].as_f64().unwrap(), "Q {}", plane.q);
        assert_eq!(frequency, want["peak_frequency"].as_f64().unwrap(), "Q {}", plane.q);
        // gwpy stores normalised energies as float32.
        assert!((energy / want_energy - 1.0).abs() < 1e-5, "Q {}: energy {energy} vs gwpy {want_energy}", plane.q);
    }
}
