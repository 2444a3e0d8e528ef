//! `gwml tradeoff`: one scene compiled under every combination of the
//! speed/accuracy knobs (precision, math, and any values given for the
//! scene's own `knob`s, such as its grid step or PN order), each timed and
//! compared with the f64-exact reference at the scene's own knob values, so
//! a user can pick a point on the Pareto front.
//!
//! Errors are measured on the same bound params and inputs:
//! - output error: over every output, the largest `max_i |a_i − r_i| / max_i |r_i|`
//!   (a max-norm relative error, so tiny elements do not dominate);
//! - gradient error: over every declared gradient, the largest `|g − g_ref| / |g_ref|`;
//! - mismatch of each complex array output (a waveform):
//!   `1 − Re⟨a, r⟩ / √(⟨a, a⟩⟨r, r⟩)` with `⟨a, b⟩ = Σ a_k conj(b_k) / S_k`, where
//!   `S` is the real array output named by `--psd` (unweighted without it).
//!   No maximisation over time or phase: a pure precision loss, not a search.
//!
//! - |Δ loss|: over every differentiated real scalar output (a likelihood
//!   or a loss, which relative binning approximates), the largest absolute
//!   difference `|a − r|`, the `|Δ ln L|` of the relative-binning literature.
//!
//! An array output whose length differs from the reference's (a knob changed
//! its grid) is not compared; scalars (a likelihood) and gradients still are.

use crate::timing::median_us;
use gwml_compiler::ir::{MathMode, Multiband, Precision, RelativeBinning};
use gwml_compiler::Options;
use gwml_runtime::{Error, Model, Outputs, Run, Value};
use num_complex::Complex64 as C64;
use std::fmt::Write;

/// One combination of knobs.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Working precision.
    pub precision: Precision,
    /// Transcendental functions.
    pub math: MathMode,
    /// Multibanding of the scene's waveform phases.
    pub multiband: Multiband,
    /// Relative binning of the scene's likelihood sums.
    pub relative_binning: RelativeBinning,
    /// Values of the scene's own `knob`s, as source text (`("df", "0.25 Hz")`);
    /// the knobs not named keep the scene's values.
    pub knobs: Vec<(String, String)>,
}

impl Config {
    /// f64, exact math, the scene's own knob values: what every row is measured against.
    pub fn reference() -> Config {
        Config {
            precision: Precision::F64,
            math: MathMode::Exact,
            multiband: Multiband::Off,
            relative_binning: RelativeBinning::Off,
            knobs: Vec::new(),
        }
    }

    /// The scene knobs as `df=0.25 Hz pn_order=5` (empty for the scene's own).
    pub fn knob_text(&self) -> String {
        self.knobs.iter().map(|(n, v)| format!("{n}={v}")).collect::<Vec<_>>().join(" ")
    }

    /// The algorithmic setting: `multiband=1e-3`, `relative_binning=100`,
    /// or `exact`.
    pub fn algorithm(&self) -> String {
        let mut parts = Vec::new();
        if self.multiband != Multiband::Off {
            parts.push(format!("multiband={}", self.multiband));
        }
        if self.relative_binning != RelativeBinning::Off {
            parts.push(format!("relative_binning={}", self.relative_binning));
        }
        if parts.is_empty() {
            "exact".into()
        } else {
            parts.join(" ")
        }
    }

    /// `f64 exact multiband=1e-3 df=0.25 Hz`: the knobs in one phrase.
    pub fn label(&self) -> String {
        let k = self.knob_text();
        let alg = if self.algorithm() == "exact" { String::new() } else { format!(" {}", self.algorithm()) };
        format!("{} {}{alg}{}{k}", self.precision, self.math, if k.is_empty() { "" } else { " " })
    }
}

/// What the sweep measures.
pub struct Settings {
    /// Configurations to measure (the f64-exact reference is always run first).
    pub configs: Vec<Config>,
    /// Timed calls per configuration and kernel (medians are reported).
    pub reps: usize,
    /// A real array output used as the PSD weighting the mismatch.
    pub psd: Option<String>,
    /// Scene knob values every configuration uses, the reference included
    /// (each configuration's own knobs come after them).
    pub knobs: Vec<(String, String)>,
}

