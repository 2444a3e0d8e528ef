//! The optimisers over the unconstrained variables: L-BFGS and Adam (the
//! update rule of [`crate::optim`]), with their settings and stopping rules.

use super::Transform;
use crate::optim::{self, Method, OptimConfig, Schedule};
use std::collections::VecDeque;
use std::fmt;

/// Which optimiser [`minimize`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Algorithm {
    /// Adam with bias correction and a cosine-decayed learning rate.
    Adam,
    /// Limited-memory BFGS with a backtracking Armijo line search.
    Lbfgs,
}

impl Algorithm {
    /// A step budget that suits the optimiser.
    pub fn default_steps(self) -> usize {
        match self {
            Algorithm::Adam => 3000,
            Algorithm::Lbfgs => 500,
        }
    }
}

/// Optimiser settings. `Settings::new(opt)` gives the defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The optimiser.
    pub optimizer: Algorithm,
    /// Maximum number of iterations.
    pub max_steps: usize,
    /// Stop when the largest component of `dL/du` is at most this.
    pub grad_tol: f64,
    /// Stop when `|ΔL| <= rel_tol · max(|L|, 1)` on two iterations in a row
    /// (L-BFGS), or when the best loss improved by less than that over the
    /// last [`Settings::adam_window`] steps (Adam).
    pub rel_tol: f64,
    /// Adam's initial learning rate in `u` (for a two-sided bound, a step of
    /// 1 in `u` moves a param near the middle of its range by a quarter of
    /// the range; for an unbounded param, by `|x0|`, or 1 if `x0 = 0`).
    pub learning_rate: f64,
    /// Adam: steps over which the loss must improve.
    pub adam_window: usize,
    /// L-BFGS memory (pairs kept).
    pub memory: usize,
    /// L-BFGS: estimate each param's curvature in `u` at the start (one
    /// more gradient per param, by finite differences) and take its
    /// inverse as the diagonal of the first inverse-Hessian estimate, for
    /// params whose curvatures differ by orders of magnitude (a whistle's
    /// vertex frequency, known to 0.1 Hz of a 1350 Hz range, against its
    /// width): without it, steps along the gradient barely move the loose
    /// params and `rel_tol` stops the fit short.
    pub diagonal: bool,
}

impl Settings {
    /// Defaults for `optimizer`.
    pub fn new(optimizer: Algorithm) -> Settings {
        Settings {
            optimizer,
            max_steps: optimizer.default_steps(),
            grad_tol: 1e-8,
            rel_tol: 1e-13,
            learning_rate: 0.02,
            adam_window: 200,
            memory: 10,
            diagonal: false,
        }
    }
}

/// Why [`minimize`] stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The gradient norm fell below `grad_tol`.
    Gradient,
    /// The loss stopped changing (`rel_tol`).
    LossChange,
    /// The line search found no decrease along the steepest-descent
    /// direction: the loss is flat to rounding there (usually converged).
    LineSearch,
    /// `max_steps` iterations ran.
    Steps,
    /// Adam could not start: the learning rate is not positive and finite.
    BadLearningRate,
}

impl Stop {
    /// Whether this counts as convergence.
    pub fn converged(self) -> bool {
        !matches!(self, Stop::Steps | Stop::BadLearningRate)
    }
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stop::Gradient => "gradient norm below tolerance",
            Stop::LossChange => "relative loss change below tolerance",
            Stop::LineSearch => "line search found no further decrease (converged to rounding)",
            Stop::Steps => "step limit reached",
            Stop::BadLearningRate => "the learning rate must be positive and finite",
        })
    }
}

/// One iteration's state, passed to the progress callback.
#[derive(Clone, Debug)]
pub struct Progress<'a> {
    /// Iteration number (1-based).
    pub step: usize,
    /// Loss at the current point.
    pub loss: f64,
    /// Largest component of `dL/du`.
    pub grad_norm: f64,
    /// The current params (in their own units).
    pub x: &'a [f64],
    /// Objective evaluations so far.
    pub evaluations: usize,
}

/// The result of [`minimize`].
#[derive(Clone, Debug, PartialEq)]
pub struct Minimum {
    /// The params at the minimum found (in their own units).
    pub x: Vec<f64>,
    /// The loss there.
    pub loss: f64,
    /// `dL/dx` there.
    pub grad: Vec<f64>,
    /// Iterations run.
    pub steps: usize,
    /// Objective evaluations.
    pub evaluations: usize,
    /// Why it stopped.
    pub stop: Stop,
}

