//! Fitting a [`Run`]: its free params, the output to minimise, and the
//! result with Fisher errors.

use super::*;
use crate::{Error, Run};
use gwml_compiler::ir::{Elem, Shape};

/// A free param of a scene fit.
#[derive(Clone, Debug, PartialEq)]
pub struct FreeParam {
    /// Name.
    pub name: String,
    /// Declared unit ("1" when dimensionless).
    pub unit: String,
    /// Bounds in the declared unit.
    pub bounds: Option<(f64, f64)>,
    /// Starting value.
    pub start: f64,
}

/// The result of [`fit_run`].
#[derive(Clone, Debug)]
pub struct SceneFit {
    /// The output minimised.
    pub output: String,
    /// The free params, in the order of `grad OUTPUT wrt [...]`.
    pub free: Vec<FreeParam>,
    /// The other params, held at their values: `(name, value)`.
    pub fixed: Vec<(String, f64)>,
    /// The loss at the starting params.
    pub start_loss: f64,
    /// The optimiser's result (`x` in the order of `free`).
    pub minimum: Minimum,
    /// The Fisher matrix (Hessian of the loss) at the minimum, in declared units.
    pub fisher: Vec<Vec<f64>>,
    /// The finite-difference steps used for it.
    pub fisher_steps: Vec<f64>,
    /// Its inverse, or why there is none.
    pub covariance: Result<Covariance, FisherError>,
}

/// The real scalar outputs of the run's scene that have gradients.
pub fn candidate_outputs(run: &Run) -> Vec<String> {
    let f = run.func();
    f.outputs
        .iter()
        .enumerate()
        .filter(|(i, o)| {
            let ty = f.ty(o.value);
            ty.elem == Elem::Real && ty.shape == Shape::Scalar && f.grads.iter().any(|g| g.output == *i)
        })
        .map(|(_, o)| o.name.clone())
        .collect()
}

/// Minimises `output` (or the scene's only real scalar output with
/// gradients) over the params its `grad` statement names, from their
/// current values in `run`, then computes the Fisher matrix there. The
/// params are left at the minimum in `run`.
pub fn fit_run(run: &mut Run, output: Option<&str>, settings: &Settings, progress: impl FnMut(&Progress)) -> Result<SceneFit, Error> {
    let f = run.func();
    let candidates = candidate_outputs(run);
    let output = match output {
        Some(name) => {
            let Some(oi) = f.outputs.iter().position(|o| o.name == name) else {
                return Err(crate::unknown("output", name, f.outputs.iter().map(|o| o.name.as_str())));
            };
            if !candidates.iter().any(|c| c == name) {
                let ty = f.ty(f.outputs[oi].value);
                return Err(Error::Bind(if ty.elem != Elem::Real || ty.shape != Shape::Scalar {
                    format!("output `{name}` is not a real scalar, so it cannot be minimised")
                } else {
                    format!("output `{name}` has no gradients; add `grad {name} wrt [PARAMS]` to the scene to choose what to fit")
                }));
            }
            name.to_string()
        }
        None => match candidates.as_slice() {
            [one] => one.clone(),
            [] => {
                return Err(Error::Bind(
                    "the scene has no real scalar output with gradients to minimise; add `grad LOSS wrt [PARAMS]`".to_string(),
                ))
            }
            many => {
                return Err(Error::Bind(format!(
                    "the scene has several real scalar outputs with gradients ({}); choose one (e.g. `--output {}`)",
                    many.iter().map(|m| format!("`{m}`")).collect::<Vec<_>>().join(", "),
                    many[0]
                )))
            }
        },
    };
    let oi = f.outputs.iter().position(|o| o.name == output).expect("checked above");
    let free_idx: Vec<usize> = f.grads.iter().filter(|g| g.output == oi).map(|g| g.param).collect();
    let mut free = Vec::with_capacity(free_idx.len());
    for &pi in &free_idx {
        let p = &f.params[pi];
        let start = run.params[pi].ok_or_else(|| Error::Bind(format!("param `{}` has no default; set a starting value", p.name)))?;
        free.push(FreeParam { name: p.name.clone(), unit: p.unit.clone(), bounds: p.bounds, start });
    }
    let fixed = f
        .params
        .iter()
        .enumerate()
        .filter(|(i, _)| !free_idx.contains(i))
        .map(|(i, p)| (p.name.clone(), run.params[i].unwrap_or(f64::NAN)))
        .collect();
    let bounds: Vec<Option<(f64, f64)>> = free.iter().map(|p| p.bounds).collect();
    let x0: Vec<f64> = free.iter().map(|p| p.start).collect();
    let mut eval = |x: &[f64]| -> Result<(f64, Vec<f64>), Error> {
        for (&pi, v) in free_idx.iter().zip(x) {
            if !v.is_finite() {
                return Err(Error::Bind(format!("param `{}` = {v} is not finite", f.params[pi].name)));
            }
            run.params[pi] = Some(*v);
        }
        let out = run.value_and_grad()?;
        let loss = out.scalar(&output)?;
        // A gradient the compiler proved zero has no entry.
        let grad = free.iter().map(|p| out.grad(&output, &p.name).unwrap_or(0.0)).collect();
        Ok((loss, grad))
    };
    let start_loss = eval(&x0)?.0;
    if !start_loss.is_finite() {
        return Err(Error::Bind(format!("output `{output}` is not finite at the starting params")));
    }
    let minimum = minimize(&mut eval, &x0, &bounds, settings, progress)?;
    let steps = fisher_steps(|x: &[f64]| eval(x).map(|r| r.1), &minimum.x, &bounds)?;
    let fisher = fisher_matrix(|x: &[f64]| eval(x).map(|r| r.1), &minimum.x, &bounds, &steps)?;
    eval(&minimum.x)?;
    let covariance = invert_fisher(&fisher);
    Ok(SceneFit { output, free, fixed, start_loss, minimum, fisher, fisher_steps: steps, covariance })
}
