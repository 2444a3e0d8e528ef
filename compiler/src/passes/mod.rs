//! IR-to-IR passes. Each takes a [`Function`] and returns a new one; the
//! driver verifies the IR after each pass and can dump it.
//!
//! - [`prune`]: keep only what the requested outputs and gradients need (DCE).
//! - [`relbin`]: with the scene's `relative_binning` setting, likelihood
//!   sums from summary data of a fiducial waveform over a few bins.
//! - [`cutsum`]: a sum over a waveform cut at a param-dependent frequency
//!   (the ISCO) split into the part the cut masks and the data's own
//!   term, which staging computes once per bound input.
//! - [`multiband`]: with the scene's `multiband` setting, `cis` of a phase
//!   over a grid computed on a coarse subset of the grid's points.
//! - [`adjoint`]: symbolic reverse-mode differentiation with activity analysis.
//! - [`simplify`]: rebuild through the folding builder (CSE, constant
//!   folding, algebraic identities), then prune.
//! - [`stage`]: split off the values computed from the data alone (a
//!   prelude the runtime runs once per bound input).
//! - [`specialise`]: fold what the grid fixes into precomputed tables.
//! - [`precision`]: the analysis of which values mixed precision computes
//!   in f64, and of magnitudes at the defaults (used by rescale and codegen).
//! - [`rescale`]: in f32, store values scaled by powers of two so strains
//!   of 1e-23 and their squares stay inside f32's range.

mod adjoint;
mod cutsum;
pub mod multiband;
pub mod precision;
mod prune;
pub mod relbin;
mod rescale;
mod specialise;
pub mod stage;

pub use adjoint::adjoint;
pub use cutsum::cutsum;
pub use multiband::multiband;
pub use prune::prune;
pub use relbin::relbin;
pub use rescale::rescale;
pub use specialise::{specialise, split_powers};

use crate::ir::builder::Builder;
use crate::ir::{Function, Value};

/// CSE, constant folding and algebraic simplification, followed by DCE.
pub fn simplify(func: &Function) -> Function {
    let mut header = func.clone();
    header.insts.clear();
    let mut b = Builder::new(header, true);
    let mut map: Vec<Value> = Vec::with_capacity(func.insts.len());
    for inst in &func.insts {
        let op = inst.op.map_operands(|v| map[v.index()]);
        map.push(b.emit(op));
    }
    let mut out = b.func;
    out.remap_roots(|v| map[v.index()]);
    prune(&out)
}
