//! The meaning of each elementwise operation on one element, in f64.
//!
//! This is the single definition of IR semantics used by the constant
//! folder and the reference interpreter; the Cranelift backend must agree
//! with it (the differential tests check that). Real and bool values are
//! carried as complex numbers with zero imaginary part; bools are 0 or 1.

use crate::ir::{BinOp, Elem, UnOp};
use num_complex::Complex64 as C64;

fn real(x: f64) -> C64 {
    C64::new(x, 0.0)
}

fn truth(b: bool) -> C64 {
    real(if b { 1.0 } else { 0.0 })
}

/// Sign of a real: -1, 0 or 1 (NaN stays NaN).
pub fn sign(x: f64) -> f64 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        x * 0.0
    }
}

/// Applies unary `op` to `x`, whose element kind is `elem`.
pub fn unary(op: UnOp, x: C64, elem: Elem) -> C64 {
    let complex = elem == Elem::Complex;
    let r = x.re;
    match op {
        UnOp::Neg => -x,
        UnOp::Sqrt => real(r.sqrt()),
        UnOp::Cbrt => real(r.cbrt()),
        UnOp::Exp if complex => x.exp(),
        UnOp::Exp => real(r.exp()),
        UnOp::Log => real(r.ln()),
        UnOp::Sin => real(r.sin()),
        UnOp::Cos => real(r.cos()),
        UnOp::Tan => real(r.tan()),
        UnOp::Tanh => real(r.tanh()),
        UnOp::Abs if complex => real(x.re.hypot(x.im)),
        UnOp::Abs => real(r.abs()),
        UnOp::Sign => real(sign(r)),
        UnOp::Re => real(x.re),
        UnOp::Im => real(x.im),
        UnOp::Conj => x.conj(),
        UnOp::Abs2 => real(x.re * x.re + x.im * x.im),
        UnOp::Cis => C64::new(r.cos(), r.sin()),
        UnOp::ToComplex => real(r),
    }
}

/// Applies binary `op` to `a` and `b`, whose element kind is `elem`.
pub fn binary(op: BinOp, a: C64, b: C64, elem: Elem) -> C64 {
    let complex = elem == Elem::Complex;
    match op {
        BinOp::Add => a + b,
        BinOp::Sub => a - b,
        BinOp::Mul if complex => a * b,
        BinOp::Mul => real(a.re * b.re),
        BinOp::Div if complex => complex_div(a, b),
        BinOp::Div => real(a.re / b.re),
        BinOp::Pow => real(a.re.powf(b.re)),
        BinOp::Atan2 => real(a.re.atan2(b.re)),
        BinOp::Min => real(a.re.min(b.re)),
        BinOp::Max => real(a.re.max(b.re)),
        BinOp::Lt => truth(a.re < b.re),
        BinOp::Le => truth(a.re <= b.re),
        BinOp::Gt => truth(a.re > b.re),
        BinOp::Ge => truth(a.re >= b.re),
        BinOp::Eq => truth(a == b),
        BinOp::Ne => truth(a != b),
        BinOp::Complex => C64::new(a.re, b.re),
    }
}

/// Complex division `a / b` computed as `a * conj(b) / |b|^2`, the formula
/// the code generator also uses.
pub fn complex_div(a: C64, b: C64) -> C64 {
    let d = b.re * b.re + b.im * b.im;
    C64::new((a.re * b.re + a.im * b.im) / d, (a.im * b.re - a.re * b.im) / d)
}

/// `x^c` for a constant exponent.
pub fn pow_const(x: f64, c: f64) -> f64 {
    if c == c.trunc() && c.abs() <= 16.0 {
        x.powi(c as i32)
    } else {
        x.powf(c)
    }
}
