//! Specialisation to the scene's grids: fold what the grid fixes.
//!
//! Profiles of TaylorF2-like workloads put most of the time in pow, cbrt,
//! sin/cos and log per frequency bin. Many of those depend only on the grid
//! (`f^(-7/6)`, a PSD model), so they are computed once at compile time by
//! the reference interpreter and stored as tables the kernel reads.
//!
//! Two rewrites make more values grid-only:
//! - `(s · a)^c → s^c · a^c` when `s` is a scalar and `a` a grid-only array
//!   whose values are all positive (checked on the actual grid), so
//!   `(π Mc f)^(-5/3)` costs one scalar pow per call and a table read per bin;
//! - the same for `(a / s)^c` and `(s / a)^c`, and `cbrt(s · a) →
//!   cbrt(s) · cbrt(a)` (any signs);
//! - `log(s · a) → log s + log a` for the same s and a, also when `s · a`
//!   is itself such a split power, so TaylorF2's `log v` with
//!   `v = (π M f)^(1/3)` costs one scalar log per call and a table read.
//!
//! - in `fast` and `fastest` math, `x / a → x · (1/a)` for a grid-only
//!   array `a` (a noise PSD), so the kernel multiplies by a table of
//!   reciprocals instead of dividing; and for an array that divides two or
//!   more values (TaylorF2's `v⁵` in its phase's adjoint), one reciprocal
//!   per bin serves them all.
//!
//! - a `select` whose condition is a grid-only array that holds one truth
//!   value over the whole grid (the `psd > 0` guard of an inner product
//!   with a positive PSD) is that branch: no compare, select or table read
//!   per bin.
//!
//! Then every real grid-only array that a non-grid-only instruction (or a
//! result) uses, and that costs more than a load, becomes a table.

use crate::ir::builder::Builder;
use crate::ir::*;
use crate::kernels::interp;

fn grid_only_flags(func: &Function) -> Vec<bool> {
    let mut g = vec![false; func.insts.len()];
    for (i, inst) in func.insts.iter().enumerate() {
        g[i] = match inst.op {
            Op::Const(_) | Op::ConstComplex(..) | Op::GridCoord(_) | Op::Table(_) => true,
            Op::Param(_) | Op::Input(_) | Op::Reduce(..) => false,
            op => op.operands().iter().all(|v| g[v.index()]),
        };
    }
    g
}

/// Evaluates the grid-only instructions (`grid_only`, from
/// [`grid_only_flags`]), which depend on neither params nor inputs, handing
/// each value to `visit`; a value's real parts are kept (and returned) only
/// where `visit` returns true, the others are left empty.
fn evaluate_grid_only(func: &Function, grid_only: &[bool], visit: impl FnMut(usize, &interp::Tensor) -> bool) -> Vec<Vec<f64>> {
    let nan_params = vec![f64::NAN; func.params.len()];
    let no_inputs = vec![Vec::new(); func.inputs.len()];
    let r = interp::interpret_streaming(func, &nan_params, &no_inputs, grid_only, visit);
    r.values.into_iter().map(|t| t.into_iter().map(|z| z.re).collect()).collect()
}

/// Splits powers of products and folds grid-only arrays into tables.
/// Scenes whose grid-only values are too large to evaluate within
/// [`interp::EVAL_BUDGET`] are left as they are.
pub fn specialise(func: &Function) -> Function {
    if !within_budget(func) {
        return func.clone();
    }
    let split = rewrite_powers(func);
    tabulate(&split)
}

/// The splits of [`specialise`] alone, run before the adjoint: the adjoint
/// of `s^c · a^c` goes to the scalar `s^c` through one sum, where that of
/// `(s · a)^c` is a chain of products and quotients through every bin
/// (TaylorF2's `v^k`, `v = (π M f)^(1/3)`).
pub fn split_powers(func: &Function) -> Function {
    if !within_budget(func) {
        return func.clone();
    }
    rewrite_powers(func)
}

/// Whether the interpreter may evaluate `func`'s grid-only values.
fn within_budget(func: &Function) -> bool {
    let longest = func.grids.iter().map(|g| g.len).max().unwrap_or(1);
    let folded = grid_only_flags(func).iter().filter(|g| **g).count();
    folded.saturating_mul(longest) <= interp::EVAL_BUDGET
}

