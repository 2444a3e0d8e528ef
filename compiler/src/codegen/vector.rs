//! Vectorised loops: the lane type a loop can use, shuffles and splats, and f64x2 halves of f64 values in f32x4 loops.

use super::elementwise::Cv;
use super::math::pow_const_is_inline;
use super::mathlib;
use super::{CodegenError, Gen, LoopCtx};
use crate::ir::*;
use cranelift_codegen::ir::{types, InstBuilder, Type};

impl Gen<'_> {
    /// `x` (converted to float type `ty`) in every lane when emitting a
    /// vectorised loop, else `x` converted.
    pub(super) fn splat_cv(&mut self, x: Cv, ty: Type) -> Cv {
        let x = self.cast_cv(x, ty);
        Cv { re: self.splat(x.re), im: x.im.map(|im| self.splat(im)) }
    }

    /// `x` in every lane when emitting a vectorised loop, else `x`.
    pub(super) fn splat(&mut self, x: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        let ty = self.b.func.dfg.value_type(x);
        match self.vector {
            Some(_) if !ty.is_vector() => self.b.ins().splat(vector_of(ty), x),
            _ => x,
        }
    }

    /// A vector whose lane `k` is lane `from(k)` of the concatenation of
    /// the same-typed vectors `a` and `b`.
    pub(super) fn shuffle_lanes(
        &mut self,
        a: cranelift_codegen::ir::Value,
        b: cranelift_codegen::ir::Value,
        from: impl Fn(usize) -> usize,
    ) -> cranelift_codegen::ir::Value {
        let ty = self.b.func.dfg.value_type(a);
        let size = ty.lane_bits() as usize / 8;
        let bytes: Vec<u8> = (0..ty.lane_count() as usize)
            .flat_map(|k| {
                let lane = from(k);
                (0..size).map(move |i| (lane * size + i) as u8)
            })
            .collect();
        let mask = self.b.func.dfg.immediates.push(bytes.into());
        let (a, b) = (mathlib::bitcast(&mut self.b, types::I8X16, a), mathlib::bitcast(&mut self.b, types::I8X16, b));
        let r = self.b.ins().shuffle(a, b, mask);
        mathlib::bitcast(&mut self.b, ty, r)
    }

    /// Lanes 0–1 and 2–3 of an f32x4, each promoted to an f64x2.
    pub(super) fn promote_halves(
        &mut self,
        x: cranelift_codegen::ir::Value,
    ) -> (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value) {
        let low = self.b.ins().fvpromote_low(x);
        let swapped = self.shuffle_lanes(x, x, |k| (k + 2) % 4);
        (low, self.b.ins().fvpromote_low(swapped))
    }

    /// The lane type loop `l` can be vectorised in (128-bit vectors: f64x2
    /// or f32x4), or `None` to keep it scalar. Vectorised loops hold real
    /// and complex values and truth values of the lane type, computed by
    /// arithmetic, comparisons, selects, `sqrt`, `abs`, `min`/`max`,
    /// complex parts, small integer powers and sin, cos, `cis` and
    /// (`fast`/`fastest`) exp (no library calls; in f32 through the f64
    /// code, [`Gen::math_in_f64`]), reading buffers of that type (complex
    /// ones are de-interleaved). In mixed precision, an f32x4 loop also
    /// holds the values computed in f64, split in two f64x2 halves (not
    /// truth values or selects), and reads and writes buffers of either
    /// type. Reductions accumulate in f64x2: two accumulators for real
    /// f32x4 ones; complex reductions only in f64x2 loops.
    pub(super) fn vector_lane(&self, l: usize) -> Option<Type> {
        let mut lanes = vec![self.storage];
        if self.storage != types::F64 {
            // Mixed precision: a loop of f64 values only (say a complex
            // reduction of a phase) may still vectorise in f64x2.
            lanes.push(types::F64);
        }
        lanes.into_iter().find(|&lane| self.vectorises_in(l, lane))
    }

    /// Whether loop `l` can be vectorised with `lane`-typed vectors (see
    /// [`Gen::vector_lane`]).
    fn vectorises_in(&self, l: usize, lane: Type) -> bool {
        let (epoch, _, ref members) = self.sched.loops[l];
        let mut seen = std::collections::HashSet::new();
        for &m in members {
            let ok = match self.func.insts[m].op {
                // f32x4 reductions use the imaginary accumulator for lanes 2–3.
                Op::Reduce(_, a) => {
                    (lane == types::F64 || self.func.ty(a).elem != Elem::Complex) && self.vectorisable(a.index(), lane, epoch, &mut seen)
                }
                _ => {
                    self.vectorisable(m, lane, epoch, &mut seen) && self.sched.stored.get(&m).is_none_or(|&buf| self.buffer_fits(buf, lane))
                }
            };
            if !ok {
                return false;
            }
        }
        !members.is_empty()
    }

    /// Whether value `i`, and what a loop of `epoch` computes it from, can
    /// be emitted with `lane`-typed vectors (see [`Gen::vector_lane`]).
    fn vectorisable(&self, i: usize, lane: Type, epoch: u32, seen: &mut std::collections::HashSet<usize>) -> bool {
        if !seen.insert(i) {
            return true;
        }
        let inst = self.func.insts[i];
        if inst.ty.shape == Shape::Scalar {
            return inst.ty.elem != Elem::Bool;
        }
        // Split into f64x2 halves in an f32x4 loop (mixed precision).
        let split = lane == types::F32 && self.wide[i];
        if split && (inst.ty.elem == Elem::Bool || matches!(inst.op, Op::Select(..))) {
            return false;
        }
        if self.ty_of(i) != lane && !split {
            return false;
        }
        let buffer_ok = |buf: usize| self.buffer_fits(buf, lane);
        let mut operands_ok = || inst.op.operands().iter().all(|o| self.vectorisable(o.index(), lane, epoch, seen));
        match inst.op {
            Op::Broadcast(..) => operands_ok(),
            Op::GridCoord(_) => true,
            Op::Input(k) => buffer_ok(k as usize),
            Op::Table(t) => buffer_ok(self.table_buffer(t)),
            Op::Dft(..) | Op::Tensor(..) | Op::Band(..) => buffer_ok(self.sched.stored[&i]),
            _ if self.reloaded(i, epoch) => buffer_ok(self.sched.stored[&i]),
            Op::Unary(u, _) => {
                let inline = matches!(
                    u,
                    UnOp::Neg | UnOp::Sqrt | UnOp::Abs | UnOp::Sign | UnOp::Re | UnOp::Im | UnOp::Conj | UnOp::Abs2 | UnOp::ToComplex
                );
                // The inline f64 sin/cos/sincos and exp take f64x2 (a
                // complex exp needs both exp and sincos); f32x4 goes
                // through them as two promoted halves.
                let f64_math = |name| self.inline_math_in(name, false);
                let math = match u {
                    UnOp::Sin => f64_math("sin"),
                    UnOp::Cos => f64_math("cos"),
                    UnOp::Cis => f64_math("sincos"),
                    UnOp::Exp => f64_math("exp") && f64_math("sincos"),
                    _ => false,
                };
                (inline || math) && operands_ok()
            }
            Op::Binary(op, ..) => !matches!(op, BinOp::Pow | BinOp::Atan2) && operands_ok(),
            Op::PowConst(_, bits) => pow_const_is_inline(f64::from_bits(bits)) && operands_ok(),
            Op::Select(..) => operands_ok(),
            _ => false,
        }
    }

    /// Whether a `lane`-typed vector loop can read and write buffer `buf`:
    /// one of the lane type, or any in an f32x4 loop (whose split values
    /// convert between f32 and f64).
    fn buffer_fits(&self, buf: usize, lane: Type) -> bool {
        lane == types::F32 || self.buffer_ty(buf) == lane
    }

    /// In a split loop: value `v` as two f64x2 halves, lanes 0–1 and 2–3
    /// (a value computed in f32 is promoted, a scalar splat). Each f64
    /// operation is emitted once per half, as the scalar tail would
    /// compute it lane by lane.
    pub(super) fn wide_operand(&mut self, lc: &mut LoopCtx, v: Value) -> Result<[Cv; 2], CodegenError> {
        let i = v.index();
        if let Some(h) = lc.halves.get(&i) {
            return Ok(*h);
        }
        let inst = self.func.insts[i];
        let halves = if let Some(taken) = self.resolved(lc.known, i) {
            self.wide_operand(lc, taken)?
        } else if inst.ty.shape == Shape::Scalar {
            let x = self.vals[&i];
            let x = self.in_f64(|g| g.splat_cv(x, types::F64));
            [x, x]
        } else if !self.wide[i] {
            let x = self.loop_operand(lc, v)?;
            self.promote_cv(x)
        } else {
            match inst.op {
                Op::Broadcast(a, _) => self.wide_operand(lc, a)?,
                Op::GridCoord(g) => [0, 2].map(|first| Cv::real(self.grid_coords(g, lc.index, first))),
                Op::Input(_) | Op::Table(_) | Op::Dft(..) | Op::Tensor(..) | Op::Band(..) => {
                    self.load_halves(self.operand_buffer(v), lc.index, inst.ty.elem == Elem::Complex)
                }
                _ if self.reloaded(i, lc.epoch) => self.load_halves(self.sched.stored[&i], lc.index, inst.ty.elem == Elem::Complex),
                op => {
                    let mut ops = Vec::new();
                    for o in op.operands() {
                        ops.push(self.wide_operand(lc, o)?);
                    }
                    let mut halves = Vec::new();
                    for h in 0..2 {
                        let ops: Vec<Cv> = ops.iter().map(|o| o[h]).collect();
                        halves.push(self.in_f64(|g| g.elementwise(inst, &ops, None))?);
                    }
                    [halves[0], halves[1]]
                }
            }
        };
        lc.halves.insert(i, halves);
        Ok(halves)
    }

    /// Elements `index..` of buffer `buf` in the loop's lane type: as
    /// [`Gen::load_elem`], except that a split loop reads an f64 buffer as
    /// two f64x2 halves rounded to one f32x4.
    pub(super) fn load_lanes(&mut self, buf: usize, index: cranelift_codegen::ir::Value, complex: bool) -> Cv {
        if self.vector == Some(types::F32) && self.buffer_ty(buf) == types::F64 {
            let halves = self.load_halves(buf, index, complex);
            return self.demote_cv(halves);
        }
        self.load_elem(buf, index, complex)
    }

    /// In a split loop: four elements from `index` of buffer `buf` as two
    /// f64x2 halves (an f32 buffer's f32x4 promoted).
    fn load_halves(&mut self, buf: usize, index: cranelift_codegen::ir::Value, complex: bool) -> [Cv; 2] {
        if self.buffer_ty(buf) == types::F32 {
            let x = self.load_elem(buf, index, complex);
            return self.promote_cv(x);
        }
        self.in_f64(|g| {
            let second = g.b.ins().iadd_imm_s(index, 2);
            [g.load_elem(buf, index, complex), g.load_elem(buf, second, complex)]
        })
    }

    /// In a split loop: stores the halves of four elements from `index` to
    /// buffer `buf` (rounded to one f32x4 for an f32 buffer).
    pub(super) fn store_halves(&mut self, buf: usize, index: cranelift_codegen::ir::Value, halves: [Cv; 2], complex: bool) {
        if self.buffer_ty(buf) == types::F32 {
            let x = self.demote_cv(halves);
            return self.store_elem(buf, index, x, complex);
        }
        self.in_f64(|g| {
            let second = g.b.ins().iadd_imm_s(index, 2);
            g.store_elem(buf, index, halves[0], complex);
            g.store_elem(buf, second, halves[1], complex);
        })
    }

    /// An f32x4 value as two f64x2 halves.
    fn promote_cv(&mut self, x: Cv) -> [Cv; 2] {
        let (re_low, re_high) = self.promote_halves(x.re);
        let im = x.im.map(|im| self.promote_halves(im));
        [Cv { re: re_low, im: im.map(|h| h.0) }, Cv { re: re_high, im: im.map(|h| h.1) }]
    }

    /// Two f64x2 halves as one f32x4 value, rounded.
    pub(super) fn demote_cv(&mut self, [low, high]: [Cv; 2]) -> Cv {
        let re = self.demote_pair(low.re, high.re);
        let im = match (low.im, high.im) {
            (Some(a), Some(b)) => Some(self.demote_pair(a, b)),
            _ => None,
        };
        Cv { re, im }
    }
}

/// The 128-bit vector of lane type `ty` (f64x2 or f32x4).
pub(super) fn vector_of(ty: Type) -> Type {
    ty.by(16 / ty.bytes()).expect("a 128-bit vector of a float type")
}
