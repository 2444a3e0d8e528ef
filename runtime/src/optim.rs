//! First-order optimisers over one flat vector of trainable values.
//!
//! The caller packs everything it trains (weight tensors, scalar
//! parameters) into one `&mut [f64]` and passes the matching gradient of
//! the loss each step. Three methods:
//!
//! - SGD with heavy-ball momentum in PyTorch's convention (no dampening):
//!   `v ← μ v + g`, `p ← p − lr v` (`μ = 0` is plain gradient descent).
//! - Adam: Kingma & Ba, "Adam: A Method for Stochastic Optimization",
//!   ICLR 2015, Algorithm 1, with bias-corrected moments.
//! - AdamW: Loshchilov & Hutter, "Decoupled Weight Decay Regularization",
//!   ICLR 2019, Algorithm 2: the weight decay acts on the values directly
//!   instead of being added to the gradient; as in PyTorch it is scaled by
//!   the learning rate, `p ← p (1 − lr λ)`, before the Adam update.
//!
//! Before the update, the gradient can be clipped by its global L2 norm:
//! when `‖g‖ > c` every component is scaled by `c / ‖g‖`. The learning rate
//! follows a [`Schedule`] of the step count. [`Optimizer::state`] and
//! [`Optimizer::restore`] carry the step count and moment buffers through a
//! checkpoint, so a resumed run repeats an uninterrupted one bit for bit.

use crate::Error;

/// The update rule and its hyper-parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Method {
    /// Stochastic gradient descent with momentum `μ ∈ [0, 1)`:
    /// `v ← μ v + g`, `p ← p − lr v` (PyTorch's convention).
    Sgd {
        /// The momentum coefficient `μ` (0 for plain gradient descent).
        momentum: f64,
    },
    /// Adam (Kingma & Ba 2015, Algorithm 1).
    Adam {
        /// Decay rate of the first-moment estimate, in `[0, 1)`.
        beta1: f64,
        /// Decay rate of the second-moment estimate, in `[0, 1)`.
        beta2: f64,
        /// Added to the root of the second moment, `> 0`.
        eps: f64,
    },
    /// AdamW: Adam with decoupled weight decay (Loshchilov & Hutter 2019).
    AdamW {
        /// Decay rate of the first-moment estimate, in `[0, 1)`.
        beta1: f64,
        /// Decay rate of the second-moment estimate, in `[0, 1)`.
        beta2: f64,
        /// Added to the root of the second moment, `> 0`.
        eps: f64,
        /// Decoupled weight decay `λ ≥ 0`; each step multiplies the values by `1 − lr λ`.
        weight_decay: f64,
    },
}

impl Method {
    /// Adam with PyTorch's defaults: `β₁ = 0.9`, `β₂ = 0.999`, `ε = 1e-8`.
    pub fn adam() -> Method {
        Method::Adam { beta1: 0.9, beta2: 0.999, eps: 1e-8 }
    }

    /// AdamW with PyTorch's default betas and epsilon and weight decay `weight_decay`.
    pub fn adamw(weight_decay: f64) -> Method {
        Method::AdamW { beta1: 0.9, beta2: 0.999, eps: 1e-8, weight_decay }
    }

    /// SGD with momentum `momentum` (0 for plain gradient descent).
    pub fn sgd(momentum: f64) -> Method {
        Method::Sgd { momentum }
    }

    /// Whether the method keeps a first-moment (or momentum) buffer.
    fn has_first_moment(&self) -> bool {
        match *self {
            Method::Sgd { momentum } => momentum != 0.0,
            Method::Adam { .. } | Method::AdamW { .. } => true,
        }
    }

    /// Whether the method keeps a second-moment buffer.
    fn has_second_moment(&self) -> bool {
        !matches!(self, Method::Sgd { .. })
    }
}

