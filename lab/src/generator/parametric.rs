//! The parametric glitch generator (issue #7, `gwml generator fit --kind
//! parametric`): a distribution over the params of one `std::glitch`
//! formula per family.
//!
//! Fitting is two stages. First, each example glitch is an inverse problem:
//! the family's scene in `lab/models/glitch/generator.gw` matches the family's
//! whitened shape against the example and gives the peak matched-filter SNR
//! over time shifts; L-BFGS ([`gwml_runtime::fit`]) maximises it over the
//! shape params, by gradients through the physics, from the best of a grid
//! of starts. Where the SNR peaks gives the glitch's time, its height the
//! glitch's SNR. Second, a distribution over (shape params, time, SNR) is
//! fitted to the per-example estimates: a multivariate normal over
//! unbounded coordinates (the logit of each bounded param's place in its
//! range, the log of the SNR), whose mean and covariance are the maximum
//! likelihood estimates, so correlations between params are kept.
//!
//! Sampling draws from that normal, maps back to params, and draws each
//! glitch through [`crate::synth::unit_signal`], the same whitened
//! shapes `gwml data glitch` draws, with a uniformly random phase (the fit is
//! blind to phase).

use super::{quantiles, Draws, GeneratorFitArgs, SAMPLES, SAMPLE_RATE};
use crate::plot::scatter_plot;
use crate::render;
use crate::synth::{unit_signal, GlitchSignals, GLITCH_CLASSES};
use gwml_runtime::fit::{self, Algorithm, Settings};
use gwml_runtime::{Error, Model, Run, Scene, Value};
use indicatif::{ProgressBar, ProgressStyle};
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::time::Instant;

/// The generator's inverse problems, one scene per glitch family.
pub const GENERATOR_SOURCE: &str = include_str!("../../models/glitch/generator.gw");

/// A glitch family the generator models.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Family {
    /// Its scene in `lab/models/glitch/generator.gw`.
    pub scene: &'static str,
    /// Its class index in [`GLITCH_CLASSES`].
    pub class: usize,
    /// Starting-grid points per shape param. Long coherent shapes need fine
    /// grids: a matched filter loses a whistle whose span is a few tens of
    /// Hz off, or a scratchy glitch whose arch rate is 2 Hz off.
    pub grid: &'static [usize],
}

/// The glitch families the generator models.
pub const FAMILIES: [Family; 4] = [
    Family { scene: "blip", class: 1, grid: &[4, 4] },
    Family { scene: "koi_fish", class: 2, grid: &[4, 3, 3, 3, 3] },
    Family { scene: "whistle", class: 3, grid: &[4, 16, 6] },
    Family { scene: "scratchy", class: 4, grid: &[4, 16, 4] },
];

/// The family of glitch class `class`, or an error naming the families.
pub fn family(class: usize) -> Result<Family, String> {
    FAMILIES.iter().find(|f| f.class == class).copied().ok_or_else(|| {
        format!(
            "the generator models the glitch families {}; {} is not one",
            FAMILIES.iter().map(|f| GLITCH_CLASSES[f.class]).collect::<Vec<_>>().join(", "),
            GLITCH_CLASSES.get(class).unwrap_or(&"this class")
        )
    })
}

/// The estimates from one example.
#[derive(Clone, Debug, PartialEq)]
pub struct ExampleFit {
    /// The shape params at the SNR's maximum, in the scene's declared order.
    pub shape: Vec<f64>,
    /// The glitch's centre in seconds from the segment's start.
    pub t0: f64,
    /// The peak matched-filter SNR.
    pub snr: f64,
}

/// One shape param of a family: its name and the range the scene gives it.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeParam {
    /// The scene's param name.
    pub name: String,
    /// Its unit as declared (e.g. `Hz`), empty when dimensionless.
    pub unit: String,
    /// Its bounds.
    pub range: (f64, f64),
}

