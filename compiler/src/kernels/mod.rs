//! The library code generated kernels call, and the oracle over it.
//! Enters: buffers laid out by codegen (or the interpreter's arrays);
//! leaves: transformed buffers. `dft` (realfft plans) and `tensor`
//! (the layer ops) export `extern "C"` symbols the JIT links; `interp` is
//! the reference interpreter of the IR (f64, compensated sums) that the
//! JIT is tested against and that specialisation and the precision
//! analysis evaluate with. Besides codegen's ABI, the only `unsafe` in the
//! compiler lives here.

pub mod band;
pub mod dft;
pub mod interp;
pub mod tensor;
