//! The precision analysis: which values mixed precision computes in f64,
//! and each value's magnitude at the scene's defaults (what `rescale`
//! scales by). Enters: a [`Function`]; leaves: one flag or magnitude per
//! instruction. It runs the reference interpreter, so it is a pass the
//! driver and codegen call, never something printing does.

use crate::ir::{BandOp, BandPurpose, Elem, Function, InputRole, Op, Precision, Shape, UnOp};
use crate::kernels::interp;

/// Per instruction, whether [`Precision::Mixed`] computes it in f64 (a
/// phase, the periodic function of one, a value out of f32's
/// comfortable range at the defaults, relative binning's per-bin
/// arithmetic, or a scalar computed from a sum); all false in the other
/// precisions.
pub fn wide_values(func: &Function) -> Vec<bool> {
    let mut wide = vec![false; func.insts.len()];
    if func.precision != Precision::Mixed {
        return wide;
    }
    if let Some(magnitudes) = default_magnitudes(func) {
        let (lo, hi) = (2f64.powi(-96), 2f64.powi(96));
        let out_of_range: Vec<bool> =
            magnitudes.iter().enumerate().map(|(i, m)| func.insts[i].ty.elem != Elem::Bool && *m > 0.0 && (*m < lo || *m > hi)).collect();
        // A value computed from one out of range is computed in f64 too
        // (its operands would not survive conversion to f32).
        for (i, inst) in func.insts.iter().enumerate() {
            wide[i] = out_of_range[i] || inst.op.operands().iter().any(|a| out_of_range[a.index()]);
        }
    }
    // Relative binning's per-bin arithmetic: a few hundred values whose
    // terms are of order (h|h), where f32 would move ln L by 1e-3 at SNR 100.
    // So are values the prelude computed from the data (relative binning's
    // summary data, the data term (d|d)): kept in f64 as computed.
    for (i, inst) in func.insts.iter().enumerate() {
        let cached = matches!(inst.op, Op::Input(k) if func.inputs[k as usize].role == InputRole::Cached);
        wide[i] |= cached || func.bands.iter().any(|b| b.purpose == BandPurpose::RelativeBinning && inst.ty.shape == Shape::Grid(b.coarse));
    }
    // Scalar arithmetic on sums (the likelihood's terms added up): a sum
    // is accumulated in f64, and rounding a value of 1e4 to f32 would move
    // ln L by 1e-3. Scalar work costs nothing.
    let mut after_sum = vec![false; func.insts.len()];
    for (i, inst) in func.insts.iter().enumerate() {
        let scalar = inst.ty.shape == Shape::Scalar && inst.ty.elem != Elem::Bool;
        let from_sum = scalar && inst.op.operands().iter().any(|a| after_sum[a.index()]);
        after_sum[i] = matches!(inst.op, Op::Reduce(..)) || from_sum;
        wide[i] |= from_sum;
    }
    // Operands precede their users, so one backward sweep closes the set.
    for i in (0..func.insts.len()).rev() {
        let op = func.insts[i].op;
        let phase = match op {
            Op::Unary(UnOp::Sin | UnOp::Cos | UnOp::Tan | UnOp::Cis, a) | Op::Band(BandOp::Cis, _, a) => Some(a),
            Op::Unary(UnOp::Exp, a) if func.ty(a).elem == Elem::Complex => Some(a),
            _ => None,
        };
        if let Some(a) = phase {
            wide[i] = true;
            wide[a.index()] = true;
        }
        let elementwise = !matches!(op, Op::Reduce(..) | Op::Dft(..) | Op::Tensor(..) | Op::Band(..));
        if wide[i] && elementwise {
            for a in op.operands() {
                wide[a.index()] = true;
            }
        }
    }
    wide
}

/// The scene's params (base units) and inputs at their defaults: a param
/// without one at 1, an input without one at zero.
pub fn defaults(func: &Function) -> (Vec<f64>, Vec<interp::Tensor>) {
    let params: Vec<f64> = func.params.iter().map(|p| p.default.map_or(1.0, |d| d * p.scale)).collect();
    let inputs: Vec<interp::Tensor> = func
        .inputs
        .iter()
        .map(|i| i.default.clone().unwrap_or_else(|| vec![num_complex::Complex64::new(0.0, 0.0); func.len_of(i.ty.shape)]))
        .collect();
    (params, inputs)
}

/// The largest finite magnitude of each instruction's value (0 when all
/// are zero or not finite) with the params and inputs at their defaults
/// (an input without one at zero, a param without one at 1), by the
/// reference interpreter; `None` when that would exceed
/// [`interp::EVAL_BUDGET`].
pub fn default_magnitudes(func: &Function) -> Option<Vec<f64>> {
    let longest = func.grids.iter().map(|g| g.len).max().unwrap_or(1);
    if func.insts.len().saturating_mul(longest) > interp::EVAL_BUDGET {
        return None;
    }
    let (params, inputs) = defaults(func);
    let mut magnitudes = vec![0.0; func.insts.len()];
    interp::interpret_streaming(func, &params, &inputs, &vec![true; func.insts.len()], |i, t| {
        magnitudes[i] = t.iter().flat_map(|z| [z.re.abs(), z.im.abs()]).filter(|x| x.is_finite()).fold(0.0, f64::max);
        false
    });
    Some(magnitudes)
}
