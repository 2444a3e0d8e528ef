//! gwml compiler: `.gw` source → checked IR → symbolic adjoint → optimised
//! IR → Cranelift JIT kernels. See `ARCHITECTURE.md` for the stage map.

// Checks such as `!(step > 0.0)` are written to reject NaN as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod builder;
pub mod check;
pub mod dft;
pub mod diagnostics;
pub mod driver;
pub mod eval;
pub mod interp;
pub mod ir;
pub mod passes;
pub mod source;
pub mod stdlib;
pub mod syntax;
pub mod tensor;
pub mod units;

pub use driver::{CompileError, Options, PipelineError, Program, ScenePipeline, Stats};
pub mod codegen;
