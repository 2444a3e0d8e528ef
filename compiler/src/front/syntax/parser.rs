//! The parser: tokens to AST, with error recovery at statement and item
//! boundaries so one run reports several syntax errors.

use super::ast::*;
use super::lexer::{lex, Token};
use crate::front::diagnostics::Diagnostic;
use crate::front::source::{FileId, Span, Spanned};
use crate::front::units::is_unit_name;
use chumsky::input::ValueInput;
use chumsky::pratt::{infix, left, prefix, right};
use chumsky::prelude::*;

type Err<'a> = extra::Err<Rich<'a, Token, Span>>;

fn op<'a, I: ValueInput<'a, Token = Token, Span = Span>>(s: &'static str) -> impl Parser<'a, I, Token, Err<'a>> + Clone {
    just(Token::Op(s))
}

fn kw<'a, I: ValueInput<'a, Token = Token, Span = Span>>(s: &'static str) -> impl Parser<'a, I, Token, Err<'a>> + Clone {
    just(Token::Kw(s))
}

fn ident<'a, I: ValueInput<'a, Token = Token, Span = Span>>() -> impl Parser<'a, I, Ident, Err<'a>> + Clone {
    select! { Token::Ident(s) => s }.map_with(|s, e| Spanned::new(s, e.span())).labelled("name")
}

fn unit_expr<'a, I: ValueInput<'a, Token = Token, Span = Span>>() -> impl Parser<'a, I, Spanned<UnitExpr>, Err<'a>> + Clone {
    let int = select! { Token::Num(n) if n.fract() == 0.0 && n.abs() < 1e6 => n as i32 };
    let signed = op("-").or_not().then(int).map(|(neg, n)| if neg.is_some() { -n } else { n });
    let power = signed.clone().map(|n| (n, 1)).or(signed.then_ignore(op("/")).then(int).delimited_by(op("("), op(")")));
    let name = ident().then_ignore(op(":").not().rewind()).map(UnitExpr::Name).or(select! { Token::Num(n) if n == 1.0 => UnitExpr::One });
    let factor = name.then(op("^").ignore_then(power).or_not()).map(|(u, p)| match p {
        Some((n, d)) => UnitExpr::Pow(Box::new(u), n, d),
        None => u,
    });
    factor
        .clone()
        .foldl(op("*").to(true).or(op("/").to(false)).then(factor).repeated(), |a, (mul, b)| {
            if mul {
                UnitExpr::Mul(Box::new(a), Box::new(b))
            } else {
                UnitExpr::Div(Box::new(a), Box::new(b))
            }
        })
        .map_with(|u, e| Spanned::new(u, e.span()))
        .labelled("unit")
}

fn type_ann<'a, I: ValueInput<'a, Token = Token, Span = Span>>() -> impl Parser<'a, I, TypeAnn, Err<'a>> + Clone {
    let elem = select! { Token::Ident(s) if s == "real" => ElemAnn::Real, Token::Ident(s) if s == "complex" => ElemAnn::Complex }
        .map_with(|e, x| Spanned::new(e, x.span()));
    let grid = ident().delimited_by(op("["), op("]"));
    elem.or_not()
        .then(grid.or_not())
        .then(unit_expr().or_not())
        .try_map(|((elem, grid), unit), span| {
            if elem.is_none() && grid.is_none() && unit.is_none() {
                Err(Rich::custom(span, "expected a type: `real`, `complex`, a grid `[f]` or a unit"))
            } else {
                Ok(TypeAnn { elem, grid, unit, span })
            }
        })
        .labelled("type")
}

