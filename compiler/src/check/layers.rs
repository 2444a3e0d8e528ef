//! Checking `learned` components: weight declarations (shapes and
//! initialisers) and the layer builtins (`dense`, the convolutions and
//! pooling of `convs`, reshaping), which lower to [`TensorOp`] library calls.
//!
//! Arrays of layers live on tensor grids: index grids whose `dims` give the
//! row-major shape (`[channels, positions]` for convolutions). A real array
//! over a physical grid (a time series) is one channel.

use super::{Checker, Scope, Tv};
use crate::front::diagnostics::{did_you_mean, Diagnostic};
use crate::front::source::{Span, Spanned};
use crate::front::syntax::ast::{self, Expr, ExprKind, ModuleDef, WeightDecl};
use crate::front::units::Dim;
use crate::ir::builder::Builder;
use crate::ir::{self, Elem, GridId, InputRole, Op, Rows, Shape, TensorOp, Ty};
use num_complex::Complex64 as C64;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal, Uniform};

/// The layer builtins (their usage lines are in `BUILTINS`).
pub const LAYERS: &[&str] = &[
    "dense",
    "conv1d",
    "conv_transpose1d",
    "conv2d",
    "upsample",
    "max_pool",
    "avg_pool",
    "max_pool2d",
    "avg_pool2d",
    "global_avg_pool",
    "dropout",
    "randn",
    "reshape",
    "slice",
    "stack",
];

/// Initialisers a `weight` may use.
const INITIALISERS: &[&str] = &["zeros", "ones", "normal", "uniform", "glorot", "he"];

/// Largest weight tensor (elements): 2^28 f64 values, 2 GiB.
const MAX_WEIGHT_ELEMENTS: usize = 1 << 28;

impl<'a> Checker<'a> {
    /// The tensor grid of shape `dims` (an existing one with the same
    /// dims, or a new one named like `16x128`).
    pub(super) fn tensor_grid(b: &mut Builder, dims: &[usize]) -> GridId {
        if let Some(i) = b.func.grids.iter().position(|g| g.unit.is_empty() && g.dims == dims) {
            return GridId(i as u32);
        }
        let name = dims.iter().map(|d| d.to_string()).collect::<Vec<_>>().join("x");
        b.func.grids.push(ir::Grid { name, start: 0.0, step: 1.0, len: dims.iter().product(), unit: String::new(), dims: dims.to_vec() });
        GridId(b.func.grids.len() as u32 - 1)
    }

    /// Binds the weights of learned component `m` in `inner`: each weight is
    /// a trainable scene input named `component.weight`, created (and
    /// initialised) on the component's first call and shared by later ones.
    pub(super) fn bind_weights(&mut self, b: &mut Builder, m: &'a ModuleDef, inner: &mut Scope<'a>) -> Option<()> {
        let mut ok = true;
        for w in &m.weights {
            if !m.learned {
                self.error(
                    Diagnostic::error(w.span, format!("module `{}` declares a weight", m.name.node))
                        .with_secondary(m.name.span, "a plain module")
                        .with_help(format!("write `learned {}(...)` to give it trainable weights", m.name.node)),
                );
                ok = false;
                continue;
            }
            let full = format!("{}.{}", m.name.node, w.name.node);
            let index = match b.func.inputs.iter().position(|i| i.name == full) {
                Some(i) => i,
                None => {
                    let Some(info) = self.weight_input(b, w, &full) else {
                        ok = false;
                        continue;
                    };
                    b.func.inputs.push(info);
                    b.func.inputs.len() - 1
                }
            };
            let v = b.push(Op::Input(index as u32));
            inner.values.insert(w.name.node.clone(), Tv { v, dim: Dim::NONE });
        }
        ok.then_some(())
    }

