//! Math functions: inline (`mathlib`) or libm per the scene's `math` knob, library-call imports, and constant powers.

use super::mathlib::{SlowPath, EXP_ZERO};
use super::{CodegenError, Gen};
use crate::ir::*;
use crate::kernels::band;
use crate::kernels::dft::{gwml_dft_f32, gwml_dft_f64};
use crate::kernels::tensor::{gwml_tensor_f32, gwml_tensor_f64};
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, AbiParam, BlockArg, FuncRef, InstBuilder, Signature, StackSlotData, StackSlotKind};
use cranelift_frontend::FunctionBuilder;
use cranelift_module::{Linkage, Module};
use std::collections::HashMap;

/// libm functions the kernels may call, resolved to this process's symbols.
mod libm {
    unsafe extern "C" {
        pub fn cbrt(x: f64) -> f64;
        pub fn exp(x: f64) -> f64;
        pub fn log(x: f64) -> f64;
        pub fn sin(x: f64) -> f64;
        pub fn cos(x: f64) -> f64;
        pub fn tan(x: f64) -> f64;
        pub fn tanh(x: f64) -> f64;
        pub fn pow(x: f64, y: f64) -> f64;
        pub fn atan2(y: f64, x: f64) -> f64;
        pub fn sincos(x: f64, s: *mut f64, c: *mut f64);
        pub fn cbrtf(x: f32) -> f32;
        pub fn expf(x: f32) -> f32;
        pub fn logf(x: f32) -> f32;
        pub fn sinf(x: f32) -> f32;
        pub fn cosf(x: f32) -> f32;
        pub fn tanf(x: f32) -> f32;
        pub fn tanhf(x: f32) -> f32;
        pub fn powf(x: f32, y: f32) -> f32;
        pub fn atan2f(y: f32, x: f32) -> f32;
        pub fn sincosf(x: f32, s: *mut f32, c: *mut f32);
    }
}

/// Below this, f32 e^x rounds to +0: it is under half of f32's least
/// subnormal, 2^-150, for x < −150·ln 2 = −103.97….
const EXP_ZERO_F32: f32 = -104.0;

const MATH1: &[&str] = &["cbrt", "exp", "log", "sin", "cos", "tan", "tanh"];
const MATH2: &[&str] = &["pow", "atan2"];

pub(super) fn libm_symbols() -> Vec<(&'static str, *const u8)> {
    vec![
        ("cbrt", libm::cbrt as *const u8),
        ("exp", libm::exp as *const u8),
        ("log", libm::log as *const u8),
        ("sin", libm::sin as *const u8),
        ("cos", libm::cos as *const u8),
        ("tan", libm::tan as *const u8),
        ("tanh", libm::tanh as *const u8),
        ("pow", libm::pow as *const u8),
        ("atan2", libm::atan2 as *const u8),
        ("sincos", libm::sincos as *const u8),
        ("cbrtf", libm::cbrtf as *const u8),
        ("expf", libm::expf as *const u8),
        ("logf", libm::logf as *const u8),
        ("sinf", libm::sinf as *const u8),
        ("cosf", libm::cosf as *const u8),
        ("tanf", libm::tanf as *const u8),
        ("tanhf", libm::tanhf as *const u8),
        ("powf", libm::powf as *const u8),
        ("atan2f", libm::atan2f as *const u8),
        ("sincosf", libm::sincosf as *const u8),
        ("gwml_dft_f64", gwml_dft_f64 as *const u8),
        ("gwml_dft_f32", gwml_dft_f32 as *const u8),
        ("gwml_tensor_f64", gwml_tensor_f64 as *const u8),
        ("gwml_tensor_f32", gwml_tensor_f32 as *const u8),
        ("gwml_band_f64", band::gwml_band_f64 as *const u8),
        ("gwml_band_f32", band::gwml_band_f32 as *const u8),
        ("gwml_band_f64_f32", band::gwml_band_f64_f32 as *const u8),
        ("gwml_band_f32_f64", band::gwml_band_f32_f64 as *const u8),
    ]
}

