//! Grid declarations: frequency and time grids, and the spectrum grid of
//! a time grid.

use super::*;

impl<'a> Checker<'a> {
    pub(super) fn grid_def(
        &mut self,
        name: &Spanned<String>,
        def: &'a Expr,
        known: &HashMap<String, ir::GridId>,
        grids: &[ir::Grid],
    ) -> Option<ir::Grid> {
        let ExprKind::Call { callee, args } = &def.node else {
            self.error(
                Diagnostic::error(def.span, "a grid is defined by `frequencies(...)` or `times(...)`")
                    .with_help("e.g. `grid f = frequencies(from: 20 Hz, to: 1024 Hz, step: 0.125 Hz)`"),
            );
            return None;
        };
        if callee.node == "spectrum" {
            return self.spectrum_grid(name, def.span, args, known, grids);
        }
        if callee.node == "index" {
            let [ast::Arg { name: None, value }] = args.as_slice() else {
                self.error(
                    Diagnostic::error(def.span, "`index` takes one number: the count of points")
                        .with_help("e.g. `grid classes = index(6)`"),
                );
                return None;
            };
            let n = self.const_count(value, "the number of points", 1)? as usize;
            return Some(ir::Grid { name: name.node.clone(), start: 0.0, step: 1.0, len: n, unit: String::new(), dims: vec![n] });
        }
        let (wanted, dims): (&[&str], &[Dim]) = match callee.node.as_str() {
            "frequencies" => (&["from", "to", "step"], &[Dim::FREQ, Dim::FREQ, Dim::FREQ]),
            "times" => (&["rate", "duration"], &[Dim::FREQ, Dim::TIME]),
            _ => {
                self.error(
                    Diagnostic::error(callee.span, format!("`{}` does not define a grid", callee.node))
                        .with_help("use `frequencies(from:, to:, step:)`, `times(rate:, duration:)`, `spectrum(t)` or `index(n)`"),
                );
                return None;
            }
        };
        let mut vals = vec![None; wanted.len()];
        for a in args {
            let Some(n) = &a.name else {
                self.error(Diagnostic::error(a.value.span, "grid arguments must be named").with_help(format!(
                    "write `{}(` {} `)`",
                    callee.node,
                    wanted.iter().map(|w| format!("{w}: ...")).collect::<Vec<_>>().join(", ")
                )));
                continue;
            };
            if args.iter().take_while(|b| !std::ptr::eq(*b, a)).any(|b| b.name.as_ref().is_some_and(|m| m.node == n.node)) {
                self.error(Diagnostic::error(n.span, format!("argument `{}` is given twice", n.node)).with_help("give each argument once"));
                continue;
            }
            let Some(i) = wanted.iter().position(|w| *w == n.node) else {
                let mut d = Diagnostic::error(n.span, format!("`{}` has no argument `{}`", callee.node, n.node));
                if let Some(s) = did_you_mean(&n.node, wanted.iter().copied()) {
                    d = d.with_help(format!("did you mean `{s}`?"));
                } else {
                    d = d.with_help(format!("its arguments are {}", wanted.join(", ")));
                }
                self.error(d);
                continue;
            };
            if let Some((x, dim)) = self.const_eval(&a.value) {
                if dim != dims[i] {
                    self.error(unit_mismatch(a.value.span, dims[i], dim, &format!("`{}` of `{}`", n.node, callee.node)));
                } else {
                    vals[i] = Some(x);
                }
            }
        }
        if let Some(i) = vals.iter().position(|v| v.is_none()) {
            if !args.iter().any(|a| a.name.as_ref().is_some_and(|n| n.node == wanted[i])) {
                self.error(
                    Diagnostic::error(def.span, format!("`{}` needs `{}`", callee.node, wanted[i]))
                        .with_help(format!("add `{}: ...`", wanted[i])),
                );
            }
            return None;
        }
        let v: Vec<f64> = vals.into_iter().flatten().collect();
        const MAX_POINTS: f64 = 1e9;
        let (start, step, len, unit) = if callee.node == "frequencies" {
            let (from, to, step) = (v[0], v[1], v[2]);
            if !(step > 0.0) || !(to >= from) || !from.is_finite() || !to.is_finite() {
                self.error(
                    Diagnostic::error(def.span, format!("empty or invalid grid `{}`: need from <= to and step > 0", name.node))
                        .with_help("check the bounds and the step"),
                );
                return None;
            }
            let n = ((to - from) / step * (1.0 + 1e-12)).floor() + 1.0;
            (from, step, n, "Hz")
        } else {
            let (rate, duration) = (v[0], v[1]);
            if !(rate > 0.0) || !(duration > 0.0) {
                self.error(
                    Diagnostic::error(def.span, format!("invalid grid `{}`: rate and duration must be positive", name.node))
                        .with_help("check the rate and the duration"),
                );
                return None;
            }
            let samples = rate * duration;
            if samples.round() < 1.0 || (samples - samples.round()).abs() > 1e-9 * samples {
                self.error(
                    Diagnostic::error(
                        def.span,
                        format!(
                            "invalid grid `{}`: rate × duration is {}, not a whole number of samples",
                            name.node,
                            (samples * 1e6).round() / 1e6
                        ),
                    )
                    .with_help(
                        "choose a duration that holds a whole number of samples at the rate, e.g. `times(rate: 4096 Hz, duration: 2 s)`",
                    ),
                );
                return None;
            }
            (0.0, 1.0 / rate, samples.round(), "s")
        };
        if !(len <= MAX_POINTS) {
            self.error(
                Diagnostic::error(def.span, format!("grid `{}` would have {len:e} points", name.node))
                    .with_help("grids are limited to 1e9 points; use a coarser step"),
            );
            return None;
        }
        Some(ir::Grid { name: name.node.clone(), start, step, len: len as usize, unit: unit.into(), dims: vec![len as usize] })
    }

    /// `grid f = spectrum(t)`: the n/2 + 1 rfft bins of time grid `t`.
    pub(super) fn spectrum_grid(
        &mut self,
        name: &Spanned<String>,
        at: Span,
        args: &[ast::Arg],
        known: &HashMap<String, ir::GridId>,
        grids: &[ir::Grid],
    ) -> Option<ir::Grid> {
        let time = match args {
            [ast::Arg { name: None, value }] => match &value.node {
                ExprKind::Name(n) => match known.get(n).map(|g| &grids[g.0 as usize]) {
                    Some(g) if g.unit == "s" => Some(g),
                    Some(_) => {
                        self.error(
                            Diagnostic::error(value.span, format!("`{}` is not a time grid", n))
                                .with_help("`spectrum` takes a grid declared with `times(rate:, duration:)`"),
                        );
                        return None;
                    }
                    None => None,
                },
                _ => None,
            },
            _ => None,
        };
        let Some(t) = time else {
            self.error(
                Diagnostic::error(at, "`spectrum` takes the name of a time grid declared before it")
                    .with_help("e.g. `grid t = times(rate: 4096 Hz, duration: 2 s)` then `grid f = spectrum(t)`"),
            );
            return None;
        };
        let n = t.len;
        Some(ir::Grid {
            name: name.node.clone(),
            start: 0.0,
            step: 1.0 / (n as f64 * t.step),
            len: n / 2 + 1,
            unit: "Hz".into(),
            dims: vec![n / 2 + 1],
        })
    }
}
