//! The kernel's calling convention ([`Layout`]: its buffers and scalar slots) and the compiled [`Kernel`].

use crate::ir::*;
use crate::kernels::band::BandPlan;
use crate::kernels::dft::DftPlan;
use cranelift_jit::JITModule;
use std::fmt;

/// What a buffer passed to the kernel holds.
#[derive(Clone, Debug, PartialEq)]
pub enum BufferKind {
    /// Input number `i` (read only).
    Input(usize),
    /// An intermediate array read by a later loop.
    Scratch,
    /// Array output number `i` (index into [`Function::outputs`]).
    Output(usize),
    /// Precomputed table number `i` (index into [`Function::tables`], read only).
    Table(usize),
    /// Gradient number `i` of [`Function::input_grads`] (an array).
    InputGrad(usize),
}

/// One buffer the kernel reads or writes.
#[derive(Clone, Debug, PartialEq)]
pub struct BufferInfo {
    /// Its role.
    pub kind: BufferKind,
    /// Number of elements.
    pub len: usize,
    /// Complex elements take two floats.
    pub complex: bool,
    /// Element precision: [`Precision::storage`] of the scene's, except
    /// that in mixed precision the tables, scratch arrays and outputs of
    /// values computed in f64 are f64 (unless a library call reads them).
    pub precision: Precision,
}

/// Where a scalar result is written.
#[derive(Clone, Debug, PartialEq)]
pub struct ScalarSlot {
    /// The IR value.
    pub value: Value,
    /// First slot in the `scalars` array.
    pub slot: usize,
    /// Complex results take `slot` and `slot + 1`.
    pub complex: bool,
}

/// How the runtime must call a kernel.
#[derive(Clone, Debug, PartialEq)]
pub struct Layout {
    /// Buffers in call order.
    pub buffers: Vec<BufferInfo>,
    /// Scalar results.
    pub scalars: Vec<ScalarSlot>,
    /// Total scalar slots.
    pub scalar_slots: usize,
    /// Number of fused loops.
    pub loops: usize,
    /// How many of them are split at an interval condition (emitted once
    /// for each side of it, see `Gen::emit_loop`).
    pub split_loops: usize,
    /// How many sums, in split loops, add nothing on one side (the
    /// condition makes their terms +0 there) and are not accumulated on it.
    pub sums_skipped: usize,
    /// The scene's precision (each buffer states its element type).
    pub precision: Precision,
    /// Per entry of [`Function::outputs`], the buffer holding it (`None`
    /// for a scalar, which has a slot in `scalars`).
    pub outputs: Vec<Option<usize>>,
    /// Per entry of [`Function::input_grads`], the buffer holding it
    /// (`None` for a scalar, which has a slot in `scalars`).
    pub input_grads: Vec<Option<usize>>,
}

impl Layout {
    /// A layout with no buffers, slots or loops yet, for a kernel in `precision`.
    pub(super) fn empty(precision: Precision) -> Layout {
        Layout {
            buffers: Vec::new(),
            scalars: Vec::new(),
            scalar_slots: 0,
            loops: 0,
            split_loops: 0,
            sums_skipped: 0,
            precision,
            outputs: Vec::new(),
            input_grads: Vec::new(),
        }
    }
}

/// Code generation failed (a compiler bug or an unsupported target).
#[derive(Clone, Debug)]
pub struct CodegenError(pub String);

impl fmt::Display for CodegenError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "code generation failed: {}", self.0)
    }
}

impl std::error::Error for CodegenError {}

pub(super) type KernelFn = unsafe extern "C" fn(*const f64, *const *mut u8, *mut f64);

/// What a library call in a kernel points at (a planned transform or a
/// tensor op's sizes); boxed so its address is stable.
pub(super) enum PlanBox {
    F64(Box<DftPlan<f64>>),
    F32(Box<DftPlan<f32>>),
    Tensor(Box<TensorOp>),
    Band(Box<BandPlan>),
}

impl PlanBox {
    pub(super) fn new(dft: Dft, n: usize, precision: Precision) -> PlanBox {
        match precision {
            Precision::F64 => PlanBox::F64(Box::new(DftPlan::new(dft, n))),
            Precision::F32 | Precision::Mixed => PlanBox::F32(Box::new(DftPlan::new(dft, n))),
        }
    }

    pub(super) fn work_floats(&self) -> usize {
        match self {
            PlanBox::F64(p) => p.work_floats(),
            PlanBox::F32(p) => p.work_floats(),
            PlanBox::Tensor(_) | PlanBox::Band(_) => 0,
        }
    }

    pub(super) fn address(&self) -> i64 {
        match self {
            PlanBox::F64(p) => &**p as *const DftPlan<f64> as i64,
            PlanBox::F32(p) => &**p as *const DftPlan<f32> as i64,
            PlanBox::Tensor(t) => &**t as *const TensorOp as i64,
            PlanBox::Band(b) => &**b as *const BandPlan as i64,
        }
    }
}

/// A JIT-compiled scene.
pub struct Kernel {
    pub(super) module: Option<JITModule>,
    /// Transform plans the code points at (kept alive with it).
    pub(super) _plans: Vec<PlanBox>,
    pub(super) entry: KernelFn,
    /// Calling convention.
    pub layout: Layout,
    /// Cranelift IR text (before optimisation), for `--emit clif`.
    pub clif: String,
    /// Cranelift instructions in the kernel.
    pub clif_insts: usize,
}

impl Kernel {
    /// Calls the kernel.
    ///
    /// # Safety
    /// `params` must hold one value per scene param, `buffers` one pointer per
    /// [`Layout::buffers`] entry to at least `len` (×2 if complex) elements of
    /// the layout's precision, writable for scratch and output buffers, and
    /// `scalars` at least [`Layout::scalar_slots`] values.
    pub unsafe fn call(&self, params: *const f64, buffers: *const *mut u8, scalars: *mut f64) {
        unsafe { (self.entry)(params, buffers, scalars) }
    }
}

// SAFETY: after `finalize_definitions` the kernel's code and data are never
// written again; the generated function keeps no state between calls (every
// buffer it touches is passed in by the caller), so one kernel may be called
// from several threads at once, each with its own buffers.
unsafe impl Send for Kernel {}
unsafe impl Sync for Kernel {}

impl Drop for Kernel {
    fn drop(&mut self) {
        if let Some(m) = self.module.take() {
            // SAFETY: the kernel is being dropped, so no pointer into its code survives.
            unsafe { m.free_memory() };
        }
    }
}

impl fmt::Debug for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Kernel").field("layout", &self.layout).finish()
    }
}