fn rewrite_powers(func: &Function) -> Function {
    let grid_only = grid_only_flags(func);
    // Evaluated only if a rewrite asks whether an array is positive: on long
    // grids (a 72 s chunk at 4096 Hz) the interpreter is most of the time
    // a scene takes to compile.
    // Per grid-only value: whether every element is positive, and for a
    // condition, the one truth value it holds everywhere, if any.
    let facts = std::cell::OnceCell::new();
    let facts = || {
        facts.get_or_init(|| {
            let mut positive = vec![false; func.insts.len()];
            let mut uniform = vec![None; func.insts.len()];
            evaluate_grid_only(func, &grid_only, |i, t| {
                positive[i] = t.iter().all(|x| x.re > 0.0);
                if func.insts[i].ty.elem == Elem::Bool {
                    let truth = |x: &num_complex::Complex64| x.re != 0.0;
                    uniform[i] = match t.first().map(truth) {
                        Some(first) if t.iter().all(|x| truth(x) == first) => Some(first),
                        _ => None,
                    };
                }
                false
            });
            (positive, uniform)
        })
    };
    let positives = || &facts().0;
    let mut header = func.clone();
    header.insts.clear();
    let mut b = Builder::new(header, true);
    let mut map: Vec<Value> = Vec::with_capacity(func.insts.len());
    // Rewritten values known as a product `s^±1 · a` (new scalar s, new
    // grid-only positive array a), so `log` of them splits too.
    let mut products: std::collections::HashMap<Value, (Value, Value, f64)> = std::collections::HashMap::new();
    let positive = |v: Value| func.ty(v).elem == Elem::Real && grid_only[v.index()] && positives()[v.index()];
    let scalar_of = |v: Value| match func.insts[v.index()].op {
        Op::Broadcast(s, _) if func.ty(s).elem == Elem::Real => Some(s),
        _ => None,
    };
    // How many real quotients each value divides, and the reciprocals made.
    let mut divisions = vec![0usize; func.insts.len()];
    for inst in &func.insts {
        if let (Op::Binary(BinOp::Div, _, y), Elem::Real) = (inst.op, inst.ty.elem) {
            divisions[y.index()] += 1;
        }
    }
    let mut reciprocals: std::collections::HashMap<Value, Value> = std::collections::HashMap::new();
    for inst in &func.insts {
        let mut rewritten = None;
        if let Op::Select(c, x, y) = inst.op {
            // A condition that holds one truth value on the whole grid.
            if grid_only[c.index()] && matches!(func.ty(c).shape, Shape::Grid(_)) {
                rewritten = facts().1[c.index()].map(|truth| map[if truth { x } else { y }.index()]);
            }
        }
        if let (Op::PowConst(base, c), Shape::Grid(g)) = (inst.op, inst.ty.shape) {
            // A power of a value already split: (s^±1 · a)^c = s^(±c) · a^c.
            if let Some(&(sp, arr, sign)) = products.get(&map[base.index()]) {
                let cf = f64::from_bits(c);
                let spc = b.emit(Op::PowConst(sp, (sign * cf).to_bits()));
                let sb = b.emit(Op::Broadcast(spc, g));
                let ac = b.emit(Op::PowConst(arr, c));
                let v = b.mul(sb, ac);
                products.insert(v, (spc, ac, 1.0));
                rewritten = Some(v);
            }
        }
        if let (Op::PowConst(base, c), None) = (inst.op, rewritten) {
            if let Op::Binary(op @ (BinOp::Mul | BinOp::Div), x, y) = func.insts[base.index()].op {
                // (s·a)^c, (a·s)^c, (a/s)^c, (s/a)^c with a grid-only and positive.
                let pick = match (scalar_of(x), scalar_of(y)) {
                    (Some(s), None) if positive(y) => Some((s, y, true)),
                    (None, Some(s)) if positive(x) => Some((s, x, false)),
                    _ => None,
                };
                if let Some((s, a, scalar_first)) = pick {
                    let Shape::Grid(g) = inst.ty.shape else { unreachable!("a broadcast operand means an array") };
                    let cf = f64::from_bits(c);
                    let sp = b.emit(Op::PowConst(map[s.index()], c));
                    let sb = b.emit(Op::Broadcast(sp, g));
                    let ap = b.emit(Op::PowConst(map[a.index()], c));
                    let (v, arr, sign) = match (op, scalar_first) {
                        (BinOp::Mul, _) => (b.mul(sb, ap), ap, 1.0),
                        (_, false) => (b.div(ap, sb), ap, -1.0), // (a/s)^c = a^c / s^c
                        (_, true) => {
                            // (s/a)^c = s^c · a^(-c)
                            let an = b.emit(Op::PowConst(map[a.index()], (-cf).to_bits()));
                            (b.mul(sb, an), an, 1.0)
                        }
                    };
                    products.insert(v, (sp, arr, sign));
                    rewritten = Some(v);
                }
            }
        }
        if let (Op::Unary(UnOp::Cbrt, base), Shape::Grid(g)) = (inst.op, inst.ty.shape) {
            // cbrt(s · a) = cbrt(s) · cbrt(a) for any signs (cbrt is odd and multiplicative).
            if let Op::Binary(BinOp::Mul, x, y) = func.insts[base.index()].op {
                let pick = match (scalar_of(x), scalar_of(y)) {
                    (Some(s), None) if grid_only[y.index()] => Some((s, y)),
                    (None, Some(s)) if grid_only[x.index()] => Some((s, x)),
                    _ => None,
                };
                if let Some((s, a)) = pick {
                    let cs = b.unary(UnOp::Cbrt, map[s.index()]);
                    let csb = b.emit(Op::Broadcast(cs, g));
                    let ca = b.unary(UnOp::Cbrt, map[a.index()]);
                    let v = b.mul(csb, ca);
                    if positive(a) {
                        products.insert(v, (cs, ca, 1.0));
                    }
                    rewritten = Some(v);
                }
            }
        }
        if let (Op::Binary(BinOp::Div, x, y), MathMode::Fast | MathMode::Fastest) = (inst.op, func.math) {
            // x / a = x · (1/a) for a grid-only real array a: a table of
            // reciprocals and a multiplication per bin instead of a
            // division (up to 1 ulp more error, so not in `exact`).
            // Likewise for an array that divides two or more values: one
            // division per bin instead of one per quotient.
            let array = match func.ty(y).shape {
                Shape::Grid(g) if grid_only[y.index()] && !grid_only[x.index()] && scalar_of(y).is_none() => Some(g),
                Shape::Grid(g) if !grid_only[y.index()] && divisions[y.index()] >= 2 => Some(g),
                _ => None,
            };
            if let (Some(g), Elem::Real, Elem::Real) = (array, func.ty(y).elem, inst.ty.elem) {
                let reciprocal = *reciprocals.entry(y).or_insert_with(|| {
                    let one = b.constant(num_complex::Complex64::new(1.0, 0.0), Ty::REAL);
                    let ones = b.emit(Op::Broadcast(one, g));
                    b.div(ones, map[y.index()])
                });
                rewritten = Some(b.mul(map[x.index()], reciprocal));
            }
        }
        if let (Op::Unary(UnOp::Log, base), Shape::Grid(g)) = (inst.op, inst.ty.shape) {
            // log(s^±1 · a) = ±log s + log a: a scalar log per call and a table.
            let known = products.get(&map[base.index()]).copied().or_else(|| match func.insts[base.index()].op {
                Op::Binary(BinOp::Mul, x, y) => match (scalar_of(x), scalar_of(y)) {
                    (Some(s), None) if positive(y) => Some((map[s.index()], map[y.index()], 1.0)),
                    (None, Some(s)) if positive(x) => Some((map[s.index()], map[x.index()], 1.0)),
                    _ => None,
                },
                _ => None,
            });
            if let Some((sp, arr, sign)) = known {
                let ls = b.unary(UnOp::Log, sp);
                let lsb = b.emit(Op::Broadcast(ls, g));
                let la = b.unary(UnOp::Log, arr);
                rewritten = Some(if sign > 0.0 { b.add(lsb, la) } else { b.sub(la, lsb) });
            }
        }
        let v = match rewritten {
            Some(v) => v,
            None => {
                let op = inst.op.map_operands(|v| map[v.index()]);
                b.emit(op)
            }
        };
        map.push(v);
    }
    let mut out = b.func;
    out.remap_roots(|v| map[v.index()]);
    super::prune(&out)
}

