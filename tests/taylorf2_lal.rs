//! `std::taylorf2` against LALSimulation 6.2.1 TaylorF2
//! (`fixtures/lal/taylorf2.json`, written by `scripts/lal_fixtures.py`), and
//! gradient checks of TaylorF2 losses.
//!
//! Conventions aligned, exactly as the fixture's `conventions` document them
//! (nothing is fitted):
//! - LAL's h+ is `-(1+cos^2 i)/2 A(f) exp(-i Psi(f))` with
//!   `Psi = 2 pi f tc - phic - pi/4 + psi_PN(f)`, `tc = 0` (LAL's time shift
//!   is 2 pi k on bin k) and `phic = 2 phiRef + psi_PN(f_ref)` when f_ref > 0
//!   (else `2 phiRef`); psi_PN(f_ref) is computed by the gwml model itself.
//! - So `arg h+ = pi - Psi(f)` (mod 2 pi): the pi is LAL's negative amplitude
//!   prefactor. The fixture's unwrapped phase equals that plus 2 pi n with n
//!   recorded (`checks.lal_model.n_2pi`); we compute n by rounding, assert
//!   it equals the recorded n, then assert the remainder is <= 1e-7 rad.
//! - `|h+| = (1+cos^2 i)/2 A(f)`, asserted to 1e-9 relative; `hx = -i cos(i) h`.
//! - Below f_isco LAL (called with f_max = 1024 Hz) and gwml agree; above it
//!   gwml's amplitude is exactly 0 (LAL's cut with f_max = 0, whose last
//!   nonzero bin is also recorded and checked).

use gwml::{Model, Scene, Value};
use num_complex::Complex64 as C64;
use serde_json::Value as Json;
use std::f64::consts::PI;

#[path = "common/gradient_check.rs"]
mod gradient_check;
use gradient_check::{assert_gradient_matches, central_difference};

/// Frequency slots per run: up to 72 fixture samples, padding, and the two
/// bins around LAL's ISCO cut in the last two slots.
const N: usize = 74;

const PHASE_TOL: f64 = 1e-7;
const AMP_TOL: f64 = 1e-9;

/// One scene per PN order (the order is a compile-time knob).
fn fixture_source() -> String {
    let mut s = String::from("use std::taylorf2::{tf2_phase, tf2_psi_pn, tf2_amplitude, tf2_hplus, tf2_hcross, tf2_isco_frequency}\n");
    for order in 0..=7 {
        s += &format!(
            "scene tf2_o{order} {{
    precision: f64
    grid k = frequencies(from: 0 Hz, to: {last} Hz, step: 1 Hz)
    input fk: real[k] Hz
    param mc: Msun = 10.0
    param q = 1.0
    param chi1 = 0.0
    param chi2 = 0.0
    param dist: Mpc = 100.0
    param tc: s = 0.0
    param phic = 0.0
    param iota = 0.0
    output psi = tf2_phase(fk, mc, q, chi1, chi2, tc, phic, pn_order: {order})
    output psi_pn = tf2_psi_pn(fk, mc, q, chi1, chi2, pn_order: {order})
    output amp = tf2_amplitude(fk, mc, q, dist)
    output hp = tf2_hplus(fk, mc, q, chi1, chi2, dist, tc, phic, iota, pn_order: {order})
    output hc = tf2_hcross(fk, mc, q, chi1, chi2, dist, tc, phic, iota, pn_order: {order})
    output fisco = tf2_isco_frequency(mc, q)
}}
",
            last = N - 1
        );
    }
    s
}

/// The fixture (serde_json's `float_roundtrip` feature reads every number exactly).
fn load_fixtures() -> Json {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/lal/taylorf2.json");
    let text = std::fs::read_to_string(path).expect("fixtures/lal/taylorf2.json is readable");
    serde_json::from_str(&text).expect("valid JSON")
}

fn num(j: &Json, key: &str) -> f64 {
    j[key].as_f64().unwrap_or_else(|| panic!("`{key}` is a number"))
}

