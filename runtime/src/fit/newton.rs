//! Newton steps on the Fisher matrix: the last stretch of a fit whose
//! quasi-Newton run stopped short of its floor.
//!
//! Near a minimum of `L = ½ (d − h | d − h)` the loss is close to
//! quadratic, and the Hessian [`fisher_matrix`] takes there anyway (for
//! σ and the evidence) gives the step to its floor in one solve, where
//! L-BFGS on an ill-conditioned fit (a loud glitch with ten params) can
//! spend hundreds of steps. Each step costs one loss evaluation per
//! backtracking trial and a new Hessian (`2n` gradients).

use super::{fisher_matrix, invert_fisher, Minimum};

/// How far [`newton_polish`] goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NewtonSettings {
    /// Most Newton steps.
    pub max_steps: usize,
    /// Stop when the quadratic model's predicted decrease, `½ gᵀ F⁻¹ g`,
    /// is at most this (in units of the loss).
    pub decrease_tol: f64,
}

/// What [`newton_polish`] ends with.
#[derive(Clone, Debug)]
pub struct Polished {
    /// The minimum (its `steps` and `evaluations` include the Newton steps').
    pub minimum: Minimum,
    /// The Hessian at `minimum.x`.
    pub fisher: Vec<Vec<f64>>,
    /// Newton steps taken.
    pub newton_steps: usize,
    /// Whether the predicted decrease fell to `decrease_tol`.
    pub converged: bool,
}

/// Newton steps from `start` (a minimum and its Hessian `fisher`, taken
/// with per-param difference `steps` as [`fisher_matrix`] does) on
/// `eval`, the loss and its gradient in the params' own units. Each step
/// solves `F δ = −g` over the params not held at a bound (within a
/// thousandth of their range of one, the loss falling beyond it), with
/// `F`'s diagonal raised by a factor `1 + λ`, λ from 0 up by tenfold
/// steps from 1e-3 to 1e3 (Levenberg–Marquardt), until the system is
/// positive definite. The step is shortened to stay within `bounds` (99 %
/// of the way to the nearest) and halved until the loss falls (at most 8
/// times). Stops where the predicted decrease is within tolerance, where
/// no λ makes `F` positive definite or no trial lowers the loss, or after
/// `max_steps`.
pub fn newton_polish<E>(
    mut eval: impl FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
    start: Minimum,
    fisher: Vec<Vec<f64>>,
    bounds: &[Option<(f64, f64)>],
    steps: &[f64],
    settings: &NewtonSettings,
) -> Result<Polished, E> {
    let (mut minimum, mut fisher) = (start, fisher);
    let mut newton_steps = 0;
    loop {
        let Some(delta) = newton_step(&fisher, &minimum.grad, &minimum.x, bounds) else {
            return Ok(Polished { minimum, fisher, newton_steps, converged: false });
        };
        let predicted = -0.5 * minimum.grad.iter().zip(&delta).map(|(a, b)| a * b).sum::<f64>();
        if predicted <= settings.decrease_tol {
            return Ok(Polished { minimum, fisher, newton_steps, converged: true });
        }
        if newton_steps == settings.max_steps {
            return Ok(Polished { minimum, fisher, newton_steps, converged: false });
        }
        let mut t = bounds.iter().zip(minimum.x.iter().zip(&delta)).fold(1.0f64, |t, (b, (x, d))| match b {
            Some((_, hi)) if *d > 0.0 => t.min(0.99 * (hi - x) / d),
            Some((lo, _)) if *d < 0.0 => t.min(0.99 * (lo - x) / d),
            _ => t,
        });
        let mut accepted = None;
        for _ in 0..=8 {
            let x: Vec<f64> = minimum.x.iter().zip(&delta).map(|(x, d)| x + t * d).collect();
            let (loss, grad) = eval(&x)?;
            minimum.evaluations += 1;
            if loss < minimum.loss {
                accepted = Some((x, loss, grad));
                break;
            }
            t *= 0.5;
        }
        let Some((x, loss, grad)) = accepted else {
            return Ok(Polished { minimum, fisher, newton_steps, converged: false });
        };
        fisher = fisher_matrix(|x: &[f64]| eval(x).map(|r| r.1), &x, bounds, steps)?;
        minimum.evaluations += 2 * x.len();
        minimum.steps += 1;
        newton_steps += 1;
        (minimum.x, minimum.loss, minimum.grad) = (x, loss, grad);
    }
}

/// The (damped) Newton step `δ` of [`newton_polish`] at `x`, zero for the
/// params held at a bound; none where no damping makes the system
/// positive definite.
fn newton_step(fisher: &[Vec<f64>], g: &[f64], x: &[f64], bounds: &[Option<(f64, f64)>]) -> Option<Vec<f64>> {
    let held = |i: usize| {
        bounds[i].is_some_and(|(lo, hi)| {
            let near = 1e-3 * (hi - lo);
            (x[i] - lo <= near && g[i] > 0.0) || (hi - x[i] <= near && g[i] < 0.0)
        })
    };
    let free: Vec<usize> = (0..x.len()).filter(|i| !held(*i)).collect();
    for lambda in [0.0, 1e-3, 1e-2, 1e-1, 1.0, 10.0, 100.0, 1000.0] {
        let m: Vec<Vec<f64>> = free
            .iter()
            .map(|&i| free.iter().map(|&j| if i == j { fisher[i][j] * (1.0 + lambda) } else { fisher[i][j] }).collect())
            .collect();
        if let Ok(c) = invert_fisher(&m) {
            let mut delta = vec![0.0; x.len()];
            for (a, &i) in free.iter().enumerate() {
                delta[i] = -free.iter().enumerate().map(|(b, &j)| c.covariance[a][b] * g[j]).sum::<f64>();
            }
            return Some(delta);
        }
    }
    None
}