/// Measurements of one configuration.
#[derive(Clone, Debug)]
pub struct Row {
    /// The knobs.
    pub config: Config,
    /// Median time of a forward call, µs.
    pub forward_us: f64,
    /// Median time of a value-and-gradient call, µs (scenes with
    /// gradients): the differentiated outputs and their gradients only.
    pub grad_us: Option<f64>,
    /// Largest relative (max-norm) error of any output against the reference.
    pub output_error: f64,
    /// Largest relative error of any gradient.
    pub grad_error: Option<f64>,
    /// Largest mismatch of any complex array output.
    pub mismatch: Option<f64>,
    /// Largest absolute error of a differentiated real scalar output.
    pub delta_loss: Option<f64>,
    /// No other row is at least as fast and at least as accurate (and better in one).
    pub pareto: bool,
    /// Why this configuration could not run (e.g. a non-finite output in
    /// f32); its times and errors are then NaN.
    pub failure: Option<String>,
}

impl Row {
    /// The row of a configuration that failed to compile or run.
    fn failed(config: Config, e: &Error) -> Row {
        let nan = f64::NAN;
        Row {
            config,
            forward_us: nan,
            grad_us: None,
            output_error: nan,
            grad_error: None,
            mismatch: None,
            delta_loss: None,
            pareto: false,
            failure: Some(e.to_string()),
        }
    }

    /// The time that ranks rows: forward+gradient if the scene has gradients.
    pub fn time_us(&self) -> f64 {
        self.grad_us.unwrap_or(self.forward_us)
    }

    /// The error that ranks rows: the worst of outputs, gradients and mismatch
    /// (infinite for a failed configuration).
    pub fn error(&self) -> f64 {
        if self.failure.is_some() {
            return f64::INFINITY;
        }
        self.output_error.max(self.grad_error.unwrap_or(0.0)).max(self.mismatch.unwrap_or(0.0))
    }
}

/// Every precision × math combination, multibanding off.
pub fn all_configs() -> Vec<Config> {
    let mut v = Vec::new();
    for precision in [Precision::F64, Precision::Mixed, Precision::F32] {
        for math in [MathMode::Exact, MathMode::Fast, MathMode::Fastest] {
            v.push(Config { precision, math, ..Config::reference() });
        }
    }
    v
}

/// The multibanding tolerances `gwml tradeoff` sweeps by default (radians
/// of phase error; the mismatch is below half the square).
pub const DEFAULT_MULTIBAND: [Multiband; 5] =
    [Multiband::Off, Multiband::Tolerance(1e-2), Multiband::Tolerance(2e-3), Multiband::Tolerance(1e-3), Multiband::Tolerance(1e-4)];

/// The bin counts `gwml tradeoff` sweeps by default for relative binning
/// (jimgw's default is 100).
pub const DEFAULT_RELATIVE_BINNING: [RelativeBinning; 3] =
    [RelativeBinning::Bins(50), RelativeBinning::Bins(100), RelativeBinning::Bins(200)];

/// Every configuration of `configs` with every algorithmic setting of
/// `settings` (multibanding and relative binning, each pair as given).
pub fn with_algorithms(configs: Vec<Config>, settings: &[(Multiband, RelativeBinning)]) -> Vec<Config> {
    configs
        .into_iter()
        .flat_map(|c| settings.iter().map(move |&(multiband, relative_binning)| Config { multiband, relative_binning, ..c.clone() }))
        .collect()
}

/// Every configuration of `configs` combined with every combination of the
/// scene-knob values in `sweeps` (name, values as source text).
pub fn with_knob_sweeps(configs: Vec<Config>, sweeps: &[(String, Vec<String>)]) -> Vec<Config> {
    let mut out = configs;
    for (name, values) in sweeps {
        out = out
            .into_iter()
            .flat_map(|c| {
                values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.knobs.push((name.clone(), v.clone()));
                    c
                })
            })
            .collect();
    }
    out
}

fn rel_max_norm(a: &[C64], r: &[C64]) -> f64 {
    let scale = r.iter().map(|z| z.norm()).fold(0.0, f64::max);
    let diff = a.iter().zip(r).map(|(x, y)| (x - y).norm()).fold(0.0, f64::max);
    if scale > 0.0 {
        diff / scale
    } else {
        diff
    }
}

fn as_complex(v: &Value) -> Vec<C64> {
    match v {
        Value::Real(x) => vec![C64::new(*x, 0.0)],
        Value::Complex(z) => vec![*z],
        Value::RealArray(x) => x.iter().map(|x| C64::new(*x, 0.0)).collect(),
        Value::ComplexArray(z) => z.clone(),
    }
}

