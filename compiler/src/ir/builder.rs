//! Building IR: type inference for each op, hash-consing (CSE) and, when
//! enabled, constant folding and algebraic simplification at construction.
//!
//! The checker builds without folding so `--stats` can show what each pass
//! removes; the adjoint and simplify passes build with folding on.

use super::eval;
use crate::ir::*;
use num_complex::Complex64 as C64;
use std::collections::HashMap;

/// Appends instructions to a [`Function`].
pub struct Builder {
    /// The function being built.
    pub func: Function,
    fold: bool,
    memo: HashMap<Inst, Value>,
}

impl Builder {
    /// Builds into `func` (which may already hold instructions).
    /// `fold` turns on CSE, constant folding and algebraic rules.
    pub fn new(func: Function, fold: bool) -> Self {
        let mut memo = HashMap::new();
        if fold {
            for (i, inst) in func.insts.iter().enumerate() {
                memo.entry(*inst).or_insert(Value(i as u32));
            }
        }
        Builder { func, fold, memo }
    }

    /// Type of `v`.
    pub fn ty(&self, v: Value) -> Ty {
        self.func.ty(v)
    }

    /// The result type of `op`.
    pub fn infer(&self, op: &Op) -> Ty {
        let t = |v: Value| self.func.ty(v);
        match *op {
            Op::Const(_) => Ty::REAL,
            Op::ConstComplex(..) => Ty::COMPLEX,
            Op::Param(_) => Ty::REAL,
            Op::Input(i) => self.func.inputs[i as usize].ty,
            Op::GridCoord(g) => Ty { elem: Elem::Real, shape: Shape::Grid(g) },
            Op::Table(t) => Ty { elem: Elem::Real, shape: Shape::Grid(self.func.tables[t as usize].grid) },
            Op::Unary(u, a) => match u {
                UnOp::Abs | UnOp::Re | UnOp::Im | UnOp::Abs2 | UnOp::Sign => t(a).with_elem(Elem::Real),
                UnOp::Cis | UnOp::ToComplex => t(a).with_elem(Elem::Complex),
                _ => t(a),
            },
            Op::Binary(b, x, _) => match b {
                BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne => t(x).with_elem(Elem::Bool),
                BinOp::Complex => t(x).with_elem(Elem::Complex),
                _ => t(x),
            },
            Op::PowConst(a, _) => t(a),
            Op::Select(_, a, _) => t(a),
            Op::Broadcast(a, g) => Ty { elem: t(a).elem, shape: Shape::Grid(g) },
            Op::Reduce(_, a) => Ty { elem: t(a).elem, shape: Shape::Scalar },
            Op::Dft(d, _) => Ty { elem: if d.inverse { Elem::Real } else { Elem::Complex }, shape: Shape::Grid(d.out) },
            Op::Tensor(_, g, ..) => Ty { elem: Elem::Real, shape: Shape::Grid(g) },
            Op::Band(o, n, _) => {
                let band = &self.func.bands[n as usize];
                let elem = if o == BandOp::Cis { Elem::Complex } else { Elem::Real };
                Ty { elem, shape: Shape::Grid(band.grid_on(o.sides().1)) }
            }
        }
    }

    /// Appends `op` as is (CSE only when folding is on).
    pub fn push(&mut self, op: Op) -> Value {
        let inst = Inst { op, ty: self.infer(&op) };
        if self.fold {
            if let Some(v) = self.memo.get(&inst) {
                return *v;
            }
        }
        let v = Value(self.func.insts.len() as u32);
        self.func.insts.push(inst);
        if self.fold {
            self.memo.insert(inst, v);
        }
        v
    }

    /// The value of `v` when it is computed from constants alone by
    /// elementwise arithmetic (whether or not this builder folds), e.g. a
    /// module argument `k + 1` with `k` bound to 0.
    pub fn evaluate_constant(&self, v: Value) -> Option<C64> {
        let elem = self.ty(v).elem;
        match self.func.insts[v.index()].op {
            Op::Unary(op, a) => Some(super::eval::unary(op, self.evaluate_constant(a)?, elem)),
            Op::Binary(op, a, b) => Some(super::eval::binary(op, self.evaluate_constant(a)?, self.evaluate_constant(b)?, elem)),
            Op::PowConst(a, c) => {
                let x = self.evaluate_constant(a)?;
                (x.im == 0.0).then(|| C64::new(super::eval::pow_const(x.re, f64::from_bits(c)), 0.0))
            }
            Op::Broadcast(a, _) => self.evaluate_constant(a),
            _ => self.const_of(v),
        }
    }

