//! Inverse problems: minimise a scene's scalar loss over its free params and
//! estimate their uncertainties from the Fisher matrix.
//!
//! The pieces are pure Rust and independent of the JIT:
//!
//! - [`Transform`] maps each param to an unconstrained variable `u`, so an
//!   optimiser never steps outside the declared bounds: `x = lo + (hi - lo)
//!   σ(u)` for two-sided bounds (σ the logistic sigmoid), `x = lo + e^u` or
//!   `x = hi - e^(-u)` for one-sided ones, and `x = x0 + s u` (an affine
//!   rescaling, `s = |x0|` or 1) for unbounded params. Gradients are carried
//!   to `u` by the chain rule, `dL/du = dL/dx · dx/du`.
//! - [`minimize`] runs [`Optimizer::Lbfgs`] (limited-memory BFGS, two-loop
//!   recursion, with a backtracking line search under the Armijo
//!   sufficient-decrease condition) or [`Optimizer::Adam`] (Kingma & Ba
//!   2015, with a cosine-decayed learning rate) in `u`, and stops on the
//!   gradient norm, the relative change of the loss, or the step budget.
//! - [`fisher_matrix`] takes the Hessian of the loss at the optimum by
//!   central finite differences of the analytic gradient, in the params'
//!   own (declared) units; [`invert_fisher`] inverts it with nalgebra.
//!   For a loss `L = ½ (d - h | d - h)`, the negative log-likelihood of
//!   data in stationary Gaussian noise, this Hessian is the (observed)
//!   Fisher information and its inverse the covariance of the estimate in
//!   the linear-signal approximation (Vallisneri 2008, PRD 77, 042001).
//!   The loss must be normalised that way for the σ to mean anything.
//! - [`fit_run`] ties them to a [`Run`]: the free params are those the
//!   scene names in `grad OUTPUT wrt [...]`, started from their current
//!   values (defaults or what was set).

use crate::{Error, Run};
use gwml_compiler::ir::{Elem, Shape};
use nalgebra::{DMatrix, SymmetricEigen};
use std::collections::VecDeque;
use std::fmt;

/// How one param is mapped to the unconstrained variable `u`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transform {
    /// No bounds: `x = center + scale · u`.
    Affine {
        /// The value at `u = 0`.
        center: f64,
        /// Units of `x` per unit of `u`.
        scale: f64,
    },
    /// Two finite bounds: `x = lo + (hi - lo) σ(u)`, σ the logistic sigmoid.
    Interval {
        /// Lower bound.
        lo: f64,
        /// Upper bound.
        hi: f64,
    },
    /// Only a lower bound: `x = lo + e^u`.
    Lower {
        /// Lower bound.
        lo: f64,
    },
    /// Only an upper bound: `x = hi - e^(-u)`.
    Upper {
        /// Upper bound.
        hi: f64,
    },
}

/// Keeps `u` for a value at (or outside) a bound finite: a start exactly on
/// a bound is moved this fraction of the width inside.
const EDGE: f64 = 1e-9;

fn sigmoid(u: f64) -> f64 {
    if u >= 0.0 {
        1.0 / (1.0 + (-u).exp())
    } else {
        let e = u.exp();
        e / (1.0 + e)
    }
}

impl Transform {
    /// The transform for a param starting at `x0` with optional bounds
    /// (infinite bounds count as absent).
    pub fn new(x0: f64, bounds: Option<(f64, f64)>) -> Transform {
        let (lo, hi) = bounds.unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
        match (lo.is_finite(), hi.is_finite()) {
            (true, true) if hi > lo => Transform::Interval { lo, hi },
            (true, true) => Transform::Affine { center: lo, scale: 0.0 },
            (true, false) => Transform::Lower { lo },
            (false, true) => Transform::Upper { hi },
            (false, false) => Transform::Affine { center: x0, scale: if x0 != 0.0 { x0.abs() } else { 1.0 } },
        }
    }

