//! The ops of [`BandOp`]: linear interpolation from the nodes of a
//! [`Banding`](crate::ir::Banding) onto every point of its fine grid, its
//! transpose, and `e^{i L(x)}` by rotation (multibanding; see
//! `passes::multiband`). [`apply`] is the definition the interpreter
//! uses (`Cis` through one exact `e^{iφ}` per point); the `extern "C"`
//! symbols generated kernels call compute `Cis` by rotation: an exact
//! `e^{iφ}` at each node and every [`RESYNC`] points, and one complex
//! multiply per point in between, on four interleaved chains (so the
//! multiplies do not wait on each other).

use crate::ir::{BandOp, BandSide};
use num_complex::Complex64 as C64;

/// Most fine points advanced by rotation before an exact restart. The
/// rounding of the rotation grows by about one ulp per multiply: with
/// restarts every 512 points it stays below 1e-13 rad in f64 (this
/// module's tests), far below any tolerance the setting accepts; against
/// an exact `e^{iφ}` of a large phase the phase's own rounding dominates
/// (an ulp of 3e4 rad is 4e-12 rad).
pub const RESYNC: usize = 512;

/// What a band call needs: the op and the nodes (fine indices).
#[derive(Clone, Debug, PartialEq)]
pub struct BandPlan {
    /// The operation.
    pub op: BandOp,
    /// Fine indices of the nodes: increasing, from 0 to the last fine point.
    pub nodes: Vec<u32>,
}

impl BandPlan {
    /// Points of the fine grid.
    pub fn fine_len(&self) -> usize {
        self.nodes.last().map_or(0, |&l| l as usize + 1)
    }

    fn len_on(&self, side: BandSide) -> usize {
        match side {
            BandSide::Fine => self.fine_len(),
            BandSide::Coarse => self.nodes.len(),
        }
    }

    /// Floats read: the operand's element count.
    pub fn operand_len(&self) -> usize {
        self.len_on(self.op.sides().0)
    }

    /// Floats written (a complex element counts two).
    pub fn out_floats(&self) -> usize {
        let n = self.len_on(self.op.sides().1);
        if self.op == BandOp::Cis {
            2 * n
        } else {
            n
        }
    }
}

/// Calls `each(k, j, t)` for every fine point `k` in node `j`'s band
/// (`nodes[j] ≤ k < nodes[j+1]`, and the last point with the last node),
/// `t` its interpolation weight toward node `j + 1`.
fn for_each_point(nodes: &[u32], mut each: impl FnMut(usize, usize, f64)) {
    for (j, w) in nodes.windows(2).enumerate() {
        let (a, b) = (w[0] as usize, w[1] as usize);
        let m = (b - a) as f64;
        for k in a..b {
            each(k, j, (k - a) as f64 / m);
        }
    }
    if let Some(&last) = nodes.last() {
        each(last as usize, nodes.len() - 1, 0.0);
    }
}

/// The op by its definition, in f64 (the interpreter's semantics): the
/// linear ops as kernels run them, `Cis` as an exact `e^{iφ}` of each
/// interpolated phase (the oracle for the rotation).
pub fn apply(op: BandOp, nodes: &[u32], x: &[C64]) -> Vec<C64> {
    let re: Vec<f64> = x.iter().map(|z| z.re).collect();
    let linear = if op == BandOp::Cis { BandOp::Interp } else { op };
    let plan = BandPlan { op: linear, nodes: nodes.to_vec() };
    let mut out = vec![0.0; plan.out_floats()];
    run(linear, nodes, &re, &mut out);
    out.into_iter().map(|v| if op == BandOp::Cis { C64::from_polar(1.0, v) } else { C64::new(v, 0.0) }).collect()
}

/// An element type of kernel buffers.
trait Elt: Copy {
    fn get(self) -> f64;
    fn put(x: f64) -> Self;
}

impl Elt for f64 {
    fn get(self) -> f64 {
        self
    }
    fn put(x: f64) -> f64 {
        x
    }
}

impl Elt for f32 {
    fn get(self) -> f64 {
        self as f64
    }
    fn put(x: f64) -> f32 {
        x as f32
    }
}

fn cis(phase: f64) -> C64 {
    let (s, c) = phase.sin_cos();
    C64::new(c, s)
}

