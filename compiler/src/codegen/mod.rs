//! Optimised IR ([`Function`]) in, a JIT-compiled [`Kernel`] with its [`Layout`] out.
//!
//! Code generation: fuse the optimised IR into loops and JIT-compile it
//! with Cranelift.
//!
//! # Fusion
//! Every value gets an *epoch*: reductions finish at the end of a loop, so
//! `epoch(reduce(x)) = epoch(x) + 1` and every other value takes the largest
//! epoch of its operands. All array instructions of one epoch over one grid
//! run in ONE loop, together with the reductions that consume them. A
//! forward pass and the adjoint of an elementwise chain (whose seeds do not
//! depend on a reduction) therefore share a loop, and the gradients w.r.t.
//! scalar params accumulate in registers with no intermediate arrays.
//! Arrays are stored to a scratch buffer only when a later loop reads them
//! or they are outputs. A transform (`Op::Dft`) behaves like a reduction
//! for scheduling (`epoch(dft(x)) = epoch(x) + 1`): its operand is stored,
//! the call runs before the loops of its epoch, and they read its result
//! from its buffer. Broadcasts, grid coordinates and inputs are
//! recomputed (or reloaded) in each loop that uses them.
//!
//! # Kernel ABI
//! `extern "C" fn(params: *const f64, buffers: *const *mut u8, scalars: *mut f64)`:
//! `params` holds the scene's params in base units; `buffers[k]` points at
//! buffer `k` of [`Layout::buffers`] (elements of the buffer's precision,
//! complex interleaved re/im) holding exactly `len` elements, which the
//! runtime guarantees; scalar results are written as f64 to
//! `scalars[slot]` (complex results take two slots).
//!
//! # Files
//! This file drives compilation and holds the emitter state (`Gen`);
//! `abi` the calling convention ([`Layout`], [`Kernel`]); `schedule` the
//! epochs, loops and buffers; `loops` the emission of the body and of
//! each fused loop; `vector` vectorised loops; `elementwise` one
//! instruction's code; `math` math functions and library-call imports;
//! `mathlib` the inline transcendental functions.

mod abi;
mod elementwise;
mod loops;
mod math;
pub mod mathlib;
mod schedule;
#[cfg(test)]
mod tests;
mod vector;

pub use abi::{BufferInfo, BufferKind, CodegenError, Kernel, Layout, ScalarSlot};

use crate::ir::*;
use abi::{KernelFn, PlanBox};
use cranelift_codegen::ir::{types, AbiParam, FuncRef, Type};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};
use elementwise::Cv;
use math::libm_symbols;
use mathlib::MathEmitter;
use schedule::{schedule, Schedule};
use std::collections::{HashMap, HashSet};
use std::fmt;

/// Compiles `func` (optimised IR) to a native kernel.
pub fn compile(func: &Function) -> Result<Kernel, CodegenError> {
    compile_with(func, false).map(|(kernel, _)| kernel)
}

/// The machine code `func` compiles to, as Cranelift prints it (its VCode:
/// one block per label, stack slots as `<offset:1>+N(%rsp)`), for `--emit
/// asm`. Compiles the kernel again with the disassembler on, which
/// [`compile`] leaves off because it slows compilation.
pub fn disassemble(func: &Function) -> Result<String, CodegenError> {
    compile_with(func, true).map(|(_, asm)| asm.unwrap_or_default())
}