/// `1 − Re⟨a, r⟩ / √(⟨a, a⟩⟨r, r⟩)` weighted by `1/psd` when given.
pub fn mismatch(a: &[C64], r: &[C64], psd: Option<&[f64]>) -> f64 {
    let w = |k: usize| psd.map_or(1.0, |s| 1.0 / s[k]);
    let (mut aa, mut rr) = (0.0, 0.0);
    for k in 0..a.len().min(r.len()) {
        aa += a[k].norm_sqr() * w(k);
        rr += r[k].norm_sqr() * w(k);
    }
    if aa == 0.0 && rr == 0.0 {
        return 0.0;
    }
    // 1 − Re⟨â, r̂⟩ loses digits near 0: ‖â − r̂‖² / 2 equals it and does not.
    let (na, nr) = (aa.sqrt(), rr.sqrt());
    let mut d2 = 0.0;
    for k in 0..a.len().min(r.len()) {
        d2 += (a[k] / na - r[k] / nr).norm_sqr() * w(k);
    }
    d2 / 2.0
}

/// Runs the sweep: compiles the scene under each configuration, binds it
/// with `bind`, times both kernels and compares with the f64-exact run
/// (at `settings.knobs`), which is the first row returned. `progress` is
/// told (index, count, configuration) before each is measured.
pub fn sweep(
    model: &Model,
    scene: Option<&str>,
    settings: &Settings,
    bind: &dyn Fn(&mut Run) -> Result<(), Error>,
    progress: &mut dyn FnMut(usize, usize, &Config),
) -> Result<Vec<Row>, Error> {
    let reference = Config { knobs: settings.knobs.clone(), ..Config::reference() };
    let mut configs = vec![reference.clone()];
    configs.extend(settings.configs.iter().filter(|c| **c != reference).cloned());
    let mut rows: Vec<Row> = Vec::new();
    let mut reference_out: Option<Outputs> = None;
    let count = configs.len();
    for (i, config) in configs.into_iter().enumerate() {
        progress(i, count, &config);
        // The reference must compile and run; other settings may fail
        // (reported in their row), at compile time or when run.
        let options = Options {
            precision: Some(config.precision),
            math: Some(config.math),
            multiband: Some(config.multiband),
            relative_binning: Some(config.relative_binning),
            knobs: config.knobs.clone(),
            outputs: None,
            ..Options::default()
        };
        let compiled = match model.scene_with(scene, options.clone()) {
            Ok(compiled) => compiled,
            Err(e) if i > 0 => {
                rows.push(Row::failed(config, &e));
                continue;
            }
            Err(e) => return Err(e),
        };
        let has_grads = compiled.ir().has_gradients();
        let mut run = compiled.bind();
        match bind(&mut run) {
            Ok(()) => {}
            Err(e) if i > 0 => {
                rows.push(Row::failed(config, &e));
                continue;
            }
            Err(e) => return Err(e),
        }
        let first = if has_grads { run.value_and_grad() } else { run.forward() };
        let out = match first {
            Ok(out) => out,
            Err(e) if i > 0 => {
                rows.push(Row::failed(config, &e));
                continue;
            }
            Err(e) => return Err(e),
        };
        let forward_us = timed(settings.reps, &mut run, false)?;
        let grad_us = if has_grads {
            let graded = Options { outputs: Some(differentiated_outputs(compiled.ir())), ..options };
            Some(time_value_and_grad(model, scene, graded, bind, settings.reps)?)
        } else {
            None
        };
        let r = reference_out.get_or_insert_with(|| out.clone());
        let (output_error, grad_error, mismatch) = compare(&out, r, settings.psd.as_deref())?;
        let delta_loss = loss_error(&out, r, &differentiated_outputs(compiled.ir()))?;
        rows.push(Row { config, forward_us, grad_us, output_error, grad_error, mismatch, delta_loss, pareto: false, failure: None });
    }
    mark_pareto(&mut rows);
    Ok(rows)
}

/// The names of the outputs a scene differentiates.
fn differentiated_outputs(f: &gwml_compiler::ir::Function) -> Vec<String> {
    let mut names: Vec<String> = Vec::new();
    for o in f.grads.iter().map(|g| g.output).chain(f.input_grads.iter().map(|g| g.output)) {
        if !names.contains(&f.outputs[o].name) {
            names.push(f.outputs[o].name.clone());
        }
    }
    names
}