impl Gen<'_> {
    pub(super) fn import(&mut self, name: &'static str) -> Result<FuncRef, CodegenError> {
        if let Some(f) = self.imports.get(name) {
            return Ok(*f);
        }
        let ft = self.ft;
        let mut sig = Signature::new(self.module.isa().default_call_conv());
        let base = name.strip_suffix('f').filter(|b| MATH1.contains(b) || MATH2.contains(b) || *b == "sincos").unwrap_or(name);
        if name.starts_with("gwml_dft_") || name.starts_with("gwml_tensor_") {
            // (plan, input, output, work): see `dft::gwml_dft_f64`;
            // (op, a, b, output): see `tensor::gwml_tensor_f64`.
            for _ in 0..4 {
                sig.params.push(AbiParam::new(self.ptr));
            }
        } else if name.starts_with("gwml_band_") {
            // (plan, input, output): see `band::gwml_band_f64`.
            for _ in 0..3 {
                sig.params.push(AbiParam::new(self.ptr));
            }
        } else if base == "sincos" {
            sig.params.push(AbiParam::new(ft));
            sig.params.push(AbiParam::new(self.ptr));
            sig.params.push(AbiParam::new(self.ptr));
        } else {
            let arity = if MATH2.contains(&base) { 2 } else { 1 };
            for _ in 0..arity {
                sig.params.push(AbiParam::new(ft));
            }
            sig.returns.push(AbiParam::new(ft));
        }
        let id = self.module.declare_function(name, Linkage::Import, &sig).map_err(|e| CodegenError(e.to_string()))?;
        let f = self.module.declare_func_in_func(id, self.b.func);
        self.imports.insert(name, f);
        Ok(f)
    }

    pub(super) fn call(
        &mut self,
        base: &'static str,
        args: &[cranelift_codegen::ir::Value],
    ) -> Result<cranelift_codegen::ir::Value, CodegenError> {
        let name: &'static str = if self.f32() { f32_name(base) } else { base };
        let f = self.import(name)?;
        let c = self.b.ins().call(f, args);
        Ok(self.b.inst_results(c)[0])
    }

    /// Whether `name` is emitted inline (`mathlib`) rather than called in
    /// libm. The policy follows mathlib's measurements: in f64, inline
    /// sin/cos/sincos/cbrt are as exact as libm and faster, so `exact` uses
    /// them; exp/log/pow are only faster at reduced accuracy. In f32, glibc's
    /// float functions are faster than the inline code except cbrt.
    fn inline_math(&self, name: &str) -> bool {
        self.inline_math_in(name, self.f32())
    }

    /// Whether `name` is emitted inline in f32 (`f32`) or f64 code.
    pub(super) fn inline_math_in(&self, name: &str, f32: bool) -> bool {
        match (self.func.math, f32) {
            (MathMode::Exact, false) => matches!(name, "sin" | "cos" | "sincos" | "cbrt"),
            (MathMode::Exact, true) => false,
            (_, false) => matches!(name, "sin" | "cos" | "sincos" | "cbrt" | "exp" | "log" | "pow"),
            (_, true) => name == "cbrt",
        }
    }

    /// libm's e^x (`exp`, or `expf` in f32) without the call where it
    /// rounds to +0 (below `EXP_ZERO`, or [`EXP_ZERO_F32`], and at −inf):
    /// the far tails of a Gaussian envelope, which glibc takes through its
    /// slow underflow path. The same results as the call.
    fn libm_exp(&mut self, x: cranelift_codegen::ir::Value) -> Result<cranelift_codegen::ir::Value, CodegenError> {
        let f32 = self.f32();
        let f = self.import(if f32 { "expf" } else { "exp" })?;
        let b = &mut self.b;
        let (call_blk, merge) = (b.create_block(), b.create_block());
        let (limit, zero) = if f32 {
            b.append_block_param(merge, types::F32);
            (b.ins().f32const(EXP_ZERO_F32), b.ins().f32const(0.0))
        } else {
            b.append_block_param(merge, types::F64);
            (b.ins().f64const(EXP_ZERO), b.ins().f64const(0.0))
        };
        let underflows = b.ins().fcmp(FloatCC::LessThan, x, limit);
        b.ins().brif(underflows, merge, &[BlockArg::Value(zero)], call_blk, &[]);
        b.seal_block(call_blk);
        b.switch_to_block(call_blk);
        let c = b.ins().call(f, &[x]);
        let y = b.inst_results(c)[0];
        b.ins().jump(merge, &[BlockArg::Value(y)]);
        b.seal_block(merge);
        b.switch_to_block(merge);
        Ok(b.block_params(merge)[0])
    }

    /// `name(args)` (f64 names) inline or through libm, per [`Gen::inline_math`].
    pub(super) fn math(
        &mut self,
        name: &'static str,
        args: &[cranelift_codegen::ir::Value],
    ) -> Result<Vec<cranelift_codegen::ir::Value>, CodegenError> {
        if self.f32() && args.len() == 1 && !self.inline_math(name) && self.inline_math_in(name, false) {
            return self.math_in_f64(name, args[0]);
        }
        if !self.inline_math(name) {
            if name == "sincos" {
                let (s, c) = self.libm_sincos(args[0])?;
                return Ok(vec![s, c]);
            }
            if name == "exp" {
                return Ok(vec![self.libm_exp(args[0])?]);
            }
            return Ok(vec![self.call(name, args)?]);
        }
        // The inline code's cold path calls libm: import what it may need first.
        let slow_names: &[&'static str] = if name == "sincos" { &["sin", "cos"] } else { std::slice::from_ref(&name) };
        for n in slow_names {
            let n = if self.f32() { f32_name(n) } else { n };
            self.import(n)?;
        }
        let f32 = self.f32();
        let Gen { b, imports, math64, math32, .. } = self;
        let math = if f32 { math32 } else { math64 };
        let imports: &HashMap<&'static str, FuncRef> = imports;
        let mut slow = |fb: &mut FunctionBuilder, n: &'static str, a: &[cranelift_codegen::ir::Value]| slow_call(fb, imports, f32, n, a);
        let slow: &mut SlowPath = &mut slow;
        Ok(match name {
            "sincos" => {
                let (s, c) = math.sincos(b, args[0], slow);
                vec![s, c]
            }
            "sin" => vec![math.sin(b, args[0], slow)],
            "cos" => vec![math.cos(b, args[0], slow)],
            "exp" => vec![math.exp(b, args[0], slow)],
            "log" => vec![math.log(b, args[0], slow)],
            "cbrt" => vec![math.cbrt(b, args[0], slow)],
            "pow" => vec![math.pow(b, args[0], args[1], slow)],
            other => return Err(CodegenError(format!("no inline code for `{other}`"))),
        })
    }

    /// `name(x)` for an f32 (or f32x4) `x` by the inline f64 code, where
    /// f32 has none: promoted (an f32x4 as two f64x2 halves), computed,
    /// and rounded back to f32, so f32 loops with sin, cos, `cis` and (in
    /// `fast`/`fastest`) exp vectorise, and their tails compute the same.
    fn math_in_f64(
        &mut self,
        name: &'static str,
        x: cranelift_codegen::ir::Value,
    ) -> Result<Vec<cranelift_codegen::ir::Value>, CodegenError> {
        let vector = self.vector;
        let parts = match vector {
            Some(_) => {
                let (low, high) = self.promote_halves(x);
                vec![low, high]
            }
            None => vec![self.b.ins().fpromote(types::F64, x)],
        };
        let results: Result<Vec<Vec<_>>, _> = self.in_f64(|g| parts.iter().map(|&p| g.math(name, &[p])).collect());
        let results = results?;
        Ok((0..results[0].len())
            .map(|k| match vector {
                Some(_) => self.demote_pair(results[0][k], results[1][k]),
                None => self.b.ins().fdemote(types::F32, results[0][k]),
            })
            .collect())
    }

    /// `emit(self)` with f64 as the float type (and f64x2 lanes in a
    /// vectorised loop), restoring the current types afterwards.
    pub(super) fn in_f64<T>(&mut self, emit: impl FnOnce(&mut Self) -> T) -> T {
        let (ft, vector) = (self.ft, self.vector);
        self.ft = types::F64;
        self.vector = vector.map(|_| types::F64);
        let result = emit(self);
        (self.ft, self.vector) = (ft, vector);
        result
    }

    /// The f32x4 of two f64x2 halves (lanes 0–1, then 2–3), rounded.
    pub(super) fn demote_pair(
        &mut self,
        low: cranelift_codegen::ir::Value,
        high: cranelift_codegen::ir::Value,
    ) -> cranelift_codegen::ir::Value {
        let (low, high) = (self.b.ins().fvdemote(low), self.b.ins().fvdemote(high));
        // Lanes 0–1 of each demoted half.
        self.shuffle_lanes(low, high, |lane| if lane < 2 { lane } else { lane + 2 })
    }

    pub(super) fn math1(
        &mut self,
        name: &'static str,
        x: cranelift_codegen::ir::Value,
    ) -> Result<cranelift_codegen::ir::Value, CodegenError> {
        Ok(self.math(name, &[x])?[0])
    }

    pub(super) fn sincos(
        &mut self,
        x: cranelift_codegen::ir::Value,
    ) -> Result<(cranelift_codegen::ir::Value, cranelift_codegen::ir::Value), CodegenError> {
        let r = self.math("sincos", &[x])?;
        Ok((r[0], r[1]))
    }

    fn libm_sincos(
        &mut self,
        x: cranelift_codegen::ir::Value,
    ) -> Result<(cranelift_codegen::ir::Value, cranelift_codegen::ir::Value), CodegenError> {
        let slot = match self.sincos_slot {
            Some(s) => s,
            None => {
                let s = self.b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 3));
                self.sincos_slot = Some(s);
                s
            }
        };
        let name = if self.f32() { "sincosf" } else { "sincos" };
        let f = self.import(name)?;
        let size = self.ft.bytes() as i32;
        let ps = self.b.ins().stack_addr(self.ptr, slot, 0);
        let pc = self.b.ins().stack_addr(self.ptr, slot, size);
        self.b.ins().call(f, &[x, ps, pc]);
        let s = self.b.ins().stack_load(self.ptr, self.ft, slot, 0);
        let c = self.b.ins().stack_load(self.ptr, self.ft, slot, size);
        Ok((s, c))
    }

    /// `x^c`: repeated multiplication for small integer c, sqrt for ±1/2,
    /// otherwise a call to `pow`.
    pub(super) fn pow_const(&mut self, x: cranelift_codegen::ir::Value, c: f64) -> Result<cranelift_codegen::ir::Value, CodegenError> {
        if pow_const_is_small_integer(c) {
            let n = c.abs() as u32;
            let mut result: Option<cranelift_codegen::ir::Value> = None;
            let mut base = x;
            let mut k = n;
            while k > 0 {
                if k & 1 == 1 {
                    result = Some(match result {
                        Some(r) => self.b.ins().fmul(r, base),
                        None => base,
                    });
                }
                k >>= 1;
                if k > 0 {
                    base = self.b.ins().fmul(base, base);
                }
            }
            let r = match result {
                Some(r) => r,
                None => self.fconst(1.0),
            };
            return Ok(if c < 0.0 {
                let one = self.fconst(1.0);
                self.b.ins().fdiv(one, r)
            } else {
                r
            });
        }
        if c == 0.5 {
            return Ok(self.b.ins().sqrt(x));
        }
        let e = self.fconst(c);
        Ok(self.math("pow", &[x, e])?[0])
    }
}