impl ShapeParam {
    /// The name with its unit, e.g. `f0 (Hz)`; just the name when
    /// dimensionless.
    pub fn label(&self) -> String {
        match self.unit.as_str() {
            "" | "1" => self.name.clone(),
            unit => format!("{} ({unit})", self.name),
        }
    }
}

/// The shape params of a family scene (its `grad loss wrt` list).
pub fn shape_params(scene: &Scene) -> Result<Vec<ShapeParam>, Error> {
    let f = scene.ir();
    let loss =
        f.outputs.iter().position(|o| o.name == "loss").ok_or_else(|| Error::Bind("the family scene has no output `loss`".into()))?;
    f.grads
        .iter()
        .filter(|g| g.output == loss)
        .map(|g| {
            let p = &f.params[g.param];
            let range = p.bounds.ok_or_else(|| Error::Bind(format!("shape param `{}` needs bounds (`in LO..HI`)", p.name)))?;
            Ok(ShapeParam { name: p.name.clone(), unit: p.unit.clone(), range })
        })
        .collect()
}

/// Starting points: a grid over each param's range, evenly spaced in the
/// logarithm (every range is positive), with `points[i]` values for param
/// `i`. The first param is a frequency: `peak` (the whitened data's
/// spectral peak, where a glitch's carrier or a whistle's lowest frequency
/// puts most power) and 3 % either side of it join its values.
fn starts(params: &[ShapeParam], points: &[usize], peak: f64) -> Vec<Vec<f64>> {
    let mut grid = vec![Vec::new()];
    for (i, p) in params.iter().enumerate() {
        let (lo, hi) = p.range;
        let n = points.get(i).copied().unwrap_or(3);
        let mut values: Vec<f64> = (0..n).map(|k| lo * (hi / lo).powf((k as f64 + 0.5) / n as f64)).collect();
        if i == 0 && peak.is_finite() {
            values.extend([0.97 * peak, peak, 1.03 * peak].map(|v| v.clamp(lo, hi)));
        }
        grid = grid.iter().flat_map(|g| values.iter().map(move |v| [g.as_slice(), &[*v]].concat())).collect();
    }
    grid
}

/// The frequency in 20 Hz–2 kHz where the power of whitened `x` (smoothed
/// over 5 bins of 1 Hz) peaks.
fn spectral_peak(x: &[f64]) -> f64 {
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(x.len());
    let mut input = x.to_vec();
    let mut spectrum = fft.make_output_vec();
    if fft.process(&mut input, &mut spectrum).is_err() {
        return f64::NAN;
    }
    let df = SAMPLE_RATE / x.len() as f64;
    let power: Vec<f64> = spectrum.iter().map(|c| c.norm_sqr()).collect();
    let (lo, hi) = ((20.0 / df) as usize, ((2000.0 / df) as usize).min(power.len().saturating_sub(3)));
    (lo.max(2)..hi)
        .map(|k| (k, power[k - 2..=k + 2].iter().sum::<f64>()))
        .fold((0, f64::NEG_INFINITY), |b, (k, p)| if p > b.1 { (k, p) } else { b })
        .0 as f64
        * df
}