/// [`compile`], also returning the disassembly when `disasm` is set.
fn compile_with(func: &Function, disasm: bool) -> Result<(Kernel, Option<String>), CodegenError> {
    let err = |e: &dyn fmt::Display| CodegenError(e.to_string());
    if let Some(problem) = f32_range_problem(func) {
        return Err(CodegenError(problem));
    }
    let mut flags = settings::builder();
    flags.set("opt_level", "speed").map_err(|e| err(&e))?;
    flags.set("enable_verifier", if cfg!(debug_assertions) { "true" } else { "false" }).map_err(|e| err(&e))?;
    let isa = cranelift_native::builder().map_err(|e| err(&e))?.finish(settings::Flags::new(flags)).map_err(|e| err(&e))?;
    let mut jb = JITBuilder::with_isa(isa, default_libcall_names());
    for (name, ptr) in libm_symbols() {
        jb.symbol(name, ptr);
    }
    let mut module = JITModule::new(jb);
    let ptr = module.target_config().pointer_type();
    let mut ctx = module.make_context();
    for _ in 0..3 {
        ctx.func.signature.params.push(AbiParam::new(ptr));
    }
    let id = module.declare_function("gwml_kernel", Linkage::Export, &ctx.func.signature).map_err(|e| err(&e))?;
    let mut layout = Layout::empty(func.precision);
    let storage = func.precision.storage();
    let wide = crate::passes::precision::wide_values(func);
    for (i, input) in func.inputs.iter().enumerate() {
        // Inputs mixed precision keeps in f64 (values a prelude computed) arrive in f64.
        let kept_wide = func.insts.iter().enumerate().any(|(v, inst)| wide[v] && inst.op == Op::Input(i as u32));
        let precision = if kept_wide && input.role == InputRole::Cached { Precision::F64 } else { storage };
        layout.buffers.push(BufferInfo {
            kind: BufferKind::Input(i),
            len: func.len_of(input.ty.shape),
            complex: input.ty.elem == Elem::Complex,
            precision,
        });
    }
    for (k, t) in func.tables.iter().enumerate() {
        let phase = func.insts.iter().enumerate().any(|(i, inst)| wide[i] && inst.op == Op::Table(k as u32));
        let precision = if phase { Precision::F64 } else { storage };
        layout.buffers.push(BufferInfo { kind: BufferKind::Table(k), len: t.data.len(), complex: false, precision });
    }
    let mut plans = Vec::new();
    let sched = schedule(func, &wide, &mut layout, &mut plans);
    layout.loops = sched.loops.len();
    for r in func.roots() {
        let ty = func.ty(r);
        if ty.shape == Shape::Scalar && !layout.scalars.iter().any(|s| s.value == r) {
            let complex = ty.elem == Elem::Complex;
            layout.scalars.push(ScalarSlot { value: r, slot: layout.scalar_slots, complex });
            layout.scalar_slots += if complex { 2 } else { 1 };
        }
    }
    let mut fbc = FunctionBuilderContext::new();
    let storage_ty = if storage == Precision::F32 { types::F32 } else { types::F64 };
    let math64 = MathEmitter::new(module.isa(), types::F64, func.math);
    let math32 = MathEmitter::new(module.isa(), types::F32, func.math);
    let sums_skipped = {
        let b = FunctionBuilder::new(&mut ctx.func, &mut fbc);
        let mut g = Gen {
            func,
            b,
            module: &mut module,
            layout: &layout,
            sched: &sched,
            vals: HashMap::new(),
            imports: HashMap::new(),
            ptr,
            bufs: Vec::new(),
            ft: storage_ty,
            storage: storage_ty,
            wide,
            vector: None,
            sincos_slot: None,
            sums_skipped: HashSet::new(),
            plans: &plans,
            math64,
            math32,
        };
        g.emit_body()?;
        g.b.seal_all_blocks();
        let cfg = g.module.target_config();
        g.b.finalize(cfg);
        g.sums_skipped.len()
    };
    layout.sums_skipped = sums_skipped;
    let clif = ctx.func.display().to_string();
    let clif_insts = ctx.func.dfg.num_insts();
    ctx.set_disasm(disasm);
    module.define_function(id, &mut ctx).map_err(|e| CodegenError(format!("{e:?}")))?;
    let asm = ctx.compiled_code().and_then(|c| c.vcode.clone());
    module.clear_context(&mut ctx);
    module.finalize_definitions().map_err(|e| err(&e))?;
    let code = module.get_finalized_function(id);
    // SAFETY: `code` is the finalized function with the signature declared above.
    let entry: KernelFn = unsafe { std::mem::transmute::<*const u8, KernelFn>(code) };
    Ok((Kernel { module: Some(module), _plans: plans, entry, layout, clif, clif_insts }, asm))
}

