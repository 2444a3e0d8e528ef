//! Relative binning (`relative_binning: BINS`, issue #26): the
//! heterodyned TaylorF2 likelihood against the exact one at W1 and at the
//! extremes of `tests/extremes.rs` (BNS from 20 Hz, q = 1/50, spins ±0.9,
//! heavy from 10 Hz), on a signal in seeded Gaussian noise, in every
//! precision; bilby's acceptance check (|Δ ln L| ≤ 1e-3 at the fiducial,
//! ≤ 1 % of ln L's change from the fiducial for 100 draws around it);
//! the gradient against finite differences of the approximation itself;
//! the summary data computed once per bound input.

use gwml::compiler::ir::{Precision, RelativeBinning};
use gwml::compiler::Options;
use gwml::{Model, Scene, Value};
use gwml_runtime::noise::{colored_noise, rng};
use num_complex::Complex64 as C64;
use rand::Rng;

#[path = "common/taylorf2_scene.rs"]
mod taylorf2_scene;

/// The likelihood with params defaulting to the fiducial; the tests bind the data.
fn source(f_low: f64, fiducial: (f64, f64, f64)) -> String {
    taylorf2_scene::taylorf2_likelihood(f_low, fiducial, false)
}

/// One of the extremes: the source, its fiducial and the relative widths
/// of the draws around it in mc and q (ln L moves by up to a few hundred).
struct Case {
    name: &'static str,
    f_low: f64,
    fiducial: (f64, f64, f64),
    mc_width: f64,
    q_width: f64,
}

const CASES: [Case; 5] = [
    Case { name: "W1", f_low: 20.0, fiducial: (28.1, 0.8, 0.0), mc_width: 2e-3, q_width: 0.05 },
    Case { name: "BNS from 20 Hz", f_low: 20.0, fiducial: (1.2, 0.9, 0.0), mc_width: 2e-5, q_width: 0.05 },
    Case { name: "q = 1/50", f_low: 20.0, fiducial: (5.0, 0.02, 0.0), mc_width: 2e-4, q_width: 0.01 },
    Case { name: "spins ±0.9", f_low: 20.0, fiducial: (15.0, 0.5, 0.9), mc_width: 5e-4, q_width: 0.05 },
    Case { name: "heavy from 10 Hz", f_low: 10.0, fiducial: (80.0, 0.7, 0.0), mc_width: 5e-3, q_width: 0.05 },
];

fn compiled(model: &Model, precision: Precision, bins: Option<u32>) -> Scene {
    let relative_binning = Some(bins.map_or(RelativeBinning::Off, RelativeBinning::Bins));
    model.scene_with(None, Options { precision: Some(precision), relative_binning, ..Options::default() }).unwrap()
}

/// Params (mc, q, tc, phic).
type Point = [f64; 4];

fn bind<'s>(scene: &'s Scene, data: &[C64], p: Point) -> gwml::Run<'s> {
    let mut run = scene.bind();
    run.input_complex("d", data).unwrap();
    run.param("mc", p[0]).unwrap().param("q", p[1]).unwrap().param("tc", p[2]).unwrap().param("phic", p[3]).unwrap();
    run
}

/// The signal slightly off the fiducial (as a real event is: the fiducial
/// comes from a maximum-likelihood search) in seeded Gaussian noise.
fn data(model: &Model, case: &Case, seed: u64) -> Vec<C64> {
    let exact = compiled(model, Precision::F64, None);
    let (mc, q, _) = case.fiducial;
    let truth = [mc * (1.0 + 0.2 * case.mc_width), (q * 0.995).max(0.011), 2e-4, 0.3];
    let mut run = exact.bind();
    let zeros = vec![C64::new(0.0, 0.0); grid_len(case)];
    run.input_complex("d", &zeros).unwrap();
    run.param("mc", truth[0]).unwrap().param("q", truth[1]).unwrap().param("tc", truth[2]).unwrap().param("phic", truth[3]).unwrap();
    let out = run.forward().unwrap();
    let (Value::ComplexArray(h), Value::RealArray(psd)) = (out.value("strain").unwrap(), out.value("psd_out").unwrap()) else {
        panic!("strain and psd outputs")
    };
    let noise = colored_noise(psd, 0.125, seed).unwrap();
    h.iter().zip(noise).map(|(h, n)| h + n).collect()
}