/// Fits one whitened example `x` (4096 samples) with a run of its family's
/// scene: the best start of the grid (`points` values per shape param, see
/// [`Family::grid`]) by peak SNR, then L-BFGS on the shape params.
pub fn fit_example(run: &mut Run, params: &[ShapeParam], points: &[usize], x: &[f64]) -> Result<ExampleFit, Error> {
    run.input_real("x", x)?;
    let set = |run: &mut Run, values: &[f64]| -> Result<(), Error> {
        for (p, v) in params.iter().zip(values) {
            run.param(&p.name, *v)?;
        }
        Ok(())
    };
    let mut ranked = Vec::new();
    for start in starts(params, points, spectral_peak(x)) {
        set(run, &start)?;
        ranked.push((run.forward()?.scalar("loss")?, start));
    }
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    // L-BFGS from the best few starts: the SNR's landscape over a long
    // shape's params has many local maxima.
    let settings = Settings { max_steps: 200, rel_tol: 1e-10, ..Settings::new(Algorithm::Lbfgs) };
    let bounds: Vec<Option<(f64, f64)>> = params.iter().map(|p| Some(p.range)).collect();
    let mut best: Option<fit::Minimum> = None;
    for (_, start) in ranked.iter().take(STARTS_REFINED) {
        let eval = |values: &[f64]| -> Result<(f64, Vec<f64>), Error> {
            set(run, values)?;
            let out = run.value_and_grad()?;
            let grad = params.iter().map(|p| out.grad("loss", &p.name).unwrap_or(0.0)).collect();
            Ok((out.scalar("loss")?, grad))
        };
        let m = fit::minimize(eval, start, &bounds, &settings, |_| {})?;
        if best.as_ref().is_none_or(|b| m.loss < b.loss) {
            best = Some(m);
        }
    }
    let best = best.expect("the grid has at least one point");
    set(run, &best.x)?;
    let out = run.forward()?;
    let Value::RealArray(rho) = out.value("rho")? else {
        return Err(Error::Bind("the family scene's `rho` is not a real array".into()));
    };
    let (peak, snr) = rho.iter().enumerate().fold((0, f64::NEG_INFINITY), |b, (j, r)| if *r > b.1 { (j, *r) } else { b });
    // The template is centred at 0.5 s: rho peaks at the shift t0 - 0.5 s.
    let t0 = (peak as f64 / SAMPLES as f64 + 0.5).rem_euclid(1.0);
    Ok(ExampleFit { shape: best.x, t0, snr })
}

/// A fitted generator: a multivariate normal over unbounded coordinates of
/// (shape params, t0, SNR).
#[derive(Clone, Debug, PartialEq)]
pub struct Generator {
    /// The family's scene name (e.g. `blip`).
    pub family: String,
    /// The shape params, then `t0` (in 0..1 s) and `snr` (positive).
    pub params: Vec<ShapeParam>,
    /// Mean of the unbounded coordinates.
    pub mean: Vec<f64>,
    /// Their covariance (row-major, `params.len()` squared).
    pub covariance: Vec<f64>,
    /// How many examples it was fitted to (those with estimates inside the
    /// ranges).
    pub examples: usize,
}

/// How many of the best grid points [`fit_example`] refines with L-BFGS.
const STARTS_REFINED: usize = 3;

/// Bounded coordinates are cut this far inside their range before the logit.
const EDGE: f64 = 1e-6;

fn to_unbounded(p: &ShapeParam, v: f64) -> f64 {
    if p.name == "snr" {
        return v.max(1e-300).ln();
    }
    let u = ((v - p.range.0) / (p.range.1 - p.range.0)).clamp(EDGE, 1.0 - EDGE);
    (u / (1.0 - u)).ln()
}

fn from_unbounded(p: &ShapeParam, z: f64) -> f64 {
    if p.name == "snr" {
        return z.exp();
    }
    p.range.0 + (p.range.1 - p.range.0) / (1.0 + (-z).exp())
}

impl ExampleFit {
    /// Whether a shape param ended within 0.1 % of its range from a bound:
    /// the matched filter found no maximum inside the range, so the estimate
    /// says where the search stopped rather than what the glitch is.
    pub fn on_bound(&self, shape: &[ShapeParam]) -> bool {
        shape.iter().zip(&self.shape).any(|(p, v)| {
            let margin = 1e-3 * (p.range.1 - p.range.0);
            *v <= p.range.0 + margin || *v >= p.range.1 - margin
        })
    }
}

