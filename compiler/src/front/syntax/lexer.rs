//! The lexer: characters to tokens, skipping whitespace and `//` comments.

use crate::front::diagnostics::Diagnostic;
use crate::front::source::{FileId, Span};
use chumsky::prelude::*;
use std::fmt;

/// A lexical token.
#[derive(Clone, Debug, PartialEq)]
pub enum Token {
    /// A real literal.
    Num(f64),
    /// An imaginary literal such as `2i`.
    Imag(f64),
    /// An identifier or unit name.
    Ident(String),
    /// A keyword.
    Kw(&'static str),
    /// An operator or punctuation.
    Op(&'static str),
    /// `(` written directly after a name, opening a call's arguments.
    CallOpen,
}

const KEYWORDS: &[&str] =
    &["use", "module", "learned", "weight", "scene", "let", "param", "input", "output", "knob", "grad", "wrt", "grid", "in", "if", "else"];

const OPS: &[&str] =
    &["::", "..", "==", "!=", "<=", ">=", "->", "+", "-", "*", "/", "^", "<", ">", "=", ":", ",", ";", "(", ")", "[", "]", "{", "}"];

impl fmt::Display for Token {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Token::Num(n) => write!(f, "{n}"),
            Token::Imag(n) => write!(f, "{n}i"),
            Token::Ident(s) => write!(f, "{s}"),
            Token::Kw(s) | Token::Op(s) => write!(f, "{s}"),
            Token::CallOpen => write!(f, "("),
        }
    }
}

type LexErr<'a> = extra::Err<Rich<'a, char, SimpleSpan>>;

fn lexer<'a>() -> impl Parser<'a, &'a str, Vec<(Token, SimpleSpan)>, LexErr<'a>> {
    let digits = text::digits(10);
    let exponent = one_of("eE").then(one_of("+-").or_not()).then(digits);
    let number = text::int(10)
        .then(just('.').then(digits).or_not())
        .then(exponent.or_not())
        .to_slice()
        .then(just('i').then(text::ident().not()).or_not())
        .try_map(|(s, imag): (&str, Option<_>), span| {
            let v: f64 = s.parse().map_err(|_| Rich::custom(span, "invalid number"))?;
            Ok(if imag.is_some() { Token::Imag(v) } else { Token::Num(v) })
        });
    let ident = text::ident().map(|s: &str| match KEYWORDS.iter().find(|k| **k == s) {
        Some(k) => Token::Kw(k),
        None => Token::Ident(s.to_string()),
    });
    let op = choice(OPS.iter().map(|o| just(*o).to(Token::Op(o))).collect::<Vec<_>>());
    let comment = just("//").then(any().and_is(just('\n').not()).repeated()).padded();
    let token = number.or(ident).or(op);
    token
        .map_with(|t, e| (t, e.span()))
        .padded_by(comment.repeated())
        .padded()
        .recover_with(skip_then_retry_until(any().ignored(), end()))
        .repeated()
        .collect()
        .then_ignore(comment.repeated())
        .then_ignore(end())
}

/// Lexes `text` (file `file`) into tokens; unknown characters are reported
/// and skipped.
pub fn lex(text: &str, file: FileId) -> (Vec<(Token, Span)>, Vec<Diagnostic>) {
    let (tokens, errs) = lexer().parse(text).into_output_errors();
    let diags = errs
        .into_iter()
        .map(|e| {
            let span = Span::new(file, e.span().into_range());
            let found = e.found().map(|c| format!("`{}`", c.escape_debug())).unwrap_or("end of file".into());
            Diagnostic::error(span, format!("unexpected character {found}"))
                .with_label("not part of any token")
                .with_help("remove it; comments start with `//`")
        })
        .collect();
    let mut out: Vec<(Token, Span)> = Vec::new();
    for (tok, s) in tokens.unwrap_or_default() {
        let span = Span::new(file, s.into_range());
        let tok = match (&tok, out.last()) {
            (Token::Op("("), Some((Token::Ident(_), prev))) if prev.end == span.start => Token::CallOpen,
            _ => tok,
        };
        out.push((tok, span));
    }
    (out, diags)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn toks(s: &str) -> Vec<Token> {
        let (t, d) = lex(s, FileId(0));
        assert!(d.is_empty(), "{d:?}");
        t.into_iter().map(|(t, _)| t).collect()
    }

    #[test]
    fn numbers_ranges_units_and_calls() {
        assert_eq!(
            toks("5.0..100 2.5i 1e-3 s f(x) g (y)"),
            vec![
                Token::Num(5.0),
                Token::Op(".."),
                Token::Num(100.0),
                Token::Imag(2.5),
                Token::Num(1e-3),
                Token::Ident("s".into()),
                Token::Ident("f".into()),
                Token::CallOpen,
                Token::Ident("x".into()),
                Token::Op(")"),
                Token::Ident("g".into()),
                Token::Op("("),
                Token::Ident("y".into()),
                Token::Op(")"),
            ]
        );
    }

    #[test]
    fn comments_and_bad_characters() {
        let (t, d) = lex("a // hi\n # b", FileId(0));
        assert_eq!(t.len(), 2);
        assert_eq!(d.len(), 1);
        assert!(d[0].message.contains('#'));
    }
}