/// `x^c` by repeated multiplication (see [`Gen::pow_const`]).
fn pow_const_is_small_integer(c: f64) -> bool {
    c == c.trunc() && c.abs() <= 16.0
}

/// `x^c` without a `pow` call: repeated multiplication or `sqrt`.
pub(super) fn pow_const_is_inline(c: f64) -> bool {
    pow_const_is_small_integer(c) || c == 0.5
}

/// Calls libm's `name` (f64 name) from the inline code's cold path; the
/// functions were imported beforehand (see [`Gen::math`]).
fn slow_call(
    fb: &mut FunctionBuilder,
    imports: &HashMap<&'static str, FuncRef>,
    f32: bool,
    name: &'static str,
    args: &[cranelift_codegen::ir::Value],
) -> Vec<cranelift_codegen::ir::Value> {
    if name == "sincos" {
        let s = slow_call(fb, imports, f32, "sin", args)[0];
        let c = slow_call(fb, imports, f32, "cos", args)[0];
        return vec![s, c];
    }
    let f = imports[if f32 { f32_name(name) } else { name }];
    let call = fb.ins().call(f, args);
    fb.inst_results(call).to_vec()
}

fn f32_name(base: &'static str) -> &'static str {
    match base {
        "cbrt" => "cbrtf",
        "exp" => "expf",
        "log" => "logf",
        "sin" => "sinf",
        "cos" => "cosf",
        "tan" => "tanf",
        "tanh" => "tanhf",
        "pow" => "powf",
        "atan2" => "atan2f",
        "sincos" => "sincosf",
        other => other,
    }
}
