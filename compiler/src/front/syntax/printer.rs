//! A stable text dump of the AST (`gwml compile --emit ast`): items and
//! statements one per line, expressions fully parenthesised.

use super::ast::*;
use std::fmt::Write;

/// Prints `ast` as text.
pub fn print_ast(ast: &SourceFileAst) -> String {
    let mut out = String::new();
    for item in &ast.items {
        match item {
            Item::Use(u) => {
                let path: Vec<_> = u.path.iter().map(|p| p.node.as_str()).collect();
                let names: Vec<_> = u.names.iter().map(|p| p.node.as_str()).collect();
                let _ = writeln!(out, "use {}::{{{}}}", path.join("::"), names.join(", "));
            }
            Item::Module(m) => {
                let args: Vec<_> = m
                    .args
                    .iter()
                    .map(|a| {
                        let mut s = a.name.node.clone();
                        if let Some(t) = &a.ty {
                            s += &format!(": {}", ty(t));
                        }
                        if let Some(d) = &a.default {
                            s += &format!(" = {}", expr(d));
                        }
                        s
                    })
                    .collect();
                let _ = writeln!(out, "{} {}({})", if m.learned { "learned" } else { "module" }, m.name.node, args.join(", "));
                for w in &m.weights {
                    let dims: Vec<_> = w.dims.iter().map(expr).collect();
                    let _ = writeln!(out, "  weight {}: [{}] = {}", w.name.node, dims.join(", "), expr(&w.init));
                }
                for l in &m.lets {
                    let _ = writeln!(out, "  let {}{} = {}", l.name.node, opt_ty(&l.ty), expr(&l.value));
                }
                let _ = writeln!(out, "  result {}", expr(&m.result));
            }
            Item::Scene(s) => {
                let _ = writeln!(out, "scene {}", s.name.node);
                for st in &s.stmts {
                    let line = match st {
                        SceneStmt::Grid { name, def } => {
                            format!("grid {} = {}", name.node, expr(def))
                        }
                        SceneStmt::Input { name, ty: t, default } => {
                            let d = default.as_ref().map(|d| format!(" = {}", expr(d))).unwrap_or_default();
                            format!("input {}: {}{d}", name.node, ty(t))
                        }
                        SceneStmt::Param(p) => {
                            let mut s = format!("param {}{}", p.name.node, opt_ty(&p.ty));
                            if let Some(d) = &p.default {
                                s += &format!(" = {}", expr(d));
                            }
                            if let Some((lo, hi)) = &p.bounds {
                                s += &format!(" in {}..{}", expr(lo), expr(hi));
                            }
                            s
                        }
                        SceneStmt::Let(l) => {
                            format!("let {}{} = {}", l.name.node, opt_ty(&l.ty), expr(&l.value))
                        }
                        SceneStmt::Output(l) => format!("output {}{} = {}", l.name.node, opt_ty(&l.ty), expr(&l.value)),
                        SceneStmt::Grad { output, wrt, .. } => {
                            let w: Vec<_> = wrt.iter().map(|w| w.node.as_str()).collect();
                            format!("grad {} wrt [{}]", output.node, w.join(", "))
                        }
                        SceneStmt::Setting { name, value } => format!("{}: {}", name.node, value.node),
                        SceneStmt::Knob(l) => format!("knob {}{} = {}", l.name.node, opt_ty(&l.ty), expr(&l.value)),
                    };
                    let _ = writeln!(out, "  {line}");
                }
            }
        }
    }
    out
}

fn opt_ty(t: &Option<TypeAnn>) -> String {
    t.as_ref().map(|t| format!(": {}", ty(t))).unwrap_or_default()
}

fn ty(t: &TypeAnn) -> String {
    let mut parts = Vec::new();
    let mut head = String::new();
    if let Some(e) = &t.elem {
        head += match e.node {
            ElemAnn::Real => "real",
            ElemAnn::Complex => "complex",
        };
    }
    if let Some(g) = &t.grid {
        head += &format!("[{}]", g.node);
    }
    if !head.is_empty() {
        parts.push(head);
    }
    if let Some(u) = &t.unit {
        parts.push(u.node.to_string());
    }
    parts.join(" ")
}

/// Prints one expression, fully parenthesised.
pub fn expr(e: &Expr) -> String {
    match &e.node {
        ExprKind::Error => "<error>".into(),
        ExprKind::Number(n, None) => format!("{n:?}"),
        ExprKind::Number(n, Some(u)) => format!("{n:?} [{}]", u.node),
        ExprKind::Imaginary(n) => format!("{n:?}i"),
        ExprKind::Name(n) => n.clone(),
        ExprKind::Neg(a) => format!("(-{})", expr(a)),
        ExprKind::Binary(op, a, b) => format!("({} {} {})", expr(a), op.symbol(), expr(b)),
        ExprKind::Call { callee, args } => {
            let a: Vec<_> = args
                .iter()
                .map(|a| match &a.name {
                    Some(n) => format!("{}: {}", n.node, expr(&a.value)),
                    None => expr(&a.value),
                })
                .collect();
            format!("{}({})", callee.node, a.join(", "))
        }
        ExprKind::If(c, a, b) => format!("(if {} then {} else {})", expr(c), expr(a), expr(b)),
    }
}
