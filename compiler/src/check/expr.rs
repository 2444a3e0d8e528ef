//! Expressions: names and `let` definitions, operators, powers, selects,
//! and unifying the shapes of operands.

use super::*;

impl<'a> Checker<'a> {
    pub(super) fn lookup_let(&mut self, b: &mut Builder, scope: &mut Scope<'a>, name: &str, at: Span) -> Option<Tv> {
        match scope.lets.get(name) {
            Some(LetSlot::Done(tv)) => *tv,
            Some(LetSlot::Busy(def)) => {
                let def = *def;
                self.error(
                    Diagnostic::error(at, format!("cyclic definition: `{name}` depends on itself"))
                        .with_label(format!("`{name}` is used here while it is being defined"))
                        .with_secondary(def, "defined here")
                        .with_help("break the cycle: definitions may not refer to themselves, directly or through other definitions"),
                );
                None
            }
            Some(LetSlot::Pending(decl)) => {
                let decl: &'a LetDecl = decl;
                scope.lets.insert(name.to_string(), LetSlot::Busy(decl.name.span));
                let tv = self.expr(b, scope, &decl.value).and_then(|tv| self.check_ann(b, scope, decl.ty.as_ref(), tv, &decl.name));
                scope.lets.insert(name.to_string(), LetSlot::Done(tv));
                tv
            }
            None => None,
        }
    }

    /// Checks and lowers `e`. Expressions nest as deep as the source
    /// does (a sum of 5,000 terms is 5,000 deep), so the recursion grows
    /// the stack on the heap when it runs low.
    pub(super) fn expr(&mut self, b: &mut Builder, scope: &mut Scope<'a>, e: &'a Expr) -> Option<Tv> {
        stacker::maybe_grow(STACK_RED_ZONE, STACK_GROWTH, || self.expr_here(b, scope, e))
    }

    fn expr_here(&mut self, b: &mut Builder, scope: &mut Scope<'a>, e: &'a Expr) -> Option<Tv> {
        match &e.node {
            ExprKind::Error => None,
            ExprKind::Number(x, unit) => {
                let (dim, scale) = match unit {
                    Some(u) => {
                        let (d, s, _) = self.unit_expr(u)?;
                        (d, s)
                    }
                    None => (Dim::NONE, 1.0),
                };
                Some(Tv { v: b.real(x * scale), dim })
            }
            ExprKind::Imaginary(x) => Some(Tv { v: b.push(Op::ConstComplex(0f64.to_bits(), x.to_bits())), dim: Dim::NONE }),
            ExprKind::Name(n) => self.name(b, scope, n, e.span),
            ExprKind::Neg(a) => {
                let a = self.expr(b, scope, a)?;
                if b.ty(a.v).elem == Elem::Bool {
                    self.error(
                        Diagnostic::error(e.span, "cannot negate a comparison")
                            .with_help("use `select(cond, a, b)` to choose between values"),
                    );
                    return None;
                }
                Some(Tv { v: b.neg(a.v), dim: a.dim })
            }
            ExprKind::Binary(op, l, r) => {
                let (lt, rt) = (self.expr(b, scope, l), self.expr(b, scope, r));
                self.binary(b, *op, (lt?, l.span), (rt?, r.span), e.span)
            }
            ExprKind::If(c, x, y) => {
                let (c_tv, x_tv, y_tv) = (self.expr(b, scope, c), self.expr(b, scope, x), self.expr(b, scope, y));
                self.select(b, (c_tv?, c.span), (x_tv?, x.span), (y_tv?, y.span), e.span)
            }
            ExprKind::Call { callee, args } => self.call(b, scope, callee, args, e.span),
        }
    }