    /// `x(u)`, always within the bounds.
    pub fn to_x(&self, u: f64) -> f64 {
        match *self {
            Transform::Affine { center, scale } => center + scale * u,
            Transform::Interval { lo, hi } => (lo + (hi - lo) * sigmoid(u)).clamp(lo, hi),
            Transform::Lower { lo } => lo + u.exp(),
            Transform::Upper { hi } => hi - (-u).exp(),
        }
    }

    /// `u(x)`; a value on or beyond a bound is first moved just inside.
    pub fn to_u(&self, x: f64) -> f64 {
        match *self {
            Transform::Affine { center, scale } => {
                if scale == 0.0 {
                    0.0
                } else {
                    (x - center) / scale
                }
            }
            Transform::Interval { lo, hi } => {
                let p = ((x - lo) / (hi - lo)).clamp(EDGE, 1.0 - EDGE);
                (p / (1.0 - p)).ln()
            }
            Transform::Lower { lo } => (x - lo).max(EDGE * x.abs().max(1.0)).ln(),
            Transform::Upper { hi } => -(hi - x).max(EDGE * x.abs().max(1.0)).ln(),
        }
    }

    /// `dx/du` at `u`.
    pub fn dx_du(&self, u: f64) -> f64 {
        match *self {
            Transform::Affine { scale, .. } => scale,
            Transform::Interval { lo, hi } => {
                let s = sigmoid(u);
                (hi - lo) * s * (1.0 - s)
            }
            Transform::Lower { .. } => u.exp(),
            Transform::Upper { .. } => (-u).exp(),
        }
    }
}

/// Which optimiser [`minimize`] runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Optimizer {
    /// Adam with bias correction and a cosine-decayed learning rate.
    Adam,
    /// Limited-memory BFGS with a backtracking Armijo line search.
    Lbfgs,
}

impl Optimizer {
    /// A step budget that suits the optimiser.
    pub fn default_steps(self) -> usize {
        match self {
            Optimizer::Adam => 3000,
            Optimizer::Lbfgs => 500,
        }
    }
}

/// Optimiser settings. `Settings::new(opt)` gives the defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct Settings {
    /// The optimiser.
    pub optimizer: Optimizer,
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
}