fn nums(j: &Json) -> Vec<f64> {
    j.as_array().expect("an array").iter().map(|x| x.as_f64().expect("a number")).collect()
}

fn real_array(v: &Value) -> &[f64] {
    match v {
        Value::RealArray(a) => a,
        other => panic!("expected a real array, found {other:?}"),
    }
}

fn complex_array(v: &Value) -> &[C64] {
    match v {
        Value::ComplexArray(a) => a,
        other => panic!("expected a complex array, found {other:?}"),
    }
}

/// Largest errors seen over a group of fixture points.
#[derive(Default)]
struct Worst {
    phase: f64,
    amp: f64,
    strain: f64,
    points: usize,
    samples: usize,
}

/// Evaluates one fixture point with the JIT and checks every sample.
fn check_point(scenes: &[Scene], point: &Json, worst: &mut Worst) {
    let id = point["id"].as_str().expect("id");
    let p = &point["params"];
    let order = match p["phase_order"].as_i64().expect("phase_order") {
        -1 => 7,
        o => o as usize,
    };
    let scene = &scenes[order];
    let mut run = scene.bind();
    let (phi_ref, f_ref, iota) = (num(p, "phi_ref_rad"), num(p, "f_ref_hz"), num(p, "inclination_rad"));
    run.param("mc", num(p, "chirp_mass_msun")).unwrap();
    run.param("q", num(p, "q_m2_over_m1")).unwrap();
    run.param("chi1", num(p, "chi1z")).unwrap();
    run.param("chi2", num(p, "chi2z")).unwrap();
    run.param("dist", num(p, "distance_mpc")).unwrap();
    run.param("iota", iota).unwrap();
    run.param("tc", 0.0).unwrap();

    // Documented reference phase: phic = 2 phiRef + psi_PN(f_ref) (f_ref > 0).
    let psi_ref = if f_ref > 0.0 {
        run.input_real("fk", &[f_ref; N]).unwrap();
        let out = run.forward().unwrap();
        real_array(out.value("psi_pn").unwrap())[0]
    } else {
        0.0
    };
    run.param("phic", 2.0 * phi_ref + psi_ref).unwrap();

    let s = &point["samples"];
    let freqs = nums(&s["freq_hz"]);
    let n = freqs.len();
    assert!(n <= N - 2, "{id}: {n} samples do not fit in {N} slots");
    let lal_out = &point["lal_output"];
    let df = num(p, "delta_f_hz");
    let k_isco = lal_out["last_nonzero_bin_if_f_max_0"].as_u64().expect("bin") as f64;
    let mut fk = freqs.clone();
    fk.resize(N - 2, *freqs.last().expect("samples"));
    fk.push(k_isco * df);
    fk.push((k_isco + 1.0) * df);
    run.input_real("fk", &fk).unwrap();
    let out = run.forward().unwrap();
    let psi = real_array(out.value("psi").unwrap());
    let amp = real_array(out.value("amp").unwrap());
    let hp = complex_array(out.value("hp").unwrap());
    let hc = complex_array(out.value("hc").unwrap());

    // ISCO: same frequency as LAL's, and the same last bin as LAL's cut.
    let fisco = out.scalar("fisco").unwrap();
    let lal_fisco = num(lal_out, "f_isco_hz");
    assert!((fisco / lal_fisco - 1.0).abs() < 1e-13, "{id}: f_isco {fisco} vs LAL {lal_fisco}");
    assert!(amp[N - 2] > 0.0 && amp[N - 1] == 0.0, "{id}: ISCO cut not between bins {k_isco} and {}", k_isco + 1.0);

    let above: Vec<bool> = s["above_isco"].as_array().expect("above_isco").iter().map(|b| b.as_bool().expect("bool")).collect();
    let lal_arg = nums(&s["hplus"]["arg_unwrapped"]);
    let lal_abs = nums(&s["hplus"]["abs"]);
    let lal_hp: Vec<C64> = nums(&s["hplus"]["re"]).into_iter().zip(nums(&s["hplus"]["im"])).map(|(r, i)| C64::new(r, i)).collect();
    let lal_hc: Option<Vec<C64>> =
        s.get("hcross").map(|x| nums(&x["re"]).into_iter().zip(nums(&x["im"])).map(|(r, i)| C64::new(r, i)).collect());
    let n_2pi = point["checks"]["lal_model"]["n_2pi"].as_i64().expect("n_2pi");
    let pfac = 0.5 * (1.0 + iota.cos().powi(2));
    for i in 0..n {
        let f = freqs[i];
        if above[i] {
            assert!(f > fisco, "{id}: sample {f} Hz flagged above ISCO {fisco}");
            assert_eq!(amp[i], 0.0, "{id}: amplitude above ISCO at {f} Hz");
            assert_eq!(hp[i], C64::new(0.0, 0.0), "{id}: h+ above ISCO at {f} Hz");
            continue;
        }
        assert!(f <= fisco, "{id}: sample {f} Hz below LAL's ISCO is above gwml's {fisco}");
        // Phase: arg h+ = pi - Psi + 2 pi n, n as recorded by the fixture.
        let d = lal_arg[i] - (PI - psi[i]);
        let k = (d / (2.0 * PI)).round();
        assert_eq!(k as i64, n_2pi, "{id}: 2 pi multiple at {f} Hz");
        let dphi = (d - 2.0 * PI * k).abs();
        assert!(dphi <= PHASE_TOL, "{id}: phase error {dphi:e} rad at {f} Hz");
        // Amplitude.
        let damp = (lal_abs[i] / (pfac * amp[i]) - 1.0).abs();
        assert!(damp <= AMP_TOL, "{id}: amplitude relative error {damp:e} at {f} Hz");
        // The complex h+ (and hx where recorded), bin for bin.
        let dh = (hp[i] - lal_hp[i]).norm() / lal_hp[i].norm();
        assert!(dh <= PHASE_TOL + AMP_TOL, "{id}: h+ relative error {dh:e} at {f} Hz");
        let mut ds = dh;
        if let Some(lal_hc) = &lal_hc {
            let dx = (hc[i] - lal_hc[i]).norm() / lal_hc[i].norm();
            assert!(dx <= PHASE_TOL + AMP_TOL, "{id}: hx relative error {dx:e} at {f} Hz");
            ds = ds.max(dx);
        }
        worst.phase = worst.phase.max(dphi);
        worst.amp = worst.amp.max(damp);
        worst.strain = worst.strain.max(ds);
        worst.samples += 1;
    }
    worst.points += 1;
}

