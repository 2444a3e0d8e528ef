//! The SSA IR: a flat list of instructions over scalars and arrays on named
//! grids. Every instruction defines one value (its index); operands always
//! refer to earlier instructions. Elementwise operands have equal element
//! kind and shape: the checker inserts explicit [`Op::Broadcast`] and
//! [`UnOp::ToComplex`] so that passes and backends never guess.
//!
//! Enters: nothing (the checker and the passes build it through
//! [`builder::Builder`]); leaves: a [`Function`] that passes rewrite and
//! codegen compiles. [`verify`](Function::verify) checks its invariants;
//! printing it ([`Function`]'s `Display`) only formats.

pub mod builder;
mod display;
pub mod eval;
mod function;
mod ops;
mod settings;
mod types;
mod verify;

pub use display::Marked;
pub use function::*;
pub use ops::*;
pub use settings::{MathMode, Multiband, Precision, RelativeBinning, UnknownSetting};
pub use types::*;