/// Median time of value-and-gradient as a sampler or optimiser calls it:
/// the scene compiled with `options` naming only its differentiated
/// outputs, so array outputs kept for the error columns (a waveform, a
/// PSD) are neither computed nor copied out.
fn time_value_and_grad(
    model: &Model,
    scene: Option<&str>,
    options: Options,
    bind: &dyn Fn(&mut Run) -> Result<(), Error>,
    reps: usize,
) -> Result<f64, Error> {
    let compiled = model.scene_with(scene, options)?;
    let mut run = compiled.bind();
    bind(&mut run)?;
    timed(reps, &mut run, true)
}

fn timed(reps: usize, run: &mut Run, grad: bool) -> Result<f64, Error> {
    let mut failure = None;
    let t = median_us(reps, || {
        let r = if grad { run.value_and_grad() } else { run.forward() };
        if let Err(e) = r {
            failure.get_or_insert(e);
        }
    });
    failure.map_or(Ok(t), Err)
}

fn compare(out: &Outputs, r: &Outputs, psd: Option<&str>) -> Result<(f64, Option<f64>, Option<f64>), Error> {
    let weight = match psd {
        Some(name) => match r.value(name)? {
            Value::RealArray(s) => Some(s.clone()),
            _ => return Err(Error::Bind(format!("--psd {name}: the PSD must be a real array output"))),
        },
        None => None,
    };
    let mut output_error: f64 = 0.0;
    let mut mismatch_max: Option<f64> = None;
    for (name, want) in &r.values {
        let got = out.value(name)?;
        let (a, b) = (as_complex(got), as_complex(want));
        if a.len() != b.len() {
            // On another grid (a scene knob changed it): not comparable bin by bin.
            continue;
        }
        output_error = output_error.max(rel_max_norm(&a, &b));
        if let (Value::ComplexArray(a), Value::ComplexArray(b)) = (got, want) {
            let m = mismatch(a, b, weight.as_deref().filter(|w| w.len() == b.len()));
            mismatch_max = Some(mismatch_max.map_or(m, |x: f64| x.max(m)));
        }
    }
    let mut grad_error: Option<f64> = None;
    for (o, p, want) in &r.grads {
        let got = out.grad(o, p)?;
        let e = if *want != 0.0 { ((got - want) / want).abs() } else { got.abs() };
        grad_error = Some(grad_error.map_or(e, |x: f64| x.max(e)));
    }
    Ok((output_error, grad_error, mismatch_max))
}

/// The largest `|a − r|` of the real scalar outputs named in `names`.
fn loss_error(out: &Outputs, r: &Outputs, names: &[String]) -> Result<Option<f64>, Error> {
    let mut worst: Option<f64> = None;
    for name in names {
        if let (Value::Real(a), Value::Real(b)) = (out.value(name)?, r.value(name)?) {
            worst = Some(worst.map_or(0.0, |w: f64| w).max((a - b).abs()));
        }
    }
    Ok(worst)
}

/// Marks the rows no other row dominates in (time, error).
pub fn mark_pareto(rows: &mut [Row]) {
    let points: Vec<(f64, f64)> = rows.iter().map(|r| (r.time_us(), r.error())).collect();
    for (i, row) in rows.iter_mut().enumerate() {
        let (t, e) = points[i];
        row.pareto =
            row.failure.is_none() && !points.iter().enumerate().any(|(j, &(tj, ej))| j != i && tj <= t && ej <= e && (tj < t || ej < e));
    }
}

fn opt(x: Option<f64>, f: impl Fn(f64) -> String) -> String {
    x.map_or_else(|| "-".to_string(), f)
}

