//! Name resolution, type/shape/unit checking and lowering to IR, in one
//! walk over the AST (the "elaborator").
//!
//! Modules are instantiated at each call site with the types of their
//! arguments (like templates), so a module's body is checked with concrete
//! shapes and units, and modules no output reaches are never lowered.
//! Definitions inside a scene or module are order-independent; a name is
//! elaborated the first time it is used, which is also where cycles are
//! caught. Every error is reported with a span and checking continues, so
//! one run shows every problem.

use crate::builder::Builder;
use crate::diagnostics::{did_you_mean, Diagnostic};
use crate::ir::{self, BinOp as IrBin, Elem, Op, Precision, Reduce, Shape, Ty, UnOp, Value};
use crate::source::{Span, Spanned};
use crate::syntax::ast::{self, BinOp, ElemAnn, Expr, ExprKind, Item, LetDecl, ModuleDef, SceneDef, SceneStmt, TypeAnn, UnitExpr};
use crate::units::{self, Dim, Ratio};
use num_complex::Complex64 as C64;
use std::collections::{HashMap, HashSet};

mod layers;

/// A physical constant available by name in every expression.
pub struct Constant {
    /// Name in source.
    pub name: &'static str,
    /// Value in base units.
    pub value: f64,
    /// Dimension.
    pub dim: Dim,
    /// What it is, with its source.
    pub doc: &'static str,
}

const S_PER_MSUN: Dim = Dim([Ratio::int(1), Ratio::int(-1), Ratio::ZERO]);
const M_PER_MSUN: Dim = Dim([Ratio::ZERO, Ratio::int(-1), Ratio::int(1)]);
const M_PER_S: Dim = Dim([Ratio::int(-1), Ratio::ZERO, Ratio::int(1)]);

/// Named constants (values as in LALConstants.h, LALSuite).
pub const CONSTANTS: &[Constant] = &[
    Constant { name: "pi", value: std::f64::consts::PI, dim: Dim::NONE, doc: "π" },
    Constant { name: "MTSUN", value: 4.925_490_947_641_267e-6, dim: S_PER_MSUN, doc: "solar mass in seconds, G Msun / c^3 (LAL_MTSUN_SI)" },
    Constant { name: "MRSUN", value: 1.476_625_038_050_124_7e3, dim: M_PER_MSUN, doc: "solar mass in metres, G Msun / c^2 (LAL_MRSUN_SI)" },
    Constant { name: "C", value: 299_792_458.0, dim: M_PER_S, doc: "speed of light in m/s (LAL_C_SI)" },
    Constant { name: "MPC_M", value: units::MPC_IN_M, dim: Dim::LENGTH, doc: "one megaparsec in metres (LAL_PC_SI × 1e6)" },
    Constant { name: "MPC_S", value: units::MPC_IN_M / 299_792_458.0, dim: Dim::TIME, doc: "one megaparsec in light-seconds (Mpc / c)" },
];

