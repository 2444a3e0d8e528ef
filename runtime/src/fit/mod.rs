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
//! - [`minimize`] runs [`Algorithm::Lbfgs`] (limited-memory BFGS, two-loop
//!   recursion, with a backtracking line search under the Armijo
//!   sufficient-decrease condition) or [`Algorithm::Adam`] (Kingma & Ba
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
//! - [`newton_polish`] takes Newton steps on that Hessian from where a
//!   quasi-Newton run stopped short (an ill-conditioned fit), re-taking
//!   the Hessian after each.
//! - [`laplace_evidence`] turns a fit into a log evidence under uniform
//!   priors on the bounds (model comparison), [`bic`] the Bayesian
//!   information criterion.
//! - [`fit_run`] ties them to a [`Run`]: the free params are those the
//!   scene names in `grad OUTPUT wrt [...]`, started from their current
//!   values (defaults or what was set).

mod evidence;
mod fisher;
mod minimize;
mod newton;
mod scene;
mod transform;

pub use evidence::*;
pub use fisher::*;
pub use minimize::*;
pub use newton::*;
pub use scene::*;
pub use transform::*;

#[cfg(test)]
mod tests;
