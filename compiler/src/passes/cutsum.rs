//! Sums split at a cut: a likelihood of a waveform cut at the ISCO,
//! `Σ_k x_k` where the waveform inside `x` is masked by selects on
//! `c = (f ≤ f_isco)`, sums the data's own term `|d_k|² / S_k` over every
//! bin above the cut on every call, though the cut only decides where.
//! With `x°` the operand with every select on `c` resolved to its branch
//! for `c` false (what `x` is above the cut), this pass writes the sum as
//!
//! ```text
//! Σ_k select(c_k, x_k − x°_k, 0)  +  Σ_k x°_k
//! ```
//!
//! which is the same sum: where `c` holds the two terms add up to `x`,
//! elsewhere `x = x°`. The first sum is zero above the cut, where code
//! generation's loop split skips it; the second depends on the data alone
//! (it applies only when `x°` does not depend on the params), so staging
//! (`passes::stage`) computes it once per bound input. `c` is an interval
//! condition ([`Function::interval_condition`]) on the sum's grid that
//! moves with the params. The result equals the original up to rounding
//! (below the cut, `x − x°` is summed instead of `x`).

use super::prune;
use super::relbin::param_dependent;
use crate::ir::builder::Builder;
use crate::ir::*;
use std::collections::HashMap;

/// Splits every such sum of `func` (see the module doc).
pub fn cutsum(func: &Function) -> Function {
    let varies = param_dependent(func);
    let found: HashMap<usize, Value> = func
        .insts
        .iter()
        .enumerate()
        .filter_map(|(i, inst)| match inst.op {
            Op::Reduce(Reduce::Sum, x) if varies[x.index()] => cut_of_sum(func, &varies, x).map(|c| (i, c)),
            _ => None,
        })
        .collect();
    if found.is_empty() {
        return func.clone();
    }
    let mut header = func.clone();
    header.insts.clear();
    let mut b = Builder::new(header, true);
    let mut map: Vec<Value> = Vec::with_capacity(func.insts.len());
    for (i, inst) in func.insts.iter().enumerate() {
        let v = match (inst.op, found.get(&i)) {
            (Op::Reduce(Reduce::Sum, x), Some(&c)) => {
                split(func, &mut b, &map, x, c).unwrap_or_else(|| b.emit(inst.op.map_operands(|v| map[v.index()])))
            }
            (op, _) => b.emit(op.map_operands(|v| map[v.index()])),
        };
        map.push(v);
    }
    let mut out = b.func;
    out.remap_roots(|v| map[v.index()]);
    prune(&out)
}

/// The cut of sum operand `x`: an interval condition on `x`'s grid that
/// varies with the params and that a select in `x`'s cone tests, such that
/// `x` with those selects resolved to their `false` branch is param-free.
fn cut_of_sum(func: &Function, varies: &[bool], x: Value) -> Option<Value> {
    let Shape::Grid(grid) = func.ty(x).shape else { return None };
    let mut stack = vec![x.index()];
    let mut seen = std::collections::HashSet::new();
    while let Some(i) = stack.pop() {
        if !varies[i] || !seen.insert(i) || seen.len() > 10_000 {
            continue;
        }
        if let Op::Select(c, ..) = func.insts[i].op {
            let cut = func.interval_condition(c).is_some_and(|(g, _)| g == grid) && varies[c.index()];
            if cut {
                return (!varies_beyond(func, x, c)).then_some(c);
            }
        }
        stack.extend(func.insts[i].op.operands().iter().map(|v| v.index()));
    }
    None
}

/// Whether `x`, with every select on `c` resolved to its `false` branch,
/// depends on the params. A value that is zero there (the masked
/// waveform, and products with it) does not, whatever its other factors.
fn varies_beyond(func: &Function, x: Value, c: Value) -> bool {
    let n = x.index() + 1;
    let (mut varies, mut zero) = (vec![false; n], vec![false; n]);
    for (i, inst) in func.insts.iter().enumerate().take(n) {
        let (v, z) = match inst.op {
            Op::Select(k, _, otherwise) if k == c => (varies[otherwise.index()], zero[otherwise.index()]),
            Op::Param(_) => (true, false),
            Op::Const(b) => (false, f64::from_bits(b) == 0.0),
            Op::ConstComplex(r, m) => (false, f64::from_bits(r) == 0.0 && f64::from_bits(m) == 0.0),
            Op::Binary(BinOp::Mul, a, b) if zero[a.index()] || zero[b.index()] => (false, true),
            Op::Unary(UnOp::Neg | UnOp::Conj | UnOp::Re | UnOp::Im | UnOp::ToComplex, a) | Op::Broadcast(a, _) if zero[a.index()] => {
                (false, true)
            }
            op => (op.operands().iter().any(|a| varies[a.index()]), false),
        };
        varies[i] = v;
        zero[i] = z;
    }
    varies[x.index()]
}

/// The split sum of `x` at cut `c`, or `None` when `x` is zero beyond
/// the cut already.
fn split(func: &Function, b: &mut Builder, map: &[Value], x: Value, c: Value) -> Option<Value> {
    let beyond = resolve(func, b, map, x, c, &mut HashMap::new());
    if b.func.is_zero(beyond) {
        return None;
    }
    let diff = b.binary(BinOp::Sub, map[x.index()], beyond);
    let zero = b.zero(func.ty(x));
    let masked = b.emit(Op::Select(map[c.index()], diff, zero));
    let per_call = b.emit(Op::Reduce(Reduce::Sum, masked));
    let data_term = b.emit(Op::Reduce(Reduce::Sum, beyond));
    Some(b.add(per_call, data_term))
}

/// `v` with every select on `c` resolved to its `false` branch.
fn resolve(func: &Function, b: &mut Builder, map: &[Value], v: Value, c: Value, memo: &mut HashMap<usize, Value>) -> Value {
    if let Some(&done) = memo.get(&v.index()) {
        return done;
    }
    let out = match func.insts[v.index()].op {
        Op::Select(k, _, otherwise) if k == c => resolve(func, b, map, otherwise, c, memo),
        op if op.operands().is_empty() => map[v.index()],
        op => {
            let operands: Vec<(Value, Value)> = op.operands().into_iter().map(|o| (o, resolve(func, b, map, o, c, memo))).collect();
            // The masked waveform is zero here: so are its negation,
            // parts, broadcasts and products, whatever the other factor.
            let is_zero = |b: &Builder, v: Value| b.func.is_zero(v);
            let zero_preserving = matches!(
                op,
                Op::Binary(BinOp::Mul, ..)
                    | Op::Unary(UnOp::Neg | UnOp::Conj | UnOp::Re | UnOp::Im | UnOp::ToComplex, _)
                    | Op::Broadcast(..)
            );
            if zero_preserving && operands.iter().any(|&(_, r)| is_zero(b, r)) {
                b.zero(func.ty(v))
            } else {
                b.emit(op.map_operands(|o| operands.iter().find(|(k, _)| *k == o).expect("an operand").1))
            }
        }
    };
    memo.insert(v.index(), out);
    out
}