/// Names callable as builtins, with a one-line description (used by
/// diagnostics and the REPL's completion).
pub const BUILTINS: &[(&str, &str)] = &[
    ("sqrt", "sqrt(x): square root"),
    ("cbrt", "cbrt(x): cube root"),
    ("exp", "exp(x): exponential of a dimensionless real or complex x"),
    ("log", "log(x): natural logarithm of a dimensionless x"),
    ("sin", "sin(x): sine of a dimensionless x"),
    ("cos", "cos(x): cosine of a dimensionless x"),
    ("tan", "tan(x): tangent of a dimensionless x"),
    ("tanh", "tanh(x): hyperbolic tangent of a dimensionless x"),
    ("atan2", "atan2(y, x): angle of the point (x, y), y and x in the same unit"),
    ("abs", "abs(x): absolute value, or modulus of a complex x"),
    ("min", "min(a, b): elementwise minimum, or min(x): minimum over the grid"),
    ("max", "max(a, b): elementwise maximum, or max(x): maximum over the grid"),
    ("clamp", "clamp(x, lo, hi): x limited to lo..hi"),
    ("re", "re(z): real part"),
    ("im", "im(z): imaginary part"),
    ("conj", "conj(z): complex conjugate"),
    ("abs2", "abs2(z): squared modulus |z|^2"),
    ("cis", "cis(theta): e^(i theta) for a dimensionless real theta"),
    ("complex", "complex(re, im): a complex number from two reals of the same unit"),
    ("select", "select(cond, a, b): a where cond holds, else b"),
    ("masked_div", "masked_div(a, s): a / s where s is positive and finite, 0 elsewhere (in values and gradients), e.g. dividing by a PSD that is 0, inf or NaN outside its band"),
    ("sum", "sum(x): sum over the grid of x"),
    ("mean", "mean(x): mean over the grid of x"),
    ("rfft", "rfft(x, f): Fourier transform dt·Σ x_j e^(-2πi f t_j) of a real x over a time grid onto its spectrum grid f"),
    ("irfft", "irfft(X, t): inverse of rfft: df·Σ over the Hermitian spectrum X, a real array over the time grid t"),
    ("spacing", "spacing(g): the step between points of grid g (dt of a time grid, df of a frequency grid)"),
    ("dense", "dense(x, w, b): w·x + b for a weight w of shape [m, k], any array x of k elements and an optional bias b [m]"),
    (
        "conv1d",
        "conv1d(x, w, b, stride: 1, padding: 0, dilation: 1): convolution of x [c_in, n] (or a time series) with w [c_out, c_in, k], optional bias b [c_out]",
    ),
    ("max_pool", "max_pool(x, window, stride: window): the largest value of each window of x [channels, n]"),
    ("avg_pool", "avg_pool(x, window, stride: window): the mean of each window of x [channels, n]"),
    ("global_avg_pool", "global_avg_pool(x): the mean over positions of x [channels, n], one value per channel"),
    ("stack", "stack(a, b, ...): the channels of a, b, ... one after the other, one array [channels, n] (every argument has n positions)"),
    ("dropout", "dropout(x, rate): x with each value zeroed with probability rate and the rest scaled by 1/(1 - rate) while training; x itself otherwise"),
    ("index", "index(n): a grid of n points 0, 1, ..., n-1, e.g. classes (in `grid` declarations)"),
    ("frequencies", "frequencies(from:, to:, step:): a frequency grid (in `grid` declarations)"),
    ("spectrum", "spectrum(t): the grid of rfft bins of time grid t, 0 Hz to the Nyquist frequency (in `grid` declarations)"),
    ("times", "times(rate:, duration:): a time grid (in `grid` declarations)"),
];

/// A checked, lowered value: IR value and physical dimension.
#[derive(Clone, Copy, Debug)]
struct Tv {
    v: Value,
    dim: Dim,
}

enum LetSlot<'a> {
    Pending(&'a LetDecl),
    Busy(Span),
    Done(Option<Tv>),
}

#[derive(Clone, Copy, PartialEq)]
enum ScopeKind {
    Scene,
    Module,
    Const,
}

struct Scope<'a> {
    kind: ScopeKind,
    values: HashMap<String, Tv>,
    grids: HashMap<String, ir::GridId>,
    lets: HashMap<String, LetSlot<'a>>,
    /// Names whose declaration failed (already reported): uses stay silent.
    poisoned: HashSet<String>,
}

impl<'a> Scope<'a> {
    fn new(kind: ScopeKind) -> Self {
        Scope { kind, values: HashMap::new(), grids: HashMap::new(), lets: HashMap::new(), poisoned: HashSet::new() }
    }
}

/// The checker for one program: all modules visible to it.
pub struct Checker<'a> {
    modules: HashMap<String, &'a ModuleDef>,
    diags: Vec<Diagnostic>,
    seen: HashSet<(Span, String)>,
    call_stack: Vec<(String, Span)>,
    /// The knobs of the scene being lowered: name → (value, unit).
    knobs: HashMap<String, (f64, Dim)>,
    /// Knobs whose value failed to check (already reported): uses stay silent.
    failed_knobs: HashSet<String>,
}

