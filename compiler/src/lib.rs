//! gwml compiler: `.gw` source → checked IR → symbolic adjoint → optimised
//! IR → Cranelift JIT kernels. The folders are the stages, in pipeline
//! order; `driver` is the stage order. See `ARCHITECTURE.md` for the map.

// Checks such as `!(step > 0.0)` are written to reject NaN as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod check;
pub mod codegen;
pub mod driver;
pub mod front;
pub mod ir;
pub mod kernels;
pub mod passes;

pub use driver::{CompileError, Options, PipelineError, Program, ScenePipeline, Stats};

// Transitional paths, removed once every file uses the stage paths above.
pub use front::{diagnostics, source, stdlib, syntax, units};
pub use ir::{builder, eval};
pub use kernels::{dft, interp, tensor};