fn inf_norm(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

pub(super) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// `(L, dL/du, dL/dx)` at one point.
type Point = (f64, Vec<f64>, Vec<f64>);

/// The objective in `u`: evaluations, transforms and error bookkeeping.
struct InU<'f, F> {
    f: &'f mut F,
    transforms: Vec<Transform>,
    evaluations: usize,
}

impl<F, E> InU<'_, F>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    /// The result when the loss is not finite at the start `u`: nothing to
    /// do but report it.
    fn not_finite_at(&self, u: &[f64]) -> Minimum {
        let n = u.len();
        Minimum { x: self.x(u), loss: f64::NAN, grad: vec![f64::NAN; n], steps: 0, evaluations: self.evaluations, stop: Stop::Steps }
    }

    fn x(&self, u: &[f64]) -> Vec<f64> {
        self.transforms.iter().zip(u).map(|(t, u)| t.to_x(*u)).collect()
    }

    /// `(L, dL/du, dL/dx)`; a non-finite loss or gradient is `Ok(None)`.
    fn eval(&mut self, u: &[f64]) -> Result<Option<Point>, E> {
        let x = self.x(u);
        self.evaluations += 1;
        let (l, gx) = (self.f)(&x)?;
        if !l.is_finite() || gx.iter().any(|g| !g.is_finite()) {
            return Ok(None);
        }
        let gu = gx.iter().zip(&self.transforms).zip(u).map(|((g, t), u)| g * t.dx_du(*u)).collect();
        Ok(Some((l, gu, gx)))
    }
}

/// Minimises `f` (returning the loss and its gradient in `x`) from `x0`,
/// keeping each `x[i]` within `bounds[i]`. `progress` is called after every
/// iteration. An error from `f` at the start is returned; at a trial point
/// of a line search it counts as "no decrease" (the step is shortened), and
/// it is returned only if no shorter step avoids it.
pub fn minimize<F, E>(
    mut f: F,
    x0: &[f64],
    bounds: &[Option<(f64, f64)>],
    settings: &Settings,
    mut progress: impl FnMut(&Progress),
) -> Result<Minimum, E>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    assert_eq!(x0.len(), bounds.len(), "one bound per param");
    let transforms: Vec<Transform> = x0.iter().zip(bounds).map(|(x, b)| Transform::new(*x, *b)).collect();
    let u0: Vec<f64> = transforms.iter().zip(x0).map(|(t, x)| t.to_u(*x)).collect();
    let mut obj = InU { f: &mut f, transforms, evaluations: 0 };
    match settings.optimizer {
        Algorithm::Lbfgs => lbfgs(&mut obj, u0, settings, &mut progress),
        Algorithm::Adam => adam(&mut obj, u0, settings, &mut progress),
    }
}

/// First evaluation: errors and non-finite values are the caller's problem.
fn start<F, E>(obj: &mut InU<'_, F>, u: &[f64]) -> Result<Result<Point, ()>, E>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    Ok(obj.eval(u)?.ok_or(()))
}

