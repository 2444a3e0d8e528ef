//! Accuracy sweeps of the inline math functions against libm (Rust std), and their speed benchmark (`bench`, ignored).

use super::*;
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{AbiParam, FuncRef, MemFlagsData, Signature, StackSlot, StackSlotData, StackSlotKind};
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::FunctionBuilderContext;
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::{default_libcall_names, Linkage, Module};
use std::collections::HashMap;

mod libm {
    unsafe extern "C" {
        pub fn sincos(x: f64, s: *mut f64, c: *mut f64);
        pub fn sincosf(x: f32, s: *mut f32, c: *mut f32);
    }
}

thread_local! {
    /// How many times this thread's kernels called libm's exp.
    static EXP_CALLS: std::cell::Cell<usize> = const { std::cell::Cell::new(0) };
}

/// libm's exp, counted in [`EXP_CALLS`] (kernels run on the test's thread).
extern "C" fn counted_exp(x: f64) -> f64 {
    EXP_CALLS.with(|c| c.set(c.get() + 1));
    x.exp()
}

fn symbols() -> Vec<(&'static str, *const u8)> {
    vec![
        ("sin", f64::sin as fn(f64) -> f64 as *const u8),
        ("cos", f64::cos as fn(f64) -> f64 as *const u8),
        ("exp", counted_exp as extern "C" fn(f64) -> f64 as *const u8),
        ("log", f64::ln as fn(f64) -> f64 as *const u8),
        ("cbrt", f64::cbrt as fn(f64) -> f64 as *const u8),
        ("pow", f64::powf as fn(f64, f64) -> f64 as *const u8),
        ("sincos", libm::sincos as *const u8),
        ("sinf", f32::sin as fn(f32) -> f32 as *const u8),
        ("cosf", f32::cos as fn(f32) -> f32 as *const u8),
        ("expf", f32::exp as fn(f32) -> f32 as *const u8),
        ("logf", f32::ln as fn(f32) -> f32 as *const u8),
        ("cbrtf", f32::cbrt as fn(f32) -> f32 as *const u8),
        ("powf", f32::powf as fn(f32, f32) -> f32 as *const u8),
        ("sincosf", libm::sincosf as *const u8),
    ]
}

/// The function a test kernel evaluates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Func {
    Sin,
    Cos,
    SinCos,
    Exp,
    Log,
    Cbrt,
    Pow,
}

/// Inline code in a mode, or a libm call per element (as codegen does today).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Imp {
    Inline(MathMode),
    Libm,
}

type LoopFn = unsafe extern "C" fn(*const u8, *const u8, *mut u8, *mut u8, i64);

/// A JIT loop `for i in 0..n { out0[i], out1[i] = f(a[i], b[i]) }`.
pub(super) struct Kernel {
    module: Option<JITModule>,
    entry: LoopFn,
}

impl Drop for Kernel {
    fn drop(&mut self) {
        if let Some(m) = self.module.take() {
            // SAFETY: no pointer into the module's code survives the kernel.
            unsafe { m.free_memory() };
        }
    }
}

impl Kernel {
    /// Runs the kernel over `a` (and `b` for pow) into `o0` (and `o1` for sincos).
    pub(super) fn run<T: Copy>(&self, a: &[T], b: &[T], o0: &mut [T], o1: &mut [T]) {
        assert!(b.len() >= a.len() && o0.len() >= a.len() && o1.len() >= a.len());
        // SAFETY: every buffer holds at least `a.len()` elements of the kernel's type.
        unsafe { (self.entry)(a.as_ptr().cast(), b.as_ptr().cast(), o0.as_mut_ptr().cast(), o1.as_mut_ptr().cast(), a.len() as i64) }
    }
}

