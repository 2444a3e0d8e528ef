//! `std::constrained`: the learned PSD correction and the learned band
//! filter keep their properties for any weights (positive and smooth;
//! band-limited, zero-phase and of unit energy), their band powers have
//! the stated values on spectra known exactly, and their gradients agree
//! with finite differences and the interpreter.

mod common;

use common::{check_against_interpreter, check_weight_gradients, pseudo_random};
use gwml_runtime::{Model, Value};
use nalgebra::{DMatrix, DVector};

const RATE: f64 = 4096.0;

/// Runs `body` (statements and outputs of a scene over 1 s at 4096 Hz with
/// input `x`, and `c` of 7 values) and returns the real array `name`.
fn real_output(body: &str, x: &[f64], c: &[f64], bind: &[(&str, Vec<f64>)], name: &str) -> Vec<f64> {
    let src = format!(
        "use std::constrained::{{psd_correction, band_filter, log_band_powers}}\n\
         scene s {{\n  grid t = times(rate: 4096 Hz, duration: 1 s)\n  grid f = spectrum(t)\n  grid k = index(7)\n  \
         input x: real[t] = 0.0\n  input c: real[k] = 0.0\n  let d = rfft(x, f)\n{body}\n}}\n"
    );
    let model = Model::from_source("constrained.gw", &src).unwrap_or_else(|e| panic!("{e}\n{src}"));
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.input_real("x", x).unwrap().input_real("c", c).unwrap();
    for (n, v) in bind {
        run.input_real(n, v).unwrap();
    }
    match run.forward().unwrap().value(name).unwrap() {
        Value::RealArray(v) => v.clone(),
        v => panic!("{name} is {v:?}"),
    }
}

/// An impulse of height `a` at sample `at` of 1 s: a flat spectrum, whose
/// periodogram is a² / n at every bin.
fn impulse(a: f64, at: usize) -> Vec<f64> {
    let mut x = vec![0.0; RATE as usize];
    x[at] = a;
    x
}

/// The bump of `std::constrained` centred at `c` Hz, written out again.
fn bump(f: f64, c: f64) -> f64 {
    let l = (f.max(1.0) / c).log2();
    (-l * l / (2.0 * 0.25)).exp()
}

#[test]
fn band_powers_are_zero_for_white_noise_and_log_two_for_twice_its_power() {
    let n = RATE;
    let white = real_output("  output v = log_band_powers(d, t, f)", &impulse(n.sqrt(), 0), &[0.0; 7], &[], "v");
    let twice = real_output("  output v = log_band_powers(d, t, f)", &impulse((2.0 * n).sqrt(), 0), &[0.0; 7], &[], "v");
    assert_eq!(white.len(), 7);
    for (w, t) in white.iter().zip(&twice) {
        assert!((w - 1e-6f64.ln_1p()).abs() < 1e-12, "{white:?}");
        assert!((t - (2.0 + 1e-6f64).ln()).abs() < 1e-12, "{twice:?}");
    }
}

#[test]
fn a_window_of_zeros_gives_finite_band_powers_and_passes_as_zeros() {
    let zeros = vec![0.0; RATE as usize];
    let v = real_output("  output v = log_band_powers(d, t, f)", &zeros, &[0.0; 7], &[], "v");
    assert!(v.iter().all(|p| (p - 1e-6f64.ln()).abs() < 1e-9), "the floor, not -inf: {v:?}");
    let w: Vec<f64> = pseudo_random(49, 5).iter().map(|v| 0.5 * v).collect();
    let body = "  output y = irfft(psd_correction(d, t, f), t)";
    let y = real_output(body, &zeros, &[0.0; 7], &[("psd_correction.w", w)], "y");
    assert!(y.iter().all(|v| *v == 0.0), "zeros stay zeros");
}