impl Generator {
    /// Fits the normal to per-example estimates of the family `family` with
    /// shape params `shape`, leaving out estimates on a bound
    /// ([`ExampleFit::on_bound`]). Needs more examples than coordinates.
    pub fn fit(family: &str, shape: &[ShapeParam], fits: &[ExampleFit]) -> Result<Generator, String> {
        let mut params = shape.to_vec();
        params.push(ShapeParam { name: "t0".into(), unit: "s".into(), range: (0.0, 1.0) });
        params.push(ShapeParam { name: "snr".into(), unit: String::new(), range: (0.0, f64::INFINITY) });
        let k = params.len();
        let kept: Vec<&ExampleFit> = fits.iter().filter(|e| !e.on_bound(shape)).collect();
        if kept.len() <= k {
            return Err(format!(
                "a generator of {k} coordinates needs more than {k} examples whose estimates are inside the params' ranges, got {} of {}",
                kept.len(),
                fits.len()
            ));
        }
        let rows: Vec<Vec<f64>> = kept
            .iter()
            .map(|e| {
                let values = e.shape.iter().copied().chain([e.t0, e.snr]);
                params.iter().zip(values).map(|(p, v)| to_unbounded(p, v)).collect()
            })
            .collect();
        let n = rows.len() as f64;
        let mean: Vec<f64> = (0..k).map(|i| rows.iter().map(|r| r[i]).sum::<f64>() / n).collect();
        let mut covariance = vec![0.0; k * k];
        for r in &rows {
            for i in 0..k {
                for j in 0..k {
                    covariance[i * k + j] += (r[i] - mean[i]) * (r[j] - mean[j]) / n;
                }
            }
        }
        Ok(Generator { family: family.to_string(), params, mean, covariance, examples: kept.len() })
    }

    /// Draws `n` param vectors (shape params, t0, SNR), reproducibly by
    /// `seed`.
    pub fn sample_params(&self, n: usize, seed: u64) -> Result<Vec<Vec<f64>>, String> {
        let k = self.params.len();
        // A tiny ridge keeps the factorisation defined when estimates
        // coincide (e.g. a param pinned at a bound in every example).
        let mut cov = DMatrix::from_row_slice(k, k, &self.covariance);
        for i in 0..k {
            cov[(i, i)] += 1e-9;
        }
        let chol = cov.cholesky().ok_or("the generator's covariance is not positive definite")?;
        let l = chol.l();
        let mean = DVector::from_column_slice(&self.mean);
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        Ok((0..n)
            .map(|_| {
                let e = DVector::from_iterator(k, (0..k).map(|_| StandardNormal.sample(&mut rng)));
                let z = &mean + &l * e;
                self.params.iter().zip(z.iter()).map(|(p, z)| from_unbounded(p, *z)).collect()
            })
            .collect())
    }

    /// The glitch class this generator draws.
    pub fn class(&self) -> Result<usize, String> {
        FAMILIES.iter().find(|f| f.scene == self.family).map(|f| f.class).ok_or_else(|| format!("unknown glitch family `{}`", self.family))
    }

    /// Draws `n` whitened glitches and their params (in the order of
    /// [`Generator::params`]), each at its drawn SNR.
    pub fn sample(&self, n: usize, seed: u64) -> Result<Draws, String> {
        let class = self.class()?;
        let draws = self.sample_params(n, seed)?;
        let signals = GlitchSignals::new().map_err(|e| e.to_string())?;
        let mut run = signals.bind();
        let mut phases = rand_pcg::Pcg64Mcg::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
        let mut rows = Vec::with_capacity(n);
        for d in &draws {
            let mut settings: Vec<(&str, f64)> = Vec::with_capacity(d.len() + 1);
            let value = |name: &str| self.params.iter().position(|p| p.name == name).map(|i| d[i]);
            for (p, v) in self.params.iter().zip(d) {
                match p.name.as_str() {
                    "snr" => {}
                    // The whistle scene's span is f_max - f_min.
                    "span" => settings.push(("f_max", value("f_min").unwrap_or(0.0) + v)),
                    name => settings.push((name, *v)),
                }
            }
            settings.push(("phi", phases.random_range(0.0..std::f64::consts::TAU)));
            let snr = value("snr").unwrap_or(1.0);
            let w = unit_signal(&mut run, class, &settings).map_err(|e| e.to_string())?;
            rows.push(w.into_iter().map(|v| snr * v).collect());
        }
        Ok(Draws { labels: vec![class; rows.len()], rows, names: self.params.iter().map(|p| p.name.clone()).collect(), params: draws })
    }