    fn weight_input(&mut self, b: &mut Builder, w: &'a WeightDecl, full: &str) -> Option<ir::InputInfo> {
        if w.dims.is_empty() {
            self.error(
                Diagnostic::error(w.span, format!("weight `{}` has no dimensions", w.name.node))
                    .with_help("give its shape, e.g. `weight b: [16] = zeros`"),
            );
            return None;
        }
        let mut dims = Vec::new();
        for d in &w.dims {
            dims.push(self.const_count(d, "a weight dimension", 1)? as usize);
        }
        let len = dims.iter().try_fold(1usize, |acc, d| acc.checked_mul(*d)).filter(|n| *n <= MAX_WEIGHT_ELEMENTS);
        let Some(len) = len else {
            self.error(
                Diagnostic::error(w.span, format!("weight `{}` of shape {dims:?} is too large", w.name.node))
                    .with_help(format!("weights are limited to {MAX_WEIGHT_ELEMENTS} elements")),
            );
            return None;
        };
        let data = self.initial_values(w, &dims, full)?;
        debug_assert_eq!(data.len(), len);
        let grid = Self::tensor_grid(b, &dims);
        Some(ir::InputInfo {
            name: full.to_string(),
            ty: Ty { elem: Elem::Real, shape: Shape::Grid(grid) },
            scale: 1.0,
            unit: String::new(),
            default: Some(data.into_iter().map(|x| C64::new(x, 0.0)).collect()),
            role: InputRole::Weight,
        })
    }

    /// Draws the initial values of `w` (shape `dims`). Fan-in and fan-out
    /// follow PyTorch's convention (`[out, in, taps...]`: fan-in = in·taps,
    /// fan-out = out·taps): Glorot/Xavier uniform with limit
    /// √(6/(fan_in + fan_out)) (Glorot & Bengio 2010) and He/Kaiming normal
    /// with standard deviation √(2/fan_in) (He et al. 2015). The default
    /// seed is a hash of the weight's full name, so every weight differs
    /// and a file always initialises the same way.
    fn initial_values(&mut self, w: &'a WeightDecl, dims: &[usize], full: &str) -> Option<Vec<f64>> {
        let (name, args): (Spanned<String>, &[ast::Arg]) = match &w.init.node {
            ExprKind::Name(n) => (Spanned::new(n.clone(), w.init.span), &[]),
            ExprKind::Call { callee, args } => (callee.clone(), args.as_slice()),
            _ => {
                self.error(
                    Diagnostic::error(w.init.span, "a weight is initialised by name")
                        .with_help(format!("use one of {}", INITIALISERS.join(", "))),
                );
                return None;
            }
        };
        if !INITIALISERS.contains(&name.node.as_str()) {
            let d = Diagnostic::error(name.span, format!("unknown initialiser `{}`", name.node)).with_label("not an initialiser");
            self.error(match did_you_mean(&name.node, INITIALISERS.iter().copied()) {
                Some(s) => d.with_help(format!("did you mean `{s}`?")),
                None => d.with_help(format!("use one of {}", INITIALISERS.join(", "))),
            });
            return None;
        }
        let mut seed = full.bytes().fold(0xcbf2_9ce4_8422_2325u64, |h, c| (h ^ c as u64).wrapping_mul(0x0000_0100_0000_01b3));
        let mut scale = None;
        for a in args {
            let Some(n) = &a.name else {
                self.error(
                    Diagnostic::error(a.value.span, "initialiser arguments are named").with_help("e.g. `normal(std: 0.02, seed: 1)`"),
                );
                return None;
            };
            match (n.node.as_str(), name.node.as_str()) {
                ("seed", _) => seed = self.const_count(&a.value, "a seed", 0)? as u64,
                ("std", "normal") | ("limit", "uniform") => {
                    let (x, dim) = self.const_eval(&a.value)?;
                    if !dim.is_none() || !(x >= 0.0) || !x.is_finite() {
                        self.error(
                            Diagnostic::error(a.value.span, format!("`{}` must be a finite dimensionless number ≥ 0", n.node))
                                .with_help("e.g. `normal(std: 0.02)`"),
                        );
                        return None;
                    }
                    scale = Some(x);
                }
                _ => {
                    let allowed = match name.node.as_str() {
                        "normal" => "`std` and `seed`",
                        "uniform" => "`limit` and `seed`",
                        _ => "`seed`",
                    };
                    self.error(
                        Diagnostic::error(n.span, format!("`{}` has no argument `{}`", name.node, n.node))
                            .with_help(format!("it takes {allowed}")),
                    );
                    return None;
                }
            }
        }
        let taps: usize = dims.iter().skip(2).product();
        let (fan_in, fan_out) = match dims {
            [n] => (*n, *n),
            [out, inp, ..] => (inp * taps, out * taps),
            [] => (1, 1),
        };
        let len: usize = dims.iter().product();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        let normal = |rng: &mut rand_pcg::Pcg64Mcg, std: f64| -> Vec<f64> {
            (0..len).map(|_| std * <StandardNormal as Distribution<f64>>::sample(&StandardNormal, rng)).collect()
        };
        let uniform = |rng: &mut rand_pcg::Pcg64Mcg, limit: f64| -> Vec<f64> {
            match Uniform::new_inclusive(-limit, limit) {
                Ok(u) => (0..len).map(|_| u.sample(rng)).collect(),
                Err(_) => vec![0.0; len],
            }
        };
        Some(match name.node.as_str() {
            "zeros" => vec![0.0; len],
            "ones" => vec![1.0; len],
            "normal" => match scale {
                Some(s) => normal(&mut rng, s),
                None => {
                    self.error(Diagnostic::error(w.init.span, "`normal` needs `std`").with_help("e.g. `normal(std: 0.02)`"));
                    return None;
                }
            },
            "uniform" => match scale {
                Some(s) => uniform(&mut rng, s),
                None => {
                    self.error(Diagnostic::error(w.init.span, "`uniform` needs `limit`").with_help("e.g. `uniform(limit: 0.1)`"));
                    return None;
                }
            },
            "glorot" => uniform(&mut rng, (6.0 / (fan_in + fan_out) as f64).sqrt()),
            _ => normal(&mut rng, (2.0 / fan_in as f64).sqrt()),
        })
    }