/// The rows of [`sweep`] (the first is the reference) sorted by time as an
/// aligned table (Markdown-compatible); `*` marks Pareto-optimal rows,
/// `speed-up` is relative to the reference. A `knobs` column appears when
/// the sweep sets scene knobs.
pub fn table(rows: &[Row]) -> String {
    let base = rows.first().filter(|r| r.failure.is_none()).map(Row::time_us);
    let with_knobs = rows.iter().any(|r| !r.config.knobs.is_empty());
    let with_bands = rows.iter().any(|r| r.config.algorithm() != "exact");
    let with_loss = rows.iter().any(|r| r.delta_loss.is_some());
    let mut sorted: Vec<&Row> = rows.iter().collect();
    sorted.sort_by(|a, b| a.failure.is_some().cmp(&b.failure.is_some()).then(a.time_us().total_cmp(&b.time_us())));
    let knobs = |r: &Row| {
        if with_knobs {
            format!(" {} |", if r.config.knobs.is_empty() { "(scene)".into() } else { r.config.knob_text() })
        } else {
            String::new()
        }
    };
    let bands = |r: &Row| if with_bands { format!(" {} |", r.config.algorithm()) } else { String::new() };
    let mut s = String::new();
    let (kh, kr) = if with_knobs { (" knobs |", "---|") } else { ("", "") };
    let (bh, br) = if with_bands { (" algorithm |", "---|") } else { ("", "") };
    let (lh, lr) = if with_loss { (" |Δ loss| |", "---:|") } else { ("", "") };
    let loss = |r: &Row| if with_loss { format!(" {} |", opt(r.delta_loss, |e| format!("{e:.1e}"))) } else { String::new() };
    let _ = writeln!(
        s,
        "| pareto | precision | math |{bh}{kh} forward µs | value+grad µs | speed-up | output rel. err | grad rel. err | mismatch |{lh}"
    );
    let _ = writeln!(s, "|---|---|---|{br}{kr}---:|---:|---:|---:|---:|---:|{lr}");
    for r in sorted {
        if let Some(f) = &r.failure {
            let _ = writeln!(
                s,
                "|  | {} | {} |{}{} failed: {} | | | | | |{}",
                r.config.precision,
                r.config.math,
                bands(r),
                knobs(r),
                f.replace('|', "/"),
                if with_loss { " |" } else { "" }
            );
            continue;
        }
        let _ = writeln!(
            s,
            "| {} | {} | {} |{}{} {:.1} | {} | {} | {:.1e} | {} | {} |{}",
            if r.pareto { "*" } else { "" },
            r.config.precision,
            r.config.math,
            bands(r),
            knobs(r),
            r.forward_us,
            opt(r.grad_us, |t| format!("{t:.1}")),
            opt(base, |b| format!("{:.2}×", b / r.time_us())),
            r.output_error,
            opt(r.grad_error, |e| format!("{e:.1e}")),
            opt(r.mismatch, |m| format!("{m:.1e}")),
            loss(r),
        );
    }
    s
}

/// The rows as CSV with a header line.
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "precision,math,multiband,relative_binning,knobs,forward_us,grad_us,output_error,grad_error,mismatch,delta_loss,pareto,failure\n",
    );
    let o = |x: Option<f64>| x.map_or(String::new(), |v| format!("{v:e}"));
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},\"{}\",{:e},{},{:e},{},{},{},{},\"{}\"",
            r.config.precision,
            r.config.math,
            r.config.multiband,
            r.config.relative_binning,
            r.config.knob_text(),
            r.forward_us,
            o(r.grad_us),
            r.output_error,
            o(r.grad_error),
            o(r.mismatch),
            o(r.delta_loss),
            r.pareto,
            r.failure.as_deref().unwrap_or("").replace('"', "'")
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(t: f64, e: f64) -> Row {
        Row {
            config: Config::reference(),
            forward_us: t,
            grad_us: None,
            output_error: e,
            grad_error: None,
            mismatch: None,
            delta_loss: None,
            pareto: false,
            failure: None,
        }
    }

    #[test]
    fn pareto_front_keeps_only_undominated_rows() {
        let mut rows = vec![row(10.0, 0.0), row(5.0, 1e-12), row(6.0, 1e-10), row(4.0, 1e-7), row(4.0, 1e-6)];
        mark_pareto(&mut rows);
        let flags: Vec<bool> = rows.iter().map(|r| r.pareto).collect();
        assert_eq!(flags, [true, true, false, true, false]);
    }

    #[test]
    fn mismatch_is_zero_for_equal_and_small_for_perturbed_waveforms() {
        let a: Vec<C64> = (0..100).map(|k| C64::from_polar(1.0 / (1.0 + k as f64), 0.1 * (k * k) as f64)).collect();
        assert_eq!(mismatch(&a, &a, None), 0.0);
        // A phase error δ on every bin: mismatch 1 − cos δ ≈ δ²/2.
        let d = 1e-4;
        let b: Vec<C64> = a.iter().map(|z| z * C64::from_polar(1.0, d)).collect();
        let m = mismatch(&b, &a, None);
        assert!((m / (d * d / 2.0) - 1.0).abs() < 1e-6, "{m}");
        let psd: Vec<f64> = (0..100).map(|k| 1.0 + k as f64).collect();
        assert!((mismatch(&b, &a, Some(&psd)) / (d * d / 2.0) - 1.0).abs() < 1e-6);
    }
}
