//! Symbolic reverse-mode differentiation of the IR.
//!
//! For each requested gradient output, the pass walks the instructions
//! backwards from the output, accumulating each value's adjoint with the
//! per-op rules in [`rule`]. Only *active* values get adjoints: those that
//! depend on a requested param (forward activity) and that the output
//! depends on (backward activity), so nothing is built for parameters
//! nobody asked about.
//!
//! Complex values follow the convention used by JAX and PyTorch for real
//! losses: the adjoint of `z = x + iy` is `∂L/∂x + i ∂L/∂y`. For a
//! holomorphic `z = f(a)` this gives `ā += z̄ · conj(f'(a))`.

use crate::ir::builder::Builder;
use crate::ir::*;
use num_complex::Complex64 as C64;
use std::collections::HashMap;

/// Appends the adjoint of every requested gradient to `func` and fills in
/// [`GradOutput::value`].
pub fn adjoint(func: &Function) -> Function {
    let mut b = Builder::new(func.clone(), true);
    let n = func.insts.len();
    let mut grads = func.grads.clone();
    let mut input_grads = func.input_grads.clone();
    let mut outputs: Vec<usize> = grads.iter().map(|g| g.output).chain(input_grads.iter().map(|g| g.output)).collect();
    outputs.dedup();
    let mut outputs_done: Vec<usize> = Vec::new();
    for out in outputs {
        if outputs_done.contains(&out) {
            continue;
        }
        outputs_done.push(out);
        let params: Vec<u32> = grads.iter().filter(|g| g.output == out).map(|g| g.param as u32).collect();
        let inputs: Vec<u32> = input_grads.iter().filter(|g| g.output == out).map(|g| g.input as u32).collect();
        // Forward activity.
        let mut active = vec![false; n];
        for (i, inst) in func.insts.iter().enumerate() {
            active[i] = match inst.op {
                Op::Param(p) => params.contains(&p),
                Op::Input(k) => inputs.contains(&k),
                op => op.operands().iter().any(|v| active[v.index()]),
            };
        }
        // Reverse sweep.
        let root = func.outputs[out].value;
        let mut adj: HashMap<usize, Value> = HashMap::new();
        if active[root.index()] {
            let one = b.real(1.0);
            adj.insert(root.index(), one);
        }
        for i in (0..n).rev() {
            let Some(g) = adj.get(&i).copied() else {
                continue;
            };
            let inst = func.insts[i];
            for (operand, contribution) in rule(&mut b, inst, Value(i as u32), g, &active) {
                if !active[operand.index()] {
                    continue;
                }
                let acc = match adj.get(&operand.index()) {
                    Some(prev) => b.add(*prev, contribution),
                    None => contribution,
                };
                adj.insert(operand.index(), acc);
            }
        }
        // The adjoint of a param or input: the sum over every instruction that reads it.
        let total_of = |b: &mut Builder, op: Op, ty: Ty| {
            let mut total: Option<Value> = None;
            for (i, inst) in func.insts.iter().enumerate() {
                if let (true, Some(a)) = (inst.op == op, adj.get(&i)) {
                    total = Some(match total {
                        Some(t) => b.add(t, *a),
                        None => *a,
                    });
                }
            }
            total.unwrap_or_else(|| b.zero(ty))
        };
        for g in grads.iter_mut().filter(|g| g.output == out) {
            g.value = Some(total_of(&mut b, Op::Param(g.param as u32), Ty::REAL));
        }
        for g in input_grads.iter_mut().filter(|g| g.output == out) {
            g.value = Some(total_of(&mut b, Op::Input(g.input as u32), func.inputs[g.input].ty));
        }
    }
    let mut out = b.func;
    out.grads = grads;
    out.input_grads = input_grads;
    out
}

