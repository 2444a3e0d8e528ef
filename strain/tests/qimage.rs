//! The Q-transform image against gwpy's `TimeSeries.q_transform` on the same
//! data (fixtures from `scripts/strain_fixtures.py`): the same plane, the
//! image's maximum at the same time and frequency with the same value, and
//! the image value by value on a coarse grid.

use gwml_strain::qimage::{q_image, ImageOptions};
use gwml_strain::qtransform::QOptions;
use std::path::Path;

#[test]
fn the_image_matches_gwpy_s_q_transform() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/strain");
    let bytes = std::fs::read(dir.join("qscan_input.npy")).unwrap();
    let x: Vec<f64> = npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap();
    let want: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("qimage_expected.json")).unwrap()).unwrap();
    let num = |k: &str| want[k].as_f64().unwrap();
    let tiling = QOptions { q_range: (4.0, 64.0), f_range: (20.0, 400.0), mismatch: 0.2, smooth_sizes: false, plane_nyquist: false };
    let o = ImageOptions { outseg: (3.7, 4.7), search: Some((3.95, 4.45)), times: 1000, frequencies: 500 };
    let img = q_image(&x, 1024.0, 0.0, &tiling, &o).unwrap();
    assert!((img.q - num("q")).abs() < 1e-9, "plane Q {} vs gwpy {}", img.q, num("q"));
    assert!((img.times[1] - img.times[0] - num("dt")).abs() < 1e-9);
    assert!((img.frequencies[0] - num("f_lo")).abs() < 1e-9 && (img.frequencies[499] - num("f_hi")).abs() < 1e-6);
    let max = img.max();
    assert!((max.time - num("max_time")).abs() <= 0.002, "peak time {} vs gwpy {}", max.time, num("max_time"));
    assert!((max.frequency / num("max_frequency") - 1.0).abs() < 0.02, "peak frequency {} vs gwpy {}", max.frequency, num("max_frequency"));
    assert!((max.energy / num("max_value") - 1.0).abs() < 0.02, "peak energy {} vs gwpy {}", max.energy, num("max_value"));
    // Value by value where the image is bright (a fifth of the peak and up),
    // within 5 % of the peak: the interpolants differ between tiles.
    let coarse = want["coarse"].as_array().unwrap();
    let nf = img.frequencies.len();
    let mut compared = 0;
    for (a, row) in coarse.iter().enumerate() {
        for (b, v) in row.as_array().unwrap().iter().enumerate() {
            let v = v.as_f64().unwrap();
            let ours = img.values[(50 * a) * nf + 25 * b];
            if v > 0.2 * max.energy {
                compared += 1;
            }
            assert!((ours - v).abs() < 0.05 * max.energy, "at {} s, {} Hz: {ours} vs gwpy {v}", img.times[50 * a], img.frequencies[25 * b]);
        }
    }
    assert!(compared >= 1, "the coarse grid holds none of the glitch");
}