/// How the learning rate changes with the step count (counted from 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Schedule {
    /// The base learning rate at every step.
    Constant,
    /// Multiply the rate by `gamma` every `every` steps: `lr γ^⌊step / every⌋`.
    Step {
        /// Steps between decays, `> 0`.
        every: u64,
        /// The decay factor, finite and `≥ 0`.
        gamma: f64,
    },
    /// Cosine annealing from the base rate to `min_lr` over `total` steps,
    /// then `min_lr`: `min + (base − min)(1 + cos(π min(step, total) / total)) / 2`
    /// (Loshchilov & Hutter, "SGDR", ICLR 2017, without restarts).
    Cosine {
        /// Steps over which the rate decays, `> 0`.
        total: u64,
        /// The final rate, finite, `≥ 0` and at most the base rate.
        min_lr: f64,
    },
}

impl Schedule {
    /// The learning rate at step `step` (the first step is 0) for base rate `base_lr`.
    ///
    /// Degenerate parameters that [`Optimizer::new`] rejects are given a
    /// meaning here rather than a panic: `every = 0` never decays and
    /// `total = 0` is already at `min_lr`.
    pub fn lr_at(&self, base_lr: f64, step: u64) -> f64 {
        match *self {
            Schedule::Constant => base_lr,
            Schedule::Step { every, gamma } => match step.checked_div(every) {
                Some(k) => base_lr * gamma.powf(k as f64),
                None => base_lr,
            },
            Schedule::Cosine { total, min_lr } => {
                if total == 0 {
                    return min_lr;
                }
                let frac = step.min(total) as f64 / total as f64;
                min_lr + (base_lr - min_lr) * (1.0 + (std::f64::consts::PI * frac).cos()) / 2.0
            }
        }
    }
}

/// Everything that configures an [`Optimizer`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OptimConfig {
    /// The update rule.
    pub method: Method,
    /// The base learning rate (finite, `≥ 0`), shaped by `schedule`.
    pub lr: f64,
    /// How the learning rate changes with the step count.
    pub schedule: Schedule,
    /// Clip the gradient to this global L2 norm (`> 0`) before the update; `None` never clips.
    pub clip_norm: Option<f64>,
}

/// What one [`Optimizer::step`] did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepInfo {
    /// The learning rate used for this step.
    pub lr: f64,
    /// The global L2 norm of the gradient before clipping.
    pub grad_norm: f64,
    /// Whether the gradient was scaled down to `clip_norm`.
    pub clipped: bool,
}

/// An optimiser's mutable state, for checkpoints.
#[derive(Clone, Debug, PartialEq)]
pub struct OptimState {
    /// Steps taken so far.
    pub step: u64,
    /// Adam's first moment `m`, or SGD's momentum buffer `v`; empty for SGD without momentum.
    pub first_moment: Vec<f64>,
    /// Adam's second moment `v`; empty for SGD.
    pub second_moment: Vec<f64>,
}

/// An optimiser for a flat vector of `n` values.
#[derive(Clone, Debug)]
pub struct Optimizer {
    config: OptimConfig,
    n: usize,
    step: u64,
    first: Vec<f64>,
    second: Vec<f64>,
}

/// Adam's hyper-parameters; `weight_decay` is 0 for plain Adam.
#[derive(Clone, Copy)]
struct AdamHyper {
    beta1: f64,
    beta2: f64,
    eps: f64,
    weight_decay: f64,
}

fn bad(msg: String) -> Error {
    Error::Bind(msg)
}

/// Checks that `x` is finite and in `[lo, hi)` (`hi` exclusive) or `[lo, ∞)` when `hi` is `None`.
fn check_range(what: &str, x: f64, lo: f64, hi: Option<f64>) -> Result<(), Error> {
    let ok = x.is_finite() && x >= lo && hi.is_none_or(|h| x < h);
    if ok {
        return Ok(());
    }
    Err(bad(match hi {
        Some(h) => format!("optimiser: {what} must be in [{lo}, {h}), not {x}"),
        None => format!("optimiser: {what} must be finite and at least {lo}, not {x}"),
    }))
}

