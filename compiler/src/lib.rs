//! gwml compiler: `.gw` source → checked IR → symbolic adjoint → optimised
//! IR → Cranelift JIT kernels. Each module is a stage: `front` (text to
//! syntax) → `check` (syntax to IR) → `passes` (IR to IR) → `codegen` (IR
//! to a JIT kernel); `ir` is what they share and `kernels` what the JIT
//! calls; `driver` is the stage order. See `ARCHITECTURE.md` for the map.

// Checks such as `!(step > 0.0)` are written to reject NaN as well.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod check;
pub mod codegen;
pub mod driver;
pub mod front;
pub mod ir;
pub mod kernels;
pub mod passes;

pub use driver::{CompileError, KernelIr, Options, PipelineError, Program, ScenePipeline, Stats};
