//! Calls: builtins, transforms (rfft/irfft) and the instantiation of
//! modules at each call site.

use super::*;

impl<'a> Checker<'a> {
    pub(super) fn call(
        &mut self,
        b: &mut Builder,
        scope: &mut Scope<'a>,
        callee: &'a Spanned<String>,
        args: &'a [ast::Arg],
        at: Span,
    ) -> Option<Tv> {
        let name = callee.node.as_str();
        if let Some(m) = self.modules.get(name).copied() {
            return self.call_module(b, scope, m, callee, args, at);
        }
        if !BUILTINS.iter().any(|x| x.0 == name) {
            self.error(self.unknown_function(callee));
            return None;
        }
        if layers::is_layer(name) {
            return self.layer_call(b, scope, callee, args, at);
        }
        if name == "frequencies" || name == "times" || name == "spectrum" || name == "index" {
            self.error(
                Diagnostic::error(at, format!("`{name}(...)` defines a grid and can only appear in `grid NAME = {name}(...)`"))
                    .with_help("declare a grid in the scene and use its name"),
            );
            return None;
        }
        if let Some(a) = args.iter().find_map(|a| a.name.as_ref()) {
            self.error(
                Diagnostic::error(a.span, format!("builtin `{name}` takes positional arguments only"))
                    .with_help(format!("remove `{}:`", a.node)),
            );
            return None;
        }
        let mut vals = Vec::new();
        for a in args {
            vals.push(self.expr(b, scope, &a.value).map(|tv| (tv, a.value.span)));
        }
        let vals: Vec<(Tv, Span)> = vals.into_iter().collect::<Option<_>>()?;
        let arity: &[usize] = match name {
            "atan2" | "complex" | "rfft" | "irfft" | "masked_div" => &[2],
            "min" | "max" => &[1, 2],
            "clamp" | "select" => &[3],
            _ => &[1],
        };
        if !arity.contains(&vals.len()) {
            let want = arity.iter().map(|n| n.to_string()).collect::<Vec<_>>().join(" or ");
            self.error(
                Diagnostic::error(
                    at,
                    format!(
                        "`{name}` takes {want} argument{}, but {} {} given",
                        if arity == [1] { "" } else { "s" },
                        vals.len(),
                        if vals.len() == 1 { "was" } else { "were" }
                    ),
                )
                .with_label(format!("{} argument{}", vals.len(), if vals.len() == 1 { "" } else { "s" }))
                .with_help(BUILTINS.iter().find(|x| x.0 == name).map(|x| format!("usage: {}", x.1)).unwrap_or_default()),
            );
            return None;
        }
        for v in &vals {
            if name != "select" || !std::ptr::eq(v, &vals[0]) {
                self.no_bool(b, *v, &format!("`{name}`"))?;
            }
        }
        let a = vals[0];
        let dimless = |this: &mut Self, v: (Tv, Span)| -> Option<()> {
            if v.0.dim.is_none() {
                Some(())
            } else {
                this.error(
                    Diagnostic::error(v.1, format!("`{name}` needs a dimensionless argument, found unit {}", v.0.dim))
                        .with_help("divide by a reference value, or multiply frequencies by times"),
                );
                None
            }
        };
        let un = |b: &mut Builder, u: UnOp, tv: Tv, dim: Dim| Some(Tv { v: b.unary(u, tv.v), dim });
        let elem = b.ty(a.0.v).elem;
        match name {
            "sqrt" | "cbrt" => {
                self.real_only(b, a, name)?;
                let p = if name == "sqrt" { Ratio::new(1, 2) } else { Ratio::new(1, 3) };
                let dim = p.and_then(|p| a.0.dim.pow(p))?;
                un(b, if name == "sqrt" { UnOp::Sqrt } else { UnOp::Cbrt }, a.0, dim)
            }
            "exp" => {
                dimless(self, a)?;
                un(b, UnOp::Exp, a.0, Dim::NONE)
            }
            "log" | "sin" | "cos" | "tan" | "tanh" => {
                self.real_only(b, a, name)?;
                dimless(self, a)?;
                let u = match name {
                    "log" => UnOp::Log,
                    "sin" => UnOp::Sin,
                    "cos" => UnOp::Cos,
                    "tan" => UnOp::Tan,
                    _ => UnOp::Tanh,
                };
                un(b, u, a.0, Dim::NONE)
            }
            "cis" => {
                self.real_only(b, a, name)?;
                dimless(self, a)?;
                un(b, UnOp::Cis, a.0, Dim::NONE)
            }
            "abs" => un(b, UnOp::Abs, a.0, a.0.dim),
            "abs2" => {
                let d = a.0.dim.times(a.0.dim)?;
                if elem == Elem::Complex {
                    un(b, UnOp::Abs2, a.0, d)
                } else {
                    Some(Tv { v: b.mul(a.0.v, a.0.v), dim: d })
                }
            }
            "re" | "im" | "conj" => {
                if elem == Elem::Real {
                    return match name {
                        "im" => Some(Tv { v: b.zero(b.ty(a.0.v)), dim: a.0.dim }),
                        _ => Some(a.0),
                    };
                }
                let u = match name {
                    "re" => UnOp::Re,
                    "im" => UnOp::Im,
                    _ => UnOp::Conj,
                };
                un(b, u, a.0, a.0.dim)
            }
            "sum" | "mean" | "max" | "min" if vals.len() == 1 => {
                let Shape::Grid(g) = b.ty(a.0.v).shape else {
                    self.error(
                        Diagnostic::error(a.1, format!("`{name}` reduces an array over a grid, but this is a scalar"))
                            .with_help("pass an array (a value defined on a grid)"),
                    );
                    return None;
                };
                if name == "max" || name == "min" {
                    self.real_only(b, a, name)?;
                }
                let v = match name {
                    "sum" => b.emit(Op::Reduce(Reduce::Sum, a.0.v)),
                    "mean" => {
                        let s = b.emit(Op::Reduce(Reduce::Sum, a.0.v));
                        let n = b.func.grids[g.0 as usize].len as f64;
                        b.scale(s, 1.0 / n)
                    }
                    "max" => b.emit(Op::Reduce(Reduce::Max, a.0.v)),
                    _ => {
                        let n = b.neg(a.0.v);
                        let m = b.emit(Op::Reduce(Reduce::Max, n));
                        b.neg(m)
                    }
                };
                Some(Tv { v, dim: a.0.dim })
            }
            "select" => self.select(b, vals[0], vals[1], vals[2], at),
            "complex" => {
                self.real_only(b, vals[0], name)?;
                self.real_only(b, vals[1], name)?;
                self.same_dim(vals[0], vals[1], name, at)?;
                let (x, y) = self.unify(b, (vals[0].0.v, vals[0].1), (vals[1].0.v, vals[1].1), at)?;
                Some(Tv { v: b.binary(IrBin::Complex, x, y), dim: a.0.dim })
            }
            "atan2" | "min" | "max" => {
                self.real_only(b, vals[0], name)?;
                self.real_only(b, vals[1], name)?;
                self.same_dim(vals[0], vals[1], name, at)?;
                let (x, y) = self.unify(b, (vals[0].0.v, vals[0].1), (vals[1].0.v, vals[1].1), at)?;
                let (op, dim) = match name {
                    "atan2" => (IrBin::Atan2, Dim::NONE),
                    "min" => (IrBin::Min, a.0.dim),
                    _ => (IrBin::Max, a.0.dim),
                };
                Some(Tv { v: b.binary(op, x, y), dim })
            }
            "rfft" | "irfft" => self.transform(b, name, vals[0], vals[1]),
            "masked_div" => self.masked_div(b, vals[0], vals[1], at),
            "spacing" => {
                let Op::GridCoord(g) = b.func.insts[a.0.v.index()].op else {
                    self.error(
                        Diagnostic::error(a.1, "`spacing` takes the name of a grid")
                            .with_help("e.g. `spacing(t)` for the sample interval of time grid `t`"),
                    );
                    return None;
                };
                let step = b.func.grids[g.0 as usize].step;
                Some(Tv { v: b.real(step), dim: a.0.dim })
            }
            "clamp" => {
                for v in &vals {
                    self.real_only(b, *v, name)?;
                }
                self.same_dim(vals[0], vals[1], name, at)?;
                self.same_dim(vals[0], vals[2], name, at)?;
                let (x, lo) = self.unify(b, (vals[0].0.v, vals[0].1), (vals[1].0.v, vals[1].1), at)?;
                let m = b.binary(IrBin::Max, x, lo);
                let (m, hi) = self.unify(b, (m, vals[0].1), (vals[2].0.v, vals[2].1), at)?;
                Some(Tv { v: b.binary(IrBin::Min, m, hi), dim: a.0.dim })
            }
            _ => {
                self.error(self.unknown_function(callee));
                None
            }
        }
    }

