//! Power-of-two rescaling for `precision: f32` and `mixed`.
//!
//! Gravitational-wave strains are ~1e-23 and PSDs ~1e-46: in f32 (normal
//! range 1.2e-38 … 3.4e38) `|d - h|²` and the PSD itself flush to zero, so
//! a likelihood that f64 computes well is lost. This pass stores every
//! value `x` as `x_s = x · 2^-e` with an exponent `e` fixed at compile time,
//! chosen from the value's largest magnitude at the scene's defaults
//! ([`super::precision::default_magnitudes`]) so that stored values stay near 1.
//! Multiplying by a power of two is exact (barring overflow), so the f32
//! rounding of every value is the same as without rescaling.
//!
//! The rule, per instruction, with operands already rescaled:
//! - `a · b` has exponent `e_a + e_b`, `a / b` has `e_a − e_b`, `|z|²` has
//!   `2 e`; negation, conjugation, parts, `abs`, broadcasts, sums, maxima and
//!   DFTs keep their operand's exponent;
//! - `+`, `−`, `min`, `max`, comparisons, selects, `atan2` and complex
//!   construction bring both operands to one exponent: a constant takes the
//!   other operand's, otherwise the larger value's wins;
//! - `x^c` (and `sqrt`, `cbrt`) needs `c · e` to be an integer: for
//!   `c = p/q` the operand is brought to an exponent that is a multiple of
//!   `q`; other powers, and `exp`, `sin`, `cos`, `tan`, `tanh`, `cis`,
//!   `pow` and tensor ops, take operands at their true scale (exponent 0);
//! - `log x = log x_s + e ln 2`;
//! - after each instruction, if its stored magnitude at the defaults left
//!   [2^-40, 2^40], it is multiplied back to near 1; tables are stored
//!   prescaled; outputs are returned as stored with their exponent
//!   ([`Output::exponent`]), gradients at their true scale.
//!
//! A value that is out of f32's range at its true scale where it must be
//! used at that scale (the operand of `exp`, say) still is: in f32,
//! codegen's range check refuses such scenes and points to `precision:
//! mixed`, which computes them in f64.

use crate::ir::builder::Builder;
use crate::ir::*;
use num_complex::Complex64 as C64;

/// Stored magnitudes outside `[2^-LIMIT, 2^LIMIT]` are brought back near 1;
/// a product or quotient of two values inside stays far inside f32's range.
const LIMIT: i32 = 40;

/// `func` with every value stored as `x · 2^-e` (see the module doc) when
/// it stores values in f32 (precisions f32 and mixed; in mixed, this leaves
/// phases the only values computed in f64, see [`super::precision::wide_values`]);
/// unchanged in f64, and when the defaults are too expensive to evaluate.
pub fn rescale(func: &Function) -> Function {
    if func.precision.storage() != Precision::F32 {
        return func.clone();
    }
    let Some(magnitudes) = super::precision::default_magnitudes(func) else {
        return func.clone();
    };
    let mut header = func.clone();
    header.insts.clear();
    let table_exps: Vec<i32> =
        header.tables.iter().map(|t| out_of_band_exponent(t.data.iter().fold(0.0, |m: f64, x| m.max(x.abs())))).collect();
    for (t, &e) in header.tables.iter_mut().zip(&table_exps) {
        t.data.iter_mut().for_each(|x| *x = times_pow2(*x, -e));
    }
    let mut r = Rescaler { b: Builder::new(header, true), magnitudes: &magnitudes, map: Vec::new(), exps: Vec::new() };
    for (i, inst) in func.insts.iter().enumerate() {
        let (v, e) = r.rewrite(inst, &table_exps);
        let (v, e) = if inst.ty.elem == Elem::Bool { (v, 0) } else { r.keep_in_band(v, e, magnitudes[i]) };
        r.map.push(v);
        r.exps.push(e);
    }
    // Outputs are returned as stored, with their exponent (an output such
    // as a PSD of 1e-46 is itself outside f32's range); gradients at their
    // true scale.
    let exponents: Vec<i32> = func.outputs.iter().map(|o| r.exps[o.value.index()]).collect();
    let gradients: std::collections::HashMap<Value, Value> = func
        .roots()
        .into_iter()
        .skip(func.outputs.len())
        .map(|v| {
            let (nv, e) = (r.map[v.index()], r.exps[v.index()]);
            (v, r.with_exponent(nv, e, 0))
        })
        .collect();
    let map = r.map;
    let mut out = r.b.func;
    for (o, e) in out.outputs.iter_mut().zip(exponents) {
        o.value = map[o.value.index()];
        o.exponent += e;
    }
    for g in &mut out.grads {
        g.value = g.value.map(|v| gradients[&v]);
    }
    for g in &mut out.input_grads {
        g.value = g.value.map(|v| gradients[&v]);
    }
    super::prune(&out)
}