fn validate(config: &OptimConfig) -> Result<(), Error> {
    check_range("learning rate", config.lr, 0.0, None)?;
    match config.method {
        Method::Sgd { momentum } => check_range("momentum", momentum, 0.0, Some(1.0))?,
        Method::Adam { beta1, beta2, eps } => {
            check_range("beta1", beta1, 0.0, Some(1.0))?;
            check_range("beta2", beta2, 0.0, Some(1.0))?;
            check_positive("eps", eps)?;
        }
        Method::AdamW { beta1, beta2, eps, weight_decay } => {
            check_range("beta1", beta1, 0.0, Some(1.0))?;
            check_range("beta2", beta2, 0.0, Some(1.0))?;
            check_positive("eps", eps)?;
            check_range("weight decay", weight_decay, 0.0, None)?;
        }
    }
    match config.schedule {
        Schedule::Constant => {}
        Schedule::Step { every, gamma } => {
            if every == 0 {
                return Err(bad("optimiser: a step schedule needs `every` > 0".into()));
            }
            check_range("step schedule's gamma", gamma, 0.0, None)?;
        }
        Schedule::Cosine { total, min_lr } => {
            if total == 0 {
                return Err(bad("optimiser: a cosine schedule needs `total` > 0".into()));
            }
            check_range("cosine schedule's min_lr", min_lr, 0.0, None)?;
            if min_lr > config.lr {
                return Err(bad(format!("optimiser: the cosine schedule's min_lr {min_lr} exceeds the learning rate {}", config.lr)));
            }
        }
    }
    if let Some(c) = config.clip_norm {
        check_positive("clip_norm", c)?;
    }
    Ok(())
}

fn check_positive(what: &str, x: f64) -> Result<(), Error> {
    if x.is_finite() && x > 0.0 {
        Ok(())
    } else {
        Err(bad(format!("optimiser: {what} must be positive and finite, not {x}")))
    }
}

/// The L2 norm of `g`, computed with scaling so that large finite components do not overflow.
fn l2_norm(g: &[f64]) -> f64 {
    let max = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if max == 0.0 {
        return 0.0;
    }
    let sum: f64 = g.iter().map(|x| (x / max) * (x / max)).sum();
    max * sum.sqrt()
}

impl Optimizer {
    /// An optimiser for `n` values, with zeroed moments and no steps taken.
    ///
    /// Errors ([`Error::Bind`]) for a negative or non-finite learning rate,
    /// momentum or betas outside `[0, 1)`, `eps ≤ 0`, negative weight decay,
    /// `clip_norm ≤ 0`, or a schedule with `every`/`total` of 0, a negative
    /// `gamma`, or `min_lr` outside `[0, lr]`.
    pub fn new(config: OptimConfig, n: usize) -> Result<Optimizer, Error> {
        validate(&config)?;
        let first = if config.method.has_first_moment() { vec![0.0; n] } else { Vec::new() };
        let second = if config.method.has_second_moment() { vec![0.0; n] } else { Vec::new() };
        Ok(Optimizer { config, n, step: 0, first, second })
    }

    /// The configuration this optimiser was made with.
    pub fn config(&self) -> &OptimConfig {
        &self.config
    }

    /// The number of values this optimiser updates.
    pub fn len(&self) -> usize {
        self.n
    }

    /// Whether the optimiser updates no values at all.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Steps taken so far (the next step uses the schedule's rate at this count).
    pub fn steps_taken(&self) -> u64 {
        self.step
    }