/// A value given on the command line for a scene's knob (`--knob NAME=VALUE`):
/// the expression replaces the one the scene declares.
#[derive(Clone, Debug)]
pub struct KnobOverride {
    /// The knob's name.
    pub name: String,
    /// Its new value, parsed from its own pseudo-file (so errors point into it).
    pub value: Expr,
}

/// Result of lowering a scene: the IR (if no error) and diagnostics.
pub type SceneResult = Result<ir::Function, Vec<Diagnostic>>;

impl<'a> Checker<'a> {
    /// A checker that sees `modules` (user modules and imported stdlib modules).
    pub fn new(modules: HashMap<String, &'a ModuleDef>) -> Self {
        Checker {
            modules,
            diags: Vec::new(),
            seen: HashSet::new(),
            call_stack: Vec::new(),
            knobs: HashMap::new(),
            failed_knobs: HashSet::new(),
        }
    }

    fn error(&mut self, d: Diagnostic) {
        if self.seen.insert((d.span, d.message.clone())) {
            self.diags.push(d);
        }
    }

    /// Takes the diagnostics reported so far.
    pub fn take_diagnostics(&mut self) -> Vec<Diagnostic> {
        std::mem::take(&mut self.diags)
    }

    /// Resolves names in every module body without lowering it, so typos in
    /// modules no scene uses are still reported.
    pub fn resolve_module(&mut self, m: &ModuleDef) {
        let mut names: HashSet<String> = m.args.iter().map(|a| a.name.node.clone()).collect();
        for n in m.weights.iter().map(|w| &w.name).chain(m.lets.iter().map(|l| &l.name)) {
            if !names.insert(n.node.clone()) {
                self.error(
                    Diagnostic::error(n.span, format!("`{}` is defined twice in module `{}`", n.node, m.name.node))
                        .with_help("rename one of the definitions"),
                );
            }
        }
        let mut exprs: Vec<&Expr> = m.lets.iter().map(|l| &l.value).collect();
        exprs.push(&m.result);
        exprs.extend(m.args.iter().filter_map(|a| a.default.as_ref()));
        for e in exprs {
            self.resolve_expr(e, &names);
        }
    }

    fn resolve_expr(&mut self, e: &Expr, names: &HashSet<String>) {
        match &e.node {
            ExprKind::Name(n) => {
                if !names.contains(n) && !CONSTANTS.iter().any(|c| c.name == n) {
                    let cands: Vec<&str> = names.iter().map(|s| s.as_str()).chain(CONSTANTS.iter().map(|c| c.name)).collect();
                    self.error(unknown_name(e.span, n, &cands));
                }
            }
            ExprKind::Neg(a) => self.resolve_expr(a, names),
            ExprKind::Binary(_, a, b) => {
                self.resolve_expr(a, names);
                self.resolve_expr(b, names);
            }
            ExprKind::If(c, a, b) => {
                for x in [c, a, b] {
                    self.resolve_expr(x, names);
                }
            }
            ExprKind::Call { callee, args } => {
                if !self.modules.contains_key(&callee.node) && !BUILTINS.iter().any(|b| b.0 == callee.node) {
                    self.error(self.unknown_function(callee));
                }
                for a in args {
                    self.resolve_expr(&a.value, names);
                }
            }
            ExprKind::Number(..) | ExprKind::Imaginary(_) | ExprKind::Error => {}
        }
    }