/// The contributions of `z = inst` with adjoint `g` to its operands' adjoints.
/// Only contributions to active operands are built: nothing is emitted for
/// values that do not depend on a requested param.
fn rule(b: &mut Builder, inst: Inst, z: Value, g: Value, active: &[bool]) -> Vec<(Value, Value)> {
    let want = |v: Value| active[v.index()];
    let one = |b: &mut Builder, like: Value| {
        let ty = b.ty(like);
        b.constant(C64::new(1.0, 0.0), ty)
    };
    let conj = |b: &mut Builder, v: Value| {
        if b.ty(v).elem == Elem::Complex {
            b.unary(UnOp::Conj, v)
        } else {
            v
        }
    };
    match inst.op {
        Op::Const(_) | Op::ConstComplex(..) | Op::Param(_) | Op::Input(_) | Op::GridCoord(_) | Op::Table(_) => {
            vec![]
        }
        Op::Unary(u, a) => {
            let c = match u {
                UnOp::Neg => b.neg(g),
                UnOp::Sqrt => {
                    let two_z = b.scale(z, 2.0);
                    b.div(g, two_z)
                }
                UnOp::Cbrt => {
                    let zz = b.mul(z, z);
                    let d = b.scale(zz, 3.0);
                    b.div(g, d)
                }
                UnOp::Exp => {
                    let cz = conj(b, z);
                    b.mul(g, cz)
                }
                UnOp::Log => b.div(g, a),
                UnOp::Sin => {
                    let c = b.unary(UnOp::Cos, a);
                    b.mul(g, c)
                }
                UnOp::Cos => {
                    let s = b.unary(UnOp::Sin, a);
                    let gs = b.mul(g, s);
                    b.neg(gs)
                }
                UnOp::Tan => {
                    let zz = b.mul(z, z);
                    let o = one(b, z);
                    let d = b.add(o, zz);
                    b.mul(g, d)
                }
                UnOp::Tanh => {
                    // 1 - tanh² cancels in the tails; sech² = 4e/(1+e)² with
                    // e = exp(-2|x|) is accurate everywhere.
                    let ax = b.unary(UnOp::Abs, a);
                    let m2 = b.scale(ax, -2.0);
                    let e = b.unary(UnOp::Exp, m2);
                    let o = one(b, e);
                    let ope = b.add(o, e);
                    let den = b.mul(ope, ope);
                    let num = b.scale(e, 4.0);
                    let sech2 = b.div(num, den);
                    b.mul(g, sech2)
                }
                UnOp::Abs if b.ty(a).elem == Elem::Complex => {
                    // ā = g · a / |a|, and 0 where a = 0 (a subgradient).
                    let zero = b.zero(b.ty(z));
                    let pos = b.binary(BinOp::Gt, z, zero);
                    let ratio = b.div(g, z);
                    let w = b.emit(Op::Select(pos, ratio, zero));
                    let wc = b.unary(UnOp::ToComplex, w);
                    b.mul(wc, a)
                }
                UnOp::Abs => {
                    let s = b.unary(UnOp::Sign, a);
                    b.mul(g, s)
                }
                UnOp::Sign => return vec![],
                UnOp::Re => b.unary(UnOp::ToComplex, g),
                UnOp::Im => {
                    let zero = b.zero(b.ty(g));
                    b.binary(BinOp::Complex, zero, g)
                }
                UnOp::Conj => b.unary(UnOp::Conj, g),
                UnOp::Abs2 => {
                    let g2 = b.scale(g, 2.0);
                    let g2c = b.unary(UnOp::ToComplex, g2);
                    b.mul(a, g2c)
                }
                UnOp::Cis => {
                    let cz = b.unary(UnOp::Conj, z);
                    let w = b.mul(g, cz);
                    b.unary(UnOp::Im, w)
                }
                UnOp::ToComplex => b.unary(UnOp::Re, g),
            };
            vec![(a, c)]
        }
        Op::Binary(op, x, y) => {
            let mut out = Vec::new();
            match op {
                BinOp::Add => out = vec![(x, g), (y, g)],
                BinOp::Sub => {
                    out.push((x, g));
                    if want(y) {
                        out.push((y, b.neg(g)));
                    }
                }
                BinOp::Mul => {
                    if want(x) {
                        let cy = conj(b, y);
                        out.push((x, b.mul(g, cy)));
                    }
                    if want(y) {
                        let cx = conj(b, x);
                        out.push((y, b.mul(g, cx)));
                    }
                }
                BinOp::Div => {
                    // x̄ = g / conj(y) and ȳ = −g · conj(z / y) = −x̄ · conj(z):
                    // one division serves both.
                    let cy = conj(b, y);
                    let gx = b.div(g, cy);
                    if want(x) {
                        out.push((x, gx));
                    }
                    if want(y) {
                        let cz = conj(b, z);
                        let t = b.mul(gx, cz);
                        out.push((y, b.neg(t)));
                    }
                }
                BinOp::Pow => {
                    if want(x) {
                        let o = one(b, y);
                        let ym1 = b.sub(y, o);
                        let p = b.binary(BinOp::Pow, x, ym1);
                        let yp = b.mul(y, p);
                        out.push((x, b.mul(g, yp)));
                    }
                    if want(y) {
                        let lx = b.unary(UnOp::Log, x);
                        let zl = b.mul(z, lx);
                        out.push((y, b.mul(g, zl)));
                    }
                }
                BinOp::Atan2 => {
                    // z = atan2(x, y): ∂/∂x = y/r, ∂/∂y = -x/r with r = x² + y².
                    // Scaling both by m = max(|x|, |y|) keeps r from under- or
                    // overflowing; at the origin the gradient is taken as 0.
                    let (ax, ay) = (b.unary(UnOp::Abs, x), b.unary(UnOp::Abs, y));
                    let m = b.binary(BinOp::Max, ax, ay);
                    let (xs, ys) = (b.div(x, m), b.div(y, m));
                    let (xx, yy) = (b.mul(xs, xs), b.mul(ys, ys));
                    let r = b.add(xx, yy);
                    let rm = b.mul(r, m);
                    let zero = b.zero(b.ty(g));
                    let nonzero = b.binary(BinOp::Gt, m, zero);
                    if want(x) {
                        let gy = b.mul(g, ys);
                        let d = b.div(gy, rm);
                        out.push((x, b.emit(Op::Select(nonzero, d, zero))));
                    }
                    if want(y) {
                        let gx = b.mul(g, xs);
                        let d = b.div(gx, rm);
                        let nd = b.neg(d);
                        out.push((y, b.emit(Op::Select(nonzero, nd, zero))));
                    }
                }
                BinOp::Min | BinOp::Max => {
                    let cmp = if op == BinOp::Min { BinOp::Le } else { BinOp::Ge };
                    let c = b.binary(cmp, x, y);
                    let zero = b.zero(b.ty(g));
                    if want(x) {
                        out.push((x, b.emit(Op::Select(c, g, zero))));
                    }
                    if want(y) {
                        out.push((y, b.emit(Op::Select(c, zero, g))));
                    }
                }
                BinOp::Complex => {
                    if want(x) {
                        out.push((x, b.unary(UnOp::Re, g)));
                    }
                    if want(y) {
                        out.push((y, b.unary(UnOp::Im, g)));
                    }
                }
                BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne => {}
            }
            out
        }
        Op::PowConst(a, c) => {
            let e = f64::from_bits(c);
            let p = b.emit(Op::PowConst(a, (e - 1.0).to_bits()));
            let ep = b.scale(p, e);
            vec![(a, b.mul(g, ep))]
        }
        Op::Select(c, x, y) => {
            let zero = b.zero(b.ty(g));
            let mut out = Vec::new();
            if want(x) {
                out.push((x, b.emit(Op::Select(c, g, zero))));
            }
            if want(y) {
                out.push((y, b.emit(Op::Select(c, zero, g))));
            }
            out
        }
        Op::Broadcast(a, _) => vec![(a, b.emit(Op::Reduce(Reduce::Sum, g)))],
        Op::Reduce(Reduce::Sum, a) => {
            let Shape::Grid(grid) = b.ty(a).shape else {
                return vec![];
            };
            vec![(a, b.emit(Op::Broadcast(g, grid)))]
        }
        // A transform is linear; its adjoint is its transpose (see `Dft`).
        Op::Dft(d, a) => {
            let Shape::Grid(grid) = b.ty(a).shape else { return vec![] };
            vec![(a, b.emit(Op::Dft(Dft { inverse: !d.inverse, out: grid, ..d }, g)))]
        }
        Op::Tensor(t, _, x, y) => tensor_rule(b, t, x, y, g).into_iter().filter(|(v, _)| want(*v)).collect(),
        // z = e^{i L(x)}: as for `cis`, the adjoint of the interpolated
        // phase is Im(z̄ · conj(z)) per fine point; L's transpose takes it
        // to the nodes. Every other band op is linear: its adjoint is its
        // transpose.
        Op::Band(o, n, a) => {
            let back = |b: &mut Builder, o: BandOp, v: Value| b.emit(Op::Band(o, n, v));
            match o {
                BandOp::Cis => {
                    let cz = b.unary(UnOp::Conj, z);
                    let w = b.mul(g, cz);
                    let per_point = b.unary(UnOp::Im, w);
                    vec![(a, back(b, BandOp::InterpT, per_point))]
                }
                linear => vec![(a, back(b, linear.transpose(), g))],
            }
        }
        Op::Reduce(Reduce::Max, a) => {
            // The maximum's adjoint is shared equally among tied elements
            // (a subgradient; JAX's convention).
            let Shape::Grid(grid) = b.ty(a).shape else { return vec![] };
            let zb = b.emit(Op::Broadcast(z, grid));
            let hit = b.binary(BinOp::Eq, a, zb);
            let ones = b.constant(C64::new(1.0, 0.0), b.ty(a));
            let zeros = b.zero(b.ty(a));
            let mask = b.emit(Op::Select(hit, ones, zeros));
            let ties = b.emit(Op::Reduce(Reduce::Sum, mask));
            let share = b.div(g, ties);
            let gb = b.emit(Op::Broadcast(share, grid));
            vec![(a, b.mul(gb, mask))]
        }
    }
}