/// The exponent that brings magnitude `m` near 1 when it is outside
/// `[2^-LIMIT, 2^LIMIT]`, else 0.
fn out_of_band_exponent(m: f64) -> i32 {
    if m > 0.0 && m.is_finite() && !(2f64.powi(-LIMIT)..=2f64.powi(LIMIT)).contains(&m) {
        ideal_exponent(m)
    } else {
        0
    }
}

/// Factors whose product is `2^k`, each a finite f64 (`2^k` itself
/// overflows or flushes to 0 for |k| > 1023).
fn pow2_factors(k: i32) -> impl Iterator<Item = f64> {
    let steps = k.unsigned_abs().div_ceil(1000) as i32;
    (0..steps).map(move |i| 2f64.powi((k - i * k / steps) - (k - (i + 1) * k / steps)))
}

/// `x · 2^k`: 0 stays 0; a result beyond f64's range is ±inf, not NaN.
fn times_pow2(x: f64, k: i32) -> f64 {
    pow2_factors(k).fold(x, |x, f| x * f)
}

/// `floor(log2 m)`: the exponent that stores `m` in [1, 2).
fn ideal_exponent(m: f64) -> i32 {
    m.log2().floor() as i32
}

/// The smallest `q ≤ 12` with `c · q` an integer, if any.
fn denominator(c: f64) -> Option<i32> {
    (1..=12).find(|&q| {
        let p = c * q as f64;
        (p - p.round()).abs() <= 1e-9 * p.abs().max(1.0)
    })
}

struct Rescaler<'a> {
    b: Builder,
    magnitudes: &'a [f64],
    /// Per original value: its rescaled counterpart and exponent.
    map: Vec<Value>,
    exps: Vec<i32>,
}