    fn unknown_function(&self, callee: &Spanned<String>) -> Diagnostic {
        let cands: Vec<&str> = self.modules.keys().map(|s| s.as_str()).chain(BUILTINS.iter().map(|b| b.0)).collect();
        let mut d =
            Diagnostic::error(callee.span, format!("unknown function `{}`", callee.node)).with_label("not a builtin or a module in scope");
        d = match did_you_mean(&callee.node, cands) {
            Some(s) => d.with_help(format!("did you mean `{s}`?")),
            None => d.with_help("define it with `module`, or import it with `use std::FILE::{NAME}`"),
        };
        d
    }

    /// Checks `scene` and lowers it to IR, with `overrides` replacing the
    /// values of its knobs.
    pub fn lower_scene(mut self, scene: &'a SceneDef, overrides: &'a [KnobOverride]) -> SceneResult {
        let mut func = ir::Function { name: scene.name.node.clone(), ..Default::default() };
        let mut scope = Scope::new(ScopeKind::Scene);
        let mut declared: HashMap<String, Span> = HashMap::new();
        let mut knobs: HashMap<String, Span> = HashMap::new();
        for st in &scene.stmts {
            let name = match st {
                SceneStmt::Grid { name, .. } | SceneStmt::Input { name, .. } => Some(name),
                SceneStmt::Param(p) => Some(&p.name),
                SceneStmt::Let(l) | SceneStmt::Output(l) | SceneStmt::Knob(l) => Some(&l.name),
                _ => None,
            };
            if let Some(n) = name {
                if let Some(prev) = declared.insert(n.node.clone(), n.span) {
                    self.error(
                        Diagnostic::error(n.span, format!("`{}` is declared twice in scene `{}`", n.node, scene.name.node))
                            .with_secondary(prev, "first declared here")
                            .with_help("rename one of them"),
                    );
                }
            }
            if let SceneStmt::Setting { name, value } = st {
                if let Some(prev) = knobs.insert(name.node.clone(), name.span) {
                    self.error(
                        Diagnostic::error(name.span, format!("knob `{}` is set twice", name.node))
                            .with_secondary(prev, "first set here")
                            .with_help("keep one setting"),
                    );
                }
                match (name.node.as_str(), value.node.as_str()) {
                    ("precision", "f64") => func.precision = Precision::F64,
                    ("precision", "f32") => func.precision = Precision::F32,
                    ("precision", "mixed") => func.precision = Precision::Mixed,
                    ("precision", other) => self.error(
                        Diagnostic::error(value.span, format!("unknown precision `{other}`"))
                            .with_help("use `precision: f64`, `precision: f32` or `precision: mixed` (f32 with phases in f64)"),
                    ),
                    ("math", "exact") => func.math = ir::MathMode::Exact,
                    ("math", "fast") => func.math = ir::MathMode::Fast,
                    ("math", "fastest") => func.math = ir::MathMode::Fastest,
                    ("math", other) => self.error(
                        Diagnostic::error(value.span, format!("unknown math mode `{other}`"))
                            .with_help("use `math: exact` (libm accuracy), `math: fast` (~1e-12) or `math: fastest` (~1e-7)"),
                    ),
                    (other, _) => {
                        let mut d = Diagnostic::error(name.span, format!("unknown scene setting `{other}`")).with_label("not a knob");
                        d = match did_you_mean(other, ["precision", "math"]) {
                            Some(s) => d.with_help(format!("did you mean `{s}`?")),
                            None => d.with_help("the knobs are `precision: f64 | f32 | mixed` and `math: exact | fast | fastest`"),
                        };
                        self.error(d);
                    }
                }
            }
        }
        self.scene_knobs(scene, overrides);
        func.knobs = scene
            .stmts
            .iter()
            .filter_map(|st| match st {
                SceneStmt::Knob(k) => self.knobs.get(&k.name.node).map(|&(value, dim)| ir::KnobValue {
                    name: k.name.node.clone(),
                    value,
                    unit: dim.to_string(),
                }),
                _ => None,
            })
            .collect();
        let mut b = Builder::new(func, false);
        // Grids first: inputs' types name them.
        for st in &scene.stmts {
            if let SceneStmt::Grid { name, def } = st {
                let Some(grid) = self.grid_def(name, def, &scope.grids, &b.func.grids) else {
                    scope.poisoned.insert(name.node.clone());
                    continue;
                };
                {
                    let id = ir::GridId(b.func.grids.len() as u32);
                    b.func.grids.push(grid);
                    scope.grids.insert(name.node.clone(), id);
                    let coord = b.push(Op::GridCoord(id));
                    let dim = match b.func.grids[id.0 as usize].unit.as_str() {
                        "Hz" => Dim::FREQ,
                        "s" => Dim::TIME,
                        _ => Dim::NONE,
                    };
                    scope.values.insert(name.node.clone(), Tv { v: coord, dim });
                }
            }
        }
        for st in &scene.stmts {
            match st {
                SceneStmt::Param(p) => {
                    if let Some((info, dim)) = self.param_decl(p) {
                        let idx = b.func.params.len() as u32;
                        b.func.params.push(info);
                        let v = b.push(Op::Param(idx));
                        scope.values.insert(p.name.node.clone(), Tv { v, dim });
                    } else {
                        scope.poisoned.insert(p.name.node.clone());
                    }
                }
                SceneStmt::Input { name, ty, default } => {
                    if let Some((ity, dim, scale, unit)) = self.type_ann(ty, &scope) {
                        let default = default.as_ref().and_then(|e| self.input_default(&b.func, &scope, e, name, ity, dim));
                        let idx = b.func.inputs.len() as u32;
                        b.func.inputs.push(ir::InputInfo {
                            name: name.node.clone(),
                            ty: ity,
                            scale,
                            unit,
                            default,
                            role: ir::InputRole::Data,
                        });
                        let v = b.push(Op::Input(idx));
                        scope.values.insert(name.node.clone(), Tv { v, dim });
                    } else {
                        scope.poisoned.insert(name.node.clone());
                    }
                }
                SceneStmt::Let(l) | SceneStmt::Output(l) => {
                    scope.lets.insert(l.name.node.clone(), LetSlot::Pending(l));
                }
                _ => {}
            }
        }
        // Elaborate every definition (so errors in unused lets are reported);
        // pruning removes what no output needs.
        let mut outputs = Vec::new();
        for st in &scene.stmts {
            match st {
                SceneStmt::Let(l) => {
                    self.lookup_let(&mut b, &mut scope, &l.name.node, l.name.span);
                }
                SceneStmt::Output(l) => {
                    if let Some(tv) = self.lookup_let(&mut b, &mut scope, &l.name.node, l.name.span) {
                        outputs.push(ir::Output { name: l.name.node.clone(), value: tv.v, unit: tv.dim.to_string(), exponent: 0 });
                    }
                }
                _ => {}
            }
        }
        b.func.outputs = outputs;
        for st in &scene.stmts {
            if let SceneStmt::Grad { output, wrt, .. } = st {
                self.grad_request(&mut b, scene, output, wrt);
            }
        }
        if self.diags.is_empty() {
            Ok(b.func)
        } else {
            Err(self.diags)
        }
    }

