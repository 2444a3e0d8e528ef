//! `std::psd` against LALSimulation 6.2.1's analytic aLIGO zero-detuned
//! high-power PSD, `XLALSimNoisePSDaLIGOZeroDetHighPower`
//! (`fixtures/lal/psd_aligo_zerodet_highpower.json`, written by
//! `scripts/lal_fixtures.py`), and a gradient check through the PSD.
//!
//! Every fixture frequency is checked to 1e-12 relative: the 200-point log
//! grid (total, quantum and thermal parts), the `exact_points` and the
//! `below_validity` points (finite there; at f = 0, where LAL returns NaN,
//! the runtime reports a non-finite output).

use gwml::{Model, Scene, Value};
use serde_json::Value as Json;

const TOL: f64 = 1e-12;

/// Frequency slots per run (the fixture's log grid has 200 points).
const N: usize = 200;

const FIXTURE_SOURCE: &str = "use std::psd::{psd_aligo_zerodet_highpower, psd_aligo_quantum_zerodet_highpower, psd_aligo_thermal}

scene psd_fixture {
    precision: f64
    grid k = frequencies(from: 0 Hz, to: 199 Hz, step: 1 Hz)
    input fk: real[k] Hz
    output psd = psd_aligo_zerodet_highpower(fk)
    output quantum = psd_aligo_quantum_zerodet_highpower(fk)
    output thermal = psd_aligo_thermal(fk)
}
";

/// The fixture (serde_json's `float_roundtrip` feature reads every number exactly).
fn load_fixture() -> Json {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/lal/psd_aligo_zerodet_highpower.json");
    let text = std::fs::read_to_string(path).expect("fixture is readable");
    serde_json::from_str(&text).expect("valid JSON")
}

/// A number of the fixture (the string "nan" where LAL returned NaN).
fn num(j: &Json) -> f64 {
    match j.as_str() {
        Some("nan") => f64::NAN,
        _ => j.as_f64().unwrap_or_else(|| panic!("a number, found {j}")),
    }
}

fn nums(j: &Json) -> Vec<f64> {
    j.as_array().expect("an array").iter().map(num).collect()
}

fn real_array(v: &Value) -> &[f64] {
    match v {
        Value::RealArray(a) => a,
        other => panic!("expected a real array, found {other:?}"),
    }
}

/// (psd, quantum, thermal) at the given frequencies (at most N).
fn evaluate(scene: &Scene, freqs: &[f64]) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    assert!(freqs.len() <= N);
    let mut fk = freqs.to_vec();
    fk.resize(N, 100.0);
    let mut run = scene.bind();
    run.input_real("fk", &fk).unwrap();
    let out = run.forward().unwrap();
    let take = |name: &str| real_array(out.value(name).unwrap())[..freqs.len()].to_vec();
    (take("psd"), take("quantum"), take("thermal"))
}

fn rel(a: f64, b: f64) -> f64 {
    (a / b - 1.0).abs()
}