/// JIT-compiles a loop evaluating `func` with `imp` on elements of type `ty`.
pub(super) fn build(func: Func, ty: Type, imp: Imp, fma: Option<bool>) -> Kernel {
    let mut flags = settings::builder();
    flags.set("opt_level", "speed").unwrap();
    let isa = cranelift_native::builder().unwrap().finish(settings::Flags::new(flags)).unwrap();
    let mut em = MathEmitter::new(&*isa, ty, if let Imp::Inline(m) = imp { m } else { MathMode::Exact });
    if let Some(f) = fma {
        em.fma = f;
    }
    let mut jb = JITBuilder::with_isa(isa, default_libcall_names());
    for (name, ptr) in symbols() {
        jb.symbol(name, ptr);
    }
    let mut module = JITModule::new(jb);
    let ptr = module.target_config().pointer_type();
    let call_conv = module.isa().default_call_conv();
    let mut ctx = module.make_context();
    for _ in 0..4 {
        ctx.func.signature.params.push(AbiParam::new(ptr));
    }
    ctx.func.signature.params.push(AbiParam::new(types::I64));
    let id = module.declare_function("k", Linkage::Export, &ctx.func.signature).unwrap();
    let mut fbc = FunctionBuilderContext::new();
    {
        let mut b = FunctionBuilder::new(&mut ctx.func, &mut fbc);
        let entry = b.create_block();
        b.append_block_params_for_function_params(entry);
        b.switch_to_block(entry);
        let p = b.block_params(entry).to_vec();
        let header = b.create_block();
        let body = b.create_block();
        let exit = b.create_block();
        b.append_block_param(header, types::I64);
        let zero = b.ins().iconst(types::I64, 0);
        b.ins().jump(header, &[BlockArg::Value(zero)]);
        b.switch_to_block(header);
        let i = b.block_params(header)[0];
        let more = b.ins().icmp(IntCC::SignedLessThan, i, p[4]);
        b.ins().brif(more, body, &[], exit, &[]);
        b.seal_block(body);
        b.switch_to_block(body);
        let off = b.ins().imul_imm_s(i, ty.bytes() as i64);
        let flags = MemFlagsData::trusted();
        let addr = |b: &mut FunctionBuilder, k: usize| b.ins().iadd(p[k], off);
        let pa = addr(&mut b, 0);
        let x = b.ins().load(ty, flags, pa, 0);
        let pb = addr(&mut b, 1);
        let y = b.ins().load(ty, flags, pb, 0);
        let f32 = ty == types::F32;
        let mut imports: HashMap<String, FuncRef> = HashMap::new();
        let mut slot: Option<StackSlot> = None;
        let mut slow = |b: &mut FunctionBuilder, name: &'static str, args: &[Value]| -> Vec<Value> {
            let full = if f32 { format!("{name}f") } else { name.to_string() };
            let fref = *imports.entry(full.clone()).or_insert_with(|| {
                let mut sig = Signature::new(call_conv);
                for _ in 0..if name == "pow" { 2 } else { 1 } {
                    sig.params.push(AbiParam::new(ty));
                }
                if name == "sincos" {
                    sig.params.push(AbiParam::new(ptr));
                    sig.params.push(AbiParam::new(ptr));
                } else {
                    sig.returns.push(AbiParam::new(ty));
                }
                let id = module.declare_function(&full, Linkage::Import, &sig).unwrap();
                module.declare_func_in_func(id, b.func)
            });
            if name == "sincos" {
                let s = *slot.get_or_insert_with(|| b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 3)));
                let size = ty.bytes() as i32;
                let ps = b.ins().stack_addr(ptr, s, 0);
                let pc = b.ins().stack_addr(ptr, s, size);
                b.ins().call(fref, &[args[0], ps, pc]);
                vec![b.ins().stack_load(ptr, ty, s, 0), b.ins().stack_load(ptr, ty, s, size)]
            } else {
                let c = b.ins().call(fref, args);
                b.inst_results(c).to_vec()
            }
        };
        let out: Vec<Value> = match (imp, func) {
            (Imp::Libm, Func::SinCos) => slow(&mut b, "sincos", &[x]),
            (Imp::Libm, Func::Pow) => slow(&mut b, "pow", &[x, y]),
            (Imp::Libm, f) => {
                let name = match f {
                    Func::Sin => "sin",
                    Func::Cos => "cos",
                    Func::Exp => "exp",
                    Func::Log => "log",
                    _ => "cbrt",
                };
                slow(&mut b, name, &[x])
            }
            (Imp::Inline(_), Func::Sin) => vec![em.sin(&mut b, x, &mut slow)],
            (Imp::Inline(_), Func::Cos) => vec![em.cos(&mut b, x, &mut slow)],
            (Imp::Inline(_), Func::SinCos) => {
                let (s, c) = em.sincos(&mut b, x, &mut slow);
                vec![s, c]
            }
            (Imp::Inline(_), Func::Exp) => vec![em.exp(&mut b, x, &mut slow)],
            (Imp::Inline(_), Func::Log) => vec![em.log(&mut b, x, &mut slow)],
            (Imp::Inline(_), Func::Cbrt) => vec![em.cbrt(&mut b, x, &mut slow)],
            (Imp::Inline(_), Func::Pow) => vec![em.pow(&mut b, x, y, &mut slow)],
        };
        for (k, v) in out.into_iter().enumerate() {
            let po = addr(&mut b, 2 + k);
            b.ins().store(flags, v, po, 0);
        }
        let next = b.ins().iadd_imm_s(i, 1);
        b.ins().jump(header, &[BlockArg::Value(next)]);
        b.seal_block(header);
        b.seal_block(exit);
        b.switch_to_block(exit);
        b.ins().return_(&[]);
        b.seal_all_blocks();
        b.finalize(module.target_config());
    }
    let disasm = std::env::var("MATHLIB_DISASM").is_ok_and(|v| v == format!("{func:?}"));
    ctx.set_disasm(disasm);
    module.define_function(id, &mut ctx).unwrap_or_else(|e| panic!("{e:?}\n{}", ctx.func.display()));
    if disasm {
        println!("{func:?} {ty} {imp:?}:\n{}", ctx.compiled_code().and_then(|c| c.vcode.clone()).unwrap_or_default());
    }
    module.clear_context(&mut ctx);
    module.finalize_definitions().unwrap();
    let code = module.get_finalized_function(id);
    // SAFETY: `code` is the finalized function with the signature declared above.
    let entry = unsafe { std::mem::transmute::<*const u8, LoopFn>(code) };
    Kernel { module: Some(module), entry }
}