    /// Evaluates the scene's `knob` declarations in source order (a knob may
    /// use the knobs above it), each replaced by its override if one is given.
    fn scene_knobs(&mut self, scene: &'a SceneDef, overrides: &'a [KnobOverride]) {
        let mut declared = Vec::new();
        for st in &scene.stmts {
            let SceneStmt::Knob(k) = st else { continue };
            let name = &k.name.node;
            declared.push(name.as_str());
            if CONSTANTS.iter().any(|c| c.name == name) {
                self.error(
                    Diagnostic::error(k.name.span, format!("knob `{name}` would hide the constant `{name}`"))
                        .with_help("give the knob another name"),
                );
                self.failed_knobs.insert(name.clone());
                continue;
            }
            if let Some(t) = &k.ty {
                self.error(
                    Diagnostic::error(t.span, "a knob takes its unit from its value")
                        .with_label("no type here")
                        .with_help(format!("write the unit on the value, e.g. `knob {name} = 0.125 Hz`")),
                );
            }
            let Some((mut x, dim)) = self.const_eval(&k.value) else {
                self.failed_knobs.insert(name.clone());
                continue;
            };
            if let Some(o) = overrides.iter().find(|o| &o.name == name) {
                match self.const_eval(&o.value) {
                    Some((y, odim)) if odim == dim => x = y,
                    Some((_, odim)) => {
                        self.error(
                            unit_mismatch(o.value.span, dim, odim, &format!("knob `{name}`"))
                                .with_secondary(k.value.span, "the scene's value"),
                        );
                        self.failed_knobs.insert(name.clone());
                        continue;
                    }
                    None => {
                        self.failed_knobs.insert(name.clone());
                        continue;
                    }
                }
            }
            self.knobs.insert(name.clone(), (x, dim));
        }
        for o in overrides {
            if declared.contains(&o.name.as_str()) {
                continue;
            }
            let mut d = Diagnostic::error(o.value.span, format!("scene `{}` has no knob `{}`", scene.name.node, o.name));
            d = match did_you_mean(&o.name, declared.iter().copied()) {
                Some(s) => d.with_help(format!("did you mean `{s}`?")),
                None if declared.is_empty() => d.with_help("declare one in the scene, e.g. `knob pn_order = 7`"),
                None => d.with_help(format!("its knobs are {}", declared.join(", "))),
            };
            self.error(d);
        }
    }