#[test]
fn aligo_zerodet_highpower_matches_lalsimulation() {
    let fixture = load_fixture();
    let model = Model::from_source("psd_fixtures.gw", FIXTURE_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("psd_fixture")).unwrap();

    // The 200-point log grid, 9 Hz to 4096 Hz: total and both parts.
    let freqs = nums(&fixture["freq_hz"]);
    assert_eq!(freqs.len(), N);
    let (psd, quantum, thermal) = evaluate(&scene, &freqs);
    let mut worst = [0.0f64; 3];
    for (part, (ours, key)) in [(&psd, "psd"), (&quantum, "psd_quantum"), (&thermal, "psd_thermal")].into_iter().enumerate() {
        let lal = nums(&fixture[key]);
        assert_eq!(lal.len(), N);
        for i in 0..N {
            let e = rel(ours[i], lal[i]);
            assert!(e <= TOL, "{key} at {} Hz: gwml {} vs LAL {} (relative error {e:e})", freqs[i], ours[i], lal[i]);
            worst[part] = worst[part].max(e);
        }
    }

    // The exact points and the points below the model's validity (~9 Hz).
    let mut extra_f = Vec::new();
    let mut extra_psd = Vec::new();
    for group in ["exact_points", "below_validity"] {
        for p in fixture[group].as_array().expect("a fixture group") {
            extra_f.push(num(&p["freq_hz"]));
            extra_psd.push(num(&p["psd"]));
        }
    }
    // LAL's NaN at f = 0: the runtime refuses non-finite outputs, so gwml
    // reports an error there instead.
    let nan_at: Vec<f64> = extra_f.iter().zip(&extra_psd).filter(|(_, p)| p.is_nan()).map(|(f, _)| *f).collect();
    assert_eq!(nan_at, [0.0], "the fixture records NaN at f = 0 only");
    let mut run = scene.bind();
    run.input_real("fk", &[0.0; N]).unwrap();
    let err = run.forward().expect_err("the PSD at f = 0 is not finite");
    assert!(err.to_string().contains("not finite"), "{err}");
    let (extra_f, extra_psd): (Vec<f64>, Vec<f64>) = extra_f.iter().zip(&extra_psd).filter(|(_, p)| !p.is_nan()).unzip();
    let (psd, _, _) = evaluate(&scene, &extra_f);
    let mut worst_extra = 0.0f64;
    for ((f, ours), lal) in extra_f.iter().zip(&psd).zip(&extra_psd) {
        let e = rel(*ours, *lal);
        assert!(e <= TOL, "psd at {f} Hz: gwml {ours} vs LAL {lal} (relative error {e:e})");
        worst_extra = worst_extra.max(e);
    }
    println!(
        "aLIGO zero-det high-power PSD vs LALSimulation 6.2.1: max relative error over {N} grid points: \
         total {:.2e}, quantum {:.2e}, thermal {:.2e}; exact + below-validity points ({}): {worst_extra:.2e}",
        worst[0],
        worst[1],
        worst[2],
        extra_f.len()
    );
}

const GRADIENT_SOURCE: &str = "use std::psd::{psd_aligo_zerodet_highpower}

// A PSD-weighted sum with the frequencies stretched by `a`: the gradient
// runs through every term of the PSD (complex quantum part included).
scene stretched {
    grid f = frequencies(from: 10 Hz, to: 2000 Hz, step: 0.5 Hz)
    param a = 1.0 in 0.5..2.0
    output w = sum(1e-46 s / psd_aligo_zerodet_highpower(a * f)) / 3981.0
    grad w wrt [a]
}

// The PSD at one frequency, a param.
scene at_frequency {
    param fr: Hz = 50.0 in 5.0..4000.0
    output lpsd = log(psd_aligo_zerodet_highpower(fr) / 1e-46 s)
    grad lpsd wrt [fr]
}
";

/// Value, gradient and central finite difference of a one-param scene.
fn value_grad_fd(scene: &Scene, output: &str, param: &str, x: f64, h: f64) -> (f64, f64, f64) {
    let eval = |x: f64| {
        let mut run = scene.bind();
        run.param(param, x).unwrap();
        run.forward().unwrap().scalar(output).unwrap()
    };
    let mut run = scene.bind();
    run.param(param, x).unwrap();
    let out = run.value_and_grad().unwrap();
    let (v, g) = (out.scalar(output).unwrap(), out.grad(output, param).unwrap());
    assert_eq!(v, eval(x), "{output}: value_and_grad and forward disagree");
    (v, g, (eval(x + h) - eval(x - h)) / (2.0 * h))
}

#[test]
fn psd_gradients_match_finite_differences() {
    let model = Model::from_source("psd_gradients.gw", GRADIENT_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let stretched = model.scene(Some("stretched")).unwrap();
    for a in [0.9, 1.0, 1.3] {
        let (w, g, fd) = value_grad_fd(&stretched, "w", "a", a, 1e-6);
        assert!(w.is_finite() && w > 0.0, "w({a}) = {w}");
        assert!((g - fd).abs() <= 1e-7 * fd.abs(), "dw/da at a = {a}: {g} vs FD {fd}");
    }
    let at_frequency = model.scene(Some("at_frequency")).unwrap();
    for fr in [9.5, 20.0, 55.0, 300.0, 3000.0] {
        let (_, g, fd) = value_grad_fd(&at_frequency, "lpsd", "fr", fr, 1e-5 * fr);
        assert!((g - fd).abs() <= 1e-7 * fd.abs().max(1e-3 / fr), "d log S / df at {fr} Hz: {g} vs FD {fd}");
    }
}