    /// The scalar constant behind `v`, looking through broadcasts.
    pub fn const_of(&self, v: Value) -> Option<C64> {
        self.func.const_of(v)
    }

    /// The truth of a comparison of two constants (looking through
    /// broadcasts), so `if pn_order >= 4 { .. } else { .. }` with constant
    /// knobs keeps only one branch.
    pub fn const_truth(&self, v: Value) -> Option<bool> {
        match self.func.insts[v.index()].op {
            Op::Binary(op, x, y) if self.func.insts[v.index()].ty.elem == Elem::Bool => {
                let (a, b) = (self.const_of(x)?, self.const_of(y)?);
                Some(eval::binary(op, a, b, self.ty(x).elem).re != 0.0)
            }
            Op::Broadcast(c, _) => self.const_truth(c),
            _ => None,
        }
    }

    fn is_const(&self, v: Value, x: f64) -> bool {
        self.const_of(v) == Some(C64::new(x, 0.0))
    }

    /// A constant of type `ty` (broadcast if `ty` is an array).
    pub fn constant(&mut self, x: C64, ty: Ty) -> Value {
        let scalar = match ty.elem {
            Elem::Complex => self.push(Op::ConstComplex(x.re.to_bits(), x.im.to_bits())),
            _ => self.push(Op::Const(x.re.to_bits())),
        };
        match ty.shape {
            Shape::Scalar => scalar,
            Shape::Grid(g) => self.push(Op::Broadcast(scalar, g)),
        }
    }

    /// Zero of type `ty`.
    pub fn zero(&mut self, ty: Ty) -> Value {
        self.constant(C64::new(0.0, 0.0), ty)
    }

    /// A real scalar constant.
    pub fn real(&mut self, x: f64) -> Value {
        self.push(Op::constant(x))
    }

    /// Appends `op`, folding and simplifying when enabled.
    pub fn emit(&mut self, op: Op) -> Value {
        if !self.fold {
            return self.push(op);
        }
        let ty = self.infer(&op);
        // Constant folding of scalar operations.
        if ty.shape == Shape::Scalar && ty.elem != Elem::Bool {
            let ops = op.operands();
            if !ops.is_empty() && !matches!(op, Op::Reduce(..)) {
                let consts: Vec<_> = ops.iter().map(|v| self.const_of(*v)).collect();
                if consts.iter().all(Option::is_some) {
                    let c: Vec<C64> = consts.into_iter().flatten().collect();
                    let elem_in = self.ty(ops[0]).elem;
                    let r = match op {
                        Op::Unary(u, _) => eval::unary(u, c[0], elem_in),
                        Op::Binary(b, ..) => eval::binary(b, c[0], c[1], elem_in),
                        Op::PowConst(_, e) => C64::new(eval::pow_const(c[0].re, f64::from_bits(e)), 0.0),
                        Op::Select(..) => {
                            if c[0].re != 0.0 {
                                c[1]
                            } else {
                                c[2]
                            }
                        }
                        _ => return self.push(op),
                    };
                    return self.constant(r, ty);
                }
            }
        }
        if let Some(v) = self.simplify(&op, ty) {
            return v;
        }
        self.push(op)
    }