fn grid_len(case: &Case) -> usize {
    ((1024.0 - case.f_low) / 0.125) as usize + 1
}

fn loss(scene: &Scene, data: &[C64], p: Point) -> f64 {
    bind(scene, data, p).forward().unwrap().scalar("loss").unwrap()
}

/// Worst |Δ ln L| at the fiducial, and worst ratio |Δ ln L| / |ln L(θ) − ln L(fiducial)|
/// over `draws` draws around it, of the relative-binning scene against f64 exact.
fn bilby_check(case: &Case, precision: Precision, bins: u32, draws: usize) -> (f64, f64) {
    let model = Model::from_source("w.gw", &source(case.f_low, case.fiducial)).unwrap();
    let d = data(&model, case, 7);
    let exact = compiled(&model, Precision::F64, None);
    let binned = compiled(&model, precision, Some(bins));
    let (mc, q, _) = case.fiducial;
    let fiducial = [mc, q, 0.0, 0.0];
    let at_fiducial = loss(&exact, &d, fiducial);
    let delta_fiducial = (loss(&binned, &d, fiducial) - at_fiducial).abs();
    let mut r = rng(11);
    let mut worst: f64 = 0.0;
    for _ in 0..draws {
        let p = [
            mc * (1.0 + case.mc_width * r.random_range(-1.0..1.0)),
            (q * (1.0 + case.q_width * r.random_range(-1.0..1.0))).clamp(0.011, 1.0),
            1e-3 * r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
        ];
        let truth = loss(&exact, &d, p);
        let delta = (loss(&binned, &d, p) - truth).abs();
        let ratio = delta / (truth - at_fiducial).abs().max(1e-300);
        if ratio > worst && std::env::var("RELBIN_DEBUG").is_ok() {
            println!("  {p:?}: delta {delta:e}, change {:e}", truth - at_fiducial);
        }
        worst = worst.max(ratio);
    }
    (delta_fiducial, worst)
}

#[test]
fn bilby_check_at_w1_and_the_extremes_in_f64() {
    for case in &CASES {
        let (at_fiducial, worst) = bilby_check(case, Precision::F64, 100, 100);
        println!("{}: |dlnL| at fiducial {at_fiducial:e}, worst ratio {worst:e}", case.name);
        assert!(at_fiducial <= 1e-3, "{}: |Δ ln L| = {at_fiducial:e} at the fiducial", case.name);
        assert!(worst <= 0.01, "{}: |Δ ln L| is {:.2} % of ln L's change from the fiducial", case.name, 100.0 * worst);
    }
}

/// Mixed precision keeps the phase in f64: the same check holds with 50
/// draws. f32 carries its own rounding (ln L of several thousand in f32
/// steps of ~1e-4 relative), so only the fiducial and a 1e-3 relative
/// bound are asked of it.
#[test]
fn mixed_and_f32_stay_close_to_f64_exact() {
    for case in &CASES {
        let (at_fiducial, worst) = bilby_check(case, Precision::Mixed, 100, 50);
        println!("{} mixed: |dlnL| at fiducial {at_fiducial:e}, worst ratio {worst:e}", case.name);
        assert!(at_fiducial <= 1e-3 && worst <= 0.01, "{} mixed: {at_fiducial:e}, {worst:e}", case.name);
        let model = Model::from_source("w.gw", &source(case.f_low, case.fiducial)).unwrap();
        let d = data(&model, case, 7);
        let (mc, q, _) = case.fiducial;
        let p = [mc * (1.0 + 0.5 * case.mc_width), q, 1e-4, 0.2];
        let exact = loss(&compiled(&model, Precision::F64, None), &d, p);
        let single = loss(&compiled(&model, Precision::F32, Some(100)), &d, p);
        println!("{} f32: relative {:e}", case.name, (single - exact).abs() / exact.abs());
        assert!((single - exact).abs() <= 1e-3 * exact.abs(), "{} f32: {single} vs {exact}", case.name);
    }
}

