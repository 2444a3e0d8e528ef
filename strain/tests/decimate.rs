//! Decimation of fast-sampled strain: the filter against
//! `scipy.signal.firwin` and `numpy.convolve` (fixtures from
//! `scripts/strain_fixtures.py --decimation`), and a 16384 Hz input read
//! and scanned as the 4096 Hz data it was made from.

use gwml_strain::blocks::scan_sources;
use gwml_strain::classifier::Classifier;
use gwml_strain::decimate::Decimator;
use gwml_strain::input::{Source, StrainRun};
use gwml_strain::scan::{ScanOptions, Scanner};
use gwml_strain::series::Series;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use realfft::RealFftPlanner;
use std::path::Path;

#[test]
fn the_filter_and_its_output_match_scipy() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/strain");
    let bytes = std::fs::read(dir.join("decimation_input.npy")).unwrap();
    let x: Vec<f64> = npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap();
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("decimation_expected.json")).unwrap()).unwrap();
    let floats = |v: &serde_json::Value| v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect::<Vec<f64>>();
    for case in doc["cases"].as_array().unwrap() {
        let k = case["factor"].as_u64().unwrap() as usize;
        let d = Decimator::new(k);
        let taps = floats(&case["taps"]);
        assert_eq!(d.taps().len(), taps.len());
        let worst = d.taps().iter().zip(&taps).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-15, "factor {k}: taps differ by {worst:e}");
        let want = floats(&case["output"]);
        let got = d.apply(&x, 0, 0, want.len());
        let scale = want.iter().map(|v| v.abs()).fold(0.0, f64::max);
        let worst = got.iter().zip(&want).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(worst < 1e-12 * scale, "factor {k}: outputs differ by {worst:e} (scale {scale})");
    }
}

const FS: f64 = 4096.0;
const SECONDS: usize = 256;

/// 256 s at 4096 Hz: white noise of 1e-21 and two loud sine-Gaussians
/// (150 Hz Q 5 at 60.3 s, 800 Hz Q 9 at 170.7 s), band-limited below
/// 1800 Hz so the decimator's passband holds all of it.
fn slow_strain() -> Vec<f64> {
    let n = SECONDS * FS as usize;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
    let noise = Normal::new(0.0, 1e-21).unwrap();
    let mut x: Vec<f64> = (0..n).map(|_| noise.sample(&mut rng)).collect();
    for (t0, f0, q, amplitude) in [(60.3, 150.0, 5.0, 9e-21), (170.7, 800.0, 9.0, 6e-21)] {
        let tau = q / (std::f64::consts::SQRT_2 * std::f64::consts::PI * f0);
        for (j, v) in x.iter_mut().enumerate() {
            let dt = j as f64 / FS - t0;
            if dt.abs() < 8.0 * tau {
                *v += amplitude * (-(dt / tau).powi(2)).exp() * (2.0 * std::f64::consts::PI * f0 * dt).cos();
            }
        }
    }
    let mut planner = RealFftPlanner::<f64>::new();
    let mut spectrum = planner.plan_fft_forward(n).make_output_vec();
    planner.plan_fft_forward(n).process(&mut x.clone(), &mut spectrum).unwrap();
    for (k, c) in spectrum.iter_mut().enumerate() {
        if k as f64 * FS / n as f64 > 1800.0 {
            *c = 0.0.into();
        }
    }
    planner.plan_fft_inverse(n).process(&mut spectrum, &mut x).unwrap();
    x.iter().map(|v| v / n as f64).collect()
}

/// The same signal at `factor` times the rate, by band-limited (Fourier)
/// interpolation.
fn upsampled(x: &[f64], factor: usize) -> Vec<f64> {
    let (n, m) = (x.len(), x.len() * factor);
    let mut planner = RealFftPlanner::<f64>::new();
    let mut spectrum = planner.plan_fft_forward(n).make_output_vec();
    planner.plan_fft_forward(n).process(&mut x.to_vec(), &mut spectrum).unwrap();
    let mut wide = planner.plan_fft_inverse(m).make_input_vec();
    wide[..spectrum.len()].copy_from_slice(&spectrum);
    let mut y = vec![0.0; m];
    planner.plan_fft_inverse(m).process(&mut wide, &mut y).unwrap();
    y.iter().map(|v| v / n as f64).collect()
}

fn memory(samples: Vec<f64>, sample_rate: f64) -> Source {
    Source::Memory(Series { detector: "H1".into(), gps_start: 1e9, sample_rate, samples, dq: None, source: format!("{sample_rate} Hz") })
}

#[test]
fn a_fast_file_is_read_as_the_slow_data_it_was_made_from() {
    let slow = slow_strain();
    let fast = [memory(upsampled(&slow, 4), 4.0 * FS)];
    let run = StrainRun::new(&fast, &[0], Some(FS));
    assert_eq!(run.decimation(), Some(4));
    assert_eq!((run.span.sample_rate, run.span.samples), (FS, slow.len()));
    let whole = run.block(0, slow.len()).unwrap().samples;
    // Away from the ends (where the filter meets zeros), within the
    // passband's ripple (3e-4) of the original.
    let peak = slow.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let worst = whole.iter().zip(&slow).skip(100).take(slow.len() - 200).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-3 * peak, "worst difference {worst:e} against a peak of {peak:e}");
    // A block read alone is the same samples as the whole run's.
    let part = run.block(100_000, 50_000).unwrap();
    assert_eq!(part.samples, whole[100_000..150_000]);
    assert_eq!(part.gps_start, 1e9 + 100_000.0 / FS);
    // Without a rate to reach, or with one that is not a whole divisor, it is read as it is.
    assert_eq!(StrainRun::new(&fast, &[0], None).decimation(), None);
    assert_eq!(StrainRun::new(&fast, &[0], Some(3000.0)).span.sample_rate, 4.0 * FS);
}

#[test]
fn a_fast_file_scans_like_the_slow_one() {
    let slow = slow_strain();
    let scanner = Scanner::new(ScanOptions::default(), Some(Classifier::shipped().unwrap())).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let scan = |source: Source| scan_sources(&[source], 128.0, (&scanner, &pool), &|_| {}).unwrap();
    let want = scan(memory(slow.clone(), FS));
    let got = scan(memory(upsampled(&slow, 4), 4.0 * FS));
    assert_eq!(got.scanned_seconds, want.scanned_seconds);
    for t0 in [60.3, 170.7] {
        let loudest = |r: &gwml_strain::scan::Report| {
            r.rows
                .iter()
                .filter(|row| (row.trigger.time - 1e9 - t0).abs() < 0.05)
                .max_by(|a, b| a.trigger.snr.total_cmp(&b.trigger.snr))
                .cloned()
        };
        let (a, b) = (loudest(&want).expect("found at 4096 Hz"), loudest(&got).expect("found at 16384 Hz"));
        assert!((a.trigger.time - b.trigger.time).abs() < 1e-3, "{t0}: {} against {}", a.trigger.time, b.trigger.time);
        assert!((a.trigger.snr / b.trigger.snr - 1.0).abs() < 0.02, "{t0}: SNR {} against {}", a.trigger.snr, b.trigger.snr);
        assert_eq!(a.verdict.as_ref().map(|v| v.label), b.verdict.as_ref().map(|v| v.label), "{t0}");
    }
}
