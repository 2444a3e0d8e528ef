//! `gwml compare`: fit several scenes of one file to the same data and rank
//! them by Laplace log evidence (and BIC) — which model explains the data.

use crate::commands::{bind_args, options, render};
use crate::{BindArgs, Format, KnobArgs};
use gwml::Model;
use gwml_runtime::fit::{fit_run, score_fit, Algorithm, SceneFit, Score, Settings};
use serde_json::{json, Map, Value as Json};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct CompareArgs {
    /// The .gw file.
    pub file: PathBuf,
    /// Scenes to fit and compare (comma-separated), each with the same
    /// inputs bound.
    #[arg(long, value_delimiter = ',', required = true, num_args = 1..)]
    pub scenes: Vec<String>,
    #[command(flatten)]
    pub bind: BindArgs,
    /// The real scalar output each scene minimises, a negative
    /// log-likelihood (needed when a scene has several with gradients).
    #[arg(long, value_name = "NAME")]
    pub output: Option<String>,
    /// Output format.
    #[arg(long, value_enum, default_value = "text")]
    pub format: Format,
    #[command(flatten)]
    pub knobs: KnobArgs,
}

/// One scene's fit and score.
struct Fitted {
    scene: String,
    fit: SceneFit,
    score: Score,
}

/// `gwml compare`.
pub fn compare(a: CompareArgs) -> Result<(), String> {
    if a.scenes.len() < 2 {
        return Err("error: --scenes needs at least two scenes to compare".into());
    }
    let model = Model::from_file(&a.file).map_err(render)?;
    let opts = options(a.knobs.clone())?;
    let mut fitted = Vec::new();
    for name in &a.scenes {
        let scene = model.scene_with(Some(name), opts.clone()).map_err(render)?;
        let mut run = scene.bind();
        bind_args(&mut run, &a.bind)?;
        // Data points: every element of the scene's inputs (complex ones twice).
        let f = scene.ir();
        let n: usize =
            f.inputs.iter().map(|i| f.len_of(i.ty.shape) * if i.ty.elem == gwml::compiler::ir::Elem::Complex { 2 } else { 1 }).sum();
        let fit = fit_run(&mut run, a.output.as_deref(), &Settings::new(Algorithm::Lbfgs), |_| {})
            .map_err(|e| format!("scene `{name}`: {}", render(e)))?;
        let score = score_fit(&fit, n.max(1));
        fitted.push(Fitted { scene: name.clone(), fit, score });
    }
    let ln_z = |f: &Fitted| f.score.evidence.as_ref().map_or(f64::NEG_INFINITY, |e| e.ln_z);
    fitted.sort_by(|x, y| ln_z(y).total_cmp(&ln_z(x)));
    let best = ln_z(&fitted[0]);
    if a.format == Format::Json {
        let rows: Vec<Json> = fitted
            .iter()
            .map(|f| {
                let mut params = Map::new();
                let sigma = f.fit.covariance.as_ref().ok().map(|c| c.sigma.clone());
                for (i, p) in f.fit.free.iter().enumerate() {
                    params.insert(
                        p.name.clone(),
                        json!({"value": f.fit.minimum.x[i], "sigma": sigma.as_ref().map(|s| s[i]), "unit": p.unit, "bounds": p.bounds}),
                    );
                }
                let e = f.score.evidence.as_ref();
                json!({
                    "scene": f.scene, "loss": f.score.loss, "params": params, "k": f.score.params,
                    "ln_evidence": e.ok().map(|e| e.ln_z), "ln_prior_volume": e.ok().map(|e| e.ln_prior_volume),
                    "evidence_error": e.err().map(|e| e.to_string()),
                    "ln_bayes_factor_vs_best": e.ok().map(|e| e.ln_z - best), "bic": f.score.bic,
                })
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&json!({"ranking": rows})).expect("JSON"));
        return Ok(());
    }
    println!("{:<20} {:>3} {:>14} {:>12} {:>10} {:>12} {:>12}", "scene", "k", "best loss", "ln Z", "ln V", "ln B vs best", "BIC");
    for f in &fitted {
        match &f.score.evidence {
            Ok(e) => println!(
                "{:<20} {:>3} {:>14.4} {:>12.3} {:>10.3} {:>12.3} {:>12.3}",
                f.scene,
                f.score.params,
                f.score.loss,
                e.ln_z,
                e.ln_prior_volume,
                e.ln_z - best,
                f.score.bic
            ),
            Err(err) => println!(
                "{:<20} {:>3} {:>14.4} {:>12} {:>10} {:>12} {:>12.3}  ({err})",
                f.scene, f.score.params, f.score.loss, "-", "-", "-", f.score.bic
            ),
        }
    }
    println!("best: {} (ln Z is up to a constant shared by all scenes; ln V is the prior volume of the bounds)", fitted[0].scene);
    for f in &fitted {
        let sigma = f.fit.covariance.as_ref().ok().map(|c| c.sigma.clone());
        let parts: Vec<String> = f
            .fit
            .free
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let unit = if p.unit == "1" { String::new() } else { format!(" {}", p.unit) };
                match &sigma {
                    Some(s) => format!("{} = {:.6e} ± {:.2e}{unit}", p.name, f.fit.minimum.x[i], s[i]),
                    None => format!("{} = {:.6e}{unit}", p.name, f.fit.minimum.x[i]),
                }
            })
            .collect();
        println!("  {}: {}", f.scene, parts.join(", "));
    }
    Ok(())
}