#[test]
fn taylorf2_matches_lalsimulation_fixtures() {
    let fixtures = load_fixtures();
    let lal = &fixtures["lal_constants"];
    // The compiler's constants must be LAL's exactly (phases reach 1e4 rad).
    let consts =
        Model::from_source("consts.gw", "scene c {\n    output mtsun = MTSUN\n    output mrsun = MRSUN\n    output mpc = MPC_M\n}\n")
            .unwrap();
    let out = consts.scene(None).unwrap().bind().forward().unwrap();
    assert_eq!(out.scalar("mtsun").unwrap(), num(lal, "MTSUN_SI"));
    assert_eq!(out.scalar("mrsun").unwrap(), num(lal, "MRSUN_SI"));
    assert_eq!(out.scalar("mpc").unwrap(), 1e6 * num(lal, "PC_SI"));

    let model = Model::from_source("taylorf2_fixtures.gw", &fixture_source()).unwrap_or_else(|e| panic!("{e}"));
    let scenes: Vec<Scene> = (0..=7).map(|o| model.scene(Some(&format!("tf2_o{o}"))).unwrap()).collect();
    let mut report = String::new();
    for group in ["points", "phase_order_sweep", "convention_probes"] {
        let points = fixtures[group].as_array().expect("a fixture group");
        assert!(!points.is_empty());
        let mut worst = Worst::default();
        for point in points {
            check_point(&scenes, point, &mut worst);
        }
        assert_eq!(worst.points, points.len());
        report += &format!(
            "{group:>18}: {:>2} points, {:>4} samples below ISCO: max |dphase| {:.2e} rad, max |dA|/A {:.2e}, max |dh|/|h| {:.2e}\n",
            worst.points, worst.samples, worst.phase, worst.amp, worst.strain
        );
    }
    println!("TaylorF2 vs LALSimulation 6.2.1:\n{report}");
}