fn tabulate(func: &Function) -> Function {
    let grid_only = grid_only_flags(func);
    let mut frontier = vec![false; func.insts.len()];
    for (i, inst) in func.insts.iter().enumerate() {
        if !grid_only[i] {
            for v in inst.op.operands() {
                frontier[v.index()] = true;
            }
        }
    }
    for r in func.roots() {
        frontier[r.index()] = true;
    }
    // Tables are real: a complex grid-only frontier value is rebuilt per bin
    // from its (tabulated) real operands.
    for i in (0..func.insts.len()).rev() {
        if frontier[i] && grid_only[i] && func.insts[i].ty.elem != Elem::Real {
            for v in func.insts[i].op.operands() {
                frontier[v.index()] = true;
            }
        }
    }
    let cheap = |inst: &Inst| matches!(inst.op, Op::Const(_) | Op::ConstComplex(..) | Op::GridCoord(_) | Op::Table(_) | Op::Broadcast(..));
    let tabulated: Vec<Option<GridId>> = func
        .insts
        .iter()
        .enumerate()
        .map(|(i, inst)| match (frontier[i] && grid_only[i] && !cheap(inst), inst.ty.shape, inst.ty.elem) {
            (true, Shape::Grid(g), Elem::Real) => Some(g),
            _ => None,
        })
        .collect();
    let mut values = evaluate_grid_only(func, &grid_only, |i, _| tabulated[i].is_some());
    let mut out = func.clone();
    for (i, grid) in tabulated.iter().enumerate() {
        if let Some(g) = grid {
            // Equal arrays (a PSD reached by two paths) share one table.
            let data = std::mem::take(&mut values[i]);
            let same = out.tables.iter().position(|t| t.grid == *g && t.data == data);
            let index = same.unwrap_or_else(|| {
                out.tables.push(Table { grid: *g, data });
                out.tables.len() - 1
            });
            out.insts[i].op = Op::Table(index as u32);
        }
    }
    let pruned = super::prune(&out);
    drop_unused_tables(pruned)
}

fn drop_unused_tables(mut func: Function) -> Function {
    let mut used: Vec<u32> = func.insts.iter().filter_map(|i| if let Op::Table(t) = i.op { Some(t) } else { None }).collect();
    used.sort_unstable();
    used.dedup();
    let tables = std::mem::take(&mut func.tables);
    func.tables = used.iter().map(|t| tables[*t as usize].clone()).collect();
    for inst in &mut func.insts {
        if let Op::Table(t) = inst.op {
            inst.op = Op::Table(used.iter().position(|u| *u == t).expect("used") as u32);
        }
    }
    func
}