    /// Updates `values` in place from the loss gradient `grads`.
    ///
    /// Errors ([`Error::Bind`]), leaving the values and the optimiser's state
    /// untouched, when either slice's length differs from the optimiser's or
    /// a gradient component is NaN or infinite (the message names the first
    /// such index).
    pub fn step(&mut self, values: &mut [f64], grads: &[f64]) -> Result<StepInfo, Error> {
        if values.len() != self.n || grads.len() != self.n {
            return Err(bad(format!(
                "optimiser: expected {} values and gradients, got {} values and {} gradients",
                self.n,
                values.len(),
                grads.len()
            )));
        }
        if let Some(i) = grads.iter().position(|g| !g.is_finite()) {
            return Err(bad(format!("optimiser: gradient component {i} is {} (not finite); the step was skipped", grads[i])));
        }
        let lr = self.config.schedule.lr_at(self.config.lr, self.step);
        let grad_norm = l2_norm(grads);
        let (scale, clipped) = match self.config.clip_norm {
            Some(c) if grad_norm > c => (c / grad_norm, true),
            _ => (1.0, false),
        };
        let t = self.step + 1;
        match self.config.method {
            Method::Sgd { momentum } => {
                if self.first.is_empty() {
                    for (p, g) in values.iter_mut().zip(grads) {
                        *p -= lr * (g * scale);
                    }
                } else {
                    for ((p, g), v) in values.iter_mut().zip(grads).zip(&mut self.first) {
                        *v = momentum * *v + g * scale;
                        *p -= lr * *v;
                    }
                }
            }
            Method::Adam { beta1, beta2, eps } => self.adam(values, grads, scale, lr, AdamHyper { beta1, beta2, eps, weight_decay: 0.0 }),
            Method::AdamW { beta1, beta2, eps, weight_decay } => {
                self.adam(values, grads, scale, lr, AdamHyper { beta1, beta2, eps, weight_decay })
            }
        }
        self.step = t;
        Ok(StepInfo { lr, grad_norm, clipped })
    }

    /// One Adam(W) step, number `t = steps_taken + 1` in Kingma & Ba's
    /// notation, on the gradient `grads` scaled by `scale`.
    fn adam(&mut self, values: &mut [f64], grads: &[f64], scale: f64, lr: f64, h: AdamHyper) {
        let AdamHyper { beta1, beta2, eps, weight_decay: wd } = h;
        let t = (self.step + 1) as f64;
        let bias1 = 1.0 - beta1.powf(t);
        let bias2 = 1.0 - beta2.powf(t);
        let decay = 1.0 - lr * wd;
        for (((p, g), m), v) in values.iter_mut().zip(grads).zip(&mut self.first).zip(&mut self.second) {
            let g = g * scale;
            if wd != 0.0 {
                *p *= decay;
            }
            *m = beta1 * *m + (1.0 - beta1) * g;
            *v = beta2 * *v + (1.0 - beta2) * g * g;
            let m_hat = *m / bias1;
            let v_hat = *v / bias2;
            *p -= lr * m_hat / (v_hat.sqrt() + eps);
        }
    }

    /// Scales the first moment (momentum) by `factor`, as an optimiser does
    /// after undoing a step that led somewhere the loss is not finite
    /// (`fit::minimize`'s Adam halves it).
    pub fn damp_first_moment(&mut self, factor: f64) {
        for m in &mut self.first {
            *m *= factor;
        }
    }

    /// A copy of the step count and moment buffers, for a checkpoint.
    pub fn state(&self) -> OptimState {
        OptimState { step: self.step, first_moment: self.first.clone(), second_moment: self.second.clone() }
    }