fn expr<'a, I: ValueInput<'a, Token = Token, Span = Span>>() -> impl Parser<'a, I, Expr, Err<'a>> + Clone {
    recursive(|expr| {
        let unit_suffix = select! { Token::Ident(s) if is_unit_name(&s) => s }
            .map_with(|s, e| Spanned::new(UnitExpr::Name(Spanned::new(s, e.span())), e.span()))
            .or(unit_expr().delimited_by(op("["), op("]")));
        // A literal beyond f64's range reads as infinity: an error, kept
        // as the number so checking goes on.
        let finite = |n: f64, span: Span, emitter: &mut chumsky::input::Emitter<Rich<'a, Token, Span>>| {
            if !n.is_finite() {
                emitter.emit(Rich::custom(span, "number too large: the largest is about 1.8e308"));
            }
            n
        };
        let number = select! { Token::Num(n) => n }
            .validate(move |n, e, emitter| finite(n, e.span(), emitter))
            .then(unit_suffix.or_not())
            .map(|(n, u)| ExprKind::Number(n, u))
            .or(select! { Token::Imag(n) => n }.validate(move |n, e, emitter| finite(n, e.span(), emitter)).map(ExprKind::Imaginary));
        let arg = ident().then_ignore(op(":")).or_not().then(expr.clone()).map(|(name, value)| Arg { name, value });
        let args = arg.separated_by(op(",")).allow_trailing().collect::<Vec<_>>().delimited_by(just(Token::CallOpen), op(")"));
        let call = ident().then(args).map(|(callee, args)| ExprKind::Call { callee, args });
        let name = ident().map(|i| ExprKind::Name(i.node));
        let block = expr.clone().delimited_by(op("{"), op("}"));
        let if_ = kw("if")
            .ignore_then(expr.clone())
            .then(block.clone())
            .then_ignore(kw("else"))
            .then(block)
            .map(|((c, a), b)| ExprKind::If(Box::new(c), Box::new(a), Box::new(b)));
        let atom = number
            .or(call)
            .or(name)
            .or(if_)
            .map_with(|k, e| Spanned::new(k, e.span()))
            .or(expr.clone().delimited_by(op("("), op(")")))
            .recover_with(via_parser(nested_delimiters(
                Token::Op("("),
                Token::Op(")"),
                [(Token::Op("["), Token::Op("]")), (Token::Op("{"), Token::Op("}"))],
                |span| Spanned::new(ExprKind::Error, span),
            )))
            .labelled("expression");
        let bin = |o: BinOp| {
            move |a: Expr, _, b: Expr, e: &mut chumsky::input::MapExtra<'a, '_, I, Err<'a>>| {
                Spanned::new(ExprKind::Binary(o, Box::new(a), Box::new(b)), e.span())
            }
        };
        atom.pratt((
            infix(right(6), op("^"), bin(BinOp::Pow)),
            prefix(5, op("-"), |_, a: Expr, e| Spanned::new(ExprKind::Neg(Box::new(a)), e.span())),
            infix(left(4), op("*"), bin(BinOp::Mul)),
            infix(left(4), op("/"), bin(BinOp::Div)),
            infix(left(3), op("+"), bin(BinOp::Add)),
            infix(left(3), op("-"), bin(BinOp::Sub)),
            infix(left(2), op("<"), bin(BinOp::Lt)),
            infix(left(2), op("<="), bin(BinOp::Le)),
            infix(left(2), op(">"), bin(BinOp::Gt)),
            infix(left(2), op(">="), bin(BinOp::Ge)),
            infix(left(2), op("=="), bin(BinOp::Eq)),
            infix(left(2), op("!="), bin(BinOp::Ne)),
        ))
        .boxed()
    })
}

fn let_decl<'a, I: ValueInput<'a, Token = Token, Span = Span>>(keyword: &'static str) -> impl Parser<'a, I, LetDecl, Err<'a>> + Clone {
    kw(keyword)
        .ignore_then(ident())
        .then(op(":").ignore_then(type_ann()).or_not())
        .then_ignore(op("="))
        .then(expr())
        .map(|((name, ty), value)| LetDecl { name, ty, value })
}

const STMT_STARTS: &[&str] = &["grid", "input", "param", "let", "output", "knob", "grad", "use", "module", "learned", "weight", "scene"];

/// Skips a broken statement: at least one token, then up to the next
/// statement keyword or closing brace.
fn skip_stmt<'a, I: ValueInput<'a, Token = Token, Span = Span>>() -> impl Parser<'a, I, (), Err<'a>> + Clone {
    let stop = choice(STMT_STARTS.iter().map(|k| kw(k)).collect::<Vec<_>>()).or(op("}"));
    any().and_is(op("}").not()).then(any().and_is(stop.not()).repeated()).ignored()
}