    pub(super) fn name(&mut self, b: &mut Builder, scope: &mut Scope<'a>, n: &str, span: Span) -> Option<Tv> {
        if let Some(tv) = scope.values.get(n) {
            return Some(*tv);
        }
        if scope.lets.contains_key(n) {
            return self.lookup_let(b, scope, n, span);
        }
        if let Some(c) = CONSTANTS.iter().find(|c| c.name == n) {
            return Some(Tv { v: b.real(c.value), dim: c.dim });
        }
        if let Some(&(x, dim)) = self.knobs.get(n) {
            return Some(Tv { v: b.real(x), dim });
        }
        if scope.poisoned.contains(n) || self.failed_knobs.contains(n) {
            return None;
        }
        if let Some((_, usage)) = BUILTINS.iter().find(|b| b.0 == n) {
            self.error(
                Diagnostic::error(span, format!("`{n}` is a function, not a value"))
                    .with_label("used without arguments")
                    .with_help(format!("call it: {usage}")),
            );
            return None;
        }
        if self.modules.contains_key(n) {
            self.error(
                Diagnostic::error(span, format!("`{n}` is a module, not a value"))
                    .with_label("used without arguments")
                    .with_help(format!("call it: `{n}(...)`")),
            );
            return None;
        }
        if scope.kind == ScopeKind::Const {
            self.error(
                Diagnostic::error(span, format!("`{n}` is not a constant"))
                    .with_label("only numbers, units and named constants may appear here")
                    .with_help("write the value as a number with a unit, e.g. `20 Hz`"),
            );
            return None;
        }
        let cands: Vec<&str> =
            scope.values.keys().chain(scope.lets.keys()).map(|s| s.as_str()).chain(CONSTANTS.iter().map(|c| c.name)).collect();
        self.error(unknown_name(span, n, &cands));
        None
    }

    /// Unifies element kind and shape of two operands.
    pub(super) fn unify(&mut self, b: &mut Builder, (x, xs): (Value, Span), (y, ys): (Value, Span), at: Span) -> Option<(Value, Value)> {
        let (tx, ty) = (b.ty(x), b.ty(y));
        let shape = match (tx.shape, ty.shape) {
            (Shape::Scalar, s) | (s, Shape::Scalar) => s,
            (Shape::Grid(g1), Shape::Grid(g2)) if g1 == g2 => tx.shape,
            _ => {
                self.error(
                    Diagnostic::error(at, format!("shape mismatch: {} and {}", b.func.fmt_ty(tx), b.func.fmt_ty(ty)))
                        .with_label("arrays over different grids cannot be combined elementwise")
                        .with_secondary(xs, b.func.fmt_ty(tx))
                        .with_secondary(ys, b.func.fmt_ty(ty))
                        .with_help("reduce one side over its grid first (e.g. `sum(...)`), or define both on the same grid"),
                );
                return None;
            }
        };
        let elem = if tx.elem == Elem::Complex || ty.elem == Elem::Complex { Elem::Complex } else { tx.elem };
        let target = Ty { elem, shape };
        Some((b.coerce(x, target), b.coerce(y, target)))
    }

    pub(super) fn no_bool(&mut self, b: &Builder, v: (Tv, Span), what: &str) -> Option<()> {
        if b.ty(v.0.v).elem == Elem::Bool {
            self.error(
                Diagnostic::error(v.1, format!("{what} needs a number, found a comparison"))
                    .with_help("use `select(cond, a, b)` or `if cond { a } else { b }` to turn a comparison into a value"),
            );
            return None;
        }
        Some(())
    }

