//! Staging: the values a scene computes from its data alone, once per
//! bound input instead of on every call. A sampler or an optimiser calls a
//! likelihood thousands of times on the same data: the data's own noise
//! weighted norm `(d | d)`, or relative binning's summary data, do not
//! change between those calls.
//!
//! [`split`] cuts a function in two. The *prelude* computes every value
//! that depends on data inputs (role [`InputRole::Data`]) and on nothing
//! that changes per call — params, weights, dropout masks, noise draws —
//! and that is worth keeping: its computation holds a reduction, a
//! transform, a band or tensor op or a transcendental function (relative
//! binning's fiducial waveform), and a per-call value uses it. Those
//! values are the prelude's outputs (`cache.0`, `cache.1`, …). The *main*
//! function reads each of them as an input of role [`InputRole::Cached`]
//! in place of its computation. The runtime runs the prelude when a data
//! input is bound (or on the first call) and hands its outputs to the
//! main kernel. A scene with nothing to cache, or whose results all come
//! from the data alone, is not split.

use super::precision::defaults;
use super::prune;
use crate::ir::*;
use crate::kernels::interp;

/// The two parts of a staged function.
#[derive(Clone, Debug)]
pub struct Staged {
    /// Computes the cached values from the data (its outputs, in the
    /// order of the main function's cached inputs).
    pub prelude: Function,
    /// The function with each cached value read from an input.
    pub main: Function,
}

/// Splits `func` into a prelude and a main function, or `None` when no
/// value is worth caching.
pub fn split(func: &Function) -> Option<Staged> {
    let n = func.insts.len();
    // Per value: depends on data inputs; depends on something that
    // changes per call; holds costly work that could be cached.
    let (mut data, mut per_call, mut costly) = (vec![false; n], vec![false; n], vec![false; n]);
    for (i, inst) in func.insts.iter().enumerate() {
        let operands = inst.op.operands();
        let any = |flags: &[bool]| operands.iter().any(|a| flags[a.index()]);
        match inst.op {
            Op::Input(k) => match func.inputs[k as usize].role {
                InputRole::Data | InputRole::Cached => data[i] = true,
                _ => per_call[i] = true,
            },
            Op::Param(_) => per_call[i] = true,
            _ => {
                data[i] = any(&data);
                per_call[i] = any(&per_call);
            }
        }
        let work = matches!(
            inst.op,
            Op::Reduce(..)
                | Op::Dft(..)
                | Op::Tensor(..)
                | Op::Band(..)
                | Op::PowConst(..)
                | Op::Binary(BinOp::Pow | BinOp::Atan2, ..)
                | Op::Unary(
                    UnOp::Sqrt | UnOp::Cbrt | UnOp::Exp | UnOp::Log | UnOp::Sin | UnOp::Cos | UnOp::Tan | UnOp::Tanh | UnOp::Cis,
                    _
                )
        );
        costly[i] = data[i] && !per_call[i] && (work || any(&costly));
    }
    // Cached: costly values a per-call value or a root uses.
    let mut used_per_call = vec![false; n];
    for r in func.roots() {
        used_per_call[r.index()] = true;
    }
    for (i, inst) in func.insts.iter().enumerate() {
        if per_call[i] {
            for a in inst.op.operands() {
                used_per_call[a.index()] = true;
            }
        }
    }
    // Truth values are recomputed from what they compare (buffers hold numbers).
    let cached: Vec<usize> = (0..n).filter(|&i| costly[i] && used_per_call[i] && func.insts[i].ty.elem != Elem::Bool).collect();
    // A scene whose results all come from the data alone (whitening a
    // stretch of strain) gets new data on every call: nothing to keep.
    if cached.is_empty() || !func.roots().iter().any(|r| per_call[r.index()]) {
        return None;
    }
    let mut prelude = func.clone();
    // Run once per bound input, the prelude costs nothing per call: it
    // runs in f64 whatever the scene's precision, so data without a
    // default (whose magnitude f32 rescaling cannot know) and products
    // of strains (1e-46) are exact. Its outputs are O(1) sums.
    prelude.precision = Precision::F64;
    prelude.grads.clear();
    prelude.input_grads.clear();
    prelude.outputs = cached
        .iter()
        .enumerate()
        .map(|(k, &i)| Output { name: format!("cache.{k}"), value: Value(i as u32), unit: String::new(), exponent: 0 })
        .collect();
    let prelude = prune(&prelude);
    let at_defaults = values_at_defaults(&prelude);

    let mut main = func.clone();
    for (k, &i) in cached.iter().enumerate() {
        let ty = main.insts[i].ty;
        main.inputs.push(InputInfo {
            name: format!("cache.{k}"),
            ty,
            scale: 1.0,
            unit: String::new(),
            default: at_defaults.as_ref().map(|v| v[k].clone()),
            role: InputRole::Cached,
        });
        main.insts[i].op = Op::Input(main.inputs.len() as u32 - 1);
    }
    Some(Staged { prelude, main: prune(&main) })
}

/// The prelude's outputs at the scene's defaults, which the passes after
/// staging (rescaling, the precision analysis) read as the cached inputs'
/// typical values; `None` when too costly to interpret.
fn values_at_defaults(prelude: &Function) -> Option<Vec<interp::Tensor>> {
    let longest = prelude.grids.iter().map(|g| g.len).max().unwrap_or(1);
    if prelude.insts.len().saturating_mul(longest) > interp::EVAL_BUDGET {
        return None;
    }
    let (params, inputs) = defaults(prelude);
    let values = interp::interpret_only(prelude, &params, &inputs, &vec![true; prelude.insts.len()]).values;
    Some(prelude.outputs.iter().map(|o| values[o.value.index()].clone()).collect())
}
