//! Elementwise code: one instruction's value in scalar code or in a loop, buffer loads and stores, and float conversions.

use super::abi::BufferKind;
use super::mathlib;
use super::vector::vector_of;
use super::{CodegenError, Gen, LoopCtx};
use crate::ir::*;
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData, Type};

/// A value in generated code: real part, and imaginary part for complex.
#[derive(Clone, Copy)]
pub(super) struct Cv {
    pub(super) re: cranelift_codegen::ir::Value,
    pub(super) im: Option<cranelift_codegen::ir::Value>,
}

impl Cv {
    pub(super) fn real(re: cranelift_codegen::ir::Value) -> Cv {
        Cv { re, im: None }
    }
}

impl Gen<'_> {
    /// Whether `v` is the constant +0 (in every lane).
    fn is_zero_const(&self, v: Option<cranelift_codegen::ir::Value>) -> bool {
        use cranelift_codegen::ir::{InstructionData, Opcode, ValueDef};
        let Some(v) = v else { return false };
        let ValueDef::Result(inst, _) = self.b.func.dfg.value_def(v) else { return false };
        match self.b.func.dfg.insts[inst] {
            InstructionData::UnaryIeee64 { imm, .. } => imm.bits() == 0,
            InstructionData::UnaryIeee32 { imm, .. } => imm.bits() == 0,
            InstructionData::Unary { opcode: Opcode::Splat, arg } => self.is_zero_const(Some(arg)),
            _ => false,
        }
    }

    pub(super) fn fconst(&mut self, x: f64) -> cranelift_codegen::ir::Value {
        let c = if self.f32() { self.b.ins().f32const(x as f32) } else { self.b.ins().f64const(x) };
        self.splat(c)
    }

    /// `c ? x : y`, for a truth value `c` (a lane mask in vectorised loops).
    pub(super) fn select(
        &mut self,
        c: cranelift_codegen::ir::Value,
        x: cranelift_codegen::ir::Value,
        y: cranelift_codegen::ir::Value,
    ) -> cranelift_codegen::ir::Value {
        mathlib::select(&mut self.b, c, x, y)
    }

    /// The buffer holding table `t`.
    pub(super) fn table_buffer(&self, t: u32) -> usize {
        self.layout.buffers.iter().position(|b| b.kind == BufferKind::Table(t as usize)).expect("tables have buffers")
    }

    /// The buffer an array operand of a library call is read from (for an
    /// input, a table or a call's result, the buffer it lives in).
    pub(super) fn operand_buffer(&self, a: Value) -> usize {
        match self.func.insts[a.index()].op {
            Op::Input(k) => k as usize,
            Op::Table(t) => self.table_buffer(t),
            _ => self.sched.stored[&a.index()],
        }
    }

    /// `v` converted to float type `ty` (truth values pass unchanged).
    pub(super) fn cast(&mut self, v: cranelift_codegen::ir::Value, ty: Type) -> cranelift_codegen::ir::Value {
        match (self.b.func.dfg.value_type(v), ty) {
            (types::F32, types::F64) => self.b.ins().fpromote(types::F64, v),
            (types::F64, types::F32) => self.b.ins().fdemote(types::F32, v),
            _ => v,
        }
    }

    pub(super) fn cast_cv(&mut self, v: Cv, ty: Type) -> Cv {
        let re = self.cast(v.re, ty);
        Cv { re, im: v.im.map(|im| self.cast(im, ty)) }
    }

    pub(super) fn widen(&mut self, v: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        self.cast(v, types::F64)
    }

    /// The float type instruction `i` is computed in.
    pub(super) fn ty_of(&self, i: usize) -> Type {
        if self.wide[i] {
            types::F64
        } else {
            self.storage
        }
    }

    /// The element type of buffer `buf`.
    pub(super) fn buffer_ty(&self, buf: usize) -> Type {
        if self.layout.buffers[buf].precision == Precision::F64 {
            types::F64
        } else {
            types::F32
        }
    }

    pub(super) fn scalar_inst(&mut self, i: usize, params_ptr: cranelift_codegen::ir::Value) -> Result<Cv, CodegenError> {
        let inst = self.func.insts[i];
        self.ft = self.ty_of(i);
        Ok(match inst.op {
            Op::Const(b) => Cv::real(self.fconst(f64::from_bits(b))),
            Op::ConstComplex(r, im) => {
                let re = self.fconst(f64::from_bits(r));
                let im = self.fconst(f64::from_bits(im));
                Cv { re, im: Some(im) }
            }
            Op::Param(p) => {
                let v = self.b.ins().load(types::F64, MemFlagsData::trusted(), params_ptr, (p * 8) as i32);
                Cv::real(self.cast(v, self.ft))
            }
            Op::Input(k) => {
                let zero = self.b.ins().iconst(types::I64, 0);
                let v = self.load_elem(k as usize, zero, inst.ty.elem == Elem::Complex);
                self.cast_cv(v, self.ft)
            }
            op => {
                let ft = self.ft;
                let mut ops = Vec::new();
                for v in op.operands() {
                    let x = self.vals[&v.index()];
                    ops.push(self.cast_cv(x, ft));
                }
                self.elementwise(inst, &ops, None)?
            }
        })
    }

    /// Element `index` of buffer `buf`, in the buffer's element type.
    pub(super) fn load_elem(&mut self, buf: usize, index: cranelift_codegen::ir::Value, complex: bool) -> Cv {
        let ty = self.buffer_ty(buf);
        let size = ty.bytes() as i64 * if complex { 2 } else { 1 };
        let off = self.b.ins().imul_imm_s(index, size);
        let addr = self.b.ins().iadd(self.bufs[buf], off);
        let flags = MemFlagsData::trusted();
        if self.vector.is_some() {
            // Consecutive elements; buffers are only element-aligned.
            let flags = MemFlagsData::new().with_notrap();
            let v = self.b.ins().load(vector_of(ty), flags, addr, 0);
            if !complex {
                return Cv::real(v);
            }
            // Interleaved (re, im) pairs: two vectors, split into even and odd lanes.
            let w = self.b.ins().load(vector_of(ty), flags, addr, 16);
            let re = self.shuffle_lanes(v, w, |k| 2 * k);
            let im = self.shuffle_lanes(v, w, |k| 2 * k + 1);
            return Cv { re, im: Some(im) };
        }
        let re = self.b.ins().load(ty, flags, addr, 0);
        let im = complex.then(|| self.b.ins().load(ty, flags, addr, ty.bytes() as i32));
        Cv { re, im }
    }

    /// Stores `v`, converted to the buffer's element type.
    pub(super) fn store_elem(&mut self, buf: usize, index: cranelift_codegen::ir::Value, v: Cv, complex: bool) {
        let ty = self.buffer_ty(buf);
        let v = self.cast_cv(v, ty);
        let size = ty.bytes() as i64 * if complex { 2 } else { 1 };
        let off = self.b.ins().imul_imm_s(index, size);
        let addr = self.b.ins().iadd(self.bufs[buf], off);
        if self.vector.is_some() {
            let flags = MemFlagsData::new().with_notrap();
            let Some(im) = v.im.filter(|_| complex) else {
                self.b.ins().store(flags, v.re, addr, 0);
                return;
            };
            // Back to interleaved (re, im) pairs: lane j of the pair of
            // output vectors is lane j/2 of re (even j) or of im (odd j).
            let lanes = (16 / ty.bytes()) as usize;
            let pick = |j: usize| if j.is_multiple_of(2) { j / 2 } else { lanes + j / 2 };
            let first = self.shuffle_lanes(v.re, im, pick);
            let second = self.shuffle_lanes(v.re, im, |k| pick(k + lanes));
            self.b.ins().store(flags, first, addr, 0);
            self.b.ins().store(flags, second, addr, 16);
            return;
        }
        let flags = MemFlagsData::trusted();
        self.b.ins().store(flags, v.re, addr, 0);
        if complex {
            let im = v.im.expect("complex value has an imaginary part");
            self.b.ins().store(flags, im, addr, ty.bytes() as i32);
        }
    }

    /// The value of `v` inside the current loop iteration, in the loop's
    /// lane type (split values are rounded from their f64 halves).
    pub(super) fn loop_operand(&mut self, lc: &mut LoopCtx, v: Value) -> Result<Cv, CodegenError> {
        let i = v.index();
        if let Some(x) = lc.vals.get(&i) {
            return Ok(*x);
        }
        let inst = self.func.insts[i];
        if inst.ty.shape == Shape::Scalar {
            let x = self.vals[&i];
            return Ok(match self.vector {
                Some(lane) => self.splat_cv(x, lane),
                None => x,
            });
        }
        if let Some(taken) = self.resolved(lc.known, i) {
            let x = self.loop_operand(lc, taken)?;
            lc.vals.insert(i, x);
            return Ok(x);
        }
        if let Op::Binary(BinOp::Sub, a, b) = inst.op {
            if self.known_constant(lc.known, b.index()) == Some((0, 0)) {
                // x − (+0) is x, bit for bit (also for x = −0).
                let x = self.loop_operand(lc, a)?;
                let x = self.cast_cv(x, self.ty_of(i));
                lc.vals.insert(i, x);
                return Ok(x);
            }
        }
        if self.split(i) {
            let halves = self.wide_operand(lc, v)?;
            let x = self.demote_cv(halves);
            lc.vals.insert(i, x);
            return Ok(x);
        }
        let ty = self.ty_of(i);
        let x = match inst.op {
            Op::Broadcast(a, _) => {
                let x = self.vals[&a.index()];
                self.splat_cv(x, ty)
            }
            Op::GridCoord(g) => {
                let x = match self.vector {
                    // f32x4: lanes 0–1 and 2–3 as two f64x2, rounded to f32.
                    Some(types::F32) => {
                        let (low, high) = (self.grid_coords(g, lc.index, 0), self.grid_coords(g, lc.index, 2));
                        self.demote_pair(low, high)
                    }
                    _ => {
                        let x = self.grid_coords(g, lc.index, 0);
                        self.cast(x, ty)
                    }
                };
                Cv::real(x)
            }
            Op::Input(_) | Op::Table(_) | Op::Dft(..) | Op::Tensor(..) | Op::Band(..) => {
                let x = self.load_lanes(self.operand_buffer(v), lc.index, inst.ty.elem == Elem::Complex);
                self.cast_cv(x, ty)
            }
            // Stored by an earlier loop: reload instead of recomputing.
            _ if self.reloaded(i, lc.epoch) => {
                let buf = self.sched.stored[&i];
                let v = self.load_lanes(buf, lc.index, inst.ty.elem == Elem::Complex);
                if inst.ty.elem == Elem::Bool {
                    self.ft = self.vector.unwrap_or_else(|| self.buffer_ty(buf));
                    let zero = self.fconst(0.0);
                    Cv::real(self.b.ins().fcmp(FloatCC::NotEqual, v.re, zero))
                } else {
                    self.cast_cv(v, ty)
                }
            }
            op => {
                let mut ops = Vec::new();
                for o in op.operands() {
                    ops.push(self.loop_operand(lc, o)?);
                }
                for o in &mut ops {
                    *o = self.cast_cv(*o, ty);
                }
                self.ft = ty;
                self.elementwise(inst, &ops, Some(lc))?
            }
        };
        lc.vals.insert(i, x);
        Ok(x)
    }

    /// Coordinates `index + first` (and `+ 1` in lane 1 of a vectorised
    /// loop's f64x2) of grid `g`, `start + k · step` in f64 (exact in `k`:
    /// indices are far below 2^53).
    pub(super) fn grid_coords(&mut self, g: GridId, index: cranelift_codegen::ir::Value, first: i64) -> cranelift_codegen::ir::Value {
        let grid = &self.func.grids[g.0 as usize];
        let (start, step) = (grid.start, grid.step);
        let fi = self.b.ins().fcvt_from_sint(types::F64, index);
        let (st, s0) = (self.b.ins().f64const(step), self.b.ins().f64const(start));
        let (fi, st, s0) = match self.vector {
            Some(_) => {
                let base = self.b.ins().splat(types::F64X2, fi);
                let (k0, k1) = (self.b.ins().f64const(first as f64), self.b.ins().f64const(first as f64 + 1.0));
                let k = self.b.ins().scalar_to_vector(types::F64X2, k0);
                let k = self.b.ins().insertlane(k, k1, 1);
                let fi = self.b.ins().fadd(base, k);
                (fi, self.b.ins().splat(types::F64X2, st), self.b.ins().splat(types::F64X2, s0))
            }
            None => (fi, st, s0),
        };
        let prod = self.b.ins().fmul(fi, st);
        self.b.ins().fadd(s0, prod)
    }

    /// Emits one elementwise operation on already-computed operands.
    pub(super) fn elementwise(&mut self, inst: Inst, ops: &[Cv], _lc: Option<&mut LoopCtx>) -> Result<Cv, CodegenError> {
        let ins_complex = |k: usize| ops.get(k).is_some_and(|o| o.im.is_some());
        Ok(match inst.op {
            Op::Unary(u, _) => {
                let a = ops[0];
                let x = a.re;
                match u {
                    UnOp::Neg => Cv { re: self.b.ins().fneg(x), im: a.im.map(|i| self.b.ins().fneg(i)) },
                    UnOp::Sqrt => Cv::real(self.b.ins().sqrt(x)),
                    UnOp::Cbrt => Cv::real(self.math1("cbrt", x)?),
                    UnOp::Exp if ins_complex(0) => {
                        let e = self.math1("exp", x)?;
                        let (s, c) = self.sincos(a.im.expect("complex"))?;
                        Cv { re: self.b.ins().fmul(e, c), im: Some(self.b.ins().fmul(e, s)) }
                    }
                    UnOp::Exp => Cv::real(self.math1("exp", x)?),
                    UnOp::Log => Cv::real(self.math1("log", x)?),
                    UnOp::Sin => Cv::real(self.math1("sin", x)?),
                    UnOp::Cos => Cv::real(self.math1("cos", x)?),
                    UnOp::Tan => Cv::real(self.call("tan", &[x])?),
                    UnOp::Tanh => Cv::real(self.call("tanh", &[x])?),
                    UnOp::Abs if ins_complex(0) => {
                        let im = a.im.expect("complex");
                        let rr = self.b.ins().fmul(x, x);
                        let ii = self.b.ins().fmul(im, im);
                        let s = self.b.ins().fadd(rr, ii);
                        Cv::real(self.b.ins().sqrt(s))
                    }
                    UnOp::Abs => Cv::real(self.b.ins().fabs(x)),
                    UnOp::Sign => {
                        // 1 for x > 0, -1 for x < 0, x * 0 otherwise (keeps ±0 and NaN).
                        let one = self.fconst(1.0);
                        let mone = self.fconst(-1.0);
                        let zero = self.fconst(0.0);
                        let z = self.b.ins().fmul(x, zero);
                        let pos = self.b.ins().fcmp(FloatCC::GreaterThan, x, zero);
                        let neg = self.b.ins().fcmp(FloatCC::LessThan, x, zero);
                        let t = self.select(neg, mone, z);
                        Cv::real(self.select(pos, one, t))
                    }
                    UnOp::Re => Cv::real(x),
                    UnOp::Im => Cv::real(a.im.expect("complex")),
                    UnOp::Conj => Cv { re: x, im: a.im.map(|i| self.b.ins().fneg(i)) },
                    UnOp::Abs2 => {
                        let im = a.im.expect("complex");
                        let rr = self.b.ins().fmul(x, x);
                        let ii = self.b.ins().fmul(im, im);
                        Cv::real(self.b.ins().fadd(rr, ii))
                    }
                    UnOp::Cis => {
                        let (s, c) = self.sincos(x)?;
                        Cv { re: c, im: Some(s) }
                    }
                    UnOp::ToComplex => Cv { re: x, im: Some(self.fconst(0.0)) },
                }
            }
            Op::Binary(op, _, _) => {
                let (a, c) = (ops[0], ops[1]);
                let complex = a.im.is_some();
                match op {
                    BinOp::Add => Cv {
                        re: self.b.ins().fadd(a.re, c.re),
                        im: complex.then(|| self.b.ins().fadd(a.im.expect("complex"), c.im.expect("complex"))),
                    },
                    BinOp::Sub => Cv {
                        re: self.b.ins().fsub(a.re, c.re),
                        im: complex.then(|| self.b.ins().fsub(a.im.expect("complex"), c.im.expect("complex"))),
                    },
                    // A real factor (one whose imaginary part is the constant
                    // +0, e.g. `tocomplex x`) scales both parts: the same
                    // values as the full product, up to the sign of a zero.
                    BinOp::Mul if complex && (self.is_zero_const(a.im) || self.is_zero_const(c.im)) => {
                        let (z, x) = if self.is_zero_const(c.im) { (a, c.re) } else { (c, a.re) };
                        Cv { re: self.b.ins().fmul(z.re, x), im: Some(self.b.ins().fmul(z.im.expect("complex"), x)) }
                    }
                    BinOp::Mul if complex => {
                        let (ar, ai, cr, ci) = (a.re, a.im.expect("complex"), c.re, c.im.expect("complex"));
                        let rr = self.b.ins().fmul(ar, cr);
                        let ii = self.b.ins().fmul(ai, ci);
                        let ri = self.b.ins().fmul(ar, ci);
                        let ir = self.b.ins().fmul(ai, cr);
                        Cv { re: self.b.ins().fsub(rr, ii), im: Some(self.b.ins().fadd(ri, ir)) }
                    }
                    BinOp::Mul => Cv::real(self.b.ins().fmul(a.re, c.re)),
                    BinOp::Div if complex => {
                        // a * conj(c) / |c|^2, as in eval::complex_div.
                        let (ar, ai, cr, ci) = (a.re, a.im.expect("complex"), c.re, c.im.expect("complex"));
                        let cc = self.b.ins().fmul(cr, cr);
                        let dd = self.b.ins().fmul(ci, ci);
                        let d = self.b.ins().fadd(cc, dd);
                        let rr = self.b.ins().fmul(ar, cr);
                        let ii = self.b.ins().fmul(ai, ci);
                        let num_re = self.b.ins().fadd(rr, ii);
                        let ir = self.b.ins().fmul(ai, cr);
                        let ri = self.b.ins().fmul(ar, ci);
                        let num_im = self.b.ins().fsub(ir, ri);
                        Cv { re: self.b.ins().fdiv(num_re, d), im: Some(self.b.ins().fdiv(num_im, d)) }
                    }
                    BinOp::Div => Cv::real(self.b.ins().fdiv(a.re, c.re)),
                    BinOp::Pow => Cv::real(self.math("pow", &[a.re, c.re])?[0]),
                    BinOp::Atan2 => Cv::real(self.call("atan2", &[a.re, c.re])?),
                    BinOp::Min => Cv::real(self.b.ins().fmin(a.re, c.re)),
                    BinOp::Max => Cv::real(self.b.ins().fmax(a.re, c.re)),
                    BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge => {
                        let cc = match op {
                            BinOp::Lt => FloatCC::LessThan,
                            BinOp::Le => FloatCC::LessThanOrEqual,
                            BinOp::Gt => FloatCC::GreaterThan,
                            _ => FloatCC::GreaterThanOrEqual,
                        };
                        Cv::real(self.b.ins().fcmp(cc, a.re, c.re))
                    }
                    BinOp::Eq | BinOp::Ne => {
                        let cc = if op == BinOp::Eq { FloatCC::Equal } else { FloatCC::NotEqual };
                        let r = self.b.ins().fcmp(cc, a.re, c.re);
                        match (a.im, c.im) {
                            (Some(ai), Some(ci)) => {
                                let i = self.b.ins().fcmp(cc, ai, ci);
                                Cv::real(if op == BinOp::Eq { self.b.ins().band(r, i) } else { self.b.ins().bor(r, i) })
                            }
                            _ => Cv::real(r),
                        }
                    }
                    BinOp::Complex => Cv { re: a.re, im: Some(c.re) },
                }
            }
            Op::PowConst(_, bits) => Cv::real(self.pow_const(ops[0].re, f64::from_bits(bits))?),
            Op::Select(..) => {
                let (c, x, y) = (ops[0].re, ops[1], ops[2]);
                let re = self.select(c, x.re, y.re);
                let im = match (x.im, y.im) {
                    (Some(xi), Some(yi)) => Some(self.select(c, xi, yi)),
                    _ => None,
                };
                Cv { re, im }
            }
            Op::Broadcast(..) => ops[0],
            other => return Err(CodegenError(format!("unexpected operation in elementwise code: {other:?}"))),
        })
    }
}