fn scene_stmt<'a, I: ValueInput<'a, Token = Token, Span = Span>>() -> impl Parser<'a, I, Option<SceneStmt>, Err<'a>> + Clone {
    let grid = kw("grid").ignore_then(ident()).then_ignore(op("=")).then(expr()).map(|(name, def)| SceneStmt::Grid { name, def });
    let input = kw("input")
        .ignore_then(ident())
        .then_ignore(op(":"))
        .then(type_ann())
        .then(op("=").ignore_then(expr()).or_not())
        .map(|((name, ty), default)| SceneStmt::Input { name, ty, default });
    let param = kw("param")
        .ignore_then(ident())
        .then(op(":").ignore_then(type_ann()).or_not())
        .then(op("=").ignore_then(expr()).or_not())
        .then(kw("in").ignore_then(expr()).then_ignore(op("..")).then(expr()).or_not())
        .map_with(|(((name, ty), default), bounds), e| SceneStmt::Param(ParamDecl { name, ty, default, bounds, span: e.span() }));
    let wrt =
        ident().separated_by(op(",")).allow_trailing().collect::<Vec<_>>().delimited_by(op("["), op("]")).or(ident().map(|i| vec![i]));
    let grad = kw("grad").ignore_then(ident()).then_ignore(kw("wrt")).then(wrt).map_with(|(output, wrt), e| SceneStmt::Grad {
        output,
        wrt,
        span: e.span(),
    });
    // A setting's value is a word (`f64`) or a number (`1e-4`), kept as text.
    let number = select! { Token::Num(n) => n.to_string() }.map_with(|s, e| Spanned::new(s, e.span()));
    let setting = ident().then_ignore(op(":")).then(ident().or(number)).map(|(name, value)| SceneStmt::Setting { name, value });
    choice((
        grid,
        input,
        param,
        let_decl("let").map(SceneStmt::Let),
        let_decl("output").map(SceneStmt::Output),
        let_decl("knob").map(SceneStmt::Knob),
        grad,
        setting,
    ))
    .map(Some)
    .then_ignore(op(";").or_not())
    .recover_with(via_parser(skip_stmt().to(None)))
    .labelled("scene statement")
}

fn item<'a, I: ValueInput<'a, Token = Token, Span = Span>>() -> impl Parser<'a, I, Option<Item>, Err<'a>> + Clone {
    let use_ = kw("use")
        .ignore_then(ident().then_ignore(op("::")).repeated().at_least(1).collect::<Vec<_>>())
        .then(ident().map(|i| vec![i]).or(ident().separated_by(op(",")).allow_trailing().collect().delimited_by(op("{"), op("}"))))
        .map_with(|(path, names), e| Item::Use(UseDecl { path, names, span: e.span() }));
    let module_arg = ident()
        .then(op(":").ignore_then(type_ann()).or_not())
        .then(op("=").ignore_then(expr()).or_not())
        .map(|((name, ty), default)| ModuleArg { name, ty, default });
    let weight = kw("weight")
        .ignore_then(ident())
        .then_ignore(op(":"))
        .then(expr().separated_by(op(",")).allow_trailing().collect::<Vec<_>>().delimited_by(op("["), op("]")))
        .then_ignore(op("="))
        .then(expr())
        .map_with(|((name, dims), init), e| WeightDecl { name, dims, init, span: e.span() });
    let body_stmt = let_decl("let").map(BodyStmt::Let).or(weight.map(BodyStmt::Weight)).then_ignore(op(";").or_not());
    let module = kw("module")
        .to(false)
        .or(kw("learned").to(true))
        .then(ident())
        .then(
            module_arg.separated_by(op(",")).allow_trailing().collect::<Vec<_>>().delimited_by(just(Token::CallOpen).or(op("(")), op(")")),
        )
        .then(body_stmt.repeated().collect::<Vec<_>>().then(expr()).then_ignore(op(";").or_not()).delimited_by(op("{"), op("}")))
        .map_with(|(((learned, name), args), (body, result)), e| {
            let (mut lets, mut weights) = (Vec::new(), Vec::new());
            for st in body {
                match st {
                    BodyStmt::Let(l) => lets.push(l),
                    BodyStmt::Weight(w) => weights.push(w),
                }
            }
            Item::Module(ModuleDef { name, args, learned, weights, lets, result, span: e.span() })
        });
    let scene = kw("scene")
        .ignore_then(ident())
        .then(scene_stmt().repeated().collect::<Vec<_>>().delimited_by(op("{"), op("}")))
        .map_with(|(name, stmts), e| Item::Scene(SceneDef { name, stmts: stmts.into_iter().flatten().collect(), span: e.span() }));
    choice((use_, module, scene))
        .map(Some)
        .recover_with(via_parser(skip_stmt().to(None)))
        .labelled("item (`use`, `module`, `learned` or `scene`)")
}

/// A statement of a module or learned body, before they are sorted.
enum BodyStmt {
    Let(LetDecl),
    Weight(WeightDecl),
}

/// Parses the text of file `file`. Always returns a tree (possibly partial)
/// and every lexical and syntax error found.
pub fn parse(text: &str, file: FileId) -> (SourceFileAst, Vec<Diagnostic>) {
    let (tokens, mut diags) = lex(text, file);
    let eoi = Span::new(file, text.len()..text.len());
    let input = tokens.as_slice().map(eoi, |(t, s)| (t, s));
    let (items, errs) = item().repeated().collect::<Vec<_>>().then_ignore(end()).parse(input).into_output_errors();
    for e in errs {
        diags.push(explain_unclosed(syntax_diagnostic(&e), &e, text));
    }
    (SourceFileAst { items: items.unwrap_or_default().into_iter().flatten().collect() }, diags)
}