fn lbfgs<F, E>(obj: &mut InU<'_, F>, mut u: Vec<f64>, s: &Settings, progress: &mut dyn FnMut(&Progress)) -> Result<Minimum, E>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    let (mut l, mut g, mut gx) = match start(obj, &u)? {
        Ok(v) => v,
        Err(()) => return Ok(obj.not_finite_at(&u)),
    };
    let scale = if s.diagonal { inverse_curvature(obj, &u, &g)? } else { vec![1.0; u.len()] };
    let mut mem: VecDeque<(Vec<f64>, Vec<f64>, f64)> = VecDeque::new();
    let mut small_changes = 0;
    let mut stop = Stop::Steps;
    let mut steps = 0;
    let mut last_err: Option<E> = None;
    while steps < s.max_steps {
        if inf_norm(&g) <= s.grad_tol {
            stop = Stop::Gradient;
            break;
        }
        steps += 1;
        let mut accepted = None;
        // Try the quasi-Newton direction; if its line search fails, forget
        // the curvature pairs and try steepest descent once.
        for attempt in 0..2 {
            if attempt == 1 {
                if mem.is_empty() {
                    break;
                }
                mem.clear();
            }
            let mut d = two_loop(&g, &mem, &scale);
            let mut slope = dot(&g, &d);
            if slope.is_nan() || slope >= 0.0 {
                mem.clear();
                d = two_loop(&g, &mem, &scale);
                slope = dot(&g, &d);
            }
            // Without curvature information, limit the first step to 0.1 in u.
            let mut alpha = if mem.is_empty() { (0.1 / inf_norm(&d)).min(1.0) } else { 1.0 };
            for _ in 0..60 {
                let trial: Vec<f64> = u.iter().zip(&d).map(|(u, d)| u + alpha * d).collect();
                match obj.eval(&trial) {
                    Ok(Some((lt, gt, gxt))) if lt <= l + 1e-4 * alpha * slope => {
                        accepted = Some((trial, lt, gt, gxt));
                        break;
                    }
                    Ok(Some((lt, ..))) => {
                        // Minimiser of the quadratic through (0, l), slope, (alpha, lt), kept in [0.1, 0.5] alpha.
                        let q = -slope * alpha * alpha / (2.0 * (lt - l - slope * alpha));
                        alpha = if q.is_finite() { q.clamp(0.1 * alpha, 0.5 * alpha) } else { 0.5 * alpha };
                    }
                    Ok(None) => alpha *= 0.5,
                    Err(e) => {
                        last_err = Some(e);
                        alpha *= 0.5;
                    }
                }
                if alpha * inf_norm(&d) < 1e-300 {
                    break;
                }
            }
            if accepted.is_some() {
                break;
            }
        }
        let Some((un, ln, gn, gxn)) = accepted else {
            if steps == 1 {
                if let Some(e) = last_err {
                    return Err(e);
                }
            }
            steps -= 1;
            stop = Stop::LineSearch;
            break;
        };
        let sv: Vec<f64> = un.iter().zip(&u).map(|(a, b)| a - b).collect();
        let yv: Vec<f64> = gn.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&sv, &yv);
        if sy > 1e-12 * dot(&sv, &sv).sqrt() * dot(&yv, &yv).sqrt() && sy > 0.0 {
            if mem.len() == s.memory.max(1) {
                mem.pop_front();
            }
            mem.push_back((sv, yv, 1.0 / sy));
        }
        let change = (l - ln).abs();
        let scale = l.abs().max(ln.abs()).max(1.0);
        (u, l, g, gx) = (un, ln, gn, gxn);
        let x = obj.x(&u);
        progress(&Progress { step: steps, loss: l, grad_norm: inf_norm(&g), x: &x, evaluations: obj.evaluations });
        if change <= s.rel_tol * scale {
            small_changes += 1;
            if small_changes >= 2 {
                stop = Stop::LossChange;
                break;
            }
        } else {
            small_changes = 0;
        }
    }
    Ok(Minimum { x: obj.x(&u), loss: l, grad: gx, steps, evaluations: obj.evaluations, stop })
}

/// The inverse of each param's curvature `∂²L/∂u_i²` at `u` (where the
/// gradient is `g`), by a forward difference of the gradient. A curvature
/// that is not positive and finite (a saddle or an edge) takes the largest
/// of the others: that param moves as cautiously as the stiffest.
fn inverse_curvature<F, E>(obj: &mut InU<'_, F>, u: &[f64], g: &[f64]) -> Result<Vec<f64>, E>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    const STEP: f64 = 1e-4;
    let mut curvature = Vec::with_capacity(u.len());
    for i in 0..u.len() {
        let mut v = u.to_vec();
        v[i] += STEP;
        let c = obj.eval(&v)?.map_or(f64::NAN, |(_, gv, _)| (gv[i] - g[i]) / STEP);
        curvature.push(c);
    }
    let usable = |c: &f64| c.is_finite() && *c > 0.0;
    let stiffest = curvature.iter().copied().filter(usable).fold(f64::NAN, f64::max);
    if stiffest.is_nan() {
        return Ok(vec![1.0; u.len()]);
    }
    Ok(curvature.iter().map(|c| 1.0 / if usable(c) { *c } else { stiffest }).collect())
}