#[test]
fn gradient_is_the_gradient_of_the_binned_likelihood() {
    let case = &CASES[0];
    let model = Model::from_source("w.gw", &source(case.f_low, case.fiducial)).unwrap();
    let d = data(&model, case, 3);
    let scene = compiled(&model, Precision::F64, Some(50));
    let p: Point = [28.13, 0.79, 3e-4, 0.4];
    let out = bind(&scene, &d, p).value_and_grad().unwrap();
    for (i, (name, h)) in [("mc", 1e-6), ("q", 1e-6), ("tc", 1e-8), ("phic", 1e-5)].into_iter().enumerate() {
        let (mut up, mut down) = (p, p);
        up[i] += h;
        down[i] -= h;
        let fd = (loss(&scene, &d, up) - loss(&scene, &d, down)) / (2.0 * h);
        let g = out.grad("loss", name).unwrap();
        assert!((g - fd).abs() <= 1e-5 * g.abs().max(1.0), "dloss/d{name}: adjoint {g:e}, difference {fd:e}");
    }
    // Against the exact likelihood's gradient: close, not equal.
    let exact = bind(&compiled(&model, Precision::F64, None), &d, p).value_and_grad().unwrap();
    for name in ["mc", "q", "tc", "phic"] {
        let (a, b) = (out.grad("loss", name).unwrap(), exact.grad("loss", name).unwrap());
        assert!((a - b).abs() <= 1e-4 * b.abs().max(1.0), "dloss/d{name}: binned {a:e}, exact {b:e}");
    }
}

/// The summary data are computed once per bound input: calls at new
/// params reuse them, new data recompute them, and the results equal a
/// fresh run's on that data.
#[test]
fn summary_data_follow_the_bound_data_and_only_them() {
    let case = &CASES[0];
    let model = Model::from_source("w.gw", &source(case.f_low, case.fiducial)).unwrap();
    let scene = compiled(&model, Precision::F64, Some(100));
    let (d1, d2) = (data(&model, case, 1), data(&model, case, 2));
    let p: Point = [28.12, 0.79, 1e-4, 0.3];
    let mut run = bind(&scene, &d1, p);
    let first = run.value_and_grad().unwrap().scalar("loss").unwrap();
    run.param("mc", 28.11).unwrap();
    run.value_and_grad().unwrap();
    run.forward().unwrap();
    run.value_and_grad().unwrap();
    // One prelude per kernel (forward, gradient) for d1.
    assert_eq!(run.prelude_runs(), 2);
    run.param("mc", p[0]).unwrap();
    assert_eq!(run.value_and_grad().unwrap().scalar("loss").unwrap(), first);
    run.input_complex("d", &d2).unwrap();
    let second = run.value_and_grad().unwrap().scalar("loss").unwrap();
    assert_eq!(run.prelude_runs(), 3);
    let fresh = bind(&scene, &d2, p).value_and_grad().unwrap().scalar("loss").unwrap();
    assert_eq!(second, fresh);
    assert!((second - first).abs() > 1.0, "other noise, another likelihood");
    // The staged kernel reads the data term and the summary data from its prelude.
    let kernel = &scene.pipeline.kernel;
    let prelude = kernel.prelude.as_ref().expect("a prelude");
    assert!(prelude.outputs.len() >= 2, "{prelude}");
    assert!(kernel.main.to_string().contains("band_next"), "the per-call part works on the bins");
}

#[test]
fn the_setting_parses_and_bad_values_point_at_it() {
    let src = source(20.0, (10.0, 0.5, 0.0)).replace("scene w {", "scene w {\n    relative_binning: 60");
    let model = Model::from_source("w.gw", &src).unwrap();
    let scene = model.scene(None).unwrap();
    assert_eq!(scene.ir().relative_binning, RelativeBinning::Bins(60));
    let text = scene.pipeline.pruned.to_string();
    assert!(text.contains("bands 0: 61 of the 8033 points of f (relative binning"), "{text}");
    let bad = source(20.0, (10.0, 0.5, 0.0)).replace("scene w {", "scene w {\n    relative_binning: 0.5");
    let Err(err) = Model::from_source("w.gw", &bad) else { panic!("a fraction of a bin is refused") };
    let err = err.to_string();
    assert!(err.contains("unknown relative binning `0.5`") && err.contains("number of frequency bins"), "{err}");
}