    /// Algebraic identities; `None` when none applies.
    fn simplify(&mut self, op: &Op, ty: Ty) -> Option<Value> {
        let zero = |b: &Self, v| b.is_const(v, 0.0);
        let one = |b: &Self, v| b.is_const(v, 1.0);
        match *op {
            Op::Binary(BinOp::Add, a, b) if zero(self, a) => Some(b),
            Op::Binary(BinOp::Add, a, b) if zero(self, b) => Some(a),
            Op::Binary(BinOp::Sub, a, b) if zero(self, b) => Some(a),
            Op::Binary(BinOp::Sub, a, b) if zero(self, a) => Some(self.emit(Op::Unary(UnOp::Neg, b))),
            Op::Binary(BinOp::Mul, a, b) if zero(self, a) || zero(self, b) => Some(self.zero(ty)),
            Op::Binary(BinOp::Mul, a, b) if one(self, a) => Some(b),
            Op::Binary(BinOp::Mul, a, b) if one(self, b) => Some(a),
            Op::Binary(BinOp::Div, a, b) if one(self, b) => Some(a),
            Op::Binary(BinOp::Div, a, _) if zero(self, a) => Some(self.zero(ty)),
            // z·conj(z) = |z|², the real part bit for bit (re² − im·(−im)
            // is re² + im²) and the imaginary part exactly 0 for finite z.
            Op::Binary(BinOp::Mul, a, b) if self.is_conj_of(a, b) || self.is_conj_of(b, a) => {
                let z = if self.is_conj_of(a, b) { b } else { a };
                let r = self.emit(Op::Unary(UnOp::Abs2, z));
                Some(self.emit(Op::Unary(UnOp::ToComplex, r)))
            }
            Op::Unary(UnOp::Neg, a) => match self.func.insts[a.index()].op {
                Op::Unary(UnOp::Neg, x) => Some(x),
                // −(s·y) = (−s)·y for a broadcast scalar s: the negation
                // costs one scalar operation instead of one per bin.
                Op::Binary(BinOp::Mul, x, y) => {
                    let (s, g, other) = match (self.func.insts[x.index()].op, self.func.insts[y.index()].op) {
                        (Op::Broadcast(s, g), _) => (s, g, y),
                        (_, Op::Broadcast(s, g)) => (s, g, x),
                        _ => return None,
                    };
                    let ns = self.emit(Op::Unary(UnOp::Neg, s));
                    let nb = self.emit(Op::Broadcast(ns, g));
                    Some(self.emit(Op::Binary(BinOp::Mul, nb, other)))
                }
                _ => None,
            },
            Op::Unary(UnOp::Re, a) => match self.func.insts[a.index()].op {
                Op::Unary(UnOp::ToComplex, x) => Some(x),
                _ => None,
            },
            Op::Unary(UnOp::Im, a) => match self.func.insts[a.index()].op {
                Op::Unary(UnOp::ToComplex, _) => Some(self.zero(ty)),
                _ => None,
            },
            Op::Unary(UnOp::Conj, a) => match self.func.insts[a.index()].op {
                Op::Unary(UnOp::ToComplex, _) => Some(a),
                Op::Unary(UnOp::Conj, x) => Some(x),
                // conj(a·b) = conj(a)·conj(b), bit for bit, when both
                // conjugates are at hand (a conjugate, or a real as
                // complex): the adjoint of |d − h|² meets its own product.
                Op::Binary(BinOp::Mul, x, y) => {
                    let (cx, cy) = (self.conj_at_hand(x)?, self.conj_at_hand(y)?);
                    Some(self.emit(Op::Binary(BinOp::Mul, cx, cy)))
                }
                _ => None,
            },
            // A reduction of a broadcast scalar: n·s for sums, s for max.
            Op::Reduce(r, a) => match self.func.insts[a.index()].op {
                Op::Broadcast(s, g) => Some(match r {
                    Reduce::Max => s,
                    Reduce::Sum => {
                        let n = self.func.grids.get(g.0 as usize).map_or(0, |g| g.len) as f64;
                        let k = self.constant(C64::new(n, 0.0), self.ty(s).with_elem(Elem::Real));
                        let k = if self.ty(s).elem == Elem::Complex { self.emit(Op::Unary(UnOp::ToComplex, k)) } else { k };
                        self.emit(Op::Binary(BinOp::Mul, s, k))
                    }
                }),
                _ => None,
            },
            // Transforms are linear: the transform of zero is zero.
            Op::Dft(_, a) if zero(self, a) => Some(self.zero(ty)),
            Op::Band(o, _, a) if o != BandOp::Cis && zero(self, a) => Some(self.zero(ty)),
            // Tensor ops are linear in each operand, except that pooling's
            // first operand only chooses positions.
            Op::Tensor(t, _, a, b)
                if {
                    let routing = matches!(t, TensorOp::PoolPick(_) | TensorOp::PoolScatter(_));
                    (!routing && zero(self, a)) || (t.arity() == 2 && zero(self, b))
                } =>
            {
                Some(self.zero(ty))
            }
            Op::PowConst(a, c) if f64::from_bits(c) == 1.0 => Some(a),
            Op::PowConst(_, c) if f64::from_bits(c) == 0.0 => Some(self.constant(C64::new(1.0, 0.0), ty)),
            Op::Select(_, a, b) if a == b => Some(a),
            // A select on the condition already tested takes the same side.
            Op::Select(c, a, b) if matches!(self.func.insts[a.index()].op, Op::Select(k, ..) if k == c) => {
                let Op::Select(_, inner, _) = self.func.insts[a.index()].op else { unreachable!() };
                Some(self.emit(Op::Select(c, inner, b)))
            }
            Op::Select(c, a, b) if matches!(self.func.insts[b.index()].op, Op::Select(k, ..) if k == c) => {
                let Op::Select(_, _, inner) = self.func.insts[b.index()].op else { unreachable!() };
                Some(self.emit(Op::Select(c, a, inner)))
            }
            Op::Select(c, a, b) => self.const_truth(c).map(|k| if k { a } else { b }),
            _ => None,
        }
        .or_else(|| self.move_sign_out(op))
        .or_else(|| self.sink_mask(op))
    }