/// The L-BFGS two-loop recursion: `-H g` for the inverse-Hessian estimate
/// `H` built from the stored `(s, y, 1/(s·y))` pairs on the diagonal
/// `scale` (Nocedal & Wright, Numerical Optimization, 2nd ed., Algorithm
/// 7.4, with `H₀ = γ diag(scale)`, `γ = s·y / y·diag(scale)·y` of the
/// newest pair, or 1 without one), returned as a descent direction.
fn two_loop(g: &[f64], mem: &VecDeque<(Vec<f64>, Vec<f64>, f64)>, scale: &[f64]) -> Vec<f64> {
    let mut q = g.to_vec();
    let mut alphas = Vec::with_capacity(mem.len());
    for (s, y, rho) in mem.iter().rev() {
        let a = rho * dot(s, &q);
        for (qi, yi) in q.iter_mut().zip(y) {
            *qi -= a * yi;
        }
        alphas.push(a);
    }
    let gamma = mem.back().map_or(1.0, |(s, y, _)| {
        let scaled: Vec<f64> = y.iter().zip(scale).map(|(y, c)| y * c).collect();
        dot(s, y) / dot(y, &scaled)
    });
    for (qi, c) in q.iter_mut().zip(scale) {
        *qi *= gamma * c;
    }
    for ((s, y, rho), a) in mem.iter().zip(alphas.iter().rev()) {
        let b = rho * dot(y, &q);
        for (qi, si) in q.iter_mut().zip(s) {
            *qi += (a - b) * si;
        }
    }
    q.iter().map(|x| -x).collect()
}

fn adam<F, E>(obj: &mut InU<'_, F>, mut u: Vec<f64>, s: &Settings, progress: &mut dyn FnMut(&Progress)) -> Result<Minimum, E>
where
    F: FnMut(&[f64]) -> Result<(f64, Vec<f64>), E>,
{
    let n = u.len();
    let (mut l, mut g, mut gx) = match start(obj, &u)? {
        Ok(v) => v,
        Err(()) => return Ok(obj.not_finite_at(&u)),
    };
    // The update rule is the trainer's Adam (Kingma & Ba 2015, PyTorch's
    // defaults), with a cosine decay from the learning rate to 1/1000 of it
    // over the step budget.
    let config = OptimConfig {
        method: Method::adam(),
        lr: s.learning_rate,
        schedule: Schedule::Cosine { total: s.max_steps.max(1) as u64, min_lr: 1e-3 * s.learning_rate },
        clip_norm: None,
    };
    let Ok(mut adam) = optim::Optimizer::new(config, n) else {
        let x = obj.x(&u);
        return Ok(Minimum { x, loss: l, grad: gx, steps: 0, evaluations: obj.evaluations, stop: Stop::BadLearningRate });
    };
    let mut best = (u.clone(), l, gx.clone());
    let mut history = VecDeque::from([l]);
    let mut stop = Stop::Steps;
    let mut steps = 0;
    while steps < s.max_steps {
        if inf_norm(&g) <= s.grad_tol {
            stop = Stop::Gradient;
            break;
        }
        steps += 1;
        let mut trial = u.clone();
        if adam.step(&mut trial, &g).is_err() {
            break; // unreachable: `g` is finite and of length n
        }
        // A step into a non-finite region or an error is undone and the first moment damped.
        match obj.eval(&trial) {
            Ok(Some((lt, gt, gxt))) => {
                (u, l, g, gx) = (trial, lt, gt, gxt);
            }
            Ok(None) | Err(_) => {
                adam.damp_first_moment(0.5);
                continue;
            }
        }
        if l < best.1 {
            best = (u.clone(), l, gx.clone());
        }
        let x = obj.x(&u);
        progress(&Progress { step: steps, loss: l, grad_norm: inf_norm(&g), x: &x, evaluations: obj.evaluations });
        history.push_back(best.1);
        if history.len() > s.adam_window.max(1) {
            let old = history.pop_front().expect("non-empty");
            if (old - best.1).abs() <= s.rel_tol * old.abs().max(1.0) {
                stop = Stop::LossChange;
                break;
            }
        }
    }
    let (bu, bl, bg) = best;
    Ok(Minimum { x: obj.x(&bu), loss: bl, grad: bg, steps, evaluations: obj.evaluations, stop })
}
