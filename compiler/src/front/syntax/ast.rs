//! The abstract syntax tree: what the parser produces, before names are
//! resolved or types checked. Every node carries its [`Span`].

use crate::front::source::{Span, Spanned};
use std::fmt;

/// An identifier with its span.
pub type Ident = Spanned<String>;

/// A parsed source file.
#[derive(Clone, Debug, PartialEq)]
pub struct SourceFileAst {
    /// Top-level items in source order.
    pub items: Vec<Item>,
}

/// A top-level item.
#[derive(Clone, Debug, PartialEq)]
pub enum Item {
    /// `use std::path::{a, b}` or `use std::path::a`.
    Use(UseDecl),
    /// `module name(args) { ... }`.
    Module(ModuleDef),
    /// `scene name { ... }`.
    Scene(SceneDef),
}

/// `use std::waveform::{chirp, amp}`.
#[derive(Clone, Debug, PartialEq)]
pub struct UseDecl {
    /// Path segments before the imported names (`["std", "waveform"]`).
    pub path: Vec<Ident>,
    /// Imported names.
    pub names: Vec<Ident>,
    /// The whole declaration.
    pub span: Span,
}

/// A module: a pure function written as equations; or, with weights, a
/// `learned` component whose weight tensors are trained.
#[derive(Clone, Debug, PartialEq)]
pub struct ModuleDef {
    /// Its name.
    pub name: Ident,
    /// Formal arguments.
    pub args: Vec<ModuleArg>,
    /// Whether it was written `learned` (it may declare weights).
    pub learned: bool,
    /// `weight` declarations (learned components only).
    pub weights: Vec<WeightDecl>,
    /// `let` bindings in the body.
    pub lets: Vec<LetDecl>,
    /// The value the module returns.
    pub result: Expr,
    /// The whole definition.
    pub span: Span,
}

/// `weight k: [8, 1, 16] = he(seed: 3)`: a trainable tensor of a learned
/// component, with its shape and initialiser.
#[derive(Clone, Debug, PartialEq)]
pub struct WeightDecl {
    /// Its name inside the component.
    pub name: Ident,
    /// Dimensions (constant expressions).
    pub dims: Vec<Expr>,
    /// The initialiser: `zeros`, `ones`, `normal(std: s)`, `glorot`, `he`,
    /// each optionally with `seed: n`.
    pub init: Expr,
    /// The whole declaration.
    pub span: Span,
}

/// One formal argument of a module.
#[derive(Clone, Debug, PartialEq)]
pub struct ModuleArg {
    /// Its name.
    pub name: Ident,
    /// Optional annotation.
    pub ty: Option<TypeAnn>,
    /// Optional default, used when the caller omits it.
    pub default: Option<Expr>,
}

/// A type annotation: `complex[f] 1/Hz`, `Msun`, `real`.
#[derive(Clone, Debug, PartialEq)]
pub struct TypeAnn {
    /// `real` or `complex`, if written.
    pub elem: Option<Spanned<ElemAnn>>,
    /// The grid name inside `[...]`, if written.
    pub grid: Option<Ident>,
    /// The unit, if written.
    pub unit: Option<Spanned<UnitExpr>>,
    /// The whole annotation.
    pub span: Span,
}

/// Element kind written in an annotation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ElemAnn {
    /// `real`
    Real,
    /// `complex`
    Complex,
}

/// A unit expression: products and quotients of unit names with rational powers.
#[derive(Clone, Debug, PartialEq)]
pub enum UnitExpr {
    /// The dimensionless unit `1`.
    One,
    /// A unit name such as `Hz`.
    Name(Ident),
    /// `a * b`
    Mul(Box<UnitExpr>, Box<UnitExpr>),
    /// `a / b`
    Div(Box<UnitExpr>, Box<UnitExpr>),
    /// `a ^ (n/d)`
    Pow(Box<UnitExpr>, i32, i32),
}

