//! gwml compiler: `.gw` source → checked IR → symbolic adjoint → optimised
//! IR → Cranelift JIT kernels. See `ARCHITECTURE.md` for the stage map.

pub mod diagnostics;
pub mod source;
pub mod syntax;
pub mod units;
pub mod builder;
pub mod check;
pub mod eval;
pub mod ir;
pub mod passes;
pub mod interp;
pub mod stdlib;
pub mod driver;

pub use driver::{CompileError, Options, Program, ScenePipeline, Stats};
pub mod codegen;