/// SplitMix64.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn unif(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
    }
    /// ±2^u·m with u uniform in [lo, hi), m uniform in [1, 2).
    fn logspace(&mut self, lo: f64, hi: f64, signed: bool) -> f64 {
        let v = self.unif(lo, hi).exp2() * self.unif(1.0, 2.0);
        if signed && self.next() & 1 == 1 {
            -v
        } else {
            v
        }
    }
}

const N: usize = 100_000;

/// Special values every sweep includes.
fn specials() -> Vec<f64> {
    let mut v = vec![0.0, -0.0, 1e-300, -1e-300, 5e-324, -5e-324, 1e-310, f64::MIN_POSITIVE, 1.0, -1.0, 2.0, 0.5, 1e300, -1e300];
    v.extend([f64::MAX, -f64::MAX, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e-20, -1e-20, 1e5, -1e5, 1e6, -1e6]);
    v
}

/// Named sweeps of (x, y) inputs for `f`.
pub(super) fn domains(f: Func) -> Vec<(&'static str, Vec<f64>, Vec<f64>)> {
    let mut rng = Rng(0x5eed_0000 + f as u64);
    let mut d: Vec<(&'static str, Vec<f64>, Vec<f64>)> = Vec::new();
    let uni = |name, a: f64, b: f64, rng: &mut Rng| (name, (0..N).map(|_| rng.unif(a, b)).collect::<Vec<_>>(), vec![0.0; N]);
    match f {
        Func::Sin | Func::Cos | Func::SinCos => {
            d.push(uni("[-4,4]", -4.0, 4.0, &mut rng));
            d.push(uni("[-1e5,1e5]", -1e5, 1e5, &mut rng));
            d.push(uni("[-2e6,2e6]", -2e6, 2e6, &mut rng));
            // Doubles nearest to multiples of π/2 (and their neighbours), k up to 1e6.
            let mut v = specials();
            for j in 0..N / 4 {
                let k = if j < 2000 { j as f64 } else { (rng.next() % 1_000_000) as f64 };
                let x = k * std::f64::consts::FRAC_PI_2;
                let b = x.to_bits();
                v.extend([x, f64::from_bits(b + 1), f64::from_bits(b.saturating_sub(1)), -x]);
            }
            d.push(("k·π/2 ± ulp, specials", v, vec![0.0; N + 100]));
        }
        Func::Exp => {
            d.push(uni("[-1,1]", -1.0, 1.0, &mut rng));
            d.push(uni("[-746,710]", -746.0, 710.0, &mut rng));
            let mut v = specials();
            v.extend([708.0, -708.0, 707.999, 709.78, 709.79, -745.13, -745.14, 1e-17, -1e-17]);
            v.extend((0..N).map(|_| rng.logspace(-60.0, 10.0, true)));
            d.push(("±2^[-60,10], specials", v, vec![0.0; N + 100]));
        }
        Func::Log | Func::Cbrt => {
            let signed = f == Func::Cbrt;
            d.push(uni("[0.5,2]", 0.5, 2.0, &mut rng));
            let v: Vec<f64> = (0..N).map(|_| rng.logspace(-1074.0, 1024.0, signed)).collect();
            d.push(("±2^[-1074,1024]", v, vec![0.0; N]));
            let mut v = specials();
            v.extend((0..N).map(|_| 1.0 + rng.unif(-1e-6, 1e-6)));
            v.extend([-8.0, 27.0, 1e-308, 3e-308, 1.0 - f64::EPSILON / 2.0, 1.0 + f64::EPSILON]);
            d.push(("1±1e-6, specials", v, vec![0.0; N + 100]));
        }
        Func::Pow => {
            let x: Vec<f64> = (0..N).map(|_| rng.logspace(-10.0, 10.0, false)).collect();
            let y: Vec<f64> = (0..N).map(|_| rng.unif(-20.0, 20.0)).collect();
            d.push(("x∈2^[-10,10], y∈[-20,20]", x, y));
            let x: Vec<f64> = (0..N).map(|_| rng.unif(0.9, 1.1)).collect();
            let y: Vec<f64> = (0..N).map(|_| rng.unif(-5000.0, 5000.0)).collect();
            d.push(("x∈[0.9,1.1], y∈[-5e3,5e3]", x, y));
            let s = specials();
            let ys =
                [0.0, -0.0, 1.0, -1.0, 2.0, 3.0, -3.0, 0.5, 1.5, 1e10, -1e10, 400.0, -400.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
            let (mut x, mut y) = (Vec::new(), Vec::new());
            for &a in &s {
                for &b in &ys {
                    x.push(a);
                    y.push(b);
                }
            }
            for _ in 0..N {
                x.push(rng.logspace(-1074.0, 1024.0, true));
                y.push(rng.unif(-3.0, 3.0));
            }
            d.push(("specials, x∈±2^[-1074,1024]", x, y));
        }
    }
    d
}

fn reference(f: Func, x: f64, y: f64) -> (f64, f64) {
    match f {
        Func::Sin => (x.sin(), 0.0),
        Func::Cos => (x.cos(), 0.0),
        Func::SinCos => (x.sin(), x.cos()),
        Func::Exp => (x.exp(), 0.0),
        Func::Log => (x.ln(), 0.0),
        Func::Cbrt => (x.cbrt(), 0.0),
        Func::Pow => (x.powf(y), 0.0),
    }
}

fn reference32(f: Func, x: f32, y: f32) -> (f32, f32) {
    match f {
        Func::Sin => (x.sin(), 0.0),
        Func::Cos => (x.cos(), 0.0),
        Func::SinCos => (x.sin(), x.cos()),
        Func::Exp => (x.exp(), 0.0),
        Func::Log => (x.ln(), 0.0),
        Func::Cbrt => (x.cbrt(), 0.0),
        Func::Pow => (x.powf(y), 0.0),
    }
}

/// Error of `y` against `r`: in units of `ulp` if given, else relative. NaN/inf/zero-sign mismatches are infinite.
fn err(y: f64, r: f64, ulp: Option<f64>) -> f64 {
    if y.is_nan() && r.is_nan() {
        return 0.0;
    }
    if y == r {
        return if y == 0.0 && y.is_sign_negative() != r.is_sign_negative() { f64::INFINITY } else { 0.0 };
    }
    if !y.is_finite() || !r.is_finite() {
        return f64::INFINITY;
    }
    match ulp {
        Some(u) => (y - r).abs() / u,
        None => (y - r).abs() / r.abs().max(f64::MIN_POSITIVE),
    }
}

fn ulp64(r: f64) -> f64 {
    let a = r.abs();
    f64::from_bits(a.to_bits() + 1) - a
}

fn ulp32(r: f32) -> f64 {
    let a = r.abs();
    (f32::from_bits(a.to_bits() + 1) - a) as f64
}

/// Max error of `imp` on each domain of `f` (f64: ulps for Exact, relative otherwise; f32: f32 ulps).
pub(super) fn max_errors(f: Func, ty: Type, imp: Imp, fma: Option<bool>) -> Vec<(&'static str, f64, f64)> {
    let k = build(f, ty, imp, fma);
    let ulps = ty == types::F32 || imp == Imp::Inline(MathMode::Exact);
    let mut out = Vec::new();
    for (name, xs, ys) in domains(f) {
        let n = xs.len();
        let (mut worst, mut at) = (0.0f64, f64::NAN);
        if ty == types::F64 {
            let (mut o0, mut o1) = (vec![0.0f64; n], vec![0.0f64; n]);
            k.run(&xs, &ys, &mut o0, &mut o1);
            for i in 0..n {
                let (r0, r1) = reference(f, xs[i], ys[i]);
                let mut e = err(o0[i], r0, ulps.then(|| ulp64(r0)));
                if f == Func::SinCos {
                    e = e.max(err(o1[i], r1, ulps.then(|| ulp64(r1))));
                }
                if e > worst || e.is_nan() {
                    (worst, at) = (e, xs[i]);
                }
            }
        } else {
            let xs: Vec<f32> = xs.iter().map(|&v| v as f32).collect();
            let ys: Vec<f32> = ys.iter().map(|&v| v as f32).collect();
            let (mut o0, mut o1) = (vec![0.0f32; n], vec![0.0f32; n]);
            k.run(&xs, &ys, &mut o0, &mut o1);
            for i in 0..n {
                let (r0, r1) = reference32(f, xs[i], ys[i]);
                let mut e = err(o0[i] as f64, r0 as f64, Some(ulp32(r0)));
                if f == Func::SinCos {
                    e = e.max(err(o1[i] as f64, r1 as f64, Some(ulp32(r1))));
                }
                if e > worst || e.is_nan() {
                    (worst, at) = (e, xs[i] as f64);
                }
            }
        }
        out.push((name, worst, at));
    }
    out
}

/// Documented bounds: f64 Exact in ulps, f64 Fast/Fastest relative, f32 in f32 ulps.
fn bound(ty: Type, mode: MathMode) -> f64 {
    match (ty == types::F32, mode) {
        (false, MathMode::Exact) => 2.0,
        (false, MathMode::Fast) => 1e-12,
        (false, MathMode::Fastest) => 1e-7,
        (true, MathMode::Exact) => 1.0,
        (true, _) => 2.0,
    }
}

fn check(f: Func) {
    let mut failures = Vec::new();
    for ty in [types::F64, types::F32] {
        for mode in [MathMode::Exact, MathMode::Fast, MathMode::Fastest] {
            let fmas: &[Option<bool>] = if ty == types::F64 && mode == MathMode::Exact { &[None, Some(false)] } else { &[None] };
            for &fma in fmas {
                for (dom, e, at) in max_errors(f, ty, Imp::Inline(mode), fma) {
                    let unit = if ty == types::F32 || mode == MathMode::Exact { "ulp" } else { "rel" };
                    let nofma = if fma == Some(false) { " (no FMA)" } else { "" };
                    println!("| {f:?} | {ty} | {mode:?}{nofma} | {dom} | {e:.3e} {unit} | x={at:e} |");
                    if !(e <= bound(ty, mode)) {
                        failures.push(format!("{f:?} {ty} {mode:?}{nofma} on {dom}: {e:e} {unit} at x={at:e}"));
                    }
                }
            }
        }
    }
    assert!(failures.is_empty(), "errors above bound:\n{}", failures.join("\n"));
}

#[test]
fn accuracy_sincos() {
    check(Func::SinCos);
}

#[test]
fn accuracy_sin() {
    check(Func::Sin);
}

#[test]
fn accuracy_cos() {
    check(Func::Cos);
}

#[test]
fn accuracy_exp() {
    check(Func::Exp);
}

/// Arguments whose e^x rounds to +0 (the far tails of a Gaussian
/// envelope) get +0 inline, without libm, in every inline mode; just above
/// [`EXP_ZERO`], where e^x is subnormal, libm still computes it.
#[test]
fn exp_underflow_is_zero_inline() {
    let tails: Vec<f64> = (1..1000).map(|k| EXP_ZERO - 0.5 * k as f64 * k as f64).chain([-1e300, f64::NEG_INFINITY]).collect();
    for mode in [MathMode::Exact, MathMode::Fast, MathMode::Fastest] {
        let kernel = build(Func::Exp, types::F64, Imp::Inline(mode), None);
        let (mut out, mut unused) = (vec![1.0; tails.len()], vec![0.0; tails.len()]);
        let before = EXP_CALLS.with(|c| c.get());
        kernel.run(&tails, &vec![0.0; tails.len()], &mut out, &mut unused);
        assert_eq!(EXP_CALLS.with(|c| c.get()), before, "{mode:?}: libm called for an underflowing exp");
        assert!(out.iter().all(|y| y.to_bits() == 0), "{mode:?}: e^x of the tails is not +0");
        let subnormal = [-745.0, -720.0, -708.5];
        let (mut out, mut unused) = ([0.0; 3], [0.0; 3]);
        kernel.run(&subnormal, &[0.0; 3], &mut out, &mut unused);
        assert_eq!(EXP_CALLS.with(|c| c.get()), before + 3, "{mode:?}: subnormal results come from libm");
        assert_eq!(out, subnormal.map(f64::exp), "{mode:?}");
    }
}

#[test]
fn accuracy_log() {
    check(Func::Log);
}

#[test]
fn accuracy_cbrt() {
    check(Func::Cbrt);
}

#[test]
fn accuracy_pow() {
    check(Func::Pow);
}

/// FMA is used exactly when the CPU has it (cranelift_native enables `has_fma`).
#[test]
fn fma_detection() {
    let isa = cranelift_native::builder().unwrap().finish(settings::Flags::new(settings::builder())).unwrap();
    #[cfg(target_arch = "x86_64")]
    assert_eq!(isa_has_fma(&*isa), std::is_x86_feature_detected!("fma"));
    println!("isa {} has_fma = {}", isa.name(), isa_has_fma(&*isa));
}

/// The error measure is not vacuous: libm's sin vs a 1-ulp-perturbed copy is caught.
#[test]
fn error_measure_detects_mistakes() {
    let r = 0.7f64.sin();
    assert_eq!(err(f64::from_bits(r.to_bits() + 3), r, Some(ulp64(r))), 3.0);
    assert!(err(-0.0, 0.0, None).is_infinite());
    assert!(err(f64::NAN, 1.0, None).is_infinite());
    assert!(err(1.0 + 1e-6, 1.0, None) > 1e-7);
}

/// ns/element of a JIT loop over 8192 elements, inline modes vs a libm call per element.
/// Run: `CARGO_TARGET_DIR=/work/target-math cargo test --release -p gwml-compiler mathlib::tests::bench -- --ignored --nocapture`
#[test]
#[ignore]
fn bench() {
    const LEN: usize = 8192;
    let mut rng = Rng(42);
    let funcs = [
        (Func::SinCos, "sincos x∈[0,1e5]"),
        (Func::Sin, "sin x∈[0,1e5]"),
        (Func::Cos, "cos x∈[0,1e5]"),
        (Func::Exp, "exp x∈[-50,50]"),
        (Func::Log, "log x∈2^[-20,20]"),
        (Func::Cbrt, "cbrt x∈±2^[-20,20]"),
        (Func::Pow, "pow x∈2^[-10,10], y∈[-3,3]"),
    ];
    println!("ns/element, median (min) of 41 rounds of 5 × {LEN} elements");
    println!("| function | type | libm | Exact | Fast | Fastest |");
    println!("|---|---|---|---|---|---|");
    for (f, label) in funcs {
        let xs: Vec<f64> = (0..LEN)
            .map(|_| match f {
                Func::Sin | Func::Cos | Func::SinCos => rng.unif(0.0, 1e5),
                Func::Exp => rng.unif(-50.0, 50.0),
                Func::Log => rng.logspace(-20.0, 20.0, false),
                Func::Cbrt => rng.logspace(-20.0, 20.0, true),
                Func::Pow => rng.logspace(-10.0, 10.0, false),
            })
            .collect();
        let ys: Vec<f64> = (0..LEN).map(|_| rng.unif(-3.0, 3.0)).collect();
        for ty in [types::F64, types::F32] {
            let imps = [Imp::Libm, Imp::Inline(MathMode::Exact), Imp::Inline(MathMode::Fast), Imp::Inline(MathMode::Fastest)];
            let kernels: Vec<Kernel> = imps.iter().map(|&imp| build(f, ty, imp, None)).collect();
            let (x32, y32): (Vec<f32>, Vec<f32>) = (xs.iter().map(|&v| v as f32).collect(), ys.iter().map(|&v| v as f32).collect());
            let (mut o0, mut o1) = (vec![0.0f64; LEN], vec![0.0f64; LEN]);
            let (mut p0, mut p1) = (vec![0.0f32; LEN], vec![0.0f32; LEN]);
            // Round-robin over the implementations so machine noise hits all of them alike.
            let mut samples = vec![Vec::new(); imps.len()];
            for _ in 0..41 {
                for (k, s) in kernels.iter().zip(samples.iter_mut()) {
                    let t = std::time::Instant::now();
                    for _ in 0..5 {
                        if ty == types::F64 {
                            k.run(&xs, &ys, &mut o0, &mut o1);
                        } else {
                            k.run(&x32, &y32, &mut p0, &mut p1);
                        }
                    }
                    s.push(t.elapsed().as_secs_f64() / (5 * LEN) as f64 * 1e9);
                }
            }
            let mut row = format!("| {label} | {ty} |");
            for s in &mut samples {
                s.sort_by(f64::total_cmp);
                row += &format!(" {:.2} ({:.2}) |", s[s.len() / 2], s[0]);
            }
            println!("{row}");
        }
    }
}
