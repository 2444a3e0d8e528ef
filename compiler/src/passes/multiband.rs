//! Multibanding (the scene's `multiband: TOLERANCE` setting): each
//! `cis(φ)` over a grid whose phase `φ` the grid's coordinates and scalars
//! determine (TaylorF2's `Ψ(f)`) becomes `band_cis(φ_c)`, with `φ_c` the
//! same computation on a coarse subset of the grid's points (a
//! [`Banding`]). The kernel then evaluates the phase, with its powers and
//! logarithms, only at the nodes, and fills the points between them by
//! rotation (see [`crate::kernels::band`]). The rewrite runs before the
//! adjoint, so gradients are those of the approximation itself.
//!
//! The nodes are chosen here, at compile time, from the phase at the
//! scene's defaults (params at their defaults, inputs at theirs): a band
//! `a..b` is accepted while `(b − a)²/8 · max |Δ²φ|` over it is at most
//! the tolerance, which bounds the error of linear interpolation of a
//! sequence with second differences `Δ²φ` (the discrete form of the
//! `h²/8 · max|φ''|` bound). Bands never exceed [`MAX_BAND`] points. A
//! phase that is not finite everywhere at the defaults, or that depends on
//! an input array, or that the grid alone fixes (folded into a table by
//! `specialise` anyway), or whose `cis` only multiplies an amplitude cut
//! at an interval condition (the ISCO: code generation already computes it
//! below the cut only), is left exact.
//!
//! Vinciguerra, Veitch & Mandel 2017 (arXiv:1703.02062) choose TaylorF2's
//! bands from the time to merger; García-Quirós et al. 2020
//! (arXiv:2001.10897, IMRPhenomXHM) interpolate the phase linearly and
//! advance `e^{iφ}` by rotation, as here.

use super::precision::defaults;
use super::prune;
use crate::ir::builder::Builder;
use crate::ir::*;
use crate::kernels::interp;
use std::collections::HashMap;

/// Longest band, in fine points (the rotation restarts exactly every
/// [`crate::kernels::band::RESYNC`] points within it anyway).
pub const MAX_BAND: usize = 4096;

/// Applies the scene's multibanding setting (nothing when it is off).
pub fn multiband(func: &Function) -> Function {
    let Multiband::Tolerance(tolerance) = func.multiband else { return func.clone() };
    let mut cone = Cone::new(func);
    // Phases fixed by the grid alone are folded into tables by
    // `specialise`, exactly: only those that vary from call to call are banded.
    let mut varies = vec![false; func.insts.len()];
    for (i, inst) in func.insts.iter().enumerate() {
        varies[i] = matches!(inst.op, Op::Param(_) | Op::Input(_)) || inst.op.operands().iter().any(|a| varies[a.index()]);
    }
    let cut = masked_products(func);
    let candidates: Vec<(usize, Value, GridId)> = func
        .insts
        .iter()
        .enumerate()
        .filter_map(|(i, inst)| match inst.op {
            Op::Unary(UnOp::Cis, x) => match func.ty(x).shape {
                Shape::Grid(g) if varies[x.index()] && !cut[i] && cone.clonable(x, g) => Some((i, x, g)),
                _ => None,
            },
            _ => None,
        })
        .collect();
    if candidates.is_empty() {
        return func.clone();
    }
    let longest = func.grids.iter().map(|g| g.len).max().unwrap_or(1);
    if func.insts.len().saturating_mul(longest) > interp::EVAL_BUDGET {
        return func.clone();
    }
    // The phases at the defaults.
    let mut wanted = vec![false; func.insts.len()];
    let mut stack: Vec<usize> = candidates.iter().map(|c| c.1.index()).collect();
    while let Some(i) = stack.pop() {
        if !std::mem::replace(&mut wanted[i], true) {
            stack.extend(func.insts[i].op.operands().iter().map(|v| v.index()));
        }
    }
    let (params, inputs) = defaults(func);
    let values = interp::interpret_only(func, &params, &inputs, &wanted).values;

    let mut header = func.clone();
    header.insts.clear();
    let mut b = Builder::new(header, true);
    // Per candidate `cis` instruction: its banding.
    let mut banding_of: HashMap<usize, u32> = HashMap::new();
    for &(i, x, g) in &candidates {
        let phase: Vec<f64> = values[x.index()].iter().map(|z| z.re).collect();
        if phase.len() < 3 || phase.iter().any(|p| !p.is_finite()) {
            continue;
        }
        let (nodes, error) = choose_nodes(&phase, tolerance);
        let existing = b.func.bands.iter().position(|band| band.fine == g && band.nodes == nodes);
        let n = existing.unwrap_or_else(|| {
            let fine = b.func.grid(g).clone();
            b.func.grids.push(Grid::index(format!("{}_bands", fine.name), nodes.len()));
            let coarse = GridId(b.func.grids.len() as u32 - 1);
            b.func.bands.push(Banding { fine: g, coarse, nodes, error, purpose: BandPurpose::Multiband });
            b.func.bands.len() - 1
        });
        banding_of.insert(i, n as u32);
    }
    let mut map: Vec<Value> = Vec::with_capacity(func.insts.len());
    let mut coarse: HashMap<(usize, u32), Value> = HashMap::new();
    for (i, inst) in func.insts.iter().enumerate() {
        let v = match (inst.op, banding_of.get(&i)) {
            (Op::Unary(UnOp::Cis, x), Some(&n)) => {
                let band = b.func.bands[n as usize].clone();
                let xc = clone_onto(func, &mut b, &map, &mut coarse, x, (n, &band));
                b.emit(Op::Band(BandOp::Cis, n, xc))
            }
            (op, _) => b.emit(op.map_operands(|v| map[v.index()])),
        };
        map.push(v);
    }
    let mut out = b.func;
    out.remap_roots(|v| map[v.index()]);
    prune(&out)
}