/// In f32, a value (or table) whose largest magnitude at the scene's
/// defaults is outside f32's normal range would flush to 0 or overflow, and
/// a masked division could turn that into a silently wrong result: such a
/// scene is refused, pointing to mixed precision.
fn f32_range_problem(func: &Function) -> Option<String> {
    if func.precision != Precision::F32 {
        return None;
    }
    let (lo, hi) = (f32::MIN_POSITIVE as f64, f32::MAX as f64);
    let out = |m: f64| m > 0.0 && (m < lo || m > hi);
    let what = if let Some(t) = func.tables.iter().position(|t| out(t.data.iter().fold(0.0, |m, x| m.max(x.abs())))) {
        format!("a precomputed table (table {t})")
    } else {
        let magnitudes = crate::passes::precision::default_magnitudes(func)?;
        // Constants (and their broadcasts) are exempt: `masked_div` compares
        // with f64::MAX, which is +inf in f32 and still masks what it should.
        let computed = |i: usize| !matches!(func.insts[i].op, Op::Const(_) | Op::Broadcast(..)) && func.insts[i].ty.elem != Elem::Bool;
        let i = (0..func.insts.len()).find(|i| computed(*i) && out(magnitudes[*i]))?;
        format!("value %{i} (largest magnitude {:e} at the scene's defaults)", magnitudes[i])
    };
    Some(format!(
        "precision f32 cannot hold {what}: it is outside f32's range 1.2e-38..3.4e38; use `precision: mixed`, which computes such values in f64"
    ))
}

struct Gen<'a> {
    func: &'a Function,
    b: FunctionBuilder<'a>,
    module: &'a mut JITModule,
    layout: &'a Layout,
    sched: &'a Schedule,
    /// Scalars and reduction results (valid everywhere after definition).
    vals: HashMap<usize, Cv>,
    imports: HashMap<&'static str, FuncRef>,
    ptr: Type,
    bufs: Vec<cranelift_codegen::ir::Value>,
    /// The float type of the instruction being emitted (the lane type in a
    /// vectorised loop).
    ft: Type,
    /// In a vectorised loop: its lane type, whose values are 128-bit
    /// vectors of that type. In an f32x4 loop of a mixed-precision scene,
    /// the values computed in f64 are *split*: two f64x2 halves per four
    /// lanes ([`Gen::wide_operand`]).
    vector: Option<Type>,
    /// The float type of inputs, outputs and library-call buffers.
    storage: Type,
    /// Per instruction: computed in f64 although the storage is f32
    /// ([`crate::passes::precision::wide_values`]).
    wide: Vec<bool>,
    sincos_slot: Option<cranelift_codegen::ir::StackSlot>,
    /// Sums not accumulated on a side of a split loop (see [`Gen::known_zero`]).
    sums_skipped: HashSet<usize>,
    plans: &'a [PlanBox],
    math64: MathEmitter,
    math32: MathEmitter,
}

/// Per-iteration state of one loop.
struct LoopCtx {
    epoch: u32,
    index: cranelift_codegen::ir::Value,
    /// Values in the loop's lane type.
    vals: HashMap<usize, Cv>,
    /// In a split loop: values as two f64x2 halves (lanes 0–1, 2–3).
    halves: HashMap<usize, [Cv; 2]>,
    /// An interval condition whose truth is known over the index range
    /// being emitted (see [`Gen::emit_loop`]): selects on it take one side.
    known: Option<(usize, bool)>,
}

impl Gen<'_> {
    fn f32(&self) -> bool {
        self.ft == types::F32
    }
}