/// `out[2k], out[2k+1] = e^{i(phase + (k − from)·step)}` for `from ≤ k < to`,
/// by rotation on four interleaved chains.
fn rotate<O: Elt>(phase: f64, step: f64, from: usize, to: usize, out: &mut [O]) {
    let w = cis(step);
    let mut z = [cis(phase), C64::new(0.0, 0.0), C64::new(0.0, 0.0), C64::new(0.0, 0.0)];
    for r in 1..4 {
        z[r] = z[r - 1] * w;
    }
    let w2 = w * w;
    let w4 = w2 * w2;
    // Four points (eight values) per step, over one slice: no bounds check
    // per store.
    let mut steps = out[2 * from..2 * to].chunks_exact_mut(8);
    for values in &mut steps {
        for (pair, zr) in values.chunks_exact_mut(2).zip(z.iter_mut()) {
            pair[0] = O::put(zr.re);
            pair[1] = O::put(zr.im);
            *zr *= w4;
        }
    }
    for (pair, zr) in steps.into_remainder().chunks_exact_mut(2).zip(&z) {
        pair[0] = O::put(zr.re);
        pair[1] = O::put(zr.im);
    }
}

/// The op as generated kernels run it (`Cis` by rotation).
fn run<I: Elt, O: Elt>(op: BandOp, nodes: &[u32], x: &[I], out: &mut [O]) {
    match op {
        BandOp::Cis => {
            for (j, w) in nodes.windows(2).enumerate() {
                let (a, b) = (w[0] as usize, w[1] as usize);
                let (x0, x1) = (x[j].get(), x[j + 1].get());
                let step = (x1 - x0) / (b - a) as f64;
                let mut k = a;
                while k < b {
                    let end = (k + RESYNC).min(b);
                    let t = (k - a) as f64 / (b - a) as f64;
                    let phase = if k == a { x0 } else { (1.0 - t) * x0 + t * x1 };
                    rotate(phase, step, k, end, out);
                    k = end;
                }
            }
            if let Some(&last) = nodes.last() {
                let z = cis(x[nodes.len() - 1].get());
                out[2 * last as usize] = O::put(z.re);
                out[2 * last as usize + 1] = O::put(z.im);
            }
        }
        BandOp::Interp => for_each_point(nodes, |k, j, t| {
            let v = if t == 0.0 { x[j].get() } else { (1.0 - t) * x[j].get() + t * x[j + 1].get() };
            out[k] = O::put(v);
        }),
        BandOp::InterpT => {
            let mut acc = vec![0.0f64; nodes.len()];
            for_each_point(nodes, |k, j, t| {
                let y = x[k].get();
                acc[j] += (1.0 - t) * y;
                if t != 0.0 {
                    acc[j + 1] += t * y;
                }
            });
            for (o, a) in out.iter_mut().zip(acc) {
                *o = O::put(a);
            }
        }
        BandOp::BinSum => {
            let mut acc = vec![0.0f64; nodes.len()];
            for_each_point(nodes, |k, j, _| acc[j] += x[k].get());
            for (o, a) in out.iter_mut().zip(acc) {
                *o = O::put(a);
            }
        }
        BandOp::BinSpread => for_each_point(nodes, |k, j, _| out[k] = O::put(x[j].get())),
        BandOp::Next => {
            for (j, o) in out.iter_mut().enumerate() {
                *o = O::put(x.get(j + 1).map_or(0.0, |v| v.get()));
            }
        }
        BandOp::Prev => {
            for (j, o) in out.iter_mut().enumerate() {
                *o = O::put(if j == 0 { 0.0 } else { x[j - 1].get() });
            }
        }
    }
}

macro_rules! band_entry {
    ($name:ident, $i:ty, $o:ty) => {
        /// Runs the band op of `plan` from `x` into `out`, elements of the
        /// named precisions.
        ///
        /// # Safety
        /// `plan` points at a live [`BandPlan`]; `x` holds
        /// [`BandPlan::operand_len`] elements and `out`
        /// [`BandPlan::out_floats`], writable.
        #[no_mangle]
        pub unsafe extern "C" fn $name(plan: *const BandPlan, x: *const $i, out: *mut $o) {
            // SAFETY: guaranteed by the caller (the code generator sizes every buffer from the plan).
            unsafe {
                let plan = &*plan;
                let x = std::slice::from_raw_parts(x, plan.operand_len());
                let out = std::slice::from_raw_parts_mut(out, plan.out_floats());
                run(plan.op, &plan.nodes, x, out);
            }
        }
    };
}