    /// A constant whole number ≥ `min` (a size, stride or seed).
    pub(super) fn const_count(&mut self, e: &'a Expr, what: &str, min: u32) -> Option<u32> {
        let (x, dim) = self.const_eval(e)?;
        if !dim.is_none() || x.fract() != 0.0 || !(x >= min as f64) || !(x < 2f64.powi(31)) {
            self.error(
                Diagnostic::error(e.span, format!("{what} must be a whole number ≥ {min}"))
                    .with_label(format!("this is {x}{}", if dim.is_none() { String::new() } else { format!(" {dim}") }))
                    .with_help("write a whole number without a unit"),
            );
            return None;
        }
        Some(x as u32)
    }

    /// A whole number ≥ `min` known at compile time, evaluated in `scope`:
    /// unlike [`Checker::const_count`], it may name a module argument bound
    /// to a constant (`module at(p, i) { sum(slice(p, i, 1)) }`).
    fn scoped_count(&mut self, b: &mut Builder, scope: &mut Scope<'a>, e: &'a Expr, what: &str, min: u32) -> Option<u32> {
        let tv = self.expr(b, scope, e)?;
        match b.evaluate_constant(tv.v) {
            Some(c) if c.im == 0.0 && b.ty(tv.v).shape == Shape::Scalar => {
                let x = c.re;
                if !tv.dim.is_none() || x.fract() != 0.0 || !(x >= min as f64) || !(x < 2f64.powi(31)) {
                    self.error(
                        Diagnostic::error(e.span, format!("{what} must be a whole number ≥ {min}"))
                            .with_label(format!("this is {x}"))
                            .with_help("write a whole number without a unit"),
                    );
                    return None;
                }
                Some(x as u32)
            }
            _ => {
                self.error(
                    Diagnostic::error(e.span, format!("{what} must be known when the scene compiles"))
                        .with_label("not a constant")
                        .with_help("use a number, a named constant, a knob, or a module argument given one of these"),
                );
                None
            }
        }
    }