/// A scene whose loss is smooth in every param (the grid stays below the ISCO).
const GRADIENT_SOURCE: &str = "use std::taylorf2::{tf2_amplitude, tf2_phase, tf2_strain}
use std::detector::{norm2}

scene weighted_phase {
    grid f = frequencies(from: 20 Hz, to: 150 Hz, step: 0.5 Hz)
    param mc: Msun = 10.0 in 1.0..100.0
    param q = 1.0 in 0.02..1.5
    param chi1 = 0.0 in -0.99..0.99
    param chi2 = 0.0 in -0.99..0.99
    let a = tf2_amplitude(f, mc, q, 100 Mpc)
    output wphase = sum(a * tf2_phase(f, mc, q, chi1, chi2, 0.0 s, 0.0)) / sum(a)
    grad wphase wrt [q, mc]
}

scene fit {
    grid f = frequencies(from: 20 Hz, to: 150 Hz, step: 0.25 Hz)
    input d: complex[f] s = tf2_strain(f, 10.0 Msun, 0.8, 0.3, -0.2, 400 Mpc, 0.001 s, 0.4)
    param mc: Msun = 10.001 in 1.0..100.0
    param q = 0.78 in 0.02..1.0
    param chi1 = 0.28 in -0.99..0.99
    param chi2 = -0.2 in -0.99..0.99
    param tc: s = 0.0012 in -0.1..0.1
    param phic = 0.35
    let h = tf2_strain(f, mc, q, chi1, chi2, 400 Mpc, tc, phic)
    let psd = 1e-47 s * ((f / 150 Hz) ^ (-4.0) + 2.0 + 2.0 * (f / 150 Hz) ^ 2.0)
    output loss = 0.5 * norm2(d - h, psd, 0.25 Hz)
    grad loss wrt [mc, q, chi1, tc, phic]
}
";

#[test]
fn amplitude_weighted_phase_gradient_is_finite_at_equal_mass() {
    let model = Model::from_source("taylorf2_gradients.gw", GRADIENT_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("weighted_phase")).unwrap();
    for (chi1, chi2) in [(0.0, 0.0), (0.5, -0.3), (0.9, 0.9)] {
        let params = [("mc", 10.0), ("q", 1.0), ("chi1", chi1), ("chi2", chi2)];
        let mut run = scene.bind();
        for (n, v) in params {
            run.param(n, v).unwrap();
        }
        let out = run.value_and_grad().unwrap();
        let g = out.grad("wphase", "q").unwrap();
        let gm = out.grad("wphase", "mc").unwrap();
        assert!(g.is_finite() && gm.is_finite(), "gradient at q = 1 (chi = {chi1}, {chi2}): d/dq {g}, d/dmc {gm}");
        let fd = central_difference(&scene, &params, "wphase", "q", 1e-5);
        let scale = g.abs().max(gm.abs());
        if chi1 == chi2 {
            // Symmetric under q -> 1/q (bodies and spins swapped): stationary in q.
            assert!(g.abs() <= 1e-9 * scale, "d/dq at q = 1 with equal spins should vanish: {g}");
        }
        assert!((g - fd).abs() <= 1e-7 * scale, "d/dq at q = 1 (chi = {chi1}, {chi2}): {g} vs FD {fd}");
    }
}