/// Parses `text` (of file `file`) as one expression: a knob's value given
/// on the command line. Returns it if it parsed, and every error found.
pub fn parse_expr(text: &str, file: FileId) -> (Option<Expr>, Vec<Diagnostic>) {
    let (tokens, mut diags) = lex(text, file);
    let eoi = Span::new(file, text.len()..text.len());
    let input = tokens.as_slice().map(eoi, |(t, s)| (t, s));
    let (e, errs) = expr().then_ignore(end()).parse(input).into_output_errors();
    for e in errs {
        diags.push(syntax_diagnostic(&e));
    }
    (e, diags)
}

/// Statement keywords, which the parser lists when an expression ends early.
const STATEMENT_WORDS: &[&str] = &["`grad`", "`grid`", "`input`", "`knob`", "`let`", "`output`", "`param`"];

/// Replaces the generic help of common mistakes with a specific one: an
/// opening parenthesis never closed on its line, and an operator that
/// neither continues an expression nor starts a statement.
fn explain_unclosed(d: Diagnostic, e: &Rich<'_, Token, Span>, text: &str) -> Diagnostic {
    let span = *e.span();
    let line_end = text[span.start.min(text.len())..].find('\n').map_or(text.len(), |i| span.start + i);
    match e.found() {
        Some(Token::Op("(")) | Some(Token::CallOpen) => {
            let rest = &text[span.start..line_end];
            let depth = rest.split("//").next().unwrap_or("").chars().fold(0i32, |d, c| match c {
                '(' => d + 1,
                ')' => d - 1,
                _ => d,
            });
            if depth > 0 {
                return Diagnostic::error(span, "unclosed `(`")
                    .with_label("this parenthesis is never closed")
                    .with_help("add the missing `)`");
            }
            d
        }
        Some(Token::Op(op))
            if ["*", "/", "^", "+", "<", ">", "<=", ">=", "==", "!="].contains(op)
                && d.help.as_deref().is_some_and(|h| STATEMENT_WORDS.iter().any(|w| h.contains(w))) =>
        {
            Diagnostic::error(span, format!("`{op}` is missing an operand"))
                .with_label(format!("`{op}` needs a value on each side"))
                .with_help("remove the extra operator, or write the missing operand")
        }
        // A statement keyword where an expression was still open: look for a
        // `(` left unclosed on the line before.
        Some(Token::Kw(_)) => {
            let before = &text[..span.start.min(text.len())];
            let line_start = before.trim_end().rfind('\n').map_or(0, |i| i + 1);
            let line = before[line_start..].split("//").next().unwrap_or("");
            let mut open: Vec<usize> = Vec::new();
            for (i, c) in line.char_indices() {
                match c {
                    '(' => open.push(i),
                    ')' => {
                        open.pop();
                    }
                    _ => {}
                }
            }
            match open.first() {
                Some(&i) => {
                    let at = Span::new(span.file, line_start + i..line_start + i + 1);
                    Diagnostic::error(at, "unclosed `(`").with_label("this parenthesis is never closed").with_help("add the missing `)`")
                }
                None => d,
            }
        }
        _ => d,
    }
}

fn syntax_diagnostic(e: &Rich<'_, Token, Span>) -> Diagnostic {
    let d = syntax_diagnostic_at(e);
    // At the end of input chumsky may give a span that ends before it
    // starts (from the end of the input back to the last token).
    let span = Span { start: d.span.start.min(d.span.end), end: d.span.start.max(d.span.end), ..d.span };
    Diagnostic { span, ..d }
}

fn syntax_diagnostic_at(e: &Rich<'_, Token, Span>) -> Diagnostic {
    let found = match e.found() {
        Some(t) => format!("`{t}`"),
        None => "end of file".to_string(),
    };
    match e.reason() {
        chumsky::error::RichReason::Custom(msg) => {
            Diagnostic::error(*e.span(), msg.clone()).with_help("see the language reference in README.md")
        }
        _ => {
            let mut expected: Vec<String> = e
                .expected()
                .map(|p| match p {
                    chumsky::error::RichPattern::Token(t) => format!("`{}`", &**t),
                    chumsky::error::RichPattern::Label(l) => l.to_string(),
                    chumsky::error::RichPattern::EndOfInput => "end of file".into(),
                    other => other.to_string(),
                })
                .collect();
            expected.sort();
            expected.dedup();
            let mut d = Diagnostic::error(*e.span(), format!("syntax error: unexpected {found}")).with_label(format!("unexpected {found}"));
            if !expected.is_empty() {
                d = d.with_help(format!("expected {}", expected.join(", ")));
            }
            for (label, span) in e.contexts() {
                d = d.with_secondary(*span, format!("while parsing this {label}"));
            }
            d
        }
    }
}