    /// The layer builtins: arguments checked, then lowered here or in `convs`.
    pub(super) fn layer_call(
        &mut self,
        b: &mut Builder,
        scope: &mut Scope<'a>,
        callee: &'a Spanned<String>,
        args: &'a [ast::Arg],
        at: Span,
    ) -> Option<Tv> {
        let name = callee.node.as_str();
        let (named, positional): (Vec<&'a ast::Arg>, Vec<&'a ast::Arg>) = args.iter().partition(|a| a.name.is_some());
        let allowed: &[&str] = match name {
            "conv1d" | "conv2d" => &["stride", "padding", "dilation"],
            "conv_transpose1d" => &["stride", "padding", "output_padding", "dilation"],
            "max_pool" | "avg_pool" | "max_pool2d" | "avg_pool2d" => &["window", "stride"],
            _ => &[],
        };
        let mut opts: Vec<(&str, u32)> = Vec::new();
        for a in named {
            let n = a.name.as_ref().expect("partitioned on names");
            if !allowed.contains(&n.node.as_str()) {
                let d = Diagnostic::error(n.span, format!("`{name}` has no argument `{}`", n.node));
                self.error(match (did_you_mean(&n.node, allowed.iter().copied()), allowed.is_empty()) {
                    (Some(s), _) => d.with_help(format!("did you mean `{s}`?")),
                    (None, true) => d.with_help(format!("`{name}` takes positional arguments only")),
                    (None, false) => d.with_help(format!("its named arguments are {}", allowed.join(", "))),
                });
                return None;
            }
            let min = if n.node == "padding" || n.node == "output_padding" { 0 } else { 1 };
            opts.push((
                allowed.iter().find(|x| **x == n.node).expect("checked above"),
                self.const_count(&a.value, &format!("`{}`", n.node), min)?,
            ));
        }
        let opt = |k: &str| opts.iter().find(|(n, _)| *n == k).map(|(_, v)| *v);
        let (lo, hi) = match name {
            "dense" | "conv1d" | "conv2d" | "conv_transpose1d" => (2, 3),
            "upsample" => (2, 2),
            "reshape" => (2, 4),
            "slice" => (3, 3),
            "max_pool" | "avg_pool" | "max_pool2d" | "avg_pool2d" => (if opt("window").is_some() { 1 } else { 2 }, 2),
            "dropout" => (2, 2),
            "stack" => (1, usize::MAX),
            _ => (1, 1),
        };
        if positional.len() < lo || positional.len() > hi {
            let usage = super::BUILTINS.iter().find(|l| l.0 == name).map(|l| l.1).unwrap_or_default();
            self.error(
                Diagnostic::error(
                    at,
                    format!(
                        "`{name}` takes {lo}{} positional arguments, but {} were given",
                        match hi {
                            usize::MAX => " or more".to_string(),
                            hi if hi > lo => format!(" to {hi}"),
                            _ => String::new(),
                        },
                        positional.len()
                    ),
                )
                .with_help(format!("usage: {usage}")),
            );
            return None;
        }
        if name == "randn" {
            return self.randn(b, scope, positional[0]);
        }
        if name == "reshape" {
            let tv = self.expr(b, scope, &positional[0].value)?;
            let x = self.layer_operand(b, (tv, positional[0].value.span), name)?;
            return self.reshape(b, scope, x, &positional[1..]);
        }
        let window_arg =
            if matches!(name, "max_pool" | "avg_pool" | "max_pool2d" | "avg_pool2d" | "dropout" | "upsample") && positional.len() == 2 {
                positional.get(1).copied()
            } else {
                None
            };
        let array_args = if window_arg.is_some() || name == "slice" { &positional[..1] } else { &positional[..] };
        let mut vals = Vec::new();
        for a in array_args {
            let tv = self.expr(b, scope, &a.value)?;
            vals.push(self.layer_operand(b, (tv, a.value.span), name)?);
        }
        let x = vals[0];
        match name {
            "dense" => self.dense(b, x, vals[1], vals.get(2).copied()),
            "conv1d" | "conv2d" => {
                let conv = (opt("stride").unwrap_or(1), opt("padding").unwrap_or(0), opt("dilation").unwrap_or(1));
                self.conv(b, x, vals[1], vals.get(2).copied(), conv, if name == "conv1d" { 1 } else { 2 })
            }
            "conv_transpose1d" => {
                let o = |k| opt(k).unwrap_or(if k == "stride" || k == "dilation" { 1 } else { 0 });
                let conv = (o("stride"), o("padding"), o("output_padding"), o("dilation"));
                self.conv_transpose1d(b, x, vals[1], vals.get(2).copied(), conv, at)
            }
            "upsample" => {
                let factor = self.const_count(&window_arg.expect("upsample takes two arguments").value, "an upsampling factor", 1)?;
                self.upsample(b, x, factor)
            }
            "stack" => self.stack(b, &vals),
            "slice" => {
                let from = self.scoped_count(b, scope, &positional[1].value, "the first channel of `slice`", 0)?;
                let count = self.scoped_count(b, scope, &positional[2].value, "the channel count of `slice`", 1)?;
                self.slice(b, x, from, count, at)
            }
            "dropout" => {
                let rate_arg = window_arg.expect("dropout takes two arguments");
                self.dropout(b, x, rate_arg)
            }
            "max_pool" | "avg_pool" | "max_pool2d" | "avg_pool2d" => {
                let window = match (window_arg, opt("window")) {
                    (Some(a), None) => self.const_count(&a.value, "a pooling window", 1)?,
                    (None, Some(w)) => w,
                    _ => {
                        self.error(
                            Diagnostic::error(at, "the pooling window is given twice").with_help("pass it once, e.g. `max_pool(x, 4)`"),
                        );
                        return None;
                    }
                };
                let stride = opt("stride").unwrap_or(window);
                let rank = if name.ends_with("2d") { 2 } else { 1 };
                self.pool(b, x, (window, stride), name.starts_with("max"), rank)
            }
            _ => {
                let (c, n) = channels(b, x.0);
                let grid = Self::tensor_grid(b, &[c as usize]);
                let s = b.emit(Op::Tensor(TensorOp::SumRows { rows: c, cols: n }, grid, x.0.v, x.0.v));
                Some(Tv { v: b.scale(s, 1.0 / n as f64), dim: Dim::NONE })
            }
        }
    }