/// Adjoints of `z = t(x, y)` with adjoint `g`: every tensor op is linear in
/// each operand, so each contribution is a transpose (see [`TensorOp`]);
/// pooling's first operand only chooses positions and gets none.
fn tensor_rule(b: &mut Builder, t: TensorOp, x: Value, y: Value, g: Value) -> Vec<(Value, Value)> {
    let grid = |b: &Builder, v: Value| match b.ty(v).shape {
        Shape::Grid(grid) => grid,
        Shape::Scalar => unreachable!("tensor operands are arrays (checked by `Function::verify`)"),
    };
    let (gx, gy) = (grid(b, x), grid(b, y));
    let op = |b: &mut Builder, t: TensorOp, out: GridId, p: Value, q: Value| b.emit(Op::Tensor(t, out, p, q));
    use TensorOp as T;
    match t {
        T::MatVec { m, k } => vec![(x, op(b, T::Outer { m, k }, gx, g, y)), (y, op(b, T::MatTVec { m, k }, gy, x, g))],
        T::MatTVec { m, k } => vec![(x, op(b, T::Outer { m, k }, gx, y, g)), (y, op(b, T::MatVec { m, k }, gy, x, g))],
        T::Outer { m, k } => vec![(x, op(b, T::MatVec { m, k }, gx, g, y)), (y, op(b, T::MatTVec { m, k }, gy, g, x))],
        T::Conv(c) => vec![(x, op(b, T::ConvBackData(c), gx, g, y)), (y, op(b, T::ConvBackWeight(c), gy, g, x))],
        T::ConvBackData(c) => vec![(x, op(b, T::Conv(c), gx, g, y)), (y, op(b, T::ConvBackWeight(c), gy, x, g))],
        T::ConvBackWeight(c) => vec![(x, op(b, T::Conv(c), gx, y, g)), (y, op(b, T::ConvBackData(c), gy, x, g))],
        T::PoolPick(p) => vec![(y, op(b, T::PoolScatter(p), gy, x, g))],
        T::PoolScatter(p) => vec![(y, op(b, T::PoolPick(p), gy, x, g))],
        T::PoolAvg(p) => vec![(x, op(b, T::PoolAvgBack(p), gx, g, g))],
        T::PoolAvgBack(p) => vec![(x, op(b, T::PoolAvg(p), gx, g, g))],
        T::Spread { rows, cols } => vec![(x, op(b, T::SumRows { rows, cols }, gx, g, g))],
        T::SumRows { rows, cols } => vec![(x, op(b, T::Spread { rows, cols }, gx, g, g))],
        T::PlaceRows(r) => vec![(x, op(b, T::TakeRows(r), gx, g, g))],
        T::TakeRows(r) => vec![(x, op(b, T::PlaceRows(r), gx, g, g))],
    }
}
