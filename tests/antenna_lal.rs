//! `std::antenna` against LAL 7.7.1 (`fixtures/lal/antenna_patterns.json`,
//! written by `scripts/lal_fixtures.py`): F+ and Fx of H1, L1, V1 from
//! `XLALComputeDetAMResponse` at every fixture point, geocentre time delays
//! from `XLALTimeDelayFromEarthCenter` and inter-site delays from
//! `XLALArrivalTimeDiff`, all to 1e-12 absolute; the response tensors and
//! vertices written in `stdlib/antenna.gw` are checked against the fixture's;
//! and gradients are checked against finite differences.

use gwml::{Model, Scene};
use serde_json::Value as Json;

const TOL: f64 = 1e-12;

const DETECTORS: [&str; 3] = ["H1", "L1", "V1"];

const FIXTURE_SOURCE: &str = "use std::antenna::{antenna_fplus_h1, antenna_fcross_h1, antenna_delay_h1}
use std::antenna::{antenna_fplus_l1, antenna_fcross_l1, antenna_delay_l1}
use std::antenna::{antenna_fplus_v1, antenna_fcross_v1, antenna_delay_v1}
use std::antenna::{antenna_fplus, antenna_fcross, antenna_geocentre_delay}

scene antenna_fixture {
    precision: f64
    param ra = 0.0
    param dec = 0.0
    param psi = 0.0
    param gmst = 0.0
    output fplus_H1 = antenna_fplus_h1(ra, dec, psi, gmst)
    output fcross_H1 = antenna_fcross_h1(ra, dec, psi, gmst)
    output delay_H1 = antenna_delay_h1(ra, dec, gmst)
    output fplus_L1 = antenna_fplus_l1(ra, dec, psi, gmst)
    output fcross_L1 = antenna_fcross_l1(ra, dec, psi, gmst)
    output delay_L1 = antenna_delay_l1(ra, dec, gmst)
    output fplus_V1 = antenna_fplus_v1(ra, dec, psi, gmst)
    output fcross_V1 = antenna_fcross_v1(ra, dec, psi, gmst)
    output delay_V1 = antenna_delay_v1(ra, dec, gmst)
}

// The per-detector constants read back: D_ij = F+ at a sky position and
// polarisation where X and Y are unit vectors e_i, e_j (see the test).
scene tensor {
    precision: f64
    param d11 = 0.0
    param d12 = 0.0
    param d13 = 0.0
    param d22 = 0.0
    param d23 = 0.0
    param d33 = 0.0
    param rx: m = 0.0
    param ry: m = 0.0
    param rz: m = 0.0
    param ra = 0.0
    param dec = 0.0
    param psi = 0.0
    param gmst = 0.0
    output fplus = antenna_fplus(ra, dec, psi, gmst, d11, d12, d13, d22, d23, d33)
    output fcross = antenna_fcross(ra, dec, psi, gmst, d11, d12, d13, d22, d23, d33)
    output delay = antenna_geocentre_delay(ra, dec, gmst, rx, ry, rz)
}
";

/// The fixture (serde_json's `float_roundtrip` feature reads every number exactly).
fn load_fixture() -> Json {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/lal/antenna_patterns.json");
    let text = std::fs::read_to_string(path).expect("fixture is readable");
    serde_json::from_str(&text).expect("valid JSON")
}

/// A number of the fixture.
fn num(j: &Json) -> f64 {
    j.as_f64().unwrap_or_else(|| panic!("a number, found {j}"))
}

/// Evaluates `scene` with the given params; returns a reader of scalar outputs.
fn eval(scene: &Scene, params: &[(&str, f64)]) -> impl Fn(&str) -> f64 {
    let mut run = scene.bind();
    for (name, v) in params {
        run.param(name, *v).unwrap();
    }
    let out = run.forward().unwrap();
    move |name: &str| out.scalar(name).unwrap()
}