    fn grad_request(&mut self, b: &mut Builder, scene: &SceneDef, output: &Spanned<String>, wrt: &[Spanned<String>]) {
        let declared = scene.stmts.iter().any(|s| matches!(s, SceneStmt::Output(l) if l.name.node == output.node));
        let Some(oi) = b.func.outputs.iter().position(|o| o.name == output.node) else {
            if declared {
                // The output itself failed to check; that error was reported.
                return;
            }
            let outs: Vec<String> = b.func.outputs.iter().map(|o| o.name.clone()).collect();
            let mut d = Diagnostic::error(output.span, format!("`{}` is not an output of scene `{}`", output.node, scene.name.node))
                .with_label("gradients are taken of outputs");
            d = match did_you_mean(&output.node, outs.iter().map(|s| s.as_str())) {
                Some(s) => d.with_help(format!("did you mean `{s}`?")),
                None => d.with_help(format!("declare it with `output {} = ...`", output.node)),
            };
            self.error(d);
            return;
        };
        let ty = b.func.ty(b.func.outputs[oi].value);
        if ty != Ty::REAL {
            self.error(
                Diagnostic::error(
                    output.span,
                    format!("cannot differentiate `{}`: it is {}, not a real scalar", output.node, b.func.fmt_ty(ty)),
                )
                .with_help("reduce it to a real scalar first, e.g. `sum(abs2(x))`"),
            );
            return;
        }
        for w in wrt {
            if self.modules.get(&w.node).is_some_and(|m| m.learned) {
                let prefix = format!("{}.", w.node);
                let weights: Vec<usize> = (0..b.func.inputs.len())
                    .filter(|i| b.func.inputs[*i].is_weight() && b.func.inputs[*i].name.starts_with(&prefix))
                    .collect();
                if weights.is_empty() {
                    self.error(
                        Diagnostic::error(w.span, format!("learned component `{}` has no weights in this scene", w.node))
                            .with_label("not called by any output, or it declares no `weight`")
                            .with_help(format!("use it in an output, e.g. `output y = {}(x)`", w.node)),
                    );
                }
                for input in weights {
                    if !b.func.input_grads.iter().any(|g| g.output == oi && g.input == input) {
                        b.func.input_grads.push(ir::InputGrad { output: oi, input, value: None });
                    }
                }
                continue;
            }
            match b.func.params.iter().position(|p| p.name == w.node) {
                Some(pi) => {
                    if !b.func.grads.iter().any(|g| g.output == oi && g.param == pi) {
                        b.func.grads.push(ir::GradOutput { output: oi, param: pi, value: None });
                    }
                }
                None => {
                    let is_other = scene.stmts.iter().find_map(|s| match s {
                        SceneStmt::Input { name, .. } if name.node == w.node => Some("an input"),
                        SceneStmt::Let(l) if l.name.node == w.node => Some("a `let`"),
                        SceneStmt::Output(l) if l.name.node == w.node => Some("an output"),
                        SceneStmt::Grid { name, .. } if name.node == w.node => Some("a grid"),
                        _ => None,
                    });
                    let params: Vec<&str> = b.func.params.iter().map(|p| p.name.as_str()).collect();
                    let mut d = Diagnostic::error(w.span, format!("cannot take a gradient with respect to `{}`", w.node));
                    d = match is_other {
                        Some(kind) => d
                            .with_label(format!("`{}` is {kind}, not a param", w.node))
                            .with_help(format!("declare it as `param {}` to differentiate with respect to it", w.node)),
                        None => {
                            let d = d.with_label("not a param of this scene");
                            match did_you_mean(&w.node, params) {
                                Some(s) => d.with_help(format!("did you mean `{s}`?")),
                                None => d.with_help("gradients are taken with respect to `param`s"),
                            }
                        }
                    };
                    self.error(d);
                }
            }
        }
    }

