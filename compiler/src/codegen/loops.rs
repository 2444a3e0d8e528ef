//! Loop emission: the kernel body epoch by epoch, library calls, and fused (vectorised, split) loops with their reductions.

use super::elementwise::Cv;
use super::{CodegenError, Gen, LoopCtx};
use crate::ir::*;
use cranelift_codegen::ir::condcodes::IntCC;
use cranelift_codegen::ir::{types, InstBuilder, MemFlagsData};
use cranelift_frontend::Variable;
use std::collections::{HashMap, HashSet};

/// The most operations (a complex one counting twice) a loop body may have
/// to run two copies per vectorised iteration (see [`Gen::small_body`]).
const SMALL_BODY: usize = 32;

/// The accumulators of a loop's reductions: real part, and imaginary part
/// (or, in f32x4 loops, lanes 2–3).
type Accs = Vec<(cranelift_codegen::ir::Value, Option<cranelift_codegen::ir::Value>)>;

impl Gen<'_> {
    pub(super) fn emit_body(&mut self) -> Result<(), CodegenError> {
        let entry = self.b.create_block();
        self.b.append_block_params_for_function_params(entry);
        self.b.switch_to_block(entry);
        let params = self.b.block_params(entry).to_vec();
        let (params_ptr, bufs_ptr, scalars_ptr) = (params[0], params[1], params[2]);
        let flags = MemFlagsData::trusted();
        for k in 0..self.layout.buffers.len() {
            let p = self.b.ins().load(self.ptr, flags, bufs_ptr, (k * self.ptr.bytes() as usize) as i32);
            self.bufs.push(p);
        }
        let max_epoch = self.sched.scalars.len();
        for e in 0..max_epoch {
            for &i in &self.sched.scalars[e] {
                let v = self.scalar_inst(i, params_ptr)?;
                self.vals.insert(i, v);
            }
            for &d in &self.sched.calls[e] {
                self.emit_call(d)?;
            }
            let loops: Vec<usize> = (0..self.sched.loops.len()).filter(|l| self.sched.loops[*l].0 as usize == e).collect();
            for l in loops {
                self.emit_loop(l)?;
            }
        }
        // Scalar results, widened to f64.
        for s in &self.layout.scalars {
            let v = self.vals[&s.value.index()];
            let re = self.widen(v.re);
            self.b.ins().store(flags, re, scalars_ptr, (s.slot * 8) as i32);
            if s.complex {
                let im = v.im.unwrap_or(v.re);
                let im = self.widen(im);
                self.b.ins().store(flags, im, scalars_ptr, (s.slot * 8 + 8) as i32);
            }
        }
        self.b.ins().return_(&[]);
        Ok(())
    }

    /// Calls the library routine behind instruction `d` (a transform or a
    /// tensor op) on buffers.
    fn emit_call(&mut self, d: usize) -> Result<(), CodegenError> {
        let (plan, work) = self.sched.call_plans[&d];
        let plan = self.b.ins().iconst(self.ptr, self.plans[plan].address());
        let out = self.bufs[self.sched.stored[&d]];
        let (f, args) = match self.func.insts[d].op {
            Op::Dft(_, a) => {
                let f = self.import(if self.storage == types::F32 { "gwml_dft_f32" } else { "gwml_dft_f64" })?;
                let work = self.bufs[work.expect("transforms have work buffers")];
                (f, vec![plan, self.bufs[self.operand_buffer(a)], out, work])
            }
            Op::Tensor(_, _, a, b) => {
                let f = self.import(if self.storage == types::F32 { "gwml_tensor_f32" } else { "gwml_tensor_f64" })?;
                (f, vec![plan, self.bufs[self.operand_buffer(a)], self.bufs[self.operand_buffer(b)], out])
            }
            // Band calls read and write each buffer in its own precision
            // (in mixed precision a phase and its `cis` stay f64).
            Op::Band(_, _, a) => {
                let wide = |buf: usize| self.layout.buffers[buf].precision == Precision::F64;
                let name = match (wide(self.operand_buffer(a)), wide(self.sched.stored[&d])) {
                    (true, true) => "gwml_band_f64",
                    (false, false) => "gwml_band_f32",
                    (true, false) => "gwml_band_f64_f32",
                    (false, true) => "gwml_band_f32_f64",
                };
                let f = self.import(name)?;
                (f, vec![plan, self.bufs[self.operand_buffer(a)], out])
            }
            _ => unreachable!("only library calls are scheduled as calls"),
        };
        self.b.ins().call(f, &args);
        Ok(())
    }

    /// Emits loop `l`: when [`Gen::vector_lane`] allows, a vectorised loop
    /// over as many whole vectors as fit, then a scalar loop over the rest.
    ///
    /// A loop whose selects test an interval condition (the ISCO cut
    /// `f <= f_isco`, see [`Function::interval_condition`]) is *split*:
    /// the kernel finds the index where the condition changes by a binary
    /// search over the grid (evaluating the condition exactly as the loop
    /// would, so the split agrees with it point by point), and emits the
    /// loop once for each side with the selects resolved. What a select
    /// throws away is then not computed at all: above the ISCO, the
    /// waveform's phase and, since `Builder` sinks the mask through
    /// products, every term of its adjoint. Reductions run on each side
    /// from zero and are added at the end.
    fn emit_loop(&mut self, l: usize) -> Result<(), CodegenError> {
        let (_, grid, ref members) = self.sched.loops[l];
        let len = self.func.grids[grid.0 as usize].len as i64;
        let reductions: Vec<(usize, Reduce, bool)> = members
            .iter()
            .filter_map(|&m| match self.func.insts[m].op {
                Op::Reduce(r, a) => Some((m, r, self.func.ty(a).elem == Elem::Complex)),
                _ => None,
            })
            .collect();
        let (zero, n) = (self.b.ins().iconst(types::I64, 0), self.b.ins().iconst(types::I64, len));
        let mut total: Option<Accs> = None;
        let ranges = match self.sched.splits[l] {
            Some((c, first)) => {
                let k = self.split_point(l, c, first, (zero, n));
                vec![(zero, k, Some((c, first))), (k, n, Some((c, !first)))]
            }
            None => vec![(zero, n, None)],
        };
        let whole = ranges.len() == 1;
        for (from, to, known) in ranges {
            let accs = self.emit_loop_part(l, (from, to), whole.then_some(len), known, &reductions)?;
            total = Some(match total {
                None => accs,
                Some(before) => before
                    .into_iter()
                    .zip(accs)
                    .zip(&reductions)
                    .map(|(((re0, im0), (re1, im1)), &(_, r, _))| {
                        let re = self.reduce_step(r, re0, re1);
                        let im = im0.zip(im1).map(|(a, b)| self.b.ins().fadd(a, b));
                        (re, im)
                    })
                    .collect(),
            });
        }
        for (&(m, ..), (re, im)) in reductions.iter().zip(total.unwrap_or_default()) {
            let ty = self.ty_of(m);
            let re = self.cast(re, ty);
            let im = im.map(|x| self.cast(x, ty));
            self.vals.insert(m, Cv { re, im });
        }
        Ok(())
    }

    /// Loop `l` over indices `from..to` (`len`, when the range is the whole
    /// grid, lets the vector and scalar parts be sized at compile time),
    /// with `known` resolving selects; returns the reductions' partial
    /// results, accumulated from zero (−∞ for a maximum).
    fn emit_loop_part(
        &mut self,
        l: usize,
        (from, to): (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value),
        len: Option<i64>,
        known: Option<(usize, bool)>,
        reductions: &[(usize, Reduce, bool)],
    ) -> Result<Accs, CodegenError> {
        // Accumulators of reductions (f64 even in f32 mode).
        let mut accs: Accs = reductions
            .iter()
            .map(|&(_, r, complex)| {
                let init = if r == Reduce::Max { f64::NEG_INFINITY } else { 0.0 };
                (self.b.ins().f64const(init), complex.then(|| self.b.ins().f64const(0.0)))
            })
            .collect();
        let mut start = from;
        // Whether the scalar loop has nothing left to do, known statically.
        let mut no_tail = len == Some(0);
        if let Some(lane) = self.vector_lane(l) {
            let lanes = (16 / lane.bytes()) as i64;
            let copies = if self.small_body(l, known) { 2 } else { 1 };
            let chunk = lanes * copies as i64;
            // The end of the whole chunks (`copies` vectors each):
            // statically when the range is the grid, else
            // `from + (to − from) & −chunk`.
            let end = match len {
                Some(len) if len < chunk => None,
                Some(len) => {
                    no_tail = len % chunk == 0;
                    Some(self.b.ins().iconst(types::I64, len - len % chunk))
                }
                None => {
                    let count = self.b.ins().isub(to, from);
                    let whole = self.b.ins().band_imm_s(count, -chunk);
                    Some(self.b.ins().iadd(from, whole))
                }
            };
            if let Some(end) = end {
                // Vectorised reductions accumulate in f64x2: complex ones
                // (f64 loops only) in two, re and im; real f32x4 ones in
                // two as well, lanes 0–1 and 2–3, the second in the slot of
                // the imaginary part.
                let init: Vec<_> = accs
                    .iter()
                    .map(|&(re, im)| {
                        let v = self.b.ins().splat(types::F64X2, re);
                        let second = match im {
                            Some(im) => Some(self.b.ins().splat(types::F64X2, im)),
                            None => (lane == types::F32).then_some(v),
                        };
                        (v, second)
                    })
                    .collect();
                self.vector = Some(lane);
                let out = self.emit_loop_range(l, (from, end), (lanes, copies), known, &init);
                self.vector = None;
                let out = out?;
                accs = Vec::new();
                for ((v, second), &(_, r, complex)) in out.into_iter().zip(reductions) {
                    accs.push(match second {
                        Some(im) if complex => (self.horizontal(r, v), Some(self.horizontal(r, im))),
                        Some(high) => {
                            let v = self.reduce_step(r, v, high);
                            (self.horizontal(r, v), None)
                        }
                        None => (self.horizontal(r, v), None),
                    });
                }
                start = end;
            }
        }
        if !no_tail {
            accs = self.emit_loop_range(l, (start, to), (1, 1), known, &accs)?;
        }
        Ok(accs)
    }

    /// The first index of loop `l`'s grid (indices `zero..n`) where
    /// condition `c` no longer has the value `first` it has on the grid's
    /// first points (`n` if none): a binary search, each step evaluating
    /// `c` as the loop's scalar code would.
    fn split_point(
        &mut self,
        l: usize,
        c: usize,
        first: bool,
        (zero, n): (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value),
    ) -> cranelift_codegen::ir::Value {
        let (lo, hi) = (self.b.declare_var(types::I64), self.b.declare_var(types::I64));
        self.b.def_var(lo, zero);
        self.b.def_var(hi, n);
        let (header, body, exit) = (self.b.create_block(), self.b.create_block(), self.b.create_block());
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let (a, b) = (self.b.use_var(lo), self.b.use_var(hi));
        let done = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, a, b);
        self.b.ins().brif(done, exit, &[], body, &[]);
        self.b.switch_to_block(body);
        let sum = self.b.ins().iadd(a, b);
        let mid = self.b.ins().ushr_imm_u(sum, 1);
        let mut lc = LoopCtx { epoch: self.sched.loops[l].0, index: mid, vals: HashMap::new(), halves: HashMap::new(), known: None };
        let ft = self.ft;
        let holds = self.loop_operand(&mut lc, Value(c as u32)).expect("an interval condition is a comparison").re;
        self.ft = ft;
        let same = if first { holds } else { self.b.ins().icmp_imm_s(IntCC::Equal, holds, 0) };
        let after = self.b.ins().iadd_imm_s(mid, 1);
        let (a2, b2) = (self.b.ins().select(same, after, a), self.b.ins().select(same, b, mid));
        self.b.def_var(lo, a2);
        self.b.def_var(hi, b2);
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(exit);
        self.b.use_var(lo)
    }

    /// One loop of `l`'s members over indices `from..to` in steps of
    /// `step` (the lane count when vectorised), with reduction accumulators
    /// starting at `init` (in member order); returns their final values.
    fn emit_loop_range(
        &mut self,
        l: usize,
        (from, to): (cranelift_codegen::ir::Value, cranelift_codegen::ir::Value),
        (step, copies): (i64, usize),
        known: Option<(usize, bool)>,
        init: &[(cranelift_codegen::ir::Value, Option<cranelift_codegen::ir::Value>)],
    ) -> Result<Accs, CodegenError> {
        let members = self.sched.loops[l].2.clone();
        // Per copy of the body, each reduction's accumulators (all start
        // from `init`: the vectorised part, the only one with copies,
        // starts from the reductions' identities).
        let mut accs: Vec<Vec<(usize, Variable, Option<Variable>)>> = Vec::new();
        for _ in 0..copies {
            let mut copy = Vec::new();
            let reductions = members.iter().filter(|&&m| matches!(self.func.insts[m].op, Op::Reduce(..)));
            for (&m, &(re0, im0)) in reductions.zip(init) {
                let re = self.b.declare_var(self.b.func.dfg.value_type(re0));
                self.b.def_var(re, re0);
                let im = im0.map(|v| {
                    let im = self.b.declare_var(self.b.func.dfg.value_type(v));
                    self.b.def_var(im, v);
                    im
                });
                copy.push((m, re, im));
            }
            accs.push(copy);
        }
        let ivar = self.b.declare_var(types::I64);
        self.b.def_var(ivar, from);
        let header = self.b.create_block();
        let body = self.b.create_block();
        let exit = self.b.create_block();
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(header);
        let i = self.b.use_var(ivar);
        // The exit is the taken branch and the body the fall-through on
        // purpose. Cranelift's egraph (0.135) hoists loop-invariant values
        // (splats, the scalar PN coefficients) out of a loop only in the
        // loop's blocks it visits before the exit: visiting the exit ends
        // the loop for it. It visits a `brif`'s successors in an order
        // that puts the exit first when the body is the taken branch. With
        // that order, 2 values were hoisted in W1's strain kernel; with
        // this one, 131 (and the kernel runs ~20 % faster).
        let done = self.b.ins().icmp(IntCC::SignedGreaterThanOrEqual, i, to);
        self.b.ins().brif(done, exit, &[], body, &[]);
        self.b.switch_to_block(body);
        for (copy, accs) in accs.iter().enumerate() {
            let index = if copy == 0 { i } else { self.b.ins().iadd_imm_s(i, step * copy as i64) };
            self.emit_body_copy(l, &members, index, known, accs)?;
        }
        let next = self.b.ins().iadd_imm_s(i, step * copies as i64);
        self.b.def_var(ivar, next);
        self.b.ins().jump(header, &[]);
        self.b.switch_to_block(exit);
        // The copies' partial results, combined.
        let mut out: Accs = Vec::new();
        for (k, &(m, re, im)) in accs[0].iter().enumerate() {
            let Op::Reduce(r, a) = self.func.insts[m].op else { unreachable!("accumulators belong to reductions") };
            let complex = self.func.ty(a).elem == Elem::Complex;
            let (mut re, mut im) = (self.b.use_var(re), im.map(|v| self.b.use_var(v)));
            for copy in &accs[1..] {
                let (_, re1, im1) = copy[k];
                let re1 = self.b.use_var(re1);
                re = self.reduce_step(r, re, re1);
                if let (Some(x), Some(im1)) = (im, im1) {
                    let y = self.b.use_var(im1);
                    // The second slot: an imaginary part, or lanes 2–3.
                    im = Some(if complex { self.b.ins().fadd(x, y) } else { self.reduce_step(r, x, y) });
                }
            }
            out.push((re, im));
        }
        Ok(out)
    }

    /// One copy of loop `l`'s body, at `index`, accumulating into `accs`.
    fn emit_body_copy(
        &mut self,
        l: usize,
        members: &[usize],
        index: cranelift_codegen::ir::Value,
        known: Option<(usize, bool)>,
        accs: &[(usize, Variable, Option<Variable>)],
    ) -> Result<(), CodegenError> {
        let mut lc = LoopCtx { epoch: self.sched.loops[l].0, index, vals: HashMap::new(), halves: HashMap::new(), known };
        for &m in members {
            let inst = self.func.insts[m];
            if !self.emitted(m, known) {
                if matches!(inst.op, Op::Reduce(..)) {
                    self.sums_skipped.insert(m);
                }
                continue;
            }
            if let Op::Reduce(r, a) = inst.op {
                let (_, re_var, im_var) = *accs.iter().find(|(k, ..)| *k == m).expect("accumulator declared");
                if self.vector == Some(types::F32) {
                    // f32x4 (real) → two f64x2 halves, into the two accumulators.
                    let [low, high] = self.wide_operand(&mut lc, a)?.map(|h| h.re);
                    let iv = im_var.expect("f32x4 reductions have two accumulators");
                    let acc = self.b.use_var(re_var);
                    let next = self.reduce_step(r, acc, low);
                    self.b.def_var(re_var, next);
                    let acc = self.b.use_var(iv);
                    let next = self.reduce_step(r, acc, high);
                    self.b.def_var(iv, next);
                    continue;
                }
                let x = self.loop_operand(&mut lc, a)?;
                let acc = self.b.use_var(re_var);
                let xr = self.widen(x.re);
                let next = self.reduce_step(r, acc, xr);
                self.b.def_var(re_var, next);
                if let (Some(iv), Some(xi)) = (im_var, x.im) {
                    let acc = self.b.use_var(iv);
                    let xi = self.widen(xi);
                    let next = self.b.ins().fadd(acc, xi);
                    self.b.def_var(iv, next);
                }
                continue;
            }
            if self.split(m) {
                let halves = self.wide_operand(&mut lc, Value(m as u32))?;
                if let Some(&buf) = self.sched.stored.get(&m) {
                    self.store_halves(buf, lc.index, halves, inst.ty.elem == Elem::Complex);
                }
                continue;
            }
            let v = self.loop_operand(&mut lc, Value(m as u32))?;
            if let Some(&buf) = self.sched.stored.get(&m) {
                self.ft = self.buffer_ty(buf);
                let v = if inst.ty.elem == Elem::Bool {
                    // Truth values travel between loops as 1.0 / 0.0.
                    let (one, zero) = (self.fconst(1.0), self.fconst(0.0));
                    Cv::real(self.select(v.re, one, zero))
                } else {
                    v
                };
                self.store_elem(buf, lc.index, v, inst.ty.elem == Elem::Complex);
            }
        }
        Ok(())
    }

    /// One step of reduction `r`: `acc + x` or `max(acc, x)`.
    fn reduce_step(
        &mut self,
        r: Reduce,
        acc: cranelift_codegen::ir::Value,
        x: cranelift_codegen::ir::Value,
    ) -> cranelift_codegen::ir::Value {
        if r == Reduce::Max {
            self.b.ins().fmax(acc, x)
        } else {
            self.b.ins().fadd(acc, x)
        }
    }

    /// Reduction `r` over the two lanes of an f64x2.
    fn horizontal(&mut self, r: Reduce, v: cranelift_codegen::ir::Value) -> cranelift_codegen::ir::Value {
        let (a, b) = (self.b.ins().extractlane(v, 0), self.b.ins().extractlane(v, 1));
        self.reduce_step(r, a, b)
    }

    /// The side a select `i` takes when its condition is known over the
    /// range being emitted.
    pub(super) fn resolved(&self, known: Option<(usize, bool)>, i: usize) -> Option<Value> {
        let (c, holds) = known?;
        match self.func.insts[i].op {
            Op::Select(k, a, b) if k.index() == c => Some(if holds { a } else { b }),
            _ => None,
        }
    }

    /// The value every element of array `i` statically holds in the range
    /// being emitted, as (re, im) bit patterns: a broadcast constant, or a
    /// select the known condition resolves to one.
    pub(super) fn known_constant(&self, known: Option<(usize, bool)>, i: usize) -> Option<(u64, u64)> {
        if let Some(taken) = self.resolved(known, i) {
            return self.known_constant(known, taken.index());
        }
        match self.func.insts[i].op {
            Op::Broadcast(a, _) => match self.func.insts[a.index()].op {
                Op::Const(x) => Some((x, 0)),
                Op::ConstComplex(re, im) => Some((re, im)),
                _ => None,
            },
            _ => None,
        }
    }

    /// Whether loop member `m` is emitted in a range where `known` holds
    /// (the whole loop when `None`): with a condition known, a sum whose
    /// terms it makes +0 is skipped, and of the rest only what is stored
    /// (and what that needs, on demand): the rest may be thrown away.
    fn emitted(&self, m: usize, known: Option<(usize, bool)>) -> bool {
        match self.func.insts[m].op {
            Op::Reduce(r, a) => !(r == Reduce::Sum && self.known_zero(known, a.index())),
            _ => known.is_none() || self.sched.stored.contains_key(&m),
        }
    }

    /// Whether loop `l`'s body, with `known` resolving selects, is a few
    /// arithmetic operations (at most [`SMALL_BODY`], no function calls
    /// or inline transcendentals). Such a loop is bound by the latency of
    /// its reductions' accumulators (an f64x2 add every 4 cycles): its
    /// vectorised part runs two copies of the body per iteration, each
    /// with its own accumulators, added at the end.
    fn small_body(&self, l: usize, known: Option<(usize, bool)>) -> bool {
        let members = &self.sched.loops[l].2;
        let mut seen = HashSet::new();
        let mut cost = 0;
        let mut stack: Vec<usize> = Vec::new();
        for &m in members.iter().filter(|&&m| self.emitted(m, known)) {
            stack.push(match self.func.insts[m].op {
                Op::Reduce(_, a) => a.index(),
                _ => m,
            });
        }
        while let Some(i) = stack.pop() {
            let inst = self.func.insts[i];
            if inst.ty.shape == Shape::Scalar || !seen.insert(i) {
                continue;
            }
            if let Some(taken) = self.resolved(known, i) {
                stack.push(taken.index());
                continue;
            }
            if matches!(inst.op, Op::Broadcast(..)) {
                continue; // hoisted out of the loop
            }
            cost += if inst.ty.elem == Elem::Complex { 2 } else { 1 };
            match inst.op {
                Op::GridCoord(_) | Op::Input(_) | Op::Table(_) | Op::Dft(..) | Op::Tensor(..) | Op::Band(..) => {}
                _ if self.reloaded(i, self.sched.loops[l].0) => {}
                Op::Unary(UnOp::Neg | UnOp::Abs | UnOp::Re | UnOp::Im | UnOp::Conj | UnOp::Abs2 | UnOp::ToComplex, a) => {
                    stack.push(a.index())
                }
                Op::Binary(
                    BinOp::Add
                    | BinOp::Sub
                    | BinOp::Mul
                    | BinOp::Div
                    | BinOp::Min
                    | BinOp::Max
                    | BinOp::Lt
                    | BinOp::Le
                    | BinOp::Gt
                    | BinOp::Ge,
                    a,
                    b,
                ) => stack.extend([a.index(), b.index()]),
                Op::Select(c, a, b) => stack.extend([c.index(), a.index(), b.index()]),
                _ => return false,
            }
        }
        cost <= SMALL_BODY
    }

    /// Whether array `i` is +0 (and +0i) over the range being emitted, so
    /// that `x − i` is exactly `x` and a sum gains nothing from it (a sum
    /// starts at +0, and never reaches −0, so adding ±0 leaves it as is).
    fn known_zero(&self, known: Option<(usize, bool)>, i: usize) -> bool {
        self.known_constant(known, i).is_some_and(|(re, im)| f64::from_bits(re) == 0.0 && f64::from_bits(im) == 0.0)
    }

    /// Whether array value `i` is split in the loop being emitted: computed
    /// in f64 (mixed precision) inside an f32x4 loop.
    pub(super) fn split(&self, i: usize) -> bool {
        self.vector == Some(types::F32) && self.wide[i]
    }

    /// Whether array value `i` is read from the buffer an earlier loop
    /// stored it to, in a loop of `epoch`.
    pub(super) fn reloaded(&self, i: usize, epoch: u32) -> bool {
        self.sched.reloaded(i, epoch)
    }
}