    /// `rfft(x, f)` and `irfft(X, t)`: checks that the two grids are a time
    /// grid of n samples and its spectrum of n/2 + 1 bins from 0 Hz.
    pub(super) fn transform(&mut self, b: &mut Builder, name: &str, x: (Tv, Span), grid: (Tv, Span)) -> Option<Tv> {
        let inverse = name == "irfft";
        let (want_dim, target_kind) = if inverse { (Dim::TIME, "time") } else { (Dim::FREQ, "frequency") };
        let Op::GridCoord(target) = b.func.insts[grid.0.v.index()].op else {
            self.error(Diagnostic::error(grid.1, format!("the second argument of `{name}` must be a {target_kind} grid")).with_help(
                format!("pass the name of the grid the result lives on, e.g. `{name}(x, {})`", if inverse { "t" } else { "f" }),
            ));
            return None;
        };
        if grid.0.dim != want_dim {
            self.error(
                Diagnostic::error(grid.1, format!("`{name}` needs a {target_kind} grid here, but this grid is in {}", grid.0.dim))
                    .with_help(if inverse {
                        "irfft goes from a spectrum grid to a time grid"
                    } else {
                        "rfft goes from a time grid to its spectrum grid"
                    }),
            );
            return None;
        }
        let ty = b.ty(x.0.v);
        let Shape::Grid(source) = ty.shape else {
            self.error(
                Diagnostic::error(x.1, format!("`{name}` transforms an array over a grid, but this is a scalar"))
                    .with_help("pass an array (a value defined on a grid)"),
            );
            return None;
        };
        let (time, freq) = if inverse { (target, source) } else { (source, target) };
        let (tg, fg) = (b.func.grids[time.0 as usize].clone(), b.func.grids[freq.0 as usize].clone());
        let n = tg.len;
        let matches = fg.start.abs() <= 1e-9 * fg.step && fg.len == n / 2 + 1 && (fg.step * tg.step * n as f64 - 1.0).abs() <= 1e-9;
        if !matches || tg.unit != "s" {
            let (ts, fs) = (tg.name.clone(), fg.name.clone());
            let expect = format!("{} bins from 0 Hz in steps of {} Hz", n / 2 + 1, 1.0 / (n as f64 * tg.step));
            self.error(
                Diagnostic::error(
                    if inverse { grid.1 } else { x.1 },
                    format!("grids `{ts}` and `{fs}` are not a time grid and its spectrum"),
                )
                .with_label(format!("`{ts}` has {n} samples every {} s, so its spectrum has {expect}", tg.step))
                .with_note(format!("`{fs}` has {} points from {} Hz in steps of {} Hz", fg.len, fg.start, fg.step))
                .with_help(format!("declare the frequency grid as `grid {fs} = spectrum({ts})`")),
            );
            return None;
        }
        if inverse {
            if ty.elem == Elem::Bool {
                return None;
            }
            let xc = b.coerce(x.0.v, ty.with_elem(Elem::Complex));
            let dft = ir::Dft { inverse: true, doubled: true, scale: fg.step.to_bits(), out: time };
            Some(Tv { v: b.emit(Op::Dft(dft, xc)), dim: x.0.dim.times(Dim::FREQ)? })
        } else {
            self.real_only(b, x, name)?;
            let dft = ir::Dft { inverse: false, doubled: false, scale: tg.step.to_bits(), out: freq };
            Some(Tv { v: b.emit(Op::Dft(dft, x.0.v)), dim: x.0.dim.times(Dim::TIME)? })
        }
    }

