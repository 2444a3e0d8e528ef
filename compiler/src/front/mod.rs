//! The front end. Enters: `.gw` source text; leaves: a syntax tree with
//! spans and the diagnostics of parsing, plus what every later stage shares
//! for reporting (source map, diagnostics, units) and the embedded
//! standard library sources.

pub mod diagnostics;
pub mod source;
pub mod stdlib;
pub mod syntax;
pub mod units;