    /// `v`'s conjugate if it costs nothing: `x` for `conj(x)`, `v` for a
    /// real made complex.
    fn conj_at_hand(&self, v: Value) -> Option<Value> {
        match self.func.insts[v.index()].op {
            Op::Unary(UnOp::Conj, x) => Some(x),
            Op::Unary(UnOp::ToComplex, _) => Some(v),
            _ => None,
        }
    }

    /// `x` for `v = −x`.
    fn negated(&self, v: Value) -> Option<Value> {
        match self.func.insts[v.index()].op {
            Op::Unary(UnOp::Neg, x) => Some(x),
            _ => None,
        }
    }

    /// Moves negations outward, where they cancel, become a subtraction,
    /// or reach a scalar: `−a·b = −(a·b)`, `a + −b = a − b`, `Σ −a = −Σ a`
    /// (the adjoint makes many; a vector negation costs three
    /// instructions per element). Rounding is symmetric, so each rewrite
    /// gives the same bits, up to the sign of a zero.
    fn move_sign_out(&mut self, op: &Op) -> Option<Value> {
        let neg = |b: &mut Self, v: Value| b.emit(Op::Unary(UnOp::Neg, v));
        match *op {
            Op::Binary(o @ (BinOp::Mul | BinOp::Div), a, b) => match (self.negated(a), self.negated(b)) {
                (Some(x), Some(y)) => Some(self.emit(Op::Binary(o, x, y))),
                (Some(x), None) => {
                    let v = self.emit(Op::Binary(o, x, b));
                    Some(neg(self, v))
                }
                (None, Some(y)) => {
                    let v = self.emit(Op::Binary(o, a, y));
                    Some(neg(self, v))
                }
                (None, None) => None,
            },
            Op::Binary(BinOp::Add, a, b) => match (self.negated(a), self.negated(b)) {
                (Some(x), Some(y)) => {
                    let v = self.emit(Op::Binary(BinOp::Add, x, y));
                    Some(neg(self, v))
                }
                (Some(x), None) => Some(self.emit(Op::Binary(BinOp::Sub, b, x))),
                (None, Some(y)) => Some(self.emit(Op::Binary(BinOp::Sub, a, y))),
                (None, None) => None,
            },
            Op::Binary(BinOp::Sub, a, b) => match (self.negated(a), self.negated(b)) {
                (_, Some(y)) => Some(self.emit(Op::Binary(BinOp::Add, a, y))),
                (Some(x), None) => {
                    let v = self.emit(Op::Binary(BinOp::Add, x, b));
                    Some(neg(self, v))
                }
                (None, None) => None,
            },
            Op::Reduce(Reduce::Sum, a) | Op::Unary(UnOp::Re | UnOp::Im | UnOp::Conj, a) => {
                let x = self.negated(a)?;
                let inner = self.emit(op.map_operands(|_| x));
                Some(neg(self, inner))
            }
            _ => None,
        }
    }

    /// Whether `c` is `conj(z)`.
    fn is_conj_of(&self, c: Value, z: Value) -> bool {
        self.func.insts[c.index()].op == Op::Unary(UnOp::Conj, z)
    }

    /// `v` as an array masked by an interval condition
    /// ([`Function::interval_condition`]), `select(c, a, 0)` or
    /// `select(c, 0, a)`: the condition, `a`, and whether `a` is kept
    /// where `c` holds.
    fn mask_of(&self, v: Value) -> Option<(Value, Value, bool)> {
        let (c, a, kept) = match self.func.insts[v.index()].op {
            Op::Select(c, a, z) if self.is_const(z, 0.0) => (c, a, true),
            Op::Select(c, z, a) if self.is_const(z, 0.0) => (c, a, false),
            _ => return None,
        };
        self.func.interval_condition(c).map(|_| (c, a, kept))
    }

    /// `inner` masked by condition `c` as [`Builder::mask_of`] describes.
    fn remask(&mut self, c: Value, inner: Value, kept: bool) -> Value {
        let zero = self.zero(self.ty(inner));
        self.emit(if kept { Op::Select(c, inner, zero) } else { Op::Select(c, zero, inner) })
    }