/// Per instruction, whether the value is only used under a mask on an
/// interval condition (`select(f <= f_isco, ·, 0)`, a waveform cut at the
/// ISCO): through products and sign changes into such a select, or
/// multiplied by a value masked so. Code generation computes it only
/// where the mask holds, which a band call over the whole grid would undo.
fn masked_products(func: &Function) -> Vec<bool> {
    let masks = |c: Value, a: Value, b: Value| func.interval_condition(c).is_some() && (func.is_zero(a) || func.is_zero(b));
    let masked = |mut v: Value| loop {
        match func.insts[v.index()].op {
            Op::Unary(UnOp::ToComplex | UnOp::Neg | UnOp::Conj, a) => v = a,
            Op::Select(c, a, b) => return masks(c, a, b),
            _ => return false,
        }
    };
    let mut users: Vec<Vec<usize>> = vec![Vec::new(); func.insts.len()];
    for (u, inst) in func.insts.iter().enumerate() {
        for a in inst.op.operands() {
            users[a.index()].push(u);
        }
    }
    let roots: std::collections::HashSet<usize> = func.roots().iter().map(|r| r.index()).collect();
    let mut under = vec![false; func.insts.len()];
    for i in (0..func.insts.len()).rev() {
        let v = Value(i as u32);
        under[i] = !users[i].is_empty()
            && !roots.contains(&i)
            && users[i].iter().all(|&u| match func.insts[u].op {
                Op::Select(c, a, b) => a != b && (a == v || b == v) && masks(c, a, b),
                Op::Binary(BinOp::Mul, x, y) => under[u] || (x == v && masked(y)) || (y == v && masked(x)),
                Op::Unary(UnOp::ToComplex | UnOp::Neg | UnOp::Conj, _) => under[u],
                _ => false,
            });
    }
    under
}

/// Which grid arrays can be recomputed on a coarse subset of their grid:
/// elementwise arithmetic on the grid's coordinates, tables and broadcast
/// scalars (no input arrays, transforms or tensor ops).
pub(super) struct Cone<'a> {
    func: &'a Function,
    memo: HashMap<usize, bool>,
}

