//! Declarations and annotations: params, input defaults, type and unit
//! annotations, and compile-time constant expressions.

use super::*;

impl<'a> Checker<'a> {
    pub(super) fn param_decl(&mut self, p: &'a ast::ParamDecl) -> Option<(ir::ParamInfo, Dim)> {
        let (dim, scale, unit) = match &p.ty {
            Some(t) => {
                if let Some(e) = &t.elem {
                    if e.node == ElemAnn::Complex {
                        self.error(
                            Diagnostic::error(e.span, "params are real scalars").with_help("use two real params and `complex(re, im)`"),
                        );
                    }
                }
                if let Some(g) = &t.grid {
                    self.error(
                        Diagnostic::error(g.span, "params are scalars, not arrays over a grid")
                            .with_help("declare array data with `input`"),
                    );
                }
                match &t.unit {
                    Some(u) => self.unit_expr(u)?,
                    None => (Dim::NONE, 1.0, "1".into()),
                }
            }
            None => (Dim::NONE, 1.0, "1".into()),
        };
        let in_unit = |this: &mut Self, e: &'a Expr| -> Option<f64> {
            let (x, d) = this.const_eval(e)?;
            if d == dim {
                Some(x / scale)
            } else if d.is_none() {
                Some(x)
            } else {
                this.error(unit_mismatch(e.span, dim, d, &format!("param `{}`", p.name.node)));
                None
            }
        };
        let default = match &p.default {
            Some(e) => Some(in_unit(self, e)?),
            None => None,
        };
        let bounds = match &p.bounds {
            Some((lo, hi)) => {
                let (l, h) = (in_unit(self, lo)?, in_unit(self, hi)?);
                if !(l < h) {
                    self.error(
                        Diagnostic::error(lo.span.to(hi.span), format!("empty bounds {l}..{h} for param `{}`", p.name.node))
                            .with_help("the lower bound must be below the upper bound"),
                    );
                    return None;
                }
                if let Some(d) = default {
                    if !(l..=h).contains(&d) {
                        self.error(
                            Diagnostic::error(
                                p.default.as_ref().map(|e| e.span).unwrap_or(p.span),
                                format!(
                                    "default {d} of `{}` is outside its bounds {l}..{h}{}",
                                    p.name.node,
                                    if unit == "1" { String::new() } else { format!(" {unit}") }
                                ),
                            )
                            .with_help("move the default inside the bounds"),
                        );
                    }
                }
                Some((l, h))
            }
            None => None,
        };
        Some((ir::ParamInfo { name: p.name.node.clone(), default, bounds, scale, unit, dim: dim.to_string() }, dim))
    }

    /// Evaluates an input's default data at compile time (grids and constants only).
    pub(super) fn input_default(
        &mut self,
        func: &ir::Function,
        scene: &Scope,
        e: &'a Expr,
        name: &Spanned<String>,
        ty: Ty,
        dim: Dim,
    ) -> Option<Vec<C64>> {
        let mut header = ir::Function { grids: func.grids.clone(), ..Default::default() };
        header.name = format!("default of {}", name.node);
        let mut b = Builder::new(header, true);
        let mut scope = Scope::new(ScopeKind::Scene);
        for (g, id) in &scene.grids {
            let v = b.push(Op::GridCoord(*id));
            scope.values.insert(g.clone(), scene.values.get(g).map(|tv| Tv { v, dim: tv.dim }).unwrap_or(Tv { v, dim: Dim::NONE }));
            scope.grids.insert(g.clone(), *id);
        }
        let tv = self.expr(&mut b, &mut scope, e)?;
        let vty = b.ty(tv.v);
        let points = b.func.len_of(ty.shape);
        if b.func.insts.len().saturating_mul(points) > crate::kernels::interp::EVAL_BUDGET {
            self.error(
                Diagnostic::error(
                    e.span,
                    format!("the default of `{}` over {points} points is too large to compute at compile time", name.node),
                )
                .with_help("bind the input at run time instead (e.g. `--input NAME=FILE.npy`), or use a coarser grid"),
            );
            return None;
        }
        if tv.dim != dim {
            self.error(unit_mismatch(e.span, dim, tv.dim, &format!("input `{}`", name.node)));
            return None;
        }
        let shape_ok = vty.shape == ty.shape || vty.shape == Shape::Scalar;
        let elem_ok = vty.elem == ty.elem || (vty.elem == Elem::Real && ty.elem == Elem::Complex);
        if !shape_ok || !elem_ok {
            self.error(
                Diagnostic::error(
                    e.span,
                    format!("default of `{}` is {}, but the input is {}", name.node, b.func.fmt_ty(vty), b.func.fmt_ty(ty)),
                )
                .with_help("make the default match the declared type"),
            );
            return None;
        }
        let v = b.coerce(tv.v, ty);
        b.func.outputs.push(ir::Output { name: "default".into(), value: v, unit: dim.to_string(), exponent: 0 });
        let r = crate::kernels::interp::interpret(&b.func, &[], &[]);
        let data = r.values[v.index()].clone();
        if let Some(i) = data.iter().position(|x| !x.re.is_finite() || !x.im.is_finite()) {
            self.error(
                Diagnostic::error(e.span, format!("default of `{}` is not finite at index {i}", name.node))
                    .with_help("check the expression for divisions by zero or logs of non-positive values"),
            );
            return None;
        }
        Some(data)
    }

    /// Resolves a type annotation in a scene: type, dimension, scale, unit text.
    pub(super) fn type_ann(&mut self, t: &TypeAnn, scope: &Scope) -> Option<(Ty, Dim, f64, String)> {
        let elem = match t.elem.as_ref().map(|e| e.node) {
            Some(ElemAnn::Complex) => Elem::Complex,
            _ => Elem::Real,
        };
        let shape = match &t.grid {
            Some(g) => match scope.grids.get(&g.node) {
                Some(id) => Shape::Grid(*id),
                None => {
                    let cands: Vec<&str> = scope.grids.keys().map(|s| s.as_str()).collect();
                    let mut d = Diagnostic::error(g.span, format!("unknown grid `{}`", g.node));
                    d = match did_you_mean(&g.node, cands) {
                        Some(s) => d.with_help(format!("did you mean `{s}`?")),
                        None => d.with_help(format!("declare it with `grid {} = frequencies(...)`", g.node)),
                    };
                    self.error(d);
                    return None;
                }
            },
            None => Shape::Scalar,
        };
        let (dim, scale, unit) = match &t.unit {
            Some(u) => self.unit_expr(u)?,
            None => (Dim::NONE, 1.0, "1".into()),
        };
        Some((Ty { elem, shape }, dim, scale, unit))
    }

    pub(super) fn unit_expr(&mut self, u: &Spanned<UnitExpr>) -> Option<(Dim, f64, String)> {
        fn go(c: &mut Checker, u: &UnitExpr) -> Option<(Dim, f64)> {
            match u {
                UnitExpr::One => Some((Dim::NONE, 1.0)),
                UnitExpr::Name(n) => match units::unit(&n.node) {
                    Some(d) => Some((d.dim, d.scale)),
                    None => {
                        let mut d = Diagnostic::error(n.span, format!("unknown unit `{}`", n.node));
                        d = match did_you_mean(&n.node, units::UNITS.iter().map(|u| u.name)) {
                            Some(s) => d.with_help(format!("did you mean `{s}`?")),
                            None => {
                                d.with_help(format!("known units: {}", units::UNITS.iter().map(|u| u.name).collect::<Vec<_>>().join(", ")))
                            }
                        };
                        c.error(d);
                        None
                    }
                },
                UnitExpr::Mul(a, b) | UnitExpr::Div(a, b) => {
                    let (da, sa) = go(c, a)?;
                    let (db, sb) = go(c, b)?;
                    if matches!(u, UnitExpr::Mul(..)) {
                        Some((da.times(db)?, sa * sb))
                    } else {
                        Some((da.times(db.inv())?, sa / sb))
                    }
                }
                UnitExpr::Pow(a, n, d) => {
                    let (da, sa) = go(c, a)?;
                    let p = Ratio::new(*n as i64, *d as i64)?;
                    Some((da.pow(p)?, sa.powf(p.to_f64())))
                }
            }
        }
        let reported = self.diags.len();
        let Some((d, s)) = go(self, &u.node) else {
            // An unknown unit name is reported where it is found; anything
            // else is an exponent that is no fraction, or too large.
            if self.diags.len() == reported {
                self.error(
                    Diagnostic::error(u.span, format!("invalid unit `{}`", u.node))
                        .with_label("an exponent here is not a fraction with a nonzero denominator, or is too large")
                        .with_help("write exponents as small fractions, e.g. `s^(-7/6)`"),
                );
            }
            return None;
        };
        Some((d, s, u.node.to_string()))
    }

    /// Evaluates a constant expression (numbers, units, constants, arithmetic).
    pub(super) fn const_eval(&mut self, e: &'a Expr) -> Option<(f64, Dim)> {
        stacker::maybe_grow(super::STACK_RED_ZONE, super::STACK_GROWTH, || self.const_eval_here(e))
    }

    fn const_eval_here(&mut self, e: &'a Expr) -> Option<(f64, Dim)> {
        let mut b = Builder::new(ir::Function::default(), true);
        let mut scope = Scope::new(ScopeKind::Const);
        let tv = self.expr(&mut b, &mut scope, e)?;
        match (b.const_of(tv.v), b.ty(tv.v)) {
            (Some(c), Ty::REAL) => Some((c.re, tv.dim)),
            _ => {
                self.error(
                    Diagnostic::error(e.span, "expected a real constant")
                        .with_label("not a constant")
                        .with_help("use numbers, units and named constants only"),
                );
                None
            }
        }
    }

    /// Checks a value against an optional annotation (in a let or module arg).
    pub(super) fn check_ann(
        &mut self,
        b: &mut Builder,
        scope: &Scope,
        ann: Option<&TypeAnn>,
        tv: Tv,
        name: &Spanned<String>,
    ) -> Option<Tv> {
        let Some(t) = ann else { return Some(tv) };
        let ty = b.ty(tv.v);
        let mut tv = tv;
        if let Some(e) = &t.elem {
            match (e.node, ty.elem) {
                (ElemAnn::Real, Elem::Complex) => {
                    self.error(
                        Diagnostic::error(name.span, format!("`{}` is declared real but its value is complex", name.node))
                            .with_secondary(e.span, "declared here")
                            .with_help("take `re(...)`, `abs(...)` or declare it `complex`"),
                    );
                    return None;
                }
                (ElemAnn::Complex, Elem::Real) => tv.v = b.coerce(tv.v, ty.with_elem(Elem::Complex)),
                _ => {}
            }
        }
        if let Some(g) = &t.grid {
            if scope.kind == ScopeKind::Scene {
                let want = scope.grids.get(&g.node).copied();
                if want.map(Shape::Grid) != Some(ty.shape) {
                    self.error(
                        Diagnostic::error(
                            name.span,
                            format!("`{}` is declared over grid `{}` but its value is {}", name.node, g.node, b.func.fmt_ty(ty)),
                        )
                        .with_secondary(g.span, "declared here")
                        .with_help("make the value an array over that grid"),
                    );
                    return None;
                }
            }
        }
        if let Some(u) = &t.unit {
            let (dim, _, _) = self.unit_expr(u)?;
            if dim != tv.dim {
                self.error(unit_mismatch(name.span, dim, tv.dim, &format!("`{}`", name.node)).with_secondary(u.span, "unit declared here"));
                return None;
            }
        }
        Some(tv)
    }
}