#[test]
fn antenna_patterns_and_delays_match_lal() {
    let fixture = load_fixture();
    let model = Model::from_source("antenna_fixtures.gw", FIXTURE_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("antenna_fixture")).unwrap();

    // F+ and Fx at every fixture point.
    let points = fixture["antenna_points"].as_array().expect("antenna_points");
    assert!(!points.is_empty());
    let mut worst_f = [0.0f64; 3];
    for p in points {
        let angles = [("ra", num(&p["ra"])), ("dec", num(&p["dec"])), ("psi", num(&p["psi"])), ("gmst", num(&p["gmst"]))];
        let out = eval(&scene, &angles);
        for (k, det) in DETECTORS.iter().enumerate() {
            for pol in ["fplus", "fcross"] {
                let (ours, lal) = (out(&format!("{pol}_{det}")), num(&p[det][pol]));
                let e = (ours - lal).abs();
                assert!(e <= TOL, "{det} {pol} at {angles:?}: gwml {ours} vs LAL {lal} (error {e:e})");
                worst_f[k] = worst_f[k].max(e);
            }
        }
    }

    // Time delays from the geocentre at the fixture's GPS time (its GMST),
    // and arrival-time differences between sites.
    let delays = &fixture["time_delays"];
    let gmst = num(&delays["gmst_rad"]);
    let delay_points = delays["points"].as_array().expect("delay points");
    assert!(!delay_points.is_empty());
    let mut worst_delay = 0.0f64;
    for p in delay_points {
        let (ra, dec) = (num(&p["ra"]), num(&p["dec"]));
        let out = eval(&scene, &[("ra", ra), ("dec", dec), ("psi", 0.3), ("gmst", gmst)]);
        for det in DETECTORS {
            let (ours, lal) = (out(&format!("delay_{det}")), num(&p["delay_from_geocenter_s"][det]));
            let e = (ours - lal).abs();
            assert!(e <= TOL, "{det} delay at ra {ra}, dec {dec}: gwml {ours} s vs LAL {lal} s (error {e:e})");
            worst_delay = worst_delay.max(e);
        }
        for (a, b) in [("H1", "L1"), ("H1", "V1"), ("L1", "V1")] {
            let ours = out(&format!("delay_{a}")) - out(&format!("delay_{b}"));
            let lal = num(&p["arrival_time_diff_s"][format!("{a}-{b}").as_str()]);
            let e = (ours - lal).abs();
            assert!(e <= TOL, "{a}-{b} arrival time difference at ra {ra}, dec {dec}: gwml {ours} s vs LAL {lal} s");
            worst_delay = worst_delay.max(e);
        }
    }
    println!(
        "antenna patterns vs LAL 7.7.1 ({} points): max |dF| H1 {:.2e}, L1 {:.2e}, V1 {:.2e}; \
         delays ({} points, geocentre and inter-site): max |dt| {worst_delay:.2e} s",
        points.len(),
        worst_f[0],
        worst_f[1],
        worst_f[2],
        delay_points.len()
    );
}

