//! The Laplace evidence of a gwml fit against direct numerical integration:
//! a sine-Gaussian's frequency and amplitude fitted to seeded white noise
//! (a 2-parameter problem whose likelihood is not exactly Gaussian in the
//! frequency), `ln Z = ln ∫ e^{−L} dθ / V` summed on a fine grid over the
//! bounds, against `laplace_evidence` at the L-BFGS fit with its Fisher
//! matrix; and Bayes factors between a right and a wrong model.

use gwml::Model;
use gwml_runtime::fit::{fit_run, laplace_evidence, Algorithm, SceneFit, Settings};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};

const SOURCE: &str = "
scene sg {
    grid t = times(rate: 256 Hz, duration: 1 s)
    input d: real[t]
    param f0: Hz = 30.5 in 24.0..36.0
    param amp = 4.4 in 0.0..8.0
    let u = (t - 0.5 s) / 0.05 s
    output h = amp * exp(-u * u) * cos(2.0 * pi * f0 * (t - 0.5 s))
    output loss = 0.5 * sum((d - h) * (d - h))
    grad loss wrt [f0, amp]
}
";

/// Unit-variance white noise plus a sine-Gaussian of amplitude 4 at 30 Hz (SNR ≈ 11).
fn data(seed: u64) -> Vec<f64> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    (0..256)
        .map(|j| {
            let t = j as f64 / 256.0 - 0.5;
            let u = t / 0.05;
            (-u * u).exp() * (2.0 * std::f64::consts::PI * 30.0 * t).cos() * 4.0 + Distribution::<f64>::sample(&StandardNormal, &mut rng)
        })
        .collect()
}

fn fit(run: &mut gwml::Run) -> SceneFit {
    fit_run(run, Some("loss"), &Settings::new(Algorithm::Lbfgs), |_| {}).unwrap()
}

#[test]
fn laplace_evidence_matches_numerical_integration() {
    let model = Model::from_source("sg.gw", SOURCE).unwrap();
    let scene = model.scene(None).unwrap();
    for seed in [1, 2, 3] {
        let d = data(seed);
        let mut run = scene.bind();
        run.input_real("d", &d).unwrap();
        let r = fit(&mut run);
        let bounds: Vec<Option<(f64, f64)>> = r.free.iter().map(|p| p.bounds).collect();
        let laplace = laplace_evidence(r.minimum.loss, &r.minimum.x, &r.fisher, &bounds).unwrap();
        // ∫ e^{−L} over the box on a grid of 600 × 300 (midpoints), with
        // the minimum loss factored out.
        let (nf, na) = (600, 300);
        let ((f_lo, f_hi), (a_lo, a_hi)) = (bounds[0].unwrap(), bounds[1].unwrap());
        let (df, da) = ((f_hi - f_lo) / nf as f64, (a_hi - a_lo) / na as f64);
        let mut sum = 0.0;
        for i in 0..nf {
            for k in 0..na {
                run.param("f0", f_lo + (i as f64 + 0.5) * df).unwrap();
                run.param("amp", a_lo + (k as f64 + 0.5) * da).unwrap();
                let loss = run.forward().unwrap().scalar("loss").unwrap();
                sum += (r.minimum.loss - loss).exp() * df * da;
            }
        }
        let numeric = -r.minimum.loss + sum.ln() - laplace.ln_prior_volume;
        assert!(
            (laplace.ln_z - numeric).abs() <= 0.1,
            "seed {seed}: Laplace ln Z {} vs numerical {numeric} (fit f0 {}, amp {})",
            laplace.ln_z,
            r.minimum.x[0],
            r.minimum.x[1]
        );
    }
}

/// `gwml compare` on a noise-free 3.5PN injection prefers a 3–3.5PN phase
/// model to 1PN and 2PN ones by a decisive log Bayes factor.
#[test]
fn compare_prefers_the_injected_pn_order() {
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/pn_orders.gw");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_gwml"))
        .args(["compare", file, "--scenes", "pn1,pn2,pn3,pn35", "--format", "json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let ranking = doc["ranking"].as_array().unwrap();
    let best = ranking[0]["scene"].as_str().unwrap();
    assert!(best == "pn35" || best == "pn3", "best {best}");
    let best_ln_z = ranking[0]["ln_evidence"].as_f64().unwrap();
    for low in ["pn1", "pn2"] {
        let row = ranking.iter().find(|r| r["scene"] == low).unwrap();
        // No evidence (a fit pinned to its bounds) ranks last.
        if let Some(z) = row["ln_evidence"].as_f64() {
            assert!(best_ln_z - z > 3.0, "{low}: ln B {}", best_ln_z - z);
        }
        assert!(row["loss"].as_f64().unwrap() > 1.0, "{low} fits the 3.5PN data too well");
    }
}
