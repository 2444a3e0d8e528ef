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

use crate::builder::Builder;
use crate::ir::*;
use num_complex::Complex64 as C64;
use std::collections::HashMap;

/// Appends the adjoint of every requested gradient to `func` and fills in
/// [`GradOutput::value`].
pub fn adjoint(func: &Function) -> Function {
    let mut b = Builder::new(func.clone(), true);
    let n = func.insts.len();
    let mut grads = func.grads.clone();
    let mut outputs_done: Vec<usize> = Vec::new();
    for gi in 0..grads.len() {
        let out = grads[gi].output;
        if outputs_done.contains(&out) {
            continue;
        }
        outputs_done.push(out);
        let params: Vec<u32> = grads.iter().filter(|g| g.output == out).map(|g| g.param as u32).collect();
        // Forward activity.
        let mut active = vec![false; n];
        for (i, inst) in func.insts.iter().enumerate() {
            active[i] = match inst.op {
                Op::Param(p) => params.contains(&p),
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
            for (operand, contribution) in rule(&mut b, inst, Value(i as u32), g) {
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
        for g in grads.iter_mut().filter(|g| g.output == out) {
            let mut total: Option<Value> = None;
            for (i, inst) in func.insts.iter().enumerate() {
                if inst.op == Op::Param(g.param as u32) {
                    if let Some(a) = adj.get(&i) {
                        total = Some(match total {
                            Some(t) => b.add(t, *a),
                            None => *a,
                        });
                    }
                }
            }
            g.value = Some(total.unwrap_or_else(|| b.real(0.0)));
        }
    }
    let mut out = b.func;
    out.grads = grads;
    out
}

/// The contributions of `z = inst` with adjoint `g` to its operands' adjoints.
fn rule(b: &mut Builder, inst: Inst, z: Value, g: Value) -> Vec<(Value, Value)> {
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
                UnOp::Tan | UnOp::Tanh => {
                    let zz = b.mul(z, z);
                    let o = one(b, z);
                    let d = if u == UnOp::Tan { b.add(o, zz) } else { b.sub(o, zz) };
                    b.mul(g, d)
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
        Op::Binary(op, x, y) => match op {
            BinOp::Add => vec![(x, g), (y, g)],
            BinOp::Sub => {
                let ng = b.neg(g);
                vec![(x, g), (y, ng)]
            }
            BinOp::Mul => {
                let (cx, cy) = (conj(b, x), conj(b, y));
                let gx = b.mul(g, cy);
                let gy = b.mul(g, cx);
                vec![(x, gx), (y, gy)]
            }
            BinOp::Div => {
                let cy = conj(b, y);
                let gx = b.div(g, cy);
                let zy = b.div(z, y);
                let czy = conj(b, zy);
                let t = b.mul(g, czy);
                let gy = b.neg(t);
                vec![(x, gx), (y, gy)]
            }
            BinOp::Pow => {
                let o = one(b, y);
                let ym1 = b.sub(y, o);
                let p = b.binary(BinOp::Pow, x, ym1);
                let yp = b.mul(y, p);
                let gx = b.mul(g, yp);
                let lx = b.unary(UnOp::Log, x);
                let zl = b.mul(z, lx);
                let gy = b.mul(g, zl);
                vec![(x, gx), (y, gy)]
            }
            BinOp::Atan2 => {
                // z = atan2(x, y) in operand order: ∂/∂x = y/r, ∂/∂y = -x/r
                // with r = x² + y².
                let xx = b.mul(x, x);
                let yy = b.mul(y, y);
                let r = b.add(xx, yy);
                let gy_ = b.mul(g, y);
                let gx = b.div(gy_, r);
                let gx_ = b.mul(g, x);
                let t = b.div(gx_, r);
                let gy = b.neg(t);
                vec![(x, gx), (y, gy)]
            }
            BinOp::Min | BinOp::Max => {
                let cmp = if op == BinOp::Min { BinOp::Le } else { BinOp::Ge };
                let c = b.binary(cmp, x, y);
                let zero = b.zero(b.ty(g));
                let gx = b.emit(Op::Select(c, g, zero));
                let gy = b.emit(Op::Select(c, zero, g));
                vec![(x, gx), (y, gy)]
            }
            BinOp::Complex => {
                let gx = b.unary(UnOp::Re, g);
                let gy = b.unary(UnOp::Im, g);
                vec![(x, gx), (y, gy)]
            }
            BinOp::Lt | BinOp::Le | BinOp::Gt | BinOp::Ge | BinOp::Eq | BinOp::Ne => vec![],
        },
        Op::PowConst(a, c) => {
            let e = f64::from_bits(c);
            let p = b.emit(Op::PowConst(a, (e - 1.0).to_bits()));
            let ep = b.scale(p, e);
            vec![(a, b.mul(g, ep))]
        }
        Op::Select(c, x, y) => {
            let zero = b.zero(b.ty(g));
            let gx = b.emit(Op::Select(c, g, zero));
            let gy = b.emit(Op::Select(c, zero, g));
            vec![(x, gx), (y, gy)]
        }
        Op::Broadcast(a, _) => vec![(a, b.emit(Op::Reduce(Reduce::Sum, g)))],
        Op::Reduce(Reduce::Sum, a) => {
            let Shape::Grid(grid) = b.ty(a).shape else {
                return vec![];
            };
            vec![(a, b.emit(Op::Broadcast(g, grid)))]
        }
        Op::Reduce(Reduce::Max, a) => {
            let Shape::Grid(grid) = b.ty(a).shape else {
                return vec![];
            };
            let zb = b.emit(Op::Broadcast(z, grid));
            let hit = b.binary(BinOp::Eq, a, zb);
            let gb = b.emit(Op::Broadcast(g, grid));
            let zero = b.zero(b.ty(gb));
            vec![(a, b.emit(Op::Select(hit, gb, zero)))]
        }
    }
}
