//! gwml's lab: the studies and measurement tools built on the runtime,
//! which a user embedding the compiler does not need. The `gwml` command
//! line dispatches to them.
//!
//! - The glitch study: [`synth`] draws seeded synthetic datasets (whitened
//!   glitches of eight classes, bursts in noise) from the models in
//!   `lab/models/glitch/`; [`experiment`] is `gwml experiment glitch` (a
//!   rule-based filter, a CNN and the differentiable template bank, trained
//!   and scored on the same splits); [`generator`] is the learned glitch
//!   generator (`gwml generator fit|sample`).
//! - Speed against accuracy: [`tradeoff`] is `gwml tradeoff` (each
//!   precision × math setting timed and compared with f64-exact), with
//!   [`timing`] (medians of repeated calls), also used by the benchmarks.
//! - [`plot`]: PNG line, scatter and learning-curve plots and confusion
//!   matrices (plotters, with an embedded font).

use std::io::IsTerminal;

pub mod experiment;
pub mod explain;
pub mod generator;
pub mod plot;
pub mod strain;
pub mod synth;
pub mod timing;
pub mod tradeoff;

/// A runtime error as the command line prints it (in colour on a terminal).
pub(crate) fn render(e: gwml_runtime::Error) -> String {
    e.render(std::io::stderr().is_terminal())
}

/// Parses a range `LO..HI` of a command-line option (`--snr 8..30`).
pub fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let bad = || format!("error: expected a range LO..HI, got `{s}`");
    let (lo, hi) = s.split_once("..").ok_or_else(bad)?;
    Ok((lo.trim().parse().map_err(|_| bad())?, hi.trim().parse().map_err(|_| bad())?))
}