impl Rescaler<'_> {
    /// `v` (stored with exponent `from`) restored with exponent `to`.
    fn with_exponent(&mut self, v: Value, from: i32, to: i32) -> Value {
        if from == to {
            return v;
        }
        if let Some(c) = self.b.const_of(v) {
            // Folded, also for broadcasts (the builder folds scalars only).
            let ty = self.b.ty(v);
            let k = from - to;
            return self.b.constant(C64::new(times_pow2(c.re, k), times_pow2(c.im, k)), ty);
        }
        pow2_factors(from - to).fold(v, |v, f| self.b.scale(v, f))
    }

    /// `v` with exponent `e` and true magnitude `m`, brought near 1 when
    /// its stored magnitude left the band.
    fn keep_in_band(&mut self, v: Value, e: i32, m: f64) -> (Value, i32) {
        if m > 0.0 && m.is_finite() {
            let ideal = ideal_exponent(m);
            if (ideal - e).abs() > LIMIT {
                return (self.with_exponent(v, e, ideal), ideal);
            }
        }
        (v, e)
    }

    /// Operand `a` (an original value) at its true scale.
    fn at_true_scale(&mut self, a: Value) -> Value {
        let (v, e) = (self.map[a.index()], self.exps[a.index()]);
        self.with_exponent(v, e, 0)
    }

    /// Operands `x` and `y` at one exponent, and that exponent.
    fn common(&mut self, x: Value, y: Value) -> (Value, Value, i32) {
        let (nx, ex, ny, ey) = (self.map[x.index()], self.exps[x.index()], self.map[y.index()], self.exps[y.index()]);
        let (mx, my) = (self.magnitudes[x.index()], self.magnitudes[y.index()]);
        let target = match (self.b.const_of(nx).is_some(), self.b.const_of(ny).is_some()) {
            (true, true) => out_of_band_exponent(mx.max(my)),
            (true, false) => ey,
            (false, true) => ex,
            (false, false) if mx > my => ex,
            (false, false) if my > mx => ey,
            (false, false) => ex.max(ey),
        };
        (self.with_exponent(nx, ex, target), self.with_exponent(ny, ey, target), target)
    }

    /// `op` applied to operand `a` raised to the constant power `c`
    /// (`PowConst`, `sqrt` or `cbrt`), with the result's exponent.
    fn power(&mut self, a: Value, c: f64, emit: impl FnOnce(&mut Builder, Value) -> Value) -> (Value, i32) {
        let (v, e) = (self.map[a.index()], self.exps[a.index()]);
        let Some(q) = denominator(c).filter(|_| c.abs() <= 64.0) else {
            let v = self.with_exponent(v, e, 0);
            return (emit(&mut self.b, v), 0);
        };
        let m = self.magnitudes[a.index()];
        // Near 1 before a large power (so it cannot overflow), else as close
        // to the current exponent as divisibility by q allows.
        let wanted = if m > 0.0 && m.is_finite() && (c.abs() > 2.0 || q > 1) { ideal_exponent(m) } else { e };
        let target = wanted.div_euclid(q) * q;
        let v = self.with_exponent(v, e, target);
        (emit(&mut self.b, v), (c * target as f64).round() as i32)
    }

    /// The rescaled form of original instruction `inst` and its exponent.
    fn rewrite(&mut self, inst: &Inst, table_exps: &[i32]) -> (Value, i32) {
        let map = |r: &Self, v: Value| r.map[v.index()];
        let exp = |r: &Self, v: Value| r.exps[v.index()];
        match inst.op {
            Op::Table(t) => (self.b.emit(inst.op), table_exps[t as usize]),
            Op::Const(_) | Op::ConstComplex(..) | Op::Param(_) | Op::Input(_) | Op::GridCoord(_) => (self.b.emit(inst.op), 0),
            Op::Unary(u, a) => match u {
                UnOp::Neg | UnOp::Conj | UnOp::Re | UnOp::Im | UnOp::ToComplex | UnOp::Abs => (self.b.unary(u, map(self, a)), exp(self, a)),
                UnOp::Abs2 => (self.b.unary(u, map(self, a)), 2 * exp(self, a)),
                UnOp::Sign => (self.b.unary(u, map(self, a)), 0),
                UnOp::Log => {
                    let l = self.b.unary(UnOp::Log, map(self, a));
                    let e = exp(self, a);
                    if e == 0 {
                        (l, 0)
                    } else {
                        let shift = self.b.constant(C64::new(e as f64 * std::f64::consts::LN_2, 0.0), inst.ty);
                        (self.b.add(l, shift), 0)
                    }
                }
                UnOp::Sqrt => self.power(a, 0.5, |b, v| b.unary(UnOp::Sqrt, v)),
                UnOp::Cbrt => self.power(a, 1.0 / 3.0, |b, v| b.unary(UnOp::Cbrt, v)),
                UnOp::Exp | UnOp::Sin | UnOp::Cos | UnOp::Tan | UnOp::Tanh | UnOp::Cis => {
                    let v = self.at_true_scale(a);
                    (self.b.unary(u, v), 0)
                }
            },
            Op::PowConst(a, c) => self.power(a, f64::from_bits(c), |b, v| b.emit(Op::PowConst(v, c))),
            Op::Binary(op, x, y) => match op {
                BinOp::Mul => (self.b.mul(map(self, x), map(self, y)), exp(self, x) + exp(self, y)),
                BinOp::Div => (self.b.div(map(self, x), map(self, y)), exp(self, x) - exp(self, y)),
                BinOp::Pow => {
                    let (vx, vy) = (self.at_true_scale(x), self.at_true_scale(y));
                    (self.b.binary(op, vx, vy), 0)
                }
                BinOp::Add | BinOp::Sub | BinOp::Min | BinOp::Max | BinOp::Complex => {
                    let (vx, vy, e) = self.common(x, y);
                    (self.b.binary(op, vx, vy), e)
                }
                BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne | BinOp::Atan2 => {
                    let (vx, vy, _) = self.common(x, y);
                    (self.b.binary(op, vx, vy), 0)
                }
            },
            Op::Select(c, x, y) => {
                let (vx, vy, e) = self.common(x, y);
                (self.b.emit(Op::Select(map(self, c), vx, vy)), e)
            }
            Op::Band(BandOp::Cis, n, a) => {
                let v = self.at_true_scale(a);
                (self.b.emit(Op::Band(BandOp::Cis, n, v)), 0)
            }
            Op::Broadcast(a, _) | Op::Reduce(_, a) | Op::Dft(_, a) | Op::Band(_, _, a) => {
                (self.b.emit(inst.op.map_operands(|v| map(self, v))), exp(self, a))
            }
            Op::Tensor(..) => {
                let scaled: Vec<(Value, Value)> = inst.op.operands().into_iter().map(|v| (v, self.at_true_scale(v))).collect();
                let op = inst.op.map_operands(|v| scaled.iter().find(|(o, _)| *o == v).expect("an operand").1);
                (self.b.emit(op), 0)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn powers_of_two_beyond_f64s_exponent_range_stay_finite_in_steps() {
        for k in [0, 1, -1, 999, 1000, 1001, -1074, 1500, -2100, 2046] {
            let product: f64 = pow2_factors(k).map(f64::log2).sum();
            assert_eq!(product, k as f64, "2^{k}");
            assert!(pow2_factors(k).all(|f| f.is_finite() && f > 0.0), "2^{k}");
        }
        assert_eq!(times_pow2(f64::MAX / 2.0, -1023) * 2f64.powi(1023), f64::MAX / 2.0);
        assert_eq!(times_pow2(0.0, 2000), 0.0);
        assert_eq!(times_pow2(3.0, 2000), f64::INFINITY);
        assert_eq!(times_pow2(1.5, -1074 - 1), 2f64.powi(-1074));
    }

    #[test]
    fn fractional_powers_find_their_small_denominator() {
        assert_eq!(denominator(-7.0 / 6.0), Some(6));
        assert_eq!(denominator(1.5), Some(2));
        assert_eq!(denominator(3.0), Some(1));
        assert_eq!(denominator(std::f64::consts::PI), None);
    }
}