    pub(super) fn binary(&mut self, b: &mut Builder, op: BinOp, l: (Tv, Span), r: (Tv, Span), at: Span) -> Option<Tv> {
        self.no_bool(b, l, &format!("`{}`", op.symbol()))?;
        self.no_bool(b, r, &format!("`{}`", op.symbol()))?;
        let (lt, rt) = (l.0, r.0);
        match op {
            BinOp::Add | BinOp::Sub => {
                if lt.dim != rt.dim {
                    self.error(
                        Diagnostic::error(
                            at,
                            format!(
                                "unit mismatch: cannot {} {} and {}",
                                if op == BinOp::Add { "add" } else { "subtract" },
                                lt.dim,
                                rt.dim
                            ),
                        )
                        .with_secondary(l.1, format!("this has unit {}", lt.dim))
                        .with_secondary(r.1, format!("this has unit {}", rt.dim))
                        .with_help("both sides of `+` and `-` must have the same unit; multiply by a constant to convert"),
                    );
                    return None;
                }
                let (x, y) = self.unify(b, (lt.v, l.1), (rt.v, r.1), at)?;
                let v = b.binary(if op == BinOp::Add { IrBin::Add } else { IrBin::Sub }, x, y);
                Some(Tv { v, dim: lt.dim })
            }
            BinOp::Mul | BinOp::Div => {
                let dim = if op == BinOp::Mul { lt.dim.times(rt.dim) } else { lt.dim.times(rt.dim.inv()) };
                let Some(dim) = dim else {
                    self.error(Diagnostic::error(at, "unit exponent overflow").with_help("simplify the units of this expression"));
                    return None;
                };
                let (x, y) = self.unify(b, (lt.v, l.1), (rt.v, r.1), at)?;
                let v = b.binary(if op == BinOp::Mul { IrBin::Mul } else { IrBin::Div }, x, y);
                Some(Tv { v, dim })
            }
            BinOp::Pow => self.pow(b, l, r, at),
            _ => {
                if lt.dim != rt.dim {
                    self.error(
                        Diagnostic::error(at, format!("unit mismatch: cannot compare {} with {}", lt.dim, rt.dim))
                            .with_secondary(l.1, format!("unit {}", lt.dim))
                            .with_secondary(r.1, format!("unit {}", rt.dim))
                            .with_help("compare quantities of the same unit"),
                    );
                    return None;
                }
                self.real_only(b, l, op.symbol())?;
                self.real_only(b, r, op.symbol())?;
                let (x, y) = self.unify(b, (lt.v, l.1), (rt.v, r.1), at)?;
                let irop = match op {
                    BinOp::Lt => IrBin::Lt,
                    BinOp::Le => IrBin::Le,
                    BinOp::Gt => IrBin::Gt,
                    BinOp::Ge => IrBin::Ge,
                    BinOp::Eq => IrBin::Eq,
                    _ => IrBin::Ne,
                };
                Some(Tv { v: b.binary(irop, x, y), dim: Dim::NONE })
            }
        }
    }

    pub(super) fn real_only(&mut self, b: &Builder, v: (Tv, Span), what: &str) -> Option<()> {
        match b.ty(v.0.v).elem {
            Elem::Complex => {
                self.error(
                    Diagnostic::error(v.1, format!("`{what}` needs a real value, found complex"))
                        .with_help("take `re(...)`, `im(...)` or `abs(...)` first"),
                );
                None
            }
            _ => Some(()),
        }
    }

    pub(super) fn pow(&mut self, b: &mut Builder, l: (Tv, Span), r: (Tv, Span), at: Span) -> Option<Tv> {
        self.real_only(b, l, "^")?;
        self.real_only(b, r, "^")?;
        if !r.0.dim.is_none() {
            self.error(Diagnostic::error(r.1, format!("exponent has unit {}", r.0.dim)).with_help("exponents must be dimensionless"));
            return None;
        }
        let exponent = if b.ty(r.0.v) == Ty::REAL { const_value(b, r.0.v) } else { None };
        match exponent {
            Some(c) => {
                let dim = if l.0.dim.is_none() {
                    Dim::NONE
                } else {
                    match Ratio::from_f64(c).and_then(|p| l.0.dim.pow(p)) {
                        Some(d) => d,
                        None => {
                            self.error(
                                Diagnostic::error(r.1, format!("cannot raise a value with unit {} to the power {c}", l.0.dim)).with_help(
                                    "use a rational exponent with a small denominator (e.g. -7/6), or make the base dimensionless",
                                ),
                            );
                            return None;
                        }
                    }
                };
                Some(Tv { v: b.emit(Op::PowConst(l.0.v, c.to_bits())), dim })
            }
            None => {
                if !l.0.dim.is_none() {
                    self.error(
                        Diagnostic::error(at, format!("a value with unit {} needs a constant exponent", l.0.dim))
                            .with_help("make the base dimensionless, e.g. divide by a reference value"),
                    );
                    return None;
                }
                let (x, y) = self.unify(b, (l.0.v, l.1), (r.0.v, r.1), at)?;
                Some(Tv { v: b.binary(IrBin::Pow, x, y), dim: Dim::NONE })
            }
        }
    }