    /// Continues from a state saved by [`Optimizer::state`]: the following
    /// steps are bit for bit those of the optimiser it was saved from.
    ///
    /// Errors ([`Error::Bind`]), leaving this optimiser unchanged, when a
    /// buffer's length does not fit this optimiser's method and size, or a
    /// value is not finite, or a second moment is negative.
    pub fn restore(&mut self, s: OptimState) -> Result<(), Error> {
        let want = |has: bool| if has { self.n } else { 0 };
        for (what, buf, len) in [
            ("first-moment", &s.first_moment, want(self.config.method.has_first_moment())),
            ("second-moment", &s.second_moment, want(self.config.method.has_second_moment())),
        ] {
            if buf.len() != len {
                return Err(bad(format!(
                    "optimiser state: the {what} buffer has {} values but this optimiser ({:?}, {} values) needs {len}",
                    buf.len(),
                    self.config.method,
                    self.n
                )));
            }
            if let Some(i) = buf.iter().position(|x| !x.is_finite()) {
                return Err(bad(format!("optimiser state: {what} value {i} is {} (not finite)", buf[i])));
            }
        }
        if let Some(i) = s.second_moment.iter().position(|x| *x < 0.0) {
            return Err(bad(format!("optimiser state: second-moment value {i} is negative ({})", s.second_moment[i])));
        }
        self.step = s.step;
        self.first = s.first_moment;
        self.second = s.second_moment;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(method: Method, lr: f64) -> OptimConfig {
        OptimConfig { method, lr, schedule: Schedule::Constant, clip_norm: None }
    }

    /// Gradient of `½ Σ aᵢ (xᵢ − cᵢ)²`, an ill-conditioned quadratic with minimum at `c`.
    fn quad_grad(x: &[f64]) -> Vec<f64> {
        const A: [f64; 3] = [1.0, 10.0, 0.1];
        const C: [f64; 3] = [1.0, -2.0, 3.0];
        x.iter().zip(A).zip(C).map(|((x, a), c)| a * (x - c)).collect()
    }

    fn minimise(method: Method, lr: f64, steps: usize) -> Vec<f64> {
        let mut opt = Optimizer::new(config(method, lr), 3).unwrap();
        let mut x = vec![0.0; 3];
        for _ in 0..steps {
            let g = quad_grad(&x);
            opt.step(&mut x, &g).unwrap();
        }
        assert_eq!(opt.steps_taken(), steps as u64);
        x
    }

    fn assert_near(x: &[f64], want: &[f64], tol: f64) {
        for (i, (a, b)) in x.iter().zip(want).enumerate() {
            assert!((a - b).abs() <= tol, "component {i}: {a} vs {b} (x = {x:?})");
        }
    }

    #[test]
    fn sgd_converges_on_a_quadratic() {
        assert_near(&minimise(Method::sgd(0.0), 0.15, 2000), &[1.0, -2.0, 3.0], 1e-6);
    }

    #[test]
    fn sgd_momentum_converges_on_a_quadratic() {
        assert_near(&minimise(Method::sgd(0.9), 0.02, 2000), &[1.0, -2.0, 3.0], 1e-6);
    }

    #[test]
    fn adam_converges_on_a_quadratic() {
        assert_near(&minimise(Method::adam(), 0.05, 5000), &[1.0, -2.0, 3.0], 1e-4);
    }

    #[test]
    fn adamw_converges_near_the_shrunk_minimum() {
        // With decoupled decay λ the fixed point has aᵢ(xᵢ − cᵢ)/(√v̂ + ε) = −λ xᵢ,
        // close to cᵢ for a small λ.
        assert_near(&minimise(Method::adamw(1e-4), 0.05, 5000), &[1.0, -2.0, 3.0], 1e-2);
    }

    #[test]
    fn adam_first_step_moves_by_lr_times_sign() {
        let mut opt = Optimizer::new(config(Method::adam(), 0.01), 4).unwrap();
        let mut x = vec![1.0, 1.0, 1.0, 1.0];
        let info = opt.step(&mut x, &[3.0, -0.5, 1e-3, -200.0]).unwrap();
        assert_eq!(info.lr, 0.01);
        assert!(!info.clipped);
        // Bias correction makes m̂ = g and v̂ = g², so the step is lr·g/(|g| + ε).
        assert_near(&x, &[0.99, 1.01, 0.99, 1.01], 1e-7);
    }

    #[test]
    fn adamw_with_zero_gradient_shrinks_by_one_minus_lr_wd() {
        let (lr, wd) = (0.1, 0.01);
        let mut opt = Optimizer::new(config(Method::adamw(wd), lr), 2).unwrap();
        let mut x = vec![2.0, -4.0];
        opt.step(&mut x, &[0.0, 0.0]).unwrap();
        assert_eq!(x, vec![2.0 * (1.0 - lr * wd), -4.0 * (1.0 - lr * wd)]);
        opt.step(&mut x, &[0.0, 0.0]).unwrap();
        assert_near(&x, &[2.0 * 0.999 * 0.999, -4.0 * 0.999 * 0.999], 1e-14);
    }

    #[test]
    fn sgd_momentum_matches_a_hand_computed_sequence() {
        let mut opt = Optimizer::new(config(Method::sgd(0.9), 0.1), 1).unwrap();
        let mut x = vec![1.0];
        // v₁ = 1, p₁ = 1 − 0.1 = 0.9
        opt.step(&mut x, &[1.0]).unwrap();
        assert_near(&x, &[0.9], 1e-15);
        // v₂ = 0.9·1 + 2 = 2.9, p₂ = 0.9 − 0.29 = 0.61
        opt.step(&mut x, &[2.0]).unwrap();
        assert_near(&x, &[0.61], 1e-15);
        // v₃ = 0.9·2.9 − 1 = 1.61, p₃ = 0.61 − 0.161 = 0.449
        opt.step(&mut x, &[-1.0]).unwrap();
        assert_near(&x, &[0.449], 1e-15);
        assert_near(&opt.state().first_moment, &[1.61], 1e-15);
    }

    #[test]
    fn clipping_caps_the_global_norm() {
        let cfg = OptimConfig { clip_norm: Some(1.0), ..config(Method::sgd(0.0), 1.0) };
        let mut opt = Optimizer::new(cfg, 2).unwrap();
        let mut x = vec![0.0, 0.0];
        let info = opt.step(&mut x, &[3.0, 4.0]).unwrap();
        assert_eq!(info.grad_norm, 5.0);
        assert!(info.clipped);
        assert_near(&x, &[-0.6, -0.8], 1e-15);
        // Below the cap nothing changes.
        let info = opt.step(&mut x, &[0.3, 0.4]).unwrap();
        assert!(!info.clipped);
        assert_near(&x, &[-0.9, -1.2], 1e-15);
        // Huge finite components do not overflow the norm.
        let info = opt.step(&mut x, &[1e300, 1e300]).unwrap();
        assert!(info.clipped);
        assert!((info.grad_norm / (1e300 * 2f64.sqrt()) - 1.0).abs() < 1e-15);
        assert_near(&x, &[-0.9 - 0.5f64.sqrt(), -1.2 - 0.5f64.sqrt()], 1e-12);
    }

    #[test]
    fn schedules_at_a_few_steps() {
        assert_eq!(Schedule::Constant.lr_at(0.3, 12345), 0.3);
        let step = Schedule::Step { every: 10, gamma: 0.5 };
        let at = |s| step.lr_at(1.0, s);
        assert_eq!((at(0), at(9), at(10), at(19), at(25)), (1.0, 1.0, 0.5, 0.5, 0.25));
        let cos = Schedule::Cosine { total: 100, min_lr: 0.1 };
        let at = |s| cos.lr_at(1.0, s);
        assert_eq!(at(0), 1.0);
        assert!((at(50) - 0.55).abs() < 1e-15);
        assert!((at(25) - (0.1 + 0.9 * (1.0 + std::f64::consts::FRAC_1_SQRT_2) / 2.0)).abs() < 1e-15);
        assert!((at(100) - 0.1).abs() < 1e-15);
        assert_eq!(at(100), at(1000));
        // The optimiser reports the scheduled rate.
        let cfg = OptimConfig { schedule: step, ..config(Method::sgd(0.0), 1.0) };
        let mut opt = Optimizer::new(cfg, 1).unwrap();
        let mut x = vec![0.0];
        let lrs: Vec<f64> = (0..21).map(|_| opt.step(&mut x, &[0.0]).unwrap().lr).collect();
        assert_eq!((lrs[9], lrs[10], lrs[20]), (1.0, 0.5, 0.25));
    }

    #[test]
    fn resuming_from_state_is_bit_for_bit() {
        let schedule = Schedule::Cosine { total: 20, min_lr: 0.001 };
        for method in [Method::sgd(0.0), Method::sgd(0.8), Method::adam(), Method::adamw(0.05)] {
            let cfg = OptimConfig { method, lr: 0.05, schedule, clip_norm: Some(2.0) };
            let mut whole = Optimizer::new(cfg, 3).unwrap();
            let mut x = vec![0.3, -0.7, 5.0];
            for _ in 0..7 {
                let g = quad_grad(&x);
                whole.step(&mut x, &g).unwrap();
            }
            let saved = whole.state();
            let mut y = x.clone();
            let mut resumed = Optimizer::new(cfg, 3).unwrap();
            resumed.restore(saved).unwrap();
            assert_eq!(resumed.steps_taken(), 7);
            for _ in 0..10 {
                let g = quad_grad(&x);
                let a = whole.step(&mut x, &g).unwrap();
                let g = quad_grad(&y);
                let b = resumed.step(&mut y, &g).unwrap();
                assert_eq!(a, b);
            }
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&x), bits(&y), "{method:?}");
            assert_eq!(whole.state(), resumed.state());
        }
    }

    #[test]
    fn restore_rejects_state_of_the_wrong_shape() {
        let mut opt = Optimizer::new(config(Method::adam(), 0.1), 2).unwrap();
        let before = opt.state();
        let wrong = OptimState { step: 3, first_moment: vec![0.0; 2], second_moment: vec![] };
        assert!(matches!(opt.restore(wrong), Err(Error::Bind(_))));
        let negative = OptimState { step: 3, first_moment: vec![0.0; 2], second_moment: vec![1.0, -1.0] };
        assert!(opt.restore(negative).is_err());
        assert_eq!(opt.state(), before);
        let mut sgd = Optimizer::new(config(Method::sgd(0.0), 0.1), 2).unwrap();
        assert!(sgd.restore(OptimState { step: 1, first_moment: vec![0.0; 2], second_moment: vec![] }).is_err());
        sgd.restore(OptimState { step: 1, first_moment: vec![], second_moment: vec![] }).unwrap();
    }

    #[test]
    fn nan_gradient_is_an_error_naming_the_index() {
        let mut opt = Optimizer::new(config(Method::adam(), 0.1), 3).unwrap();
        let mut x = vec![1.0, 2.0, 3.0];
        let err = opt.step(&mut x, &[0.5, f64::NAN, f64::INFINITY]).unwrap_err();
        assert!(matches!(&err, Error::Bind(m) if m.contains("component 1")), "{err}");
        assert_eq!(x, vec![1.0, 2.0, 3.0]);
        assert_eq!(opt.steps_taken(), 0);
        assert_eq!(opt.state().first_moment, vec![0.0; 3]);
    }

    #[test]
    fn length_mismatch_is_an_error() {
        let mut opt = Optimizer::new(config(Method::sgd(0.5), 0.1), 3).unwrap();
        let mut x = vec![1.0, 2.0, 3.0];
        assert!(matches!(opt.step(&mut x, &[1.0, 1.0]), Err(Error::Bind(_))));
        assert!(opt.step(&mut x[..2], &[1.0, 1.0]).is_err());
        assert_eq!(x, vec![1.0, 2.0, 3.0]);
        assert_eq!(opt.steps_taken(), 0);
    }

    #[test]
    fn bad_configs_are_rejected() {
        let bad = [
            config(Method::adam(), f64::NAN),
            config(Method::adam(), -0.1),
            config(Method::adam(), f64::INFINITY),
            config(Method::Adam { beta1: 1.0, beta2: 0.999, eps: 1e-8 }, 0.1),
            config(Method::Adam { beta1: 0.9, beta2: -0.1, eps: 1e-8 }, 0.1),
            config(Method::Adam { beta1: 0.9, beta2: 0.999, eps: 0.0 }, 0.1),
            config(Method::adamw(-1.0), 0.1),
            config(Method::sgd(1.0), 0.1),
            OptimConfig { clip_norm: Some(0.0), ..config(Method::adam(), 0.1) },
            OptimConfig { clip_norm: Some(f64::NAN), ..config(Method::adam(), 0.1) },
            OptimConfig { schedule: Schedule::Step { every: 0, gamma: 0.5 }, ..config(Method::adam(), 0.1) },
            OptimConfig { schedule: Schedule::Cosine { total: 0, min_lr: 0.0 }, ..config(Method::adam(), 0.1) },
            OptimConfig { schedule: Schedule::Cosine { total: 10, min_lr: 0.2 }, ..config(Method::adam(), 0.1) },
        ];
        for cfg in bad {
            assert!(matches!(Optimizer::new(cfg, 1), Err(Error::Bind(_))), "{cfg:?}");
        }
        assert!(Optimizer::new(config(Method::sgd(0.0), 0.0), 0).unwrap().is_empty());
    }
}