    /// Layers take dimensionless real arrays.
    fn layer_operand(&mut self, b: &Builder, (tv, span): (Tv, Span), name: &str) -> Option<(Tv, Span)> {
        let ty = b.ty(tv.v);
        let problem = if ty.shape == Shape::Scalar {
            Some("a scalar".to_string())
        } else if ty.elem != Elem::Real {
            Some(b.func.fmt_ty(ty))
        } else if !tv.dim.is_none() {
            Some(format!("in {}", tv.dim))
        } else {
            None
        };
        match problem {
            None => Some((tv, span)),
            Some(p) => {
                self.error(
                    Diagnostic::error(span, format!("`{name}` needs a dimensionless real array here, but this is {p}"))
                        .with_help("layers work on real arrays without units: whiten or divide by a reference scale first"),
                );
                None
            }
        }
    }

    /// Checks that `v` has shape `want` (a weight or bias).
    pub(super) fn expect_dims(&mut self, b: &Builder, (tv, span): (Tv, Span), want: &[usize], what: &str, layer: &str) -> Option<()> {
        let have = dims_of(b, tv);
        if have == want {
            return Some(());
        }
        let fmt = |d: &[usize]| format!("[{}]", d.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(", "));
        self.error(
            Diagnostic::error(span, format!("{what} of `{layer}` has shape {}, but the layer needs {}", fmt(&have), fmt(want)))
                .with_label(format!("shape {}", fmt(&have)))
                .with_help(format!("declare it as `weight NAME: {} = ...`", fmt(want))),
        );
        None
    }

    fn dense(&mut self, b: &mut Builder, x: (Tv, Span), w: (Tv, Span), bias: Option<(Tv, Span)>) -> Option<Tv> {
        let k = b.func.len_of(b.ty(x.0.v).shape);
        let wd = dims_of(b, w.0);
        let m = if wd.len() == 2 { wd[0] } else { 0 };
        self.expect_dims(b, w, &[m.max(1), k], "the weight", "dense")?;
        if let Some(bias) = bias {
            self.expect_dims(b, bias, &[m], "the bias", "dense")?;
        }
        let grid = Self::tensor_grid(b, &[m]);
        let y = b.emit(Op::Tensor(TensorOp::MatVec { m: m as u32, k: k as u32 }, grid, w.0.v, x.0.v));
        let v = match bias {
            Some(bias) => b.add(y, bias.0.v),
            None => y,
        };
        Some(Tv { v, dim: Dim::NONE })
    }