/// A scene whose sums are not quadratic in one waveform is left exact.
#[test]
fn other_sums_are_left_exact() {
    let src =
        source(20.0, (10.0, 0.5, 0.0)).replace("output loss = 0.5 * inner(d - h, d - h, psd, spacing(f))", "output loss = sum(abs(d - h))");
    let model = Model::from_source("w.gw", &src).unwrap();
    let scene = compiled(&model, Precision::F64, Some(100));
    assert!(scene.pipeline.pruned.bands.is_empty(), "|d − h| is not quadratic in h");
}

/// The fiducial is a set of inputs, `fiducial.NAME`, at the params'
/// defaults unless bound: a caller sets it from a search. Binding it
/// recomputes the summary data (not per call), and at the fiducial the
/// binned likelihood is exact.
#[test]
fn the_fiducial_is_bound_like_data() {
    let case = &CASES[0];
    let model = Model::from_source("w.gw", &source(case.f_low, case.fiducial)).unwrap();
    let d = data(&model, case, 5);
    let exact = compiled(&model, Precision::F64, None);
    let binned = compiled(&model, Precision::F64, Some(30));
    let names: Vec<&str> = binned.ir().inputs.iter().map(|i| i.name.as_str()).collect();
    assert!(names.contains(&"fiducial.mc") && names.contains(&"fiducial.phic"), "{names:?}");
    let p: Point = [28.13, 0.78, 4e-4, 0.5];
    let truth = loss(&exact, &d, p);
    let mut run = bind(&binned, &d, p);
    let away = (run.forward().unwrap().scalar("loss").unwrap() - truth).abs();
    for (name, v) in ["mc", "q", "tc", "phic"].iter().zip(p) {
        run.input_real(&format!("fiducial.{name}"), &[v]).unwrap();
    }
    let at = (run.forward().unwrap().scalar("loss").unwrap() - truth).abs();
    assert_eq!(run.prelude_runs(), 2, "once for the data, once for the new fiducial");
    run.param("mc", 28.131).unwrap();
    run.forward().unwrap();
    assert_eq!(run.prelude_runs(), 2, "not per call");
    assert!(at < 1e-9 && away > 100.0 * at, "at the fiducial {at:e}, from the default fiducial {away:e}");
    // A fiducial whose waveform vanishes is an error naming it, not a NaN.
    run.input_real("fiducial.mc", &[0.0]).unwrap_or_else(|e| panic!("{e}"));
    let err = run.forward().unwrap_err().to_string();
    assert!(err.contains("fiducial"), "{err}");
}

/// `fiducial.NAME` takes a value with a unit like its param (`--set`).
#[test]
fn the_fiducial_is_set_with_units_like_its_param() {
    let case = &CASES[0];
    let model = Model::from_source("w.gw", &source(case.f_low, case.fiducial)).unwrap();
    let d = data(&model, case, 5);
    let binned = compiled(&model, Precision::F64, Some(30));
    let p: Point = [28.13, 0.78, 4e-4, 0.5];
    let mut a = bind(&binned, &d, p);
    a.input_real("fiducial.mc", &[28.13]).unwrap().input_real("fiducial.tc", &[4e-4]).unwrap();
    let mut b = bind(&binned, &d, p);
    b.param_quantity("fiducial.mc", "28.13 Msun").unwrap().param_quantity("fiducial.tc", "0.4 ms").unwrap();
    let (la, lb) = (a.forward().unwrap().scalar("loss").unwrap(), b.forward().unwrap().scalar("loss").unwrap());
    assert!((la - lb).abs() <= 1e-12 * la.abs(), "{la} vs {lb}");
    let Err(err) = b.param_quantity("fiducial.tc", "3 Msun") else { panic!("a mass is not a time") };
    let err = err.to_string();
    assert!(err.contains("dimension"), "{err}");
}