#[test]
fn the_psd_correction_starts_as_the_identity_and_stays_positive_and_smooth() {
    let x: Vec<f64> = pseudo_random(RATE as usize, 3).iter().map(|v| v * 3f64.sqrt()).collect();
    let body = "  output ratio = abs(psd_correction(d, t, f)) / abs(d)";
    let at_start = real_output(body, &x, &[0.0; 7], &[], "ratio");
    assert!(at_start.iter().all(|r| (r - 1.0).abs() < 1e-12), "zero weights change nothing");
    // Large random weights: the correction is still positive, and its log
    // is exactly a sum of the seven bumps (least squares leaves nothing).
    let w: Vec<f64> = pseudo_random(49, 5).iter().map(|v| 4.0 * v).collect();
    let b: Vec<f64> = pseudo_random(7, 6).iter().map(|v| 2.0 * v).collect();
    let ratio = real_output(body, &x, &[0.0; 7], &[("psd_correction.w", w), ("psd_correction.b", b)], "ratio");
    assert!(ratio.iter().all(|r| r.is_finite() && *r > 0.0), "a positive, finite correction");
    let log_g: Vec<f64> = ratio.iter().map(|r| -2.0 * r.ln()).collect();
    let basis = DMatrix::from_fn(log_g.len(), 7, |k, m| bump(k as f64, 20.0 * 2f64.powi(m as i32)));
    let target = DVector::from_vec(log_g.clone());
    let coef = basis.clone().svd(true, true).solve(&target, 1e-12).unwrap();
    let residual = (&basis * &coef - &target).amax();
    let size = target.amax();
    assert!(size > 0.5, "the weights move the correction ({size})");
    assert!(residual < 1e-9 * size, "log g is a sum of the bumps: residual {residual} of {size}");
}

#[test]
fn band_filters_are_band_limited_zero_phase_and_of_unit_energy() {
    let centre = RATE as usize / 2;
    for seed in 0..3 {
        let c: Vec<f64> = pseudo_random(7, 10 + seed).iter().map(|v| 3.0 * v).collect();
        let body = "  output y = band_filter(d, c, t, f, 30 Hz, 900 Hz)\n  output spec = abs(rfft(y, f)) / 1 s";
        let y = real_output(body, &impulse(1.0, centre), &c, &[], "y");
        // The impulse response's energy is the variance white noise of unit
        // variance comes out with.
        let energy: f64 = y.iter().map(|v| v * v).sum();
        assert!((energy - 1.0).abs() < 1e-12, "unit energy: {energy}");
        for j in 1..centre {
            assert!((y[centre + j] - y[centre - j]).abs() < 1e-12, "zero phase: symmetric about the impulse");
        }
        let spec = real_output(body, &impulse(1.0, centre), &c, &[], "spec");
        let peak = spec.iter().cloned().fold(0.0, f64::max);
        for (k, s) in spec.iter().enumerate() {
            if !(30.0..=900.0).contains(&(k as f64)) {
                assert!(*s < 1e-12 * peak, "nothing at {k} Hz outside the band: {s} of {peak}");
            }
        }
    }
}

#[test]
fn constrained_layers_have_correct_gradients() {
    let src = "use std::constrained::{psd_correction, band_filter}\n\
               learned filt(d, t: s, f: Hz) {\n    weight c: [7] = normal(std: 0.7, seed: 1)\n    \
               band_filter(d, c, t, f, 20 Hz, 1500 Hz)\n}\n\
               scene s {\n  grid t = times(rate: 4096 Hz, duration: 0.0625 s)\n  grid f = spectrum(t)\n  \
               input x: real[t] = 0.0\n  input ramp: real[t] = 0.0\n  \
               let y = filt(psd_correction(rfft(x, f), t, f), t, f)\n  output out = sum(y * y * ramp)\n  \
               grad out wrt [psd_correction, filt]\n}\n";
    // The correction's weights away from their zero start, so that every
    // path through it carries a gradient.
    let data = [
        ("x", pseudo_random(256, 1)),
        ("ramp", pseudo_random(256, 2)),
        ("psd_correction.w", pseudo_random(49, 3).iter().map(|v| 0.5 * v).collect()),
        ("psd_correction.b", pseudo_random(7, 4)),
    ];
    check_weight_gradients(src, &data, "out");
    check_against_interpreter(src, &data);
}