impl<'a> Cone<'a> {
    /// No value examined yet.
    pub(super) fn new(func: &'a Function) -> Cone<'a> {
        Cone { func, memo: HashMap::new() }
    }

    /// Whether grid array `v` (on `g`) can be recomputed on a coarse grid.
    pub(super) fn clonable(&mut self, v: Value, g: GridId) -> bool {
        let inst = self.func.insts[v.index()];
        if inst.ty.shape == Shape::Scalar {
            return true;
        }
        if inst.ty.shape != Shape::Grid(g) {
            return false;
        }
        if let Some(&known) = self.memo.get(&v.index()) {
            return known;
        }
        let ok = match inst.op {
            Op::GridCoord(_) | Op::Table(_) | Op::Broadcast(..) | Op::Const(_) | Op::ConstComplex(..) => true,
            Op::Unary(..) | Op::Binary(..) | Op::PowConst(..) | Op::Select(..) => inst.op.operands().iter().all(|&a| self.clonable(a, g)),
            _ => false,
        };
        self.memo.insert(v.index(), ok);
        ok
    }
}

/// The value of fine array `x` recomputed on the coarse grid of banding
/// `n` (scalars are shared with the fine computation).
pub(super) fn clone_onto(
    func: &Function,
    b: &mut Builder,
    map: &[Value],
    coarse: &mut HashMap<(usize, u32), Value>,
    x: Value,
    (n, band): (u32, &Banding),
) -> Value {
    if func.ty(x).shape == Shape::Scalar {
        return map[x.index()];
    }
    if let Some(&v) = coarse.get(&(x.index(), n)) {
        return v;
    }
    let at_nodes = |data: &dyn Fn(usize) -> f64| band.nodes.iter().map(|&k| data(k as usize)).collect::<Vec<f64>>();
    let v = match func.insts[x.index()].op {
        Op::GridCoord(g) => {
            let grid = func.grid(g).clone();
            let data = at_nodes(&|k| grid.start + k as f64 * grid.step);
            b.func.tables.push(Table { grid: band.coarse, data });
            b.emit(Op::Table(b.func.tables.len() as u32 - 1))
        }
        Op::Table(t) => {
            let fine = func.tables[t as usize].data.clone();
            let data = at_nodes(&|k| fine[k]);
            b.func.tables.push(Table { grid: band.coarse, data });
            b.emit(Op::Table(b.func.tables.len() as u32 - 1))
        }
        Op::Broadcast(s, _) => b.emit(Op::Broadcast(map[s.index()], band.coarse)),
        op => {
            let operands: Vec<(Value, Value)> =
                op.operands().into_iter().map(|a| (a, clone_onto(func, b, map, coarse, a, (n, band)))).collect();
            let mapped = op.map_operands(|a| operands.iter().find(|(o, _)| *o == a).expect("an operand").1);
            b.emit(mapped)
        }
    };
    coarse.insert((x.index(), n), v);
    v
}

/// Nodes for phase samples `phase` (see the module doc) and the largest
/// error of linear interpolation between them, in radians.
pub fn choose_nodes(phase: &[f64], tolerance: f64) -> (Vec<u32>, f64) {
    let n = phase.len();
    let second = |k: usize| (phase[k - 1] - 2.0 * phase[k] + phase[k + 1]).abs();
    let mut nodes = vec![0u32];
    let mut a = 0usize;
    while a < n - 1 {
        let mut b = a + 1;
        let mut curvature: f64 = 0.0;
        while b < n - 1 && b + 1 - a <= MAX_BAND {
            // Extending to b + 1 adds the second difference at b.
            let c = curvature.max(second(b));
            let len = (b + 1 - a) as f64;
            if len * len / 8.0 * c > tolerance {
                break;
            }
            curvature = c;
            b += 1;
        }
        nodes.push(b as u32);
        a = b;
    }
    let mut error: f64 = 0.0;
    for w in nodes.windows(2) {
        let (a, b) = (w[0] as usize, w[1] as usize);
        for k in a + 1..b {
            let t = (k - a) as f64 / (b - a) as f64;
            error = error.max(((1.0 - t) * phase[a] + t * phase[b] - phase[k]).abs());
        }
    }
    (nodes, error)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nodes_keep_the_interpolation_within_the_tolerance() {
        // A phase with W1's curvature (Mc = 28 Msun) over 20..1024 Hz at
        // 1/8 Hz: f^(-5/3), second differences ~0.01 rad per bin² at 20 Hz.
        let phase: Vec<f64> = (0..8033).map(|k| 60.0 * ((20.0 + 0.125 * k as f64) / 20.0f64).powf(-5.0 / 3.0)).collect();
        for tolerance in [1e-2, 1e-4, 1e-6] {
            let (nodes, error) = choose_nodes(&phase, tolerance);
            assert!(error <= tolerance, "{tolerance:e}: error {error:e}");
            assert_eq!((nodes[0], *nodes.last().unwrap()), (0, 8032));
            assert!(nodes.windows(2).all(|w| w[0] < w[1] && (w[1] - w[0]) as usize <= MAX_BAND));
            // Fewer nodes than points (about tolerance^(-1/2) of them).
            let most = if tolerance >= 1e-4 { 8033 / 4 } else { 8033 / 2 };
            assert!(nodes.len() < most, "{tolerance:e}: {} nodes", nodes.len());
        }
        assert!(choose_nodes(&phase, 1e-6).0.len() > choose_nodes(&phase, 1e-4).0.len());
        // A linear phase is interpolated exactly: the longest bands allowed.
        let (nodes, error) = choose_nodes(&(0..10000).map(|k| 0.5 * k as f64).collect::<Vec<_>>(), 1e-9);
        assert!(error == 0.0 && nodes.len() == 9999usize.div_ceil(MAX_BAND) + 1, "{nodes:?}");
    }
}
