//! An explanation as people read it (a table) and as machines do (JSON),
//! shared by `gwml explain` and `gwml scan --explain`.

use super::{cause_of, Explanation, FamilyFit, Seed, Window};
use serde_json::{json, Map, Value as Json};
use std::fmt::Write;

/// One param as `name = value ± σ unit`, times relative to `gps_centre`
/// shown as GPS times.
fn param_text(p: &super::Estimate, gps_centre: f64) -> String {
    let unit = if p.unit == "1" { String::new() } else { format!(" {}", p.unit) };
    let sigma = p.sigma.map_or(" (no σ: the Fisher matrix is singular there)".to_string(), |s| format!(" ± {}", significant(s)));
    if p.name == "dt" {
        return format!("t0 = GPS {:.4}{sigma}{unit}", gps_centre + p.value);
    }
    format!("{} = {}{sigma}{unit}", p.name, significant(p.value))
}

/// Four significant digits, without an exponent for ordinary magnitudes.
fn significant(v: f64) -> String {
    if v == 0.0 || (1e-3..1e5).contains(&v.abs()) {
        let digits = (3 - v.abs().log10().floor() as i32).clamp(0, 6) as usize;
        format!("{v:.digits$}")
    } else {
        format!("{v:.3e}")
    }
}

/// The table `gwml explain` prints.
pub fn explanation_text(e: &Explanation, win: &Window, seed: &Seed) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "window: {:.2} s around GPS {:.4} ({} samples); loudest Q tile {:+.4} s, {:.1} Hz, Q {:.1}",
        win.d.len() as f64 / win.sample_rate,
        win.gps_centre,
        e.samples,
        seed.dt,
        seed.frequency,
        seed.q
    );
    let _ = writeln!(s, "{:<15} {:>10} {:>9} {:>9} {:>8} {:>7}", "family", "ln B/noise", "ln B/best", "ln Z", "ln V", "χ²/dof");
    for f in &e.fits {
        let _ = writeln!(
            s,
            "{:<15} {:>10.2} {:>9.2} {:>9.2} {:>8.2} {:>7.3}",
            f.family.scene,
            e.ln_bayes_vs_noise(f),
            e.ln_bayes_vs_best(f),
            f.ln_z(),
            f.score.evidence.as_ref().map_or(f64::NAN, |v| v.ln_prior_volume),
            f.chi2_dof
        );
    }
    let _ = writeln!(
        s,
        "{:<15} {:>10.2} {:>9} {:>9.2} {:>8} {:>7.3}",
        "noise",
        0.0,
        "",
        e.ln_z_noise(),
        "0",
        2.0 * e.noise_loss / e.samples as f64
    );
    match e.best() {
        Some(best) => {
            let _ = writeln!(s, "best: {} ({})", best.family.scene, best.family.label);
            let _ = writeln!(s, "  {}", best.params.iter().map(|p| param_text(p, win.gps_centre)).collect::<Vec<_>>().join(", "));
            if let Some(c) = cause_of(best.family.base()) {
                let _ = writeln!(s, "likely cause: {}\n  sources: {}", c.cause, c.sources);
            }
        }
        None => {
            let _ = writeln!(s, "best: noise alone (no family's evidence beats Gaussian noise)");
        }
    }
    let _ = writeln!(
        s,
        "ln B are natural-log Bayes factors (Laplace evidence, uniform priors on the bounds of lab/models/glitch/explain.gw; ln V is each prior's volume)"
    );
    s
}

/// One fit as JSON.
fn fit_json(e: &Explanation, f: &FamilyFit, gps_centre: f64) -> Json {
    let mut params = Map::new();
    for p in &f.params {
        params.insert(p.name.clone(), json!({"value": p.value, "sigma": p.sigma, "unit": p.unit, "prior": [p.bounds.0, p.bounds.1]}));
    }
    let evidence = f.score.evidence.as_ref();
    json!({
        "family": f.family.scene,
        "label": f.family.label,
        "params": params,
        "t0_gps": gps_centre + f.params[0].value,
        "chi2_per_dof": f.chi2_dof,
        "loss": f.score.loss,
        "ln_evidence": evidence.ok().map(|v| v.ln_z),
        "ln_prior_volume": evidence.ok().map(|v| v.ln_prior_volume),
        "evidence_directions_clipped": evidence.ok().map(|v| v.clipped),
        "evidence_error": evidence.err().map(|v| v.to_string()),
        "ln_bayes_factor_vs_noise": e.ln_bayes_vs_noise(f),
        "ln_bayes_factor_vs_best": e.ln_bayes_vs_best(f),
        "bic": f.score.bic,
        "evaluations": f.evaluations,
        "seconds": f.seconds,
    })
}

/// The explanation as JSON.
pub fn explanation_json(e: &Explanation, win: &Window, seed: &Seed) -> Json {
    let best = e.best();
    json!({
        "gps_centre": win.gps_centre,
        "window_samples": e.samples,
        "seed": {"dt": seed.dt, "frequency": seed.frequency, "q": seed.q},
        "noise": {"ln_evidence": e.ln_z_noise(), "chi2_per_dof": 2.0 * e.noise_loss / e.samples as f64},
        "best": best.map(|b| b.family.scene),
        "label": best.map_or("None", |b| b.family.label),
        "cause": best.and_then(|b| cause_of(b.family.base())).map(|c| json!({"cause": c.cause, "sources": c.sources})),
        "evaluations": e.evaluations(),
        "fits": e.fits.iter().map(|f| fit_json(e, f, win.gps_centre)).collect::<Vec<_>>(),
    })
}
