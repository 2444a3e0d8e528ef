//! Parsed modules and scenes in, one IR `Function` per scene (or
//! diagnostics) out: name resolution, type/shape/unit checking and
//! lowering to IR, in one walk over the AST (the "elaborator").
//!
//! Modules are instantiated at each call site with the types of their
//! arguments (like templates), so a module's body is checked with concrete
//! shapes and units, and modules no output reaches are never lowered.
//! Definitions inside a scene or module are order-independent; a name is
//! elaborated the first time it is used, which is also where cycles are
//! caught. Every error is reported with a span and checking continues, so
//! one run shows every problem.
//!
//! Files: `catalogue` (builtins and constants), `scene` (scene lowering,
//! settings, knobs, gradient requests), `grids`, `decls` (params, inputs,
//! annotations, constant expressions), `expr` (names and operators),
//! `calls` (builtins, transforms, module instantiation), `layers`
//! (`learned` components) and `convs` (their convolutions and pooling).

use crate::front::diagnostics::{did_you_mean, Diagnostic};
use crate::front::source::{Span, Spanned};
use crate::front::syntax::ast::{self, BinOp, ElemAnn, Expr, ExprKind, Item, LetDecl, ModuleDef, SceneDef, SceneStmt, TypeAnn, UnitExpr};
use crate::front::units::{self, Dim, Ratio};
use crate::ir::builder::Builder;
use crate::ir::{self, BinOp as IrBin, Elem, Op, Reduce, Shape, Ty, UnOp, Value};
use num_complex::Complex64 as C64;
use std::collections::{HashMap, HashSet};

mod calls;
mod catalogue;
mod convs;
mod decls;
mod expr;
mod grids;
mod layers;
mod scene;

pub use catalogue::{Constant, BUILTINS, CONSTANTS};

/// The recursive walks over expressions grow the stack by
/// [`STACK_GROWTH`] bytes whenever less than [`STACK_RED_ZONE`] is left
/// (`stacker`), so deeply nested source cannot overflow it.
pub(crate) const STACK_RED_ZONE: usize = 128 * 1024;
/// See [`STACK_RED_ZONE`].
pub(crate) const STACK_GROWTH: usize = 4 * 1024 * 1024;

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
        let mut names: HashSet<String> = HashSet::new();
        for n in m.args.iter().map(|a| &a.name).chain(m.weights.iter().map(|w| &w.name)).chain(m.lets.iter().map(|l| &l.name)) {
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
        stacker::maybe_grow(STACK_RED_ZONE, STACK_GROWTH, || self.resolve_expr_here(e, names))
    }

    fn resolve_expr_here(&mut self, e: &Expr, names: &HashSet<String>) {
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