    fn grid_def(
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
            (0.0, 1.0 / rate, (rate * duration).round().max(1.0), "s")
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
    fn spectrum_grid(
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

    fn param_decl(&mut self, p: &'a ast::ParamDecl) -> Option<(ir::ParamInfo, Dim)> {
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
        Some((ir::ParamInfo { name: p.name.node.clone(), default, bounds, scale, unit }, dim))
    }

    /// Evaluates an input's default data at compile time (grids and constants only).
    fn input_default(
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
        if b.func.insts.len().saturating_mul(points) > crate::interp::EVAL_BUDGET {
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
        let r = crate::interp::interpret(&b.func, &[], &[]);
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
    fn type_ann(&mut self, t: &TypeAnn, scope: &Scope) -> Option<(Ty, Dim, f64, String)> {
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

    fn unit_expr(&mut self, u: &Spanned<UnitExpr>) -> Option<(Dim, f64, String)> {
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
        let (d, s) = go(self, &u.node)?;
        Some((d, s, u.node.to_string()))
    }

    /// Evaluates a constant expression (numbers, units, constants, arithmetic).
    fn const_eval(&mut self, e: &'a Expr) -> Option<(f64, Dim)> {
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

    fn lookup_let(&mut self, b: &mut Builder, scope: &mut Scope<'a>, name: &str, at: Span) -> Option<Tv> {
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

    /// Checks a value against an optional annotation (in a let or module arg).
    fn check_ann(&mut self, b: &mut Builder, scope: &Scope, ann: Option<&TypeAnn>, tv: Tv, name: &Spanned<String>) -> Option<Tv> {
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

    fn expr(&mut self, b: &mut Builder, scope: &mut Scope<'a>, e: &'a Expr) -> Option<Tv> {
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

    fn name(&mut self, b: &mut Builder, scope: &mut Scope<'a>, n: &str, span: Span) -> Option<Tv> {
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
    fn unify(&mut self, b: &mut Builder, (x, xs): (Value, Span), (y, ys): (Value, Span), at: Span) -> Option<(Value, Value)> {
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

    fn no_bool(&mut self, b: &Builder, v: (Tv, Span), what: &str) -> Option<()> {
        if b.ty(v.0.v).elem == Elem::Bool {
            self.error(
                Diagnostic::error(v.1, format!("{what} needs a number, found a comparison"))
                    .with_help("use `select(cond, a, b)` or `if cond { a } else { b }` to turn a comparison into a value"),
            );
            return None;
        }
        Some(())
    }

    fn binary(&mut self, b: &mut Builder, op: BinOp, l: (Tv, Span), r: (Tv, Span), at: Span) -> Option<Tv> {
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

    fn real_only(&mut self, b: &Builder, v: (Tv, Span), what: &str) -> Option<()> {
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

    fn pow(&mut self, b: &mut Builder, l: (Tv, Span), r: (Tv, Span), at: Span) -> Option<Tv> {
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
    fn masked_div(&mut self, b: &mut Builder, a: (Tv, Span), s: (Tv, Span), at: Span) -> Option<Tv> {
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

    fn select(&mut self, b: &mut Builder, c: (Tv, Span), x: (Tv, Span), y: (Tv, Span), at: Span) -> Option<Tv> {
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

    fn call(&mut self, b: &mut Builder, scope: &mut Scope<'a>, callee: &'a Spanned<String>, args: &'a [ast::Arg], at: Span) -> Option<Tv> {
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
    fn transform(&mut self, b: &mut Builder, name: &str, x: (Tv, Span), grid: (Tv, Span)) -> Option<Tv> {
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

    fn same_dim(&mut self, x: (Tv, Span), y: (Tv, Span), name: &str, at: Span) -> Option<()> {
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

    fn call_module(
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
                        let mut empty = Scope::new(ScopeKind::Module);
                        self.expr(b, &mut empty, d)
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

fn const_value(b: &Builder, v: Value) -> Option<f64> {
    match b.func.insts[v.index()].op {
        Op::Const(bits) => Some(f64::from_bits(bits)),
        Op::Unary(UnOp::Neg, a) => const_value(b, a).map(|x| -x),
        Op::Binary(op @ (IrBin::Div | IrBin::Mul | IrBin::Add | IrBin::Sub), x, y) => {
            let (x, y) = (const_value(b, x)?, const_value(b, y)?);
            Some(match op {
                IrBin::Div => x / y,
                IrBin::Mul => x * y,
                IrBin::Add => x + y,
                _ => x - y,
            })
        }
        _ => None,
    }
}

fn unknown_name(span: Span, n: &str, cands: &[&str]) -> Diagnostic {
    let d = Diagnostic::error(span, format!("unknown name `{n}`")).with_label("not defined here");
    match did_you_mean(n, cands.iter().copied()) {
        Some(s) => d.with_help(format!("did you mean `{s}`?")),
        None => d.with_help(format!("define it with `let {n} = ...`, or declare it as a `param` or `input`")),
    }
}

fn unit_mismatch(span: Span, want: Dim, found: Dim, what: &str) -> Diagnostic {
    Diagnostic::error(span, format!("unit mismatch: {what} needs {want}, found {found}"))
        .with_label(format!("this has unit {found}"))
        .with_help(format!("write the value in a unit of {want}"))
}

/// Collects the modules of the user's file and its imports into one table,
/// reporting duplicates.
pub fn collect_modules<'a>(items: impl Iterator<Item = &'a Item>, diags: &mut Vec<Diagnostic>) -> HashMap<String, &'a ModuleDef> {
    let mut out: HashMap<String, &'a ModuleDef> = HashMap::new();
    for item in items {
        if let Item::Module(m) = item {
            if BUILTINS.iter().any(|b| b.0 == m.name.node) {
                diags.push(
                    Diagnostic::error(m.name.span, format!("module `{}` has the name of a builtin", m.name.node))
                        .with_help("choose another name"),
                );
            } else if let Some(prev) = out.insert(m.name.node.clone(), m) {
                diags.push(
                    Diagnostic::error(m.name.span, format!("module `{}` is defined twice", m.name.node))
                        .with_secondary(prev.name.span, "first defined here")
                        .with_help("rename one of them"),
                );
            }
        }
    }
    out
}

/// `x` of a real scalar constant, for tests and the REPL.
pub fn c64(x: f64) -> C64 {
    C64::new(x, 0.0)
}