    /// `masked_div(a, s)`: `a / s` where `0 < s < ∞`, else 0. The divisor is
    /// replaced by 1 where it is masked before dividing, so neither the value
    /// nor the adjoint (which divides by `s` and `s²`) meets 0, inf or NaN.
    pub(super) fn masked_div(&mut self, b: &mut Builder, a: (Tv, Span), s: (Tv, Span), at: Span) -> Option<Tv> {
        self.real_only(b, s, "masked_div")?;
        let Some(dim) = a.0.dim.times(s.0.dim.inv()) else {
            self.error(Diagnostic::error(at, "unit exponent overflow").with_help("simplify the units of this expression"));
            return None;
        };
        let (zero, largest) = (b.real(0.0), b.real(f64::MAX));
        let (sv, zero) = self.unify(b, (s.0.v, s.1), (zero, at), at)?;
        let (_, largest) = self.unify(b, (s.0.v, s.1), (largest, at), at)?;
        let (positive, finite) = (b.binary(IrBin::Gt, sv, zero), b.binary(IrBin::Lt, sv, largest));
        let cond = |v: Value| (Tv { v, dim: Dim::NONE }, at);
        // Both conditions fail for NaN; `finite` fails for +inf.
        let masked = |this: &mut Self, b: &mut Builder, x: Tv, fallback: f64| -> Option<Tv> {
            let other = Tv { v: b.real(fallback), dim: x.dim };
            let inner = this.select(b, cond(finite), (x, at), (other, at), at)?;
            this.select(b, cond(positive), (inner, at), (other, at), at)
        };
        let safe = masked(self, b, s.0, 1.0)?;
        let (x, y) = self.unify(b, (a.0.v, a.1), (safe.v, s.1), at)?;
        let q = Tv { v: b.binary(IrBin::Div, x, y), dim };
        let masked = masked(self, b, q, 0.0)?;
        Some(masked)
    }

    pub(super) fn select(&mut self, b: &mut Builder, c: (Tv, Span), x: (Tv, Span), y: (Tv, Span), at: Span) -> Option<Tv> {
        if b.ty(c.0.v).elem != Elem::Bool {
            self.error(Diagnostic::error(c.1, "condition is not a comparison").with_help("write a comparison such as `x > 0`"));
            return None;
        }
        self.no_bool(b, x, "a branch")?;
        self.no_bool(b, y, "a branch")?;
        if x.0.dim != y.0.dim {
            self.error(
                Diagnostic::error(at, format!("unit mismatch: branches have units {} and {}", x.0.dim, y.0.dim))
                    .with_secondary(x.1, format!("unit {}", x.0.dim))
                    .with_secondary(y.1, format!("unit {}", y.0.dim))
                    .with_help("both branches must have the same unit"),
            );
            return None;
        }
        let (xv, yv) = self.unify(b, (x.0.v, x.1), (y.0.v, y.1), at)?;
        let shape = b.ty(xv).shape;
        let cty = b.ty(c.0.v);
        let cv = match (cty.shape, shape) {
            (Shape::Scalar, Shape::Grid(g)) => b.emit(Op::Broadcast(c.0.v, g)),
            (Shape::Grid(_), Shape::Scalar) => {
                let t = Ty { elem: b.ty(xv).elem, shape: cty.shape };
                let (xv, yv) = (b.coerce(xv, t), b.coerce(yv, t));
                return Some(Tv { v: b.emit(Op::Select(c.0.v, xv, yv)), dim: x.0.dim });
            }
            (Shape::Grid(g1), Shape::Grid(g2)) if g1 != g2 => {
                self.error(
                    Diagnostic::error(at, "shape mismatch between condition and branches").with_help("define them on the same grid"),
                );
                return None;
            }
            _ => c.0.v,
        };
        Some(Tv { v: b.emit(Op::Select(cv, xv, yv)), dim: x.0.dim })
    }
}