/// `let name = value`.
#[derive(Clone, Debug, PartialEq)]
pub struct LetDecl {
    /// Bound name.
    pub name: Ident,
    /// Optional annotation, checked against the value.
    pub ty: Option<TypeAnn>,
    /// The value.
    pub value: Expr,
}

/// A scene: what one run needs.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneDef {
    /// Its name.
    pub name: Ident,
    /// Statements in source order.
    pub stmts: Vec<SceneStmt>,
    /// The whole definition.
    pub span: Span,
}

/// A statement inside a scene.
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)] // few per scene; boxing would only add noise
pub enum SceneStmt {
    /// `grid f = frequencies(...)`.
    Grid { name: Ident, def: Expr },
    /// `input d: complex[f]`, optionally `= default` (used when no data is bound).
    Input { name: Ident, ty: TypeAnn, default: Option<Expr> },
    /// `param mc: Msun = 28 in 5..100`.
    Param(ParamDecl),
    /// `let h = ...`.
    Let(LetDecl),
    /// `output loss = ...`.
    Output(LetDecl),
    /// `grad loss wrt [mc, tc]`.
    Grad { output: Ident, wrt: Vec<Ident>, span: Span },
    /// `precision: f32` or `math: fast`: a setting of the compiler.
    Setting { name: Ident, value: Ident },
    /// `knob pn_order = 7`: a named compile-time constant of the scene,
    /// which the command line may override (`--knob pn_order=5`).
    Knob(LetDecl),
}

/// A differentiable parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamDecl {
    /// Its name.
    pub name: Ident,
    /// Optional unit (params are real scalars).
    pub ty: Option<TypeAnn>,
    /// Default value (in the declared unit).
    pub default: Option<Expr>,
    /// Optional bounds `lo..hi` (in the declared unit).
    pub bounds: Option<(Expr, Expr)>,
    /// The whole declaration.
    pub span: Span,
}

/// An expression with its span.
pub type Expr = Spanned<ExprKind>;

/// Expression forms.
#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    /// Produced by error recovery; checking skips it silently.
    Error,
    /// A real number, with an optional unit written after it (`20 Hz`).
    Number(f64, Option<Spanned<UnitExpr>>),
    /// An imaginary number `2.5i`.
    Imaginary(f64),
    /// A name.
    Name(String),
    /// `-x`
    Neg(Box<Expr>),
    /// `a op b`
    Binary(BinOp, Box<Expr>, Box<Expr>),
    /// `f(a, b, name: c)`
    Call { callee: Ident, args: Vec<Arg> },
    /// `if c { a } else { b }`
    If(Box<Expr>, Box<Expr>, Box<Expr>),
}

/// A call argument, positional or named.
#[derive(Clone, Debug, PartialEq)]
pub struct Arg {
    /// `Some(name)` for `name: value`.
    pub name: Option<Ident>,
    /// The value.
    pub value: Expr,
}

/// Binary operators.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BinOp {
    /// `+`
    Add,
    /// `-`
    Sub,
    /// `*`
    Mul,
    /// `/`
    Div,
    /// `^`
    Pow,
    /// `<`
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
    /// `==`
    Eq,
    /// `!=`
    Ne,
}

impl BinOp {
    /// The operator as written.
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Pow => "^",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
        }
    }

    /// True for the comparison operators.
    pub fn is_comparison(self) -> bool {
        matches!(self, BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne)
    }
}

impl fmt::Display for UnitExpr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            UnitExpr::One => write!(f, "1"),
            UnitExpr::Name(n) => write!(f, "{}", n.node),
            UnitExpr::Mul(a, b) => write!(f, "{a}*{b}"),
            UnitExpr::Div(a, b) => write!(f, "{a}/{b}"),
            UnitExpr::Pow(a, n, 1) => write!(f, "{a}^{n}"),
            UnitExpr::Pow(a, n, d) => write!(f, "{a}^({n}/{d})"),
        }
    }
}