    /// Sinks a mask through an op that maps zero to zero:
    /// `op(select(c, a, 0), y) → select(c, op(a, y), 0)` for products,
    /// quotients, negation, conjugation, parts, `abs`, `abs2`, `sqrt`,
    /// `sign` and positive powers, and for sums, differences and
    /// `complex(·, ·)` of two arrays masked alike. Where the mask is off,
    /// the result is zero even if `y` is not finite there: the mask
    /// states that the value is zero, and a zero times anything is taken
    /// as zero (as the `0 · y → 0` rule above does). This keeps masked
    /// work (a waveform cut at the ISCO and its adjoint) behind the one
    /// condition codegen splits the loop on; other masks stay put.
    fn sink_mask(&mut self, op: &Op) -> Option<Value> {
        match *op {
            Op::Unary(u, a)
                if matches!(
                    u,
                    UnOp::Neg | UnOp::Conj | UnOp::Re | UnOp::Im | UnOp::ToComplex | UnOp::Abs | UnOp::Abs2 | UnOp::Sqrt | UnOp::Sign
                ) =>
            {
                let (c, inner, kept) = self.mask_of(a)?;
                let v = self.emit(Op::Unary(u, inner));
                Some(self.remask(c, v, kept))
            }
            Op::PowConst(a, k) if f64::from_bits(k) > 0.0 => {
                let (c, inner, kept) = self.mask_of(a)?;
                let v = self.emit(Op::PowConst(inner, k));
                Some(self.remask(c, v, kept))
            }
            Op::Binary(BinOp::Mul, x, y) => {
                let (c, v, kept) = match (self.mask_of(x), self.mask_of(y)) {
                    (Some((c, inner, kept)), _) => (c, self.emit(Op::Binary(BinOp::Mul, inner, y)), kept),
                    (None, Some((c, inner, kept))) => (c, self.emit(Op::Binary(BinOp::Mul, x, inner)), kept),
                    (None, None) => return None,
                };
                Some(self.remask(c, v, kept))
            }
            Op::Binary(BinOp::Div, x, y) => {
                let (c, inner, kept) = self.mask_of(x)?;
                let v = self.emit(Op::Binary(BinOp::Div, inner, y));
                Some(self.remask(c, v, kept))
            }
            Op::Binary(b @ (BinOp::Add | BinOp::Sub | BinOp::Complex), x, y) => {
                let ((cx, ix, kx), (cy, iy, ky)) = (self.mask_of(x)?, self.mask_of(y)?);
                if (cx, kx) != (cy, ky) {
                    return None;
                }
                let v = self.emit(Op::Binary(b, ix, iy));
                Some(self.remask(cx, v, kx))
            }
            _ => None,
        }
    }

    /// `a + b`.
    pub fn add(&mut self, a: Value, b: Value) -> Value {
        self.emit(Op::Binary(BinOp::Add, a, b))
    }
    /// `a - b`.
    pub fn sub(&mut self, a: Value, b: Value) -> Value {
        self.emit(Op::Binary(BinOp::Sub, a, b))
    }
    /// `a * b`.
    pub fn mul(&mut self, a: Value, b: Value) -> Value {
        self.emit(Op::Binary(BinOp::Mul, a, b))
    }
    /// `a / b`.
    pub fn div(&mut self, a: Value, b: Value) -> Value {
        self.emit(Op::Binary(BinOp::Div, a, b))
    }
    /// `-a`.
    pub fn neg(&mut self, a: Value) -> Value {
        self.emit(Op::Unary(UnOp::Neg, a))
    }
    /// A unary op.
    pub fn unary(&mut self, u: UnOp, a: Value) -> Value {
        self.emit(Op::Unary(u, a))
    }
    /// A binary op.
    pub fn binary(&mut self, b: BinOp, x: Value, y: Value) -> Value {
        self.emit(Op::Binary(b, x, y))
    }
    /// `a` times the real scalar constant `k`, matched to `a`'s type.
    pub fn scale(&mut self, a: Value, k: f64) -> Value {
        let ty = self.ty(a);
        let c = self.constant(C64::new(k, 0.0), ty);
        self.mul(a, c)
    }
    /// Converts a value to `target`'s elem and shape by `ToComplex` and `Broadcast`.
    pub fn coerce(&mut self, v: Value, target: Ty) -> Value {
        let mut v = v;
        if self.ty(v).elem == Elem::Real && target.elem == Elem::Complex {
            v = self.emit(Op::Unary(UnOp::ToComplex, v));
        }
        if let (Shape::Scalar, Shape::Grid(g)) = (self.ty(v).shape, target.shape) {
            v = self.emit(Op::Broadcast(v, g));
        }
        v
    }
}