band_entry!(gwml_band_f64, f64, f64);
band_entry!(gwml_band_f32, f32, f32);
band_entry!(gwml_band_f64_f32, f64, f32);
band_entry!(gwml_band_f32_f64, f32, f64);

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(op: BandOp, nodes: &[u32]) -> BandPlan {
        BandPlan { op, nodes: nodes.to_vec() }
    }

    /// A phase like TaylorF2's: steep at the start, large in magnitude.
    fn chirp_phase(k: usize) -> f64 {
        let f = 20.0 + 0.125 * k as f64;
        3.0e4 * (f / 20.0).powf(-5.0 / 3.0) + 2.0 * std::f64::consts::PI * f * 0.01
    }

    #[test]
    fn rotation_stays_on_the_exact_interpolated_phase() {
        // Long bands (up to 2,000 points, four restarts).
        let nodes: Vec<u32> = vec![0, 3, 4, 100, 613, 2613, 4000];
        let p = plan(BandOp::Cis, &nodes);
        let worst_f64 = |scale: f64| {
            let x: Vec<f64> = nodes.iter().map(|&i| scale * chirp_phase(i as usize)).collect();
            let exact = apply(p.op, &nodes, &x.iter().map(|&v| C64::new(v, 0.0)).collect::<Vec<_>>());
            let mut out64 = vec![0.0f64; p.out_floats()];
            run(p.op, &nodes, &x, &mut out64);
            (0..p.fine_len()).map(|k| (C64::new(out64[2 * k], out64[2 * k + 1]) / exact[k]).arg().abs()).fold(0.0, f64::max)
        };
        // The rotation's own drift (phases of order 1 rad)...
        let drift = worst_f64(1e-4);
        assert!(drift < 1e-13, "f64 rotation drifts by {drift:e} rad");
        // ...and on a phase of 3e4 rad, within a few ulps of the phase.
        let worst = worst_f64(1.0);
        assert!(worst < 2e-11, "f64 rotation is off by {worst:e} rad");
        let x: Vec<f64> = nodes.iter().map(|&i| chirp_phase(i as usize)).collect();
        let exact = apply(p.op, &nodes, &x.iter().map(|&v| C64::new(v, 0.0)).collect::<Vec<_>>());
        // In f32 the rounding of the stored result dominates (one f32 ulp).
        let mut out32 = vec![0.0f32; p.out_floats()];
        run(p.op, &nodes, &x, &mut out32);
        let worst32 =
            (0..p.fine_len()).map(|k| (C64::new(out32[2 * k] as f64, out32[2 * k + 1] as f64) / exact[k]).arg().abs()).fold(0.0, f64::max);
        assert!(worst32 < 2e-7, "f32 output is off by {worst32:e} rad");
    }

    #[test]
    fn interpolation_hits_the_nodes_and_is_linear_between() {
        let nodes = [0u32, 2, 6];
        let x = [1.0, 3.0, -1.0].map(|v| C64::new(v, 0.0));
        let y: Vec<f64> = apply(BandOp::Interp, &nodes, &x).iter().map(|z| z.re).collect();
        assert_eq!(y, vec![1.0, 2.0, 3.0, 2.0, 1.0, 0.0, -1.0]);
    }

    #[test]
    fn each_transpose_is_the_adjoint_of_its_op() {
        // <A x, y> = <x, Aᵀ y> for arbitrary x, y, for every linear op.
        let nodes = [0u32, 1, 5, 6, 20];
        let values = |n: usize, s: f64| (0..n).map(|k| C64::new((k as f64 * s).sin() + 0.1, 0.0)).collect::<Vec<_>>();
        for op in [BandOp::Interp, BandOp::InterpT, BandOp::BinSum, BandOp::BinSpread, BandOp::Next, BandOp::Prev] {
            let p = plan(op, &nodes);
            let x = values(p.operand_len(), 1.7);
            let y = values(p.out_floats(), 0.3);
            let ax = apply(op, &nodes, &x);
            let aty = apply(op.transpose(), &nodes, &y);
            let left: f64 = ax.iter().zip(&y).map(|(a, b)| a.re * b.re).sum();
            let right: f64 = x.iter().zip(&aty).map(|(a, b)| a.re * b.re).sum();
            assert!((left - right).abs() < 1e-12 * left.abs().max(1.0), "{op:?}: {left} vs {right}");
        }
    }

    #[test]
    fn bin_sums_cover_every_point_once() {
        let nodes = [0u32, 2, 6];
        let x: Vec<C64> = (0..7).map(|k| C64::new((k + 1) as f64, 0.0)).collect();
        let s: Vec<f64> = apply(BandOp::BinSum, &nodes, &x).iter().map(|z| z.re).collect();
        assert_eq!(s, vec![1.0 + 2.0, 3.0 + 4.0 + 5.0 + 6.0, 7.0]);
        let next: Vec<f64> = apply(BandOp::Next, &nodes, &x[..3]).iter().map(|z| z.re).collect();
        assert_eq!(next, vec![2.0, 3.0, 0.0]);
    }
}