    pub(super) fn same_dim(&mut self, x: (Tv, Span), y: (Tv, Span), name: &str, at: Span) -> Option<()> {
        if x.0.dim == y.0.dim {
            return Some(());
        }
        self.error(
            Diagnostic::error(at, format!("unit mismatch in `{name}`: {} and {}", x.0.dim, y.0.dim))
                .with_secondary(x.1, format!("unit {}", x.0.dim))
                .with_secondary(y.1, format!("unit {}", y.0.dim))
                .with_help(format!("the arguments of `{name}` must have the same unit")),
        );
        None
    }

    pub(super) fn call_module(
        &mut self,
        b: &mut Builder,
        scope: &mut Scope<'a>,
        m: &'a ModuleDef,
        callee: &Spanned<String>,
        args: &'a [ast::Arg],
        at: Span,
    ) -> Option<Tv> {
        if let Some(pos) = self.call_stack.iter().position(|(n, _)| *n == m.name.node) {
            let chain: Vec<String> = self.call_stack[pos..].iter().map(|(n, _)| n.clone()).chain([m.name.node.clone()]).collect();
            self.error(
                Diagnostic::error(callee.span, format!("cyclic definition: module `{}` calls itself", m.name.node))
                    .with_label(format!("call chain {}", chain.join(" -> ")))
                    .with_secondary(m.name.span, "module defined here")
                    .with_help("modules are expanded at each call, so recursion is not allowed; write the repetition out or use arrays"),
            );
            return None;
        }
        // Match actual arguments to formals.
        let mut bound: Vec<Option<(&'a Expr, Span)>> = vec![None; m.args.len()];
        let mut ok = true;
        let mut positional = 0;
        for a in args {
            match &a.name {
                None => {
                    if positional >= m.args.len() {
                        self.error(
                            Diagnostic::error(
                                a.value.span,
                                format!(
                                    "module `{}` takes {} argument{}, but more were given",
                                    m.name.node,
                                    m.args.len(),
                                    if m.args.len() == 1 { "" } else { "s" }
                                ),
                            )
                            .with_label("extra argument")
                            .with_secondary(m.name.span, "module defined here")
                            .with_help("remove the extra arguments"),
                        );
                        ok = false;
                        break;
                    }
                    bound[positional] = Some((&a.value, a.value.span));
                    positional += 1;
                }
                Some(n) => match m.args.iter().position(|f| f.name.node == n.node) {
                    Some(i) if bound[i].is_some() => {
                        self.error(
                            Diagnostic::error(n.span, format!("argument `{}` is given twice", n.node)).with_help("give each argument once"),
                        );
                        ok = false;
                    }
                    Some(i) => bound[i] = Some((&a.value, n.span)),
                    None => {
                        let mut d = Diagnostic::error(n.span, format!("module `{}` has no argument `{}`", m.name.node, n.node))
                            .with_secondary(m.name.span, "module defined here");
                        d = match did_you_mean(&n.node, m.args.iter().map(|a| a.name.node.as_str())) {
                            Some(s) => d.with_help(format!("did you mean `{s}`?")),
                            None => d.with_help(format!(
                                "its arguments are {}",
                                m.args.iter().map(|a| a.name.node.as_str()).collect::<Vec<_>>().join(", ")
                            )),
                        };
                        self.error(d);
                        ok = false;
                    }
                },
            }
        }
        let mut inner = Scope::new(ScopeKind::Module);
        for (formal, actual) in m.args.iter().zip(&bound) {
            let tv = match actual {
                Some((e, _)) => self.expr(b, scope, e),
                None => match &formal.default {
                    Some(d) => {
                        // On the call stack, so a default that calls the
                        // module itself is a cycle, not endless expansion.
                        let mut empty = Scope::new(ScopeKind::Module);
                        self.call_stack.push((m.name.node.clone(), callee.span));
                        let tv = self.expr(b, &mut empty, d);
                        self.call_stack.pop();
                        tv
                    }
                    None => {
                        self.error(
                            Diagnostic::error(at, format!("missing argument `{}` in call to `{}`", formal.name.node, m.name.node))
                                .with_secondary(formal.name.span, "declared here")
                                .with_help(format!("pass it, e.g. `{}: ...`, or give it a default in the module", formal.name.node)),
                        );
                        None
                    }
                },
            };
            let tv = tv.and_then(|tv| self.check_ann(b, &inner, formal.ty.as_ref(), tv, &formal.name));
            match tv {
                Some(tv) => {
                    inner.values.insert(formal.name.node.clone(), tv);
                }
                None => ok = false,
            }
        }
        if !ok {
            return None;
        }
        if !m.weights.is_empty() {
            self.bind_weights(b, m, &mut inner)?;
        }
        for l in &m.lets {
            inner.lets.insert(l.name.node.clone(), LetSlot::Pending(l));
        }
        self.call_stack.push((m.name.node.clone(), callee.span));
        let r = self.expr(b, &mut inner, &m.result);
        self.call_stack.pop();
        r
    }
}
