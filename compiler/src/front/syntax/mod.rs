//! Syntax: lexing and parsing `.gw` source into an [`ast::SourceFileAst`].
//!
//! Parsing never gives up: it returns the tree it could build together with
//! every syntax error it found, so later stages and the REPL keep working
//! on broken input.

pub mod ast;
mod lexer;
mod parser;
mod printer;

pub use lexer::{lex, Token};
pub use parser::{parse, parse_expr};
pub use printer::print_ast;