impl Settings {
    /// Defaults for `optimizer`.
    pub fn new(optimizer: Optimizer) -> Settings {
        Settings {
            optimizer,
            max_steps: optimizer.default_steps(),
            grad_tol: 1e-8,
            rel_tol: 1e-13,
            learning_rate: 0.02,
            adam_window: 200,
            memory: 10,
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
}

impl Stop {
    /// Whether this counts as convergence.
    pub fn converged(self) -> bool {
        !matches!(self, Stop::Steps)
    }
}

impl fmt::Display for Stop {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Stop::Gradient => "gradient norm below tolerance",
            Stop::LossChange => "relative loss change below tolerance",
            Stop::LineSearch => "line search found no further decrease (converged to rounding)",
            Stop::Steps => "step limit reached",
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

fn dot(a: &[f64], b: &[f64]) -> f64 {
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
        Optimizer::Lbfgs => lbfgs(&mut obj, u0, settings, &mut progress),
        Optimizer::Adam => adam(&mut obj, u0, settings, &mut progress),
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
    let n = u.len();
    let (mut l, mut g, mut gx) = match start(obj, &u)? {
        Ok(v) => v,
        Err(()) => {
            // Not finite at the start: nothing to do but report it.
            let x = obj.x(&u);
            return Ok(Minimum { x, loss: f64::NAN, grad: vec![f64::NAN; n], steps: 0, evaluations: obj.evaluations, stop: Stop::Steps });
        }
    };
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
            let mut d = two_loop(&g, &mem);
            let mut slope = dot(&g, &d);
            if slope.is_nan() || slope >= 0.0 {
                mem.clear();
                d = g.iter().map(|x| -x).collect();
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

/// The L-BFGS two-loop recursion: `-H g` for the inverse-Hessian estimate
/// `H` built from the stored `(s, y, 1/(s·y))` pairs (Nocedal & Wright,
/// Numerical Optimization, 2nd ed., Algorithm 7.4), returned as a descent
/// direction.
fn two_loop(g: &[f64], mem: &VecDeque<(Vec<f64>, Vec<f64>, f64)>) -> Vec<f64> {
    let mut q = g.to_vec();
    let mut alphas = Vec::with_capacity(mem.len());
    for (s, y, rho) in mem.iter().rev() {
        let a = rho * dot(s, &q);
        for (qi, yi) in q.iter_mut().zip(y) {
            *qi -= a * yi;
        }
        alphas.push(a);
    }
    if let Some((s, y, _)) = mem.back() {
        let gamma = dot(s, y) / dot(y, y);
        for qi in &mut q {
            *qi *= gamma;
        }
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
    let (b1, b2, eps) = (0.9, 0.999, 1e-8);
    let (mut l, mut g, mut gx) = match start(obj, &u)? {
        Ok(v) => v,
        Err(()) => {
            let x = obj.x(&u);
            return Ok(Minimum { x, loss: f64::NAN, grad: vec![f64::NAN; n], steps: 0, evaluations: obj.evaluations, stop: Stop::Steps });
        }
    };
    let mut best = (u.clone(), l, gx.clone());
    let mut history = VecDeque::from([l]);
    let (mut m, mut v) = (vec![0.0; n], vec![0.0; n]);
    let mut stop = Stop::Steps;
    let mut steps = 0;
    let total = s.max_steps.max(1) as f64;
    while steps < s.max_steps {
        if inf_norm(&g) <= s.grad_tol {
            stop = Stop::Gradient;
            break;
        }
        steps += 1;
        let t = steps as f64;
        // Cosine decay from the learning rate to 1/1000 of it.
        let lr = s.learning_rate * (1e-3 + (1.0 - 1e-3) * 0.5 * (1.0 + (std::f64::consts::PI * (t - 1.0) / total).cos()));
        let mut trial = u.clone();
        for i in 0..n {
            m[i] = b1 * m[i] + (1.0 - b1) * g[i];
            v[i] = b2 * v[i] + (1.0 - b2) * g[i] * g[i];
            let mh = m[i] / (1.0 - b1.powf(t));
            let vh = v[i] / (1.0 - b2.powf(t));
            trial[i] -= lr * mh / (vh.sqrt() + eps);
        }
        // A step into a non-finite region or an error is undone and the moments damped.
        match obj.eval(&trial) {
            Ok(Some((lt, gt, gxt))) => {
                (u, l, g, gx) = (trial, lt, gt, gxt);
            }
            Ok(None) | Err(_) => {
                for mi in &mut m {
                    *mi *= 0.5;
                }
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

/// Finite-difference steps for [`fisher_matrix`] at `x`: a tenth of the
/// conditional standard deviation `1/sqrt(F_ii)` estimated from a first,
/// small central difference of the gradient (relative step 1e-6 of
/// `max(|x_i|, 1e-3 · width_i)`, or 1e-6 if both vanish).
pub fn fisher_steps<G, E>(mut grad: G, x: &[f64], bounds: &[Option<(f64, f64)>]) -> Result<Vec<f64>, E>
where
    G: FnMut(&[f64]) -> Result<Vec<f64>, E>,
{
    let mut steps = Vec::with_capacity(x.len());
    for i in 0..x.len() {
        let width = bounds[i].map(|(lo, hi)| hi - lo).filter(|w| w.is_finite()).unwrap_or(0.0);
        let mut h0 = 1e-6 * x[i].abs().max(1e-3 * width);
        if h0 == 0.0 {
            h0 = 1e-6;
        }
        let col = column(&mut grad, x, bounds, i, h0)?;
        let c = col.0[i];
        let h = if c.is_finite() && c > 0.0 { 0.1 / c.sqrt() } else { h0 };
        steps.push(h);
    }
    Ok(steps)
}

/// Column `i` of the Hessian by differences of the gradient, with the step
/// actually used: central when `x ± h` fits within the bounds, one-sided
/// when only one side does, and central with the step shrunk to half the
/// distance to the nearer bound otherwise.
fn column<G, E>(grad: &mut G, x: &[f64], bounds: &[Option<(f64, f64)>], i: usize, h: f64) -> Result<(Vec<f64>, f64), E>
where
    G: FnMut(&[f64]) -> Result<Vec<f64>, E>,
{
    let (lo, hi) = bounds[i].unwrap_or((f64::NEG_INFINITY, f64::INFINITY));
    // At most half the width, so that one side always fits.
    let h = h.min(0.5 * (hi - lo));
    let fits = |v: f64| v >= lo && v <= hi;
    let at = |grad: &mut G, v: f64| {
        let mut p = x.to_vec();
        p[i] = v;
        grad(&p)
    };
    let (a, b, h_used) = if fits(x[i] + h) && fits(x[i] - h) {
        (x[i] + h, x[i] - h, h)
    } else if fits(x[i] - h) {
        (x[i], x[i] - h, h / 2.0)
    } else if fits(x[i] + h) {
        (x[i] + h, x[i], h / 2.0)
    } else {
        let h = 0.5 * (hi - x[i]).min(x[i] - lo).max(0.0);
        (x[i] + h, x[i] - h, h)
    };
    let ga = at(grad, a)?;
    let gb = at(grad, b)?;
    let col = ga.iter().zip(&gb).map(|(p, m)| (p - m) / (a - b)).collect();
    Ok((col, h_used))
}

/// The Hessian of a loss at `x` by central differences of its gradient
/// `grad` with per-param `steps` (see [`fisher_steps`]), symmetrised.
/// Everything is in the units `x` and `grad` use.
pub fn fisher_matrix<G, E>(mut grad: G, x: &[f64], bounds: &[Option<(f64, f64)>], steps: &[f64]) -> Result<Vec<Vec<f64>>, E>
where
    G: FnMut(&[f64]) -> Result<Vec<f64>, E>,
{
    let n = x.len();
    let mut cols = Vec::with_capacity(n);
    for (i, h) in steps.iter().enumerate() {
        cols.push(column(&mut grad, x, bounds, i, *h)?.0);
    }
    Ok((0..n).map(|i| (0..n).map(|j| 0.5 * (cols[j][i] + cols[i][j])).collect()).collect())
}

/// Uncertainties from an invertible Fisher matrix.
#[derive(Clone, Debug, PartialEq)]
pub struct Covariance {
    /// `F⁻¹`.
    pub covariance: Vec<Vec<f64>>,
    /// `σ_i = sqrt((F⁻¹)_ii)`.
    pub sigma: Vec<f64>,
    /// `C_ij = (F⁻¹)_ij / (σ_i σ_j)`.
    pub correlation: Vec<Vec<f64>>,
    /// Condition number of the correlation-scaled Fisher matrix.
    pub condition: f64,
}

/// Why a Fisher matrix gives no uncertainties.
#[derive(Clone, Debug, PartialEq)]
pub enum FisherError {
    /// An entry is NaN or infinite.
    NotFinite,
    /// Not positive definite (or singular to working precision): the point
    /// is not a strict local minimum, or some params are not constrained.
    NotPositiveDefinite {
        /// Eigenvalues of the (symmetrised) matrix, ascending.
        eigenvalues: Vec<f64>,
    },
}

impl fmt::Display for FisherError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FisherError::NotFinite => write!(f, "the Fisher matrix has non-finite entries"),
            FisherError::NotPositiveDefinite { eigenvalues } => write!(
                f,
                "the Fisher matrix is not positive definite (eigenvalues {eigenvalues:?}): the fit is not at a strict minimum, \
                 or some params are not constrained by the data; no uncertainties"
            ),
        }
    }
}

/// Inverts a symmetric Fisher matrix. To be robust to params of very
/// different scales it factors the correlation form `D F D`, `D =
/// diag(F_ii^(-1/2))`, by Cholesky (which exists exactly when `F` is
/// positive definite), and rejects condition numbers beyond 1e14.
pub fn invert_fisher(f: &[Vec<f64>]) -> Result<Covariance, FisherError> {
    let n = f.len();
    if f.iter().flatten().any(|v| !v.is_finite()) {
        return Err(FisherError::NotFinite);
    }
    let m = DMatrix::from_fn(n, n, |i, j| 0.5 * (f[i][j] + f[j][i]));
    let not_pd = || {
        let mut eigenvalues: Vec<f64> = SymmetricEigen::new(m.clone()).eigenvalues.iter().copied().collect();
        eigenvalues.sort_by(f64::total_cmp);
        FisherError::NotPositiveDefinite { eigenvalues }
    };
    if (0..n).any(|i| m[(i, i)] <= 0.0) {
        return Err(not_pd());
    }
    let d: Vec<f64> = (0..n).map(|i| 1.0 / m[(i, i)].sqrt()).collect();
    let c = DMatrix::from_fn(n, n, |i, j| m[(i, j)] * d[i] * d[j]);
    let eig = SymmetricEigen::new(c.clone()).eigenvalues;
    let (emin, emax) = eig.iter().fold((f64::INFINITY, 0.0f64), |(a, b), e| (a.min(*e), b.max(*e)));
    let condition = emax / emin;
    if emin <= 0.0 || condition.is_nan() || condition >= 1e14 {
        return Err(not_pd());
    }
    let chol = c.cholesky().ok_or_else(not_pd)?;
    let ci = chol.inverse();
    let covariance: Vec<Vec<f64>> = (0..n).map(|i| (0..n).map(|j| ci[(i, j)] * d[i] * d[j]).collect()).collect();
    let sigma: Vec<f64> = (0..n).map(|i| covariance[i][i].sqrt()).collect();
    let correlation = (0..n).map(|i| (0..n).map(|j| covariance[i][j] / (sigma[i] * sigma[j])).collect()).collect();
    Ok(Covariance { covariance, sigma, correlation, condition })
}

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

#[cfg(test)]
mod tests {
    use super::*;

    /// L = ½ (x - m)ᵀ A (x - m) with a correlated A.
    fn quadratic(x: &[f64]) -> Result<(f64, Vec<f64>), ()> {
        let a = [[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]];
        let m = [1.0, -2.0, 0.5];
        let r: Vec<f64> = x.iter().zip(&m).map(|(x, m)| x - m).collect();
        let g: Vec<f64> = (0..3).map(|i| (0..3).map(|j| a[i][j] * r[j]).sum()).collect();
        Ok((0.5 * dot(&r, &g), g))
    }

    fn rosenbrock(x: &[f64]) -> Result<(f64, Vec<f64>), ()> {
        let (a, b) = (x[0], x[1]);
        let l = (1.0 - a).powi(2) + 100.0 * (b - a * a).powi(2);
        let g = vec![-2.0 * (1.0 - a) - 400.0 * a * (b - a * a), 200.0 * (b - a * a)];
        Ok((l, g))
    }

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn transforms_round_trip_and_stay_in_bounds() {
        for (x0, b) in [(3.0, Some((1.0, 100.0))), (-0.05, Some((-0.1, 0.1))), (2.0, None), (0.0, None), (5.0, Some((1.0, f64::INFINITY)))]
        {
            let t = Transform::new(x0, b);
            let u = t.to_u(x0);
            assert!(close(t.to_x(u), x0, 1e-12 * x0.abs().max(1.0)), "{t:?}");
            let h = 1e-6;
            let fd = (t.to_x(u + h) - t.to_x(u - h)) / (2.0 * h);
            assert!(close(fd, t.dx_du(u), 1e-6 * fd.abs().max(1.0)), "{t:?}: {fd} vs {}", t.dx_du(u));
        }
        let t = Transform::new(0.5, Some((0.0, 1.0)));
        for u in [-1e6, -800.0, -40.0, 0.0, 40.0, 800.0, 1e6] {
            let x = t.to_x(u);
            assert!((0.0..=1.0).contains(&x) && x.is_finite(), "{u} -> {x}");
        }
        // A start on a bound maps to a finite u.
        assert!(t.to_u(1.0).is_finite() && t.to_u(0.0).is_finite());
    }

    #[test]
    fn lbfgs_finds_the_minimum_of_a_quadratic() {
        let m = minimize(quadratic, &[0.0, 0.0, 0.0], &[None, None, None], &Settings::new(Optimizer::Lbfgs), |_| {}).unwrap();
        for (x, want) in m.x.iter().zip([1.0, -2.0, 0.5]) {
            assert!(close(*x, want, 1e-7), "{:?}", m);
        }
        assert!(m.stop.converged() && m.steps < 50, "{m:?}");
    }

    #[test]
    fn adam_finds_the_minimum_of_a_quadratic() {
        let mut s = Settings::new(Optimizer::Adam);
        s.learning_rate = 0.1;
        let m = minimize(quadratic, &[0.0, 0.0, 0.0], &[Some((-5.0, 5.0)), None, Some((0.0, 3.0))], &s, |_| {}).unwrap();
        for (x, want) in m.x.iter().zip([1.0, -2.0, 0.5]) {
            assert!(close(*x, want, 1e-4), "{:?}", m);
        }
    }

    #[test]
    fn lbfgs_solves_rosenbrock_unbounded_and_bounded() {
        let s = Settings::new(Optimizer::Lbfgs);
        let m = minimize(rosenbrock, &[-1.2, 1.0], &[None, None], &s, |_| {}).unwrap();
        assert!(close(m.x[0], 1.0, 1e-6) && close(m.x[1], 1.0, 1e-6), "{m:?}");
        assert!(m.stop.converged(), "{m:?}");
        // With bounds (the minimum is inside), through the sigmoid transform.
        let mut seen_out = false;
        let m = minimize(rosenbrock, &[-1.2, 1.0], &[Some((-2.0, 2.0)), Some((-1.0, 3.0))], &s, |p| {
            seen_out |= !(-2.0..=2.0).contains(&p.x[0]) || !(-1.0..=3.0).contains(&p.x[1]);
        })
        .unwrap();
        assert!(close(m.x[0], 1.0, 1e-6) && close(m.x[1], 1.0, 1e-6), "{m:?}");
        assert!(!seen_out);
    }

    #[test]
    fn adam_solves_rosenbrock() {
        let mut s = Settings::new(Optimizer::Adam);
        s.max_steps = 20000;
        s.learning_rate = 0.05;
        let m = minimize(rosenbrock, &[-1.2, 1.0], &[Some((-2.0, 2.0)), Some((-1.0, 3.0))], &s, |_| {}).unwrap();
        assert!(close(m.x[0], 1.0, 1e-3) && close(m.x[1], 1.0, 2e-3), "{m:?}");
    }

    #[test]
    fn a_minimum_on_a_bound_is_approached_without_leaving_it() {
        // L = (x - 3)², x in 0..2: the constrained minimum is x = 2.
        let f = |x: &[f64]| -> Result<(f64, Vec<f64>), ()> {
            assert!((0.0..=2.0).contains(&x[0]), "left the bounds: {}", x[0]);
            Ok(((x[0] - 3.0).powi(2), vec![2.0 * (x[0] - 3.0)]))
        };
        let m = minimize(f, &[1.0], &[Some((0.0, 2.0))], &Settings::new(Optimizer::Lbfgs), |_| {}).unwrap();
        assert!(close(m.x[0], 2.0, 1e-6), "{m:?}");
        // Adam creeps towards a bound (u → ∞) with a decaying rate.
        let m = minimize(f, &[1.0], &[Some((0.0, 2.0))], &Settings::new(Optimizer::Adam), |_| {}).unwrap();
        assert!(close(m.x[0], 2.0, 2e-2), "{m:?}");
    }

    #[test]
    fn errors_at_trial_points_shorten_the_step() {
        // Undefined (an error) for x > 1.5; the minimum is at 1.
        let f = |x: &[f64]| -> Result<(f64, Vec<f64>), String> {
            if x[0] > 1.5 {
                return Err("out of domain".into());
            }
            Ok(((x[0] - 1.0).powi(2), vec![2.0 * (x[0] - 1.0)]))
        };
        let m = minimize(f, &[-3.0], &[None], &Settings::new(Optimizer::Lbfgs), |_| {}).unwrap();
        assert!(close(m.x[0], 1.0, 1e-6), "{m:?}");
        let bad = minimize(f, &[2.0], &[None], &Settings::new(Optimizer::Lbfgs), |_| {});
        assert!(bad.is_err());
    }

    #[test]
    fn fisher_of_a_quadratic_is_its_matrix_and_inverts() {
        let grad = |x: &[f64]| quadratic(x).map(|r| r.1);
        let x = [1.0, -2.0, 0.5];
        let b = [None, None, None];
        let steps = fisher_steps(grad, &x, &b).unwrap();
        let f = fisher_matrix(grad, &x, &b, &steps).unwrap();
        let a = [[4.0, 1.0, 0.0], [1.0, 3.0, 0.5], [0.0, 0.5, 2.0]];
        for i in 0..3 {
            for j in 0..3 {
                assert!(close(f[i][j], a[i][j], 1e-7), "{f:?}");
            }
        }
        let c = invert_fisher(&f).unwrap();
        let inv = DMatrix::from_fn(3, 3, |i, j| a[i][j]).try_inverse().unwrap();
        for i in 0..3 {
            assert!(close(c.sigma[i], inv[(i, i)].sqrt(), 1e-7));
            assert!(close(c.correlation[i][i], 1.0, 1e-12));
            for j in 0..3 {
                assert!(close(c.covariance[i][j], inv[(i, j)], 1e-7));
                assert!(close(c.correlation[i][j], inv[(i, j)] / (inv[(i, i)] * inv[(j, j)]).sqrt(), 1e-7));
            }
        }
    }

    #[test]
    fn fisher_handles_very_different_scales_and_a_bound() {
        // L = ½ (x/1e-4)² + ½ ((y - 1)/1e3)², y in 0..1 (the point is on the bound).
        let grad = |p: &[f64]| -> Result<Vec<f64>, ()> { Ok(vec![p[0] / 1e-8, (p[1] - 1.0) / 1e6]) };
        let x = [0.0, 1.0];
        let b = [None, Some((0.0, 1.0))];
        let steps = fisher_steps(grad, &x, &b).unwrap();
        let f = fisher_matrix(grad, &x, &b, &steps).unwrap();
        let c = invert_fisher(&f).unwrap();
        assert!(close(c.sigma[0] / 1e-4, 1.0, 1e-6) && close(c.sigma[1] / 1e3, 1.0, 1e-6), "{c:?}");
    }

    #[test]
    fn rosenbrock_fisher_at_the_minimum() {
        // Hessian of Rosenbrock at (1, 1): [[802, -400], [-400, 200]].
        let grad = |x: &[f64]| rosenbrock(x).map(|r| r.1);
        let x = [1.0, 1.0];
        let b = [None, None];
        let f = fisher_matrix(grad, &x, &b, &fisher_steps(grad, &x, &b).unwrap()).unwrap();
        let want = [[802.0, -400.0], [-400.0, 200.0]];
        for i in 0..2 {
            for j in 0..2 {
                assert!(close(f[i][j], want[i][j], 1e-3 * want[i][j].abs()), "{f:?}");
            }
        }
        let c = invert_fisher(&f).unwrap();
        // inverse = [[0.5, 1], [1, 2.005]], nearly singular: the 0.1σ steps
        // see Rosenbrock's cubic terms, so allow a few parts per thousand.
        assert!(close(c.sigma[0], 0.5f64.sqrt(), 3e-3) && close(c.sigma[1], 2.005f64.sqrt(), 3e-3), "{c:?}");
    }

    #[test]
    fn indefinite_or_singular_fisher_is_an_error_not_nan() {
        let e = invert_fisher(&[vec![1.0, 2.0], vec![2.0, 1.0]]).unwrap_err();
        match &e {
            FisherError::NotPositiveDefinite { eigenvalues } => {
                assert!(close(eigenvalues[0], -1.0, 1e-12) && close(eigenvalues[1], 3.0, 1e-12))
            }
            other => panic!("{other:?}"),
        }
        assert!(e.to_string().contains("not positive definite"));
        assert!(matches!(invert_fisher(&[vec![1.0, 1.0], vec![1.0, 1.0]]), Err(FisherError::NotPositiveDefinite { .. })));
        assert!(matches!(invert_fisher(&[vec![0.0]]), Err(FisherError::NotPositiveDefinite { .. })));
        assert_eq!(invert_fisher(&[vec![f64::NAN]]), Err(FisherError::NotFinite));
    }
}