/// The constants written in stdlib/antenna.gw are the fixture's exactly: the
/// per-detector modules agree bit for bit with the generic ones fed the
/// fixture's tensor and vertex, and LAL's float32 tensor is symmetric.
#[test]
fn detector_constants_are_the_fixtures() {
    let fixture = load_fixture();
    let model = Model::from_source("antenna_fixtures.gw", FIXTURE_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let per_detector = model.scene(Some("antenna_fixture")).unwrap();
    let generic = model.scene(Some("tensor")).unwrap();
    let detectors = fixture["detectors"].as_array().expect("detectors");
    assert_eq!(detectors.len(), DETECTORS.len());
    for d in detectors {
        let prefix = d["prefix"].as_str().expect("prefix");
        let rows: Vec<Vec<f64>> = d["response_float32_as_float64"]
            .as_array()
            .expect("rows")
            .iter()
            .map(|r| r.as_array().expect("row").iter().map(num).collect())
            .collect();
        for (i, row) in rows.iter().enumerate() {
            for (j, &x) in row.iter().enumerate() {
                assert_eq!(x, rows[j][i], "{prefix}: D is symmetric");
                assert_eq!(x, x as f32 as f64, "{prefix}: D is float32");
            }
        }
        let loc: Vec<f64> = d["location_m"].as_array().expect("location").iter().map(num).collect();
        let tensor = [
            ("d11", rows[0][0]),
            ("d12", rows[0][1]),
            ("d13", rows[0][2]),
            ("d22", rows[1][1]),
            ("d23", rows[1][2]),
            ("d33", rows[2][2]),
            ("rx", loc[0]),
            ("ry", loc[1]),
            ("rz", loc[2]),
        ];
        for (ra, dec, psi, gmst) in [(0.3, -0.4, 1.1, 2.0), (5.0, 1.2, -0.7, 36137.05523464342), (1.0, 0.0, 0.0, 0.0)] {
            let angles = [("ra", ra), ("dec", dec), ("psi", psi), ("gmst", gmst)];
            let ours = eval(&per_detector, &angles);
            let params: Vec<(&str, f64)> = tensor.iter().copied().chain(angles).collect();
            let theirs = eval(&generic, &params);
            assert_eq!(ours(&format!("fplus_{prefix}")), theirs("fplus"), "{prefix} F+");
            assert_eq!(ours(&format!("fcross_{prefix}")), theirs("fcross"), "{prefix} Fx");
            assert_eq!(ours(&format!("delay_{prefix}")), theirs("delay"), "{prefix} delay");
        }
    }
}

const GRADIENT_SOURCE: &str = "use std::antenna::{antenna_fplus_h1, antenna_fcross_h1, antenna_fplus_l1, antenna_fcross_l1}
use std::antenna::{antenna_fplus_v1, antenna_fcross_v1, antenna_delay_h1, antenna_delay_l1}

scene network {
    param ra = 1.3
    param dec = -0.4
    param psi = 0.7
    param gmst = 2.1
    output fplus = antenna_fplus_h1(ra, dec, psi, gmst)
    output fcross = antenna_fcross_h1(ra, dec, psi, gmst)
    // A smooth network quantity: sum of F+^2 + Fx^2 over detectors weighted
    // by a phase set by the H1-L1 delay.
    output power = (antenna_fplus_h1(ra, dec, psi, gmst) ^ 2.0 + antenna_fcross_h1(ra, dec, psi, gmst) ^ 2.0)
        * cos(2.0 * pi * 100 Hz * (antenna_delay_h1(ra, dec, gmst) - antenna_delay_l1(ra, dec, gmst)))
        + antenna_fplus_l1(ra, dec, psi, gmst) * antenna_fcross_v1(ra, dec, psi, gmst)
        + antenna_fcross_l1(ra, dec, psi, gmst) * antenna_fplus_v1(ra, dec, psi, gmst)
    grad fplus wrt [psi, ra, dec, gmst]
    grad fcross wrt [psi]
    grad power wrt [ra, dec, psi, gmst]
}
";

#[test]
fn antenna_gradients_match_finite_differences() {
    let model = Model::from_source("antenna_gradients.gw", GRADIENT_SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let scene = model.scene(Some("network")).unwrap();
    let params = [("ra", 1.3), ("dec", -0.4), ("psi", 0.7), ("gmst", 2.1)];
    let mut run = scene.bind();
    for (n, v) in params {
        run.param(n, v).unwrap();
    }
    let out = run.value_and_grad().unwrap();
    let (fplus, fcross) = (out.scalar("fplus").unwrap(), out.scalar("fcross").unwrap());
    // F+ + i Fx turns by -2 psi: dF+/dpsi = 2 Fx, dFx/dpsi = -2 F+.
    let dp = out.grad("fplus", "psi").unwrap();
    let dc = out.grad("fcross", "psi").unwrap();
    assert!((dp - 2.0 * fcross).abs() <= 1e-14, "dF+/dpsi {dp} vs 2 Fx {}", 2.0 * fcross);
    assert!((dc + 2.0 * fplus).abs() <= 1e-14, "dFx/dpsi {dc} vs -2 F+ {}", -2.0 * fplus);
    // F+ depends on ra and gmst only through gmst - ra.
    let (dra, dgmst) = (out.grad("fplus", "ra").unwrap(), out.grad("fplus", "gmst").unwrap());
    assert!((dra + dgmst).abs() <= 1e-14, "dF+/dra {dra} vs -dF+/dgmst {dgmst}");

    let h = 1e-6;
    for output in ["fplus", "power"] {
        for (param, _) in params {
            let Ok(g) = out.grad(output, param) else { continue };
            let at = |delta: f64| {
                let shifted: Vec<(&str, f64)> = params.iter().map(|&(n, v)| (n, if n == param { v + delta } else { v })).collect();
                eval(&scene, &shifted)(output)
            };
            let fd = (at(h) - at(-h)) / (2.0 * h);
            assert!((g - fd).abs() <= 1e-8, "d {output} / d {param}: {g} vs FD {fd}");
        }
    }
}
