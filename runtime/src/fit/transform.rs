//! Bounds as transforms: each param mapped to an unconstrained variable.

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