#[test]
fn taylorf2_loss_gradient_matches_finite_differences() {
    let model = Model::from_source("taylorf2_gradients.gw", GRADIENT_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("fit")).unwrap();
    let params = [("mc", 10.001), ("q", 0.78), ("chi1", 0.28), ("chi2", -0.2), ("tc", 0.0012), ("phic", 0.35)];
    let mut run = scene.bind();
    for (n, v) in params {
        run.param(n, v).unwrap();
    }
    let loss = run.forward().unwrap().scalar("loss").unwrap();
    assert!(loss.is_finite() && loss > 0.0, "loss {loss}");
    let steps = [("mc", 1e-6), ("q", 1e-6), ("chi1", 1e-5), ("tc", 1e-8), ("phic", 1e-5)];
    assert_gradient_matches(&scene, &params, "loss", &steps, 1e-6);
}

/// A fit whose grid straddles the ISCO (63 Hz for mc 30, q 0.8), with the
/// cut smoothed by `tf2_isco_taper`, and the taper on its own.
const TAPER_SOURCE: &str = "use std::taylorf2::{tf2_strain, tf2_strain_uncut, tf2_isco_taper, tf2_isco_frequency}
use std::detector::{norm2}

scene fit {
    grid f = frequencies(from: 30 Hz, to: 120 Hz, step: 0.5 Hz)
    input d: complex[f] s = tf2_strain(f, 30.0 Msun, 0.8, 0.0, 0.0, 400 Mpc, 0.001 s, 0.4)
    param mc: Msun = 30.2 in 10.0..40.0
    param q = 0.75 in 0.25..1.0
    param tc: s = 0.0012 in -0.1..0.1
    param phic = 0.35
    let h = tf2_strain_uncut(f, mc, q, 0.0, 0.0, 400 Mpc, tc, phic) * tf2_isco_taper(f, mc, q, 0.5 Hz)
    let psd = 1e-47 s * ((f / 150 Hz) ^ (-4.0) + 2.0 + 2.0 * (f / 150 Hz) ^ 2.0)
    output loss = 0.5 * norm2(d - h, psd, 0.5 Hz)
    grad loss wrt [mc, q, tc, phic]
}

scene taper {
    param mc: Msun = 30.0 in 10.0..40.0
    param q = 0.8 in 0.25..1.0
    let f_isco = tf2_isco_frequency(mc, q)
    output at_isco = tf2_isco_taper(f_isco, mc, q, 0.5 Hz)
    output width_below = tf2_isco_taper(f_isco - 0.5 Hz, mc, q, 0.5 Hz)
    output far_below = tf2_isco_taper(f_isco - 10 Hz, mc, q, 0.5 Hz)
    output far_above = tf2_isco_taper(f_isco + 10 Hz, mc, q, 0.5 Hz)
}
";

#[test]
fn the_smoothed_isco_cut_gives_a_loss_whose_gradient_matches_finite_differences() {
    let model = Model::from_source("taylorf2_taper.gw", TAPER_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let taper = model.scene(Some("taper")).unwrap().bind().forward().unwrap();
    let value = |name: &str| taper.scalar(name).unwrap();
    assert!((value("at_isco") - 0.5).abs() < 1e-12, "taper at the ISCO {}", value("at_isco"));
    assert!((value("width_below") - 0.5 * (1.0 + 1f64.tanh())).abs() < 1e-12, "a width below {}", value("width_below"));
    assert!(value("far_below") > 1.0 - 1e-8 && value("far_above") < 1e-8, "{} {}", value("far_below"), value("far_above"));
    // Across the ISCO the loss is smooth: a step of 0.01 Msun moves the
    // ISCO by ~0.02 Hz, and central differences agree with the gradient.
    let scene = model.scene(Some("fit")).unwrap();
    let params = [("mc", 30.2), ("q", 0.75), ("tc", 0.0012), ("phic", 0.35)];
    assert_gradient_matches(&scene, &params, "loss", &[("mc", 1e-6), ("q", 1e-6), ("tc", 1e-8), ("phic", 1e-5)], 1e-6);
}