    /// The generator as JSON (the file `gwml generator fit` writes).
    pub fn to_json(&self) -> serde_json::Value {
        serde_json::json!({
            "family": self.family,
            "examples": self.examples,
            "coordinates": "logit((x - lo) / (hi - lo)) for bounded params, ln(x) for snr",
            "params": self.params.iter().map(|p| serde_json::json!({
                "name": p.name,
                "unit": p.unit,
                "range": [p.range.0, if p.range.1.is_finite() { serde_json::json!(p.range.1) } else { serde_json::Value::Null }],
            })).collect::<Vec<_>>(),
            "mean": self.mean,
            "covariance": self.covariance,
        })
    }

    /// Reads a generator written by [`Generator::to_json`].
    pub fn from_json(v: &serde_json::Value) -> Result<Generator, String> {
        let bad = |what: &str| format!("not a gwml generator file: {what}");
        let numbers = |key: &str| -> Result<Vec<f64>, String> {
            v[key]
                .as_array()
                .ok_or_else(|| bad(&format!("no `{key}` array")))?
                .iter()
                .map(|x| x.as_f64().ok_or_else(|| bad(&format!("`{key}` holds a non-number"))))
                .collect()
        };
        let family = v["family"].as_str().ok_or_else(|| bad("no `family`"))?.to_string();
        let params = v["params"]
            .as_array()
            .ok_or_else(|| bad("no `params`"))?
            .iter()
            .map(|p| {
                let lo = p["range"][0].as_f64().ok_or_else(|| bad("a param without a range"))?;
                let hi = p["range"][1].as_f64().unwrap_or(f64::INFINITY);
                let name = p["name"].as_str().ok_or_else(|| bad("a param without a name"))?.to_string();
                Ok(ShapeParam { name, unit: p["unit"].as_str().unwrap_or("").to_string(), range: (lo, hi) })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let (mean, covariance) = (numbers("mean")?, numbers("covariance")?);
        let k = params.len();
        if mean.len() != k || covariance.len() != k * k || mean.iter().chain(&covariance).any(|x| !x.is_finite()) {
            return Err(bad(&format!("expected {k} finite means and {} covariances", k * k)));
        }
        let examples = v["examples"].as_u64().unwrap_or(0) as usize;
        let g = Generator { family, params, mean, covariance, examples };
        g.class()?;
        Ok(g)
    }
}

/// Checks the generator's model (`lab/models/glitch/generator.gw`, one scene per family).
pub fn family_model() -> Result<Model, Error> {
    Model::from_source("lab/models/glitch/generator.gw", GENERATOR_SOURCE)
}

/// `gwml generator fit --kind parametric`: each example's shape params,
/// time and SNR by matched filtering, then the normal over them; prints
/// the examples' quantiles against the generator's.
pub fn fit_command(a: &GeneratorFitArgs, class: usize, examples: &[Vec<f64>], threads: usize) -> Result<(), String> {
    let family = family(class).map_err(|e| format!("error: {e}"))?;
    let model = family_model().map_err(render)?;
    let scene = model.scene(Some(family.scene)).map_err(render)?;
    let shape = shape_params(&scene).map_err(render)?;
    if examples.len() <= shape.len() + 2 {
        return Err(format!(
            "error: {} examples of {} are too few to fit a generator: need more than {}",
            examples.len(),
            GLITCH_CLASSES[class],
            shape.len() + 2
        ));
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| format!("error: {e}"))?;
    let bar = ProgressBar::new(examples.len() as u64);
    bar.set_style(
        ProgressStyle::with_template("fitting examples [{bar:30}] {pos}/{len}, {per_sec}, eta {eta}")
            .map_err(|e| format!("error: {e}"))?
            .progress_chars("=> "),
    );
    let start = Instant::now();
    let fits: Vec<ExampleFit> = pool
        .install(|| {
            examples
                .par_iter()
                .map_init(
                    || scene.bind(),
                    |run, x| {
                        let fit = fit_example(run, &shape, family.grid, x);
                        bar.inc(1);
                        fit
                    },
                )
                .collect::<Result<_, Error>>()
        })
        .map_err(render)?;
    bar.finish_and_clear();
    let g = Generator::fit(family.scene, &shape, &fits).map_err(|e| format!("error: {e}"))?;
    let text = serde_json::to_string_pretty(&g.to_json()).map_err(|e| format!("error: {e}"))?;
    std::fs::write(&a.out, text + "\n").map_err(|e| format!("error: cannot write {}: {e}", a.out.display()))?;
    println!(
        "fitted a {} generator to {} of {} examples in {:.1} s ({threads} threads; {} left out: an estimate on a range's bound); wrote {}",
        GLITCH_CLASSES[class],
        g.examples,
        fits.len(),
        start.elapsed().as_secs_f64(),
        fits.len() - g.examples,
        a.out.display()
    );
    // What the examples say against what the generator draws.
    let draws = g.sample_params(4000, 1).map_err(|e| format!("error: {e}"))?;
    println!("{:<14} {:>30} {:>30}", "param", "examples: median [5%, 95%]", "generator: median [5%, 95%]");
    for (i, p) in g.params.iter().enumerate() {
        let column = |xs: Vec<f64>| {
            let q = quantiles(&xs, &[0.5, 0.05, 0.95]);
            format!("{:.4} [{:.4}, {:.4}]", q[0], q[1], q[2])
        };
        let estimates = fits.iter().map(|e| e.shape.iter().copied().chain([e.t0, e.snr]).nth(i).unwrap_or(f64::NAN)).collect();
        println!("{:<14} {:>30} {:>30}", p.label(), column(estimates), column(draws.iter().map(|d| d[i]).collect()));
    }
    if let Some(path) = &a.plot {
        let (x, y) = (&g.params[0], &g.params[1]);
        let ex: Vec<(f64, f64)> = fits.iter().map(|e| (e.shape[0], e.shape.get(1).copied().unwrap_or(e.t0))).collect();
        let drawn: Vec<(f64, f64)> = draws.iter().take(fits.len().max(200)).map(|d| (d[0], d[1])).collect();
        let title = format!("{} generator: {} examples and draws", GLITCH_CLASSES[class], fits.len());
        scatter_plot(path, &title, &x.label(), &y.label(), &[("examples (fitted)", &ex), ("generator draws", &drawn)])?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A whitened blip of the given params at SNR `snr` in unit white noise.
    fn noisy_blip(f0: f64, q: f64, t0: f64, snr: f64, seed: u64) -> Vec<f64> {
        let signals = GlitchSignals::new().unwrap();
        let mut run = signals.bind();
        let w = unit_signal(&mut run, 1, &[("f0", f0), ("q", q), ("t0", t0), ("phi", 1.0)]).unwrap();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
        w.iter().map(|v| snr * v + Distribution::<f64>::sample(&StandardNormal, &mut rng)).collect()
    }

    #[test]
    fn one_loud_blip_is_recovered() {
        let model = family_model().unwrap();
        let scene = model.scene(Some("blip")).unwrap();
        let mut run = scene.bind();
        let params = shape_params(&scene).unwrap();
        assert_eq!(params.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(), ["f0", "q"]);
        let fit = fit_example(&mut run, &params, FAMILIES[0].grid, &noisy_blip(173.0, 4.2, 0.61, 40.0, 5)).unwrap();
        assert!((fit.shape[0] / 173.0 - 1.0).abs() < 0.03, "f0 {}", fit.shape[0]);
        assert!((fit.shape[1] / 4.2 - 1.0).abs() < 0.15, "q {}", fit.shape[1]);
        assert!((fit.t0 - 0.61).abs() < 0.002, "t0 {}", fit.t0);
        // The peak SNR of a matched template is the injected SNR plus noise
        // of unit variance, plus a little from maximising over the shape.
        assert!((fit.snr - 40.0).abs() < 3.0, "snr {}", fit.snr);
    }

    #[test]
    fn a_fitted_generator_reproduces_the_population() {
        // Blips with ln f0 ~ N(ln 120, 0.3²) and q ~ N(4, 0.5²), SNR 30-50.
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let model = family_model().unwrap();
        let scene = model.scene(Some("blip")).unwrap();
        let mut run = scene.bind();
        let params = shape_params(&scene).unwrap();
        let mut fits = Vec::new();
        let mut truth = Vec::new();
        for i in 0..40 {
            let ln_f0 = 120f64.ln() + 0.3 * Distribution::<f64>::sample(&StandardNormal, &mut rng);
            let q = 4.0 + 0.5 * Distribution::<f64>::sample(&StandardNormal, &mut rng);
            let x = noisy_blip(ln_f0.exp(), q, rng.random_range(0.3..0.7), rng.random_range(30.0..50.0), 100 + i);
            fits.push(fit_example(&mut run, &params, FAMILIES[0].grid, &x).unwrap());
            truth.push(ln_f0);
        }
        let g = Generator::fit("blip", &params, &fits).unwrap();
        let draws = g.sample_params(4000, 1).unwrap();
        let stats = |xs: &[f64]| {
            let m = xs.iter().sum::<f64>() / xs.len() as f64;
            (m, (xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / xs.len() as f64).sqrt())
        };
        let (m_true, s_true) = stats(&truth);
        let (m, s) = stats(&draws.iter().map(|d| d[0].ln()).collect::<Vec<_>>());
        assert!((m - m_true).abs() < 0.05, "mean ln f0 {m} vs the examples' {m_true}");
        assert!((s / s_true - 1.0).abs() < 0.2, "sd ln f0 {s} vs the examples' {s_true}");
        let (mq, sq) = stats(&draws.iter().map(|d| d[1]).collect::<Vec<_>>());
        assert!((mq - 4.0).abs() < 0.4 && sq < 1.2, "q {mq} ± {sq}");
        let (mt, _) = stats(&draws.iter().map(|d| d[2]).collect::<Vec<_>>());
        assert!((mt - 0.5).abs() < 0.05, "t0 {mt}");
        // Round trip through the file format, and reproducible sampling.
        let back = Generator::from_json(&serde_json::from_str(&g.to_json().to_string()).unwrap()).unwrap();
        assert_eq!(back, g);
        let Draws { rows, params: drawn, .. } = g.sample(3, 9).unwrap();
        assert_eq!((rows.len(), rows[0].len()), (3, SAMPLES));
        assert_eq!(g.sample(3, 9).unwrap().rows, rows);
        // Each row is the unit signal at its drawn SNR.
        for (row, d) in rows.iter().zip(&drawn) {
            let norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
            assert!((norm / d[3] - 1.0).abs() < 1e-9, "norm {norm} vs snr {}", d[3]);
        }
    }

    #[test]
    fn bad_families_and_files_are_errors() {
        assert!(family(5).unwrap_err().contains("Chirp is not one"));
        assert!(Generator::from_json(&serde_json::json!({"family": "blip"})).is_err());
        assert!(Generator::fit("blip", &[], &[]).is_err());
    }
}
