//! `std::imrphenom` (IMRPhenomA) against LALSimulation 6.2.1
//! (`fixtures/lal/imrphenoma.json`, written by `scripts/phenoma_fixtures.py`):
//! the complex conjugate of its h+ at inclination 0, phiRef 0 (LAL's
//! frequency-domain IMRPhenomA runs backwards in time in its own Fourier
//! convention; `stdlib/imrphenom.gw` says why), bin for bin below LAL's
//! f_cut, and the gradient of a fit's loss against finite differences.

use gwml::{Model, Value};
use num_complex::Complex64 as C64;
use serde_json::Value as Json;

#[path = "common/gradient_check.rs"]
mod gradient_check;
use gradient_check::assert_gradient_matches;

/// The most bins of a fixture point.
const N: usize = 448;

/// The model at frequencies `fk`, its cut smoothed over a millihertz (every
/// fixture bin lies 0.09 Hz or more below f_cut).
const SOURCE: &str = "use std::imrphenom::{phenoma_strain, phenoma_peak_delay}

scene strain {
    precision: f64
    grid k = frequencies(from: 0 Hz, to: 447 Hz, step: 1 Hz)
    input fk: real[k] Hz
    param mc: Msun = 10.0
    param q = 1.0
    output h = phenoma_strain(fk, mc, q, 100 Mpc, 0 s, 0.0, 0.001 Hz)
}

scene peak {
    grid t = times(rate: 4096 Hz, duration: 8 s)
    grid f = spectrum(t)
    param mc: Msun = 30.0
    param q = 0.8
    let h = phenoma_strain(max(f, 20 Hz), mc, q, 100 Mpc, 4 s + phenoma_peak_delay(mc, q), 0.0, spacing(f)) * select(f >= 20 Hz, 1.0, 0.0)
    let x = irfft(h, t)
    let y = irfft(h * 1.0i, t)
    output envelope = (x * x + y * y) / (1e-21 * 1e-21)
}

scene fit {
    grid f = frequencies(from: 30 Hz, to: 400 Hz, step: 0.5 Hz)
    input d: complex[f] s = phenoma_strain(f, 28.0 Msun, 0.8, 400 Mpc, 0.001 s, 0.4, 0.5 Hz)
    param mc: Msun = 28.3 in 10.0..40.0
    param q = 0.75 in 0.25..1.0
    param tc: s = 0.0012 in -0.1..0.1
    param phic = 0.35
    let h = phenoma_strain(f, mc, q, 400 Mpc, tc, phic, 0.5 Hz)
    output loss = 0.5 * sum(abs2(d - h) / (1e-46 s * 1 s))
    grad loss wrt [mc, q, tc, phic]
}
";

fn fixture() -> Json {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/lal/imrphenoma.json");
    serde_json::from_str(&std::fs::read_to_string(path).expect("fixtures/lal/imrphenoma.json is readable")).expect("valid JSON")
}

fn nums(j: &Json) -> Vec<f64> {
    j.as_array().expect("an array").iter().map(|x| x.as_f64().expect("a number")).collect()
}

#[test]
fn phenoma_matches_lalsimulation_bin_for_bin() {
    let model = Model::from_source("imrphenom_lal.gw", SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("strain")).unwrap();
    let fixture = fixture();
    let mut worst = 0.0f64;
    for p in fixture["points"].as_array().expect("points") {
        let (f, re, im) = (nums(&p["f_hz"]), nums(&p["re"]), nums(&p["im"]));
        assert!(f.len() <= N && f.len() > 50, "{} bins", f.len());
        // Padded with the last frequency (its value is not checked).
        let mut fk = f.clone();
        fk.resize(N, *f.last().unwrap());
        let mut run = scene.bind();
        run.input_real("fk", &fk).unwrap();
        run.param("mc", p["mc_msun"].as_f64().unwrap()).unwrap();
        run.param("q", p["q"].as_f64().unwrap()).unwrap();
        let out = run.forward().unwrap();
        let Value::ComplexArray(h) = out.value("h").unwrap() else { panic!("h is not a complex array") };
        for (i, fi) in f.iter().enumerate() {
            let lal = C64::new(re[i], -im[i]);
            let err = (h[i] - lal).norm() / lal.norm();
            worst = worst.max(err);
            assert!(err < 1e-9, "mc {} q {} at {fi} Hz: gwml {} against LAL {lal} ({err:.1e})", p["mc_msun"], p["q"], h[i]);
        }
    }
    println!("IMRPhenomA vs LALSimulation: worst relative error {worst:.1e}");
}

#[test]
fn phenoma_chirps_forwards_in_time() {
    let model = Model::from_source("imrphenom_lal.gw", SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("strain")).unwrap();
    let mut run = scene.bind();
    // Pairs of frequencies 0.5 Hz apart: the group delay t(f) = -d arg h / (2 pi df).
    let fk: Vec<f64> = (0..N).map(|i| [60.0, 100.0, 150.0, 200.0][(i / 2).min(3)] + 0.5 * (i % 2) as f64).collect();
    run.input_real("fk", &fk).unwrap();
    run.param("mc", 28.6).unwrap();
    run.param("q", 0.81).unwrap();
    let out = run.forward().unwrap();
    let Value::ComplexArray(h) = out.value("h").unwrap() else { panic!("h is not a complex array") };
    let delay: Vec<f64> = (0..4).map(|k| -(h[2 * k + 1] / h[2 * k]).arg() / (2.0 * std::f64::consts::PI * 0.5)).collect();
    assert!(delay.windows(2).all(|w| w[0] < w[1]), "group delays at 60, 100, 150, 200 Hz: {delay:?}");
    assert!(delay[3] < 0.0 && delay[3] > -0.1, "the merger comes shortly before tc: {delay:?}");
}

#[test]
fn phenoma_loss_gradient_matches_finite_differences_through_merger_and_ringdown() {
    let model = Model::from_source("imrphenom_lal.gw", SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("fit")).unwrap();
    let params = [("mc", 28.3), ("q", 0.75), ("tc", 0.0012), ("phic", 0.35)];
    assert_gradient_matches(&scene, &params, "loss", &[("mc", 1e-6), ("q", 1e-6), ("tc", 1e-8), ("phic", 1e-5)], 1e-6);
}

/// `phenoma_peak_delay` puts the peak of the strain's envelope (the
/// analytic signal's modulus, by inverse FFT) at tc minus the delay.
#[test]
fn the_peak_delay_puts_the_merger_where_the_strain_peaks() {
    let model = Model::from_source("imrphenom_lal.gw", SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("peak")).unwrap();
    for (mc, q) in [(10.0, 1.0), (18.0, 0.5), (30.0, 0.8), (40.0, 0.3), (40.0, 1.0)] {
        let mut run = scene.bind();
        run.param("mc", mc).unwrap();
        run.param("q", q).unwrap();
        let out = run.forward().unwrap();
        let Value::RealArray(e) = out.value("envelope").unwrap() else { panic!("envelope is not a real array") };
        let peak = e.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)).unwrap().0 as f64 / 4096.0;
        assert!((peak - 4.0).abs() < 1.5e-3, "mc {mc} q {q}: the envelope peaks at {peak} s, not 4 s");
    }
}