    /// `reshape(x, g)`: the elements of x, in order, as an array over grid
    /// `g` (a time grid, say), which must have as many points; or
    /// `reshape(x, c, n)`: as a tensor `[c, n]` (channels × positions).
    fn reshape(&mut self, b: &mut Builder, scope: &mut Scope<'a>, x: (Tv, Span), shape: &[&'a ast::Arg]) -> Option<Tv> {
        let n = b.func.len_of(b.ty(x.0.v).shape);
        let target = match shape {
            [grid] if matches!(grid.value.node, ExprKind::Name(_)) => {
                let target = self.expr(b, scope, &grid.value)?;
                let Op::GridCoord(g) = b.func.insts[target.v.index()].op else {
                    self.error(
                        Diagnostic::error(grid.value.span, "the second argument of `reshape` must be the name of a grid").with_help(
                            "e.g. `reshape(y, t)` puts the 4096 values of y on time grid t, `reshape(y, 16, 32)` makes it [16, 32]",
                        ),
                    );
                    return None;
                };
                (g, format!("grid `{}`", b.func.grids[g.0 as usize].name))
            }
            dims => {
                let mut sizes = Vec::new();
                for d in dims {
                    sizes.push(self.const_count(&d.value, "a dimension of `reshape`", 1)? as usize);
                }
                (Self::tensor_grid(b, &sizes), format!("shape {sizes:?}"))
            }
        };
        let (g, what) = target;
        let want = b.func.grids[g.0 as usize].len;
        if n != want {
            self.error(
                Diagnostic::error(x.1, format!("`reshape` needs as many values as {what} holds ({want}), but this has {n}"))
                    .with_label(format!("{n} values"))
                    .with_help("the target and the array must hold the same number of elements"),
            );
            return None;
        }
        let rows = Rows { rows: 1, cols: n as u32, from: 0, count: 1 };
        Some(Tv { v: b.emit(Op::Tensor(TensorOp::TakeRows(rows), g, x.0.v, x.0.v)), dim: Dim::NONE })
    }

    /// `slice(x, from, count)`: channels `from .. from + count` of x `[c, n]`
    /// (`[count, n]`), or elements of a one-dimensional x; the inverse of
    /// `stack`. Lowers to `TakeRows`.
    fn slice(&mut self, b: &mut Builder, x: (Tv, Span), from: u32, count: u32, at: Span) -> Option<Tv> {
        let dims = dims_of(b, x.0);
        let (rows, cols, out) = match dims.as_slice() {
            [c, n] => (*c as u32, *n as u32, vec![count as usize, *n]),
            d => (d.iter().product::<usize>() as u32, 1, vec![count as usize]),
        };
        if from as u64 + count as u64 > rows as u64 {
            self.error(
                Diagnostic::error(at, format!("`slice` takes channels {from}..{} but the array has {rows}", from as u64 + count as u64))
                    .with_label(format!("{rows} channels"))
                    .with_help("the first channel is 0: `slice(x, 0, 16)` takes the first 16"),
            );
            return None;
        }
        let grid = Self::tensor_grid(b, &out);
        let r = Rows { rows, cols, from, count };
        Some(Tv { v: b.emit(Op::Tensor(TensorOp::TakeRows(r), grid, x.0.v, x.0.v)), dim: Dim::NONE })
    }

    /// `stack(a, b, ...)`: the channels of each argument one after the
    /// other, `[Σ channels, n]`; every argument has `n` positions. Lowers to
    /// one `PlaceRows` per argument, summed.
    fn stack(&mut self, b: &mut Builder, parts: &[(Tv, Span)]) -> Option<Tv> {
        let shapes: Vec<(u32, u32)> = parts.iter().map(|p| channels(b, p.0)).collect();
        let cols = shapes[0].1;
        if let Some((i, &(_, n))) = shapes.iter().enumerate().find(|(_, s)| s.1 != cols) {
            self.error(
                Diagnostic::error(parts[i].1, format!("`stack` needs arrays of the same length, but this one has {n} positions"))
                    .with_label(format!("{n} positions"))
                    .with_secondary(parts[0].1, format!("the first has {cols}"))
                    .with_help("pool or resample the arguments to one length first"),
            );
            return None;
        }
        let rows: u32 = shapes.iter().map(|s| s.0).sum();
        let grid = Self::tensor_grid(b, &[rows as usize, cols as usize]);
        let mut from = 0;
        let mut sum = None;
        for (part, (count, _)) in parts.iter().zip(&shapes) {
            let r = Rows { rows, cols, from, count: *count };
            let placed = b.emit(Op::Tensor(TensorOp::PlaceRows(r), grid, part.0.v, part.0.v));
            sum = Some(match sum {
                Some(s) => b.add(s, placed),
                None => placed,
            });
            from += count;
        }
        Some(Tv { v: sum.expect("at least one argument"), dim: Dim::NONE })
    }

    /// `dropout(x, rate)`: `x` times a mask input (see [`InputRole::DropoutMask`]),
    /// all ones unless a trainer binds one.
    fn dropout(&mut self, b: &mut Builder, x: (Tv, Span), rate: &'a ast::Arg) -> Option<Tv> {
        let (p, dim) = self.const_eval(&rate.value)?;
        if !dim.is_none() || !(0.0..1.0).contains(&p) {
            self.error(
                Diagnostic::error(rate.value.span, format!("the dropout rate must be a number in [0, 1), found {p}"))
                    .with_help("e.g. `dropout(h, 0.2)` zeroes a fifth of the values while training"),
            );
            return None;
        }
        let owner = self.call_stack.last().map(|(n, _)| format!("{n}.")).unwrap_or_default();
        let k = b.func.inputs.iter().filter(|i| matches!(i.role, InputRole::DropoutMask(_))).count() + 1;
        let ty = b.ty(x.0.v);
        let len = b.func.len_of(ty.shape);
        b.func.inputs.push(ir::InputInfo {
            name: format!("{owner}dropout{k}"),
            ty,
            scale: 1.0,
            unit: String::new(),
            default: Some(vec![C64::new(1.0, 0.0); len]),
            role: InputRole::DropoutMask(p),
        });
        let mask = b.push(Op::Input(b.func.inputs.len() as u32 - 1));
        Some(Tv { v: b.mul(x.0.v, mask), dim: Dim::NONE })
    }

    /// `randn(n)` or `randn(g)`: standard normal noise, `n` values (a
    /// tensor `[n]`) or one per point of grid `g`, as an input (see
    /// [`InputRole::Noise`]): zeros unless a trainer or sampler binds a
    /// fresh draw. The reparameterisation trick of a variational
    /// autoencoder: `mu + exp(0.5 * logvar) * randn(8)`.
    fn randn(&mut self, b: &mut Builder, scope: &mut Scope<'a>, arg: &'a ast::Arg) -> Option<Tv> {
        let named_grid = match &arg.value.node {
            ExprKind::Name(_) => {
                let v = self.expr(b, scope, &arg.value)?.v;
                match b.func.insts[v.index()].op {
                    Op::GridCoord(g) => Some(g),
                    _ => None,
                }
            }
            _ => None,
        };
        let grid = match named_grid {
            Some(g) => g,
            None => {
                let n = self.const_count(&arg.value, "the number of values of `randn`", 1)?;
                Self::tensor_grid(b, &[n as usize])
            }
        };
        let owner = self.call_stack.last().map(|(n, _)| format!("{n}.")).unwrap_or_default();
        let k = b.func.inputs.iter().filter(|i| i.role == InputRole::Noise).count() + 1;
        let ty = Ty { elem: Elem::Real, shape: Shape::Grid(grid) };
        let len = b.func.len_of(ty.shape);
        b.func.inputs.push(ir::InputInfo {
            name: format!("{owner}noise{k}"),
            ty,
            scale: 1.0,
            unit: String::new(),
            default: Some(vec![C64::new(0.0, 0.0); len]),
            role: InputRole::Noise,
        });
        Some(Tv { v: b.push(Op::Input(b.func.inputs.len() as u32 - 1)), dim: Dim::NONE })
    }
}

/// The tensor dims of an array (`[len]` for a physical grid).
pub(super) fn dims_of(b: &Builder, tv: Tv) -> Vec<usize> {
    match b.ty(tv.v).shape {
        Shape::Grid(g) => b.func.grids[g.0 as usize].dims.clone(),
        Shape::Scalar => vec![],
    }
}

/// `(channels, positions)` of an array: `[c, n]` tensors, and anything
/// else as one channel of all its elements.
pub(super) fn channels(b: &Builder, tv: Tv) -> (u32, u32) {
    match dims_of(b, tv).as_slice() {
        [c, n] => (*c as u32, *n as u32),
        d => (1, d.iter().product::<usize>() as u32),
    }
}

/// Whether `name` is a layer builtin.
pub(super) fn is_layer(name: &str) -> bool {
    LAYERS.contains(&name)
}
