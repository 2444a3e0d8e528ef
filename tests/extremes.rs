//! Numerical stability at the extremes (issue #6's list, the cases that
//! apply so far): equal mass ratio, a light system with ~1e4 rad of phase
//! in every math mode, a heavy system whose ISCO leaves few bins; gradients
//! at singular points; exp overflow and the stable activations at ±1000; a
//! 10^7-term reduction in f32; strains of 1e-23 (rescaled in f32) and
//! phases of 1e4 rad in f32 and mixed precision. Each compares with a high-precision reference
//! (or an exact limit) and asserts finite values or a clear error.

use gwml::compiler::ir::{MathMode, Precision};
use gwml::compiler::Options;
use gwml::{Model, Value};
use gwml_lab::tradeoff::mismatch;

const SOURCE: &str = "use std::taylorf2::{tf2_strain, tf2_psi_pn}
use std::detector::{inner}
use std::psd::{psd_aligo_zerodet_highpower}
scene w {
    grid f = frequencies(from: 20 Hz, to: 1024 Hz, step: 0.125 Hz)
    input d: complex[f] s = tf2_strain(f, 20 Msun, 0.9, 0.0, 0.0, 400 Mpc, 0 s, 0.0)
    param mc: Msun = 20.0 in 0.5..200.0
    param q = 1.0 in 0.01..1.0
    param tc: s = 0.0 in -0.1..0.1
    param phic = 0.0
    let psd = psd_aligo_zerodet_highpower(f)
    let h = tf2_strain(f, mc, q, 0.0, 0.0, 400 Mpc, tc, phic, pn_order: 7)
    output loss = 0.5 * inner(d - h, d - h, psd, spacing(f))
    output strain = h
    output psd_out = psd
    output phase_span = max(tf2_psi_pn(f, mc, q)) - min(tf2_psi_pn(f, mc, q))
    grad loss wrt [mc, q, tc, phic]
}";

fn loss_at(model: &Model, mc: f64, q: f64) -> f64 {
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.param("mc", mc).unwrap().param("q", q).unwrap();
    run.forward().unwrap().scalar("loss").unwrap()
}

/// q = 1 exactly: η = 1/4, where sqrt(1 − 4η) forms have an infinite
/// derivative. The gradient is finite, and zero (η(q) = q/(1+q)² is
/// stationary at q = 1): a second-order one-sided difference agrees to
/// within 1e-5 of the gradient's size nearby (q cannot exceed its bound of 1).
#[test]
fn equal_mass_ratio_gradient_is_finite_and_correct() {
    let model = Model::from_source("w.gw", SOURCE).unwrap();
    let scene = model.scene(None).unwrap();
    let out = scene.bind().value_and_grad().unwrap();
    for p in ["mc", "q", "tc", "phic"] {
        assert!(out.grad("loss", p).unwrap().is_finite(), "dloss/d{p} at q = 1");
    }
    let g = out.grad("loss", "q").unwrap();
    let mut near = scene.bind();
    near.param("q", 0.95).unwrap();
    let scale = near.value_and_grad().unwrap().grad("loss", "q").unwrap().abs();
    assert!(scale > 1.0, "|dloss/dq| at q = 0.95 is {scale}");
    let h = 1e-5;
    let fd = (3.0 * loss_at(&model, 20.0, 1.0) - 4.0 * loss_at(&model, 20.0, 1.0 - h) + loss_at(&model, 20.0, 1.0 - 2.0 * h)) / (2.0 * h);
    assert!((g - fd).abs() <= 1e-5 * scale, "dloss/dq at q = 1: adjoint {g}, difference {fd}, scale {scale}");
}

/// A light system (Mc = 1 Msun, q = 1/100): its PN phase spans 1.4e4 rad
/// from 20 Hz to 1024 Hz (about 1e5 from 10 Hz). The inline sin/cos/log of each math mode keep the
/// waveform's PSD-weighted mismatch against f64-exact within stated bounds
/// (measured: fast below 1e-18, fastest 5.4e-7, i.e. ~1e-3 rad of phase).
#[test]
fn light_system_with_1e4_rad_of_phase_in_every_math_mode() {
    let model = Model::from_source("w.gw", SOURCE).unwrap();
    let run_with = |math: MathMode| {
        let scene = model.scene_with(None, Options { math: Some(math), ..Default::default() }).unwrap();
        let mut run = scene.bind();
        run.param("mc", 1.0).unwrap().param("q", 0.01).unwrap();
        run.value_and_grad().unwrap()
    };
    let reference = run_with(MathMode::Exact);
    let span = reference.scalar("phase_span").unwrap();
    assert!(span > 1e4, "phase over the band {span} rad");
    let (Ok(Value::ComplexArray(h_ref)), Ok(Value::RealArray(psd))) = (reference.value("strain"), reference.value("psd_out")) else {
        panic!("array outputs")
    };
    for (math, bound) in [(MathMode::Fast, 1e-18), (MathMode::Fastest, 1e-6)] {
        let out = run_with(math);
        let Ok(Value::ComplexArray(h)) = out.value("strain") else { panic!("strain") };
        let m = mismatch(h, h_ref, Some(psd));
        assert!(m.is_finite() && m <= bound, "{math}: mismatch {m:e} > {bound:e}");
        for p in ["mc", "q", "tc", "phic"] {
            assert!(out.grad("loss", p).unwrap().is_finite(), "{math}: dloss/d{p}");
        }
    }
}

/// Heavy systems: at Mc = 100 Msun the ISCO (19 Hz) lies below the band, so
/// the strain is zero and the loss is the data's norm with zero gradient in
/// the waveform's params; at Mc = 45 Msun only bins below ~44 Hz remain and
/// the gradient still matches central differences.
#[test]
fn heavy_systems_with_few_or_no_bins_below_isco() {
    let model = Model::from_source("w.gw", SOURCE).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.param("mc", 100.0).unwrap();
    let out = run.value_and_grad().unwrap();
    let Ok(Value::ComplexArray(h)) = out.value("strain") else { panic!("strain") };
    assert!(h.iter().all(|z| *z == num_complex::Complex64::new(0.0, 0.0)));
    for p in ["mc", "q", "tc", "phic"] {
        assert_eq!(out.grad("loss", p).unwrap(), 0.0, "dloss/d{p} with no bins");
    }
    let mut run = scene.bind();
    run.param("mc", 45.0).unwrap().param("q", 0.8).unwrap();
    let out = run.value_and_grad().unwrap();
    let Ok(Value::ComplexArray(h)) = out.value("strain") else { panic!("strain") };
    let bins = h.iter().filter(|z| z.norm() > 0.0).count();
    assert!(bins > 0 && bins < 250, "{bins} bins below the ISCO");
    let g = out.grad("loss", "mc").unwrap();
    let step = 1e-6;
    let fd = (loss_at(&model, 45.0 + step, 0.8) - loss_at(&model, 45.0 - step, 0.8)) / (2.0 * step);
    assert!((g - fd).abs() <= 1e-5 * g.abs().max(fd.abs()), "dloss/dmc at 45 Msun: {g} vs {fd}");
}

/// Runs `src` (one scene) with its gradient kernel.
fn run_grad(src: &str, opts: Options) -> Result<gwml::Outputs, gwml::Error> {
    let model = Model::from_source("extreme.gw", src).unwrap();
    let scene = model.scene_with(None, opts).unwrap();
    let mut run = scene.bind();
    run.value_and_grad()
}

#[test]
fn gradients_at_singular_points_are_subgradients_or_clear_errors() {
    // abs and atan2 at 0 take the subgradient 0.
    let out =
        run_grad("scene s {\n param x = 0.0\n param y = 0.0\n output a = abs(x) + atan2(y, x)\n grad a wrt [x, y]\n}", Options::default())
            .unwrap();
    assert_eq!((out.grad("a", "x").unwrap(), out.grad("a", "y").unwrap()), (0.0, 0.0));
    // sqrt and log at 0 have no finite derivative: an error that names the gradient, not a NaN.
    for (f, want) in [("sqrt(x)", "inf"), ("sqrt(x * x)", "NaN")] {
        let e = run_grad(&format!("scene s {{\n param x = 0.0\n output a = {f}\n grad a wrt x\n}}"), Options::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("gradient da/dx is") && e.contains(want) && e.contains("does not exist"), "{f}: {e}");
    }
    let e = run_grad("scene s {\n param x = 0.0\n output a = log(x)\n grad a wrt x\n}", Options::default()).unwrap_err().to_string();
    assert!(e.contains("output `a` is not finite"), "{e}");
}

#[test]
fn exp_overflow_is_an_error_and_stable_forms_stay_finite_at_1000() {
    let e = run_grad("scene s {\n param x = 800.0\n output a = exp(x)\n grad a wrt x\n}", Options::default()).unwrap_err().to_string();
    assert!(e.contains("output `a` is not finite"), "{e}");
    // exp underflows to exactly 0 with a zero gradient.
    let out = run_grad("scene s {\n param x = -800.0\n output a = exp(x)\n grad a wrt x\n}", Options::default()).unwrap();
    assert_eq!((out.scalar("a").unwrap(), out.grad("a", "x").unwrap()), (0.0, 0.0));
    // softplus and sigmoid of ±1000: exact limits and gradients, in f64 and f32.
    for precision in [Precision::F64, Precision::F32, Precision::Mixed] {
        let opts = Options { precision: Some(precision), math: None, ..Default::default() };
        for (x, sp, dsp, sg) in [(1000.0, 1000.0, 1.0, 1.0), (-1000.0, 0.0, 0.0, 0.0)] {
            let src = format!(
                "use std::nn::{{softplus, sigmoid}}\nscene s {{\n param x = {x}\n output a = softplus(x)\n output b = sigmoid(x)\n grad a wrt x\n grad b wrt x\n}}"
            );
            let out = run_grad(&src, opts.clone()).unwrap();
            assert_eq!(out.scalar("a").unwrap(), sp, "softplus({x}) in {precision}");
            assert_eq!(out.grad("a", "x").unwrap(), dsp, "softplus'({x}) in {precision}");
            assert_eq!(out.scalar("b").unwrap(), sg, "sigmoid({x}) in {precision}");
            assert_eq!(out.grad("b", "x").unwrap(), 0.0, "sigmoid'({x}) in {precision}");
        }
    }
}

#[test]
fn a_reduction_of_1e7_terms_in_f32_keeps_relative_error_below_1e_6() {
    // Terms are computed in f32 and summed in f64 by the kernel: the sum of
    // 10^7 values of sin(0.001 i) + 1.1 against an f64 compensated reference.
    let n = 10_000_000usize;
    let src = format!("scene s {{\n grid g = index({n})\n param a = 0.001\n output s = sum(sin(a * g) + 1.1)\n}}");
    let model = Model::from_source("sum.gw", &src).unwrap();
    let (mut sum, mut c) = (0.0f64, 0.0f64);
    for i in 0..n {
        let x = (0.001 * i as f64).sin() + 1.1;
        let t = sum + x;
        c += if sum.abs() >= x.abs() { (sum - t) + x } else { (x - t) + sum };
        sum = t;
    }
    let reference = sum + c;
    for precision in [Precision::F64, Precision::F32, Precision::Mixed] {
        let scene = model.scene_with(None, Options { precision: Some(precision), math: None, ..Default::default() }).unwrap();
        let got = scene.bind().forward().unwrap().scalar("s").unwrap();
        let rel = ((got - reference) / reference).abs();
        assert!(rel <= 1e-6, "{precision}: {got} vs {reference} (relative error {rel:e})");
    }
}

/// Strains of 1e-23: at their true scale the PSD (~1e-46) and |d - h|²
/// are below f32's range, so f32 and mixed precision rescale every value
/// by a power of two fixed at compile time (`passes::rescale`); mixed also
/// keeps the phase in f64. Both agree with f64: the loss to 1e-4 (measured
/// 4.0e-5 in f32, where the ~1e3 rad phase carries f32's rounding, and
/// 2.3e-7 in mixed) and the gradient to 1e-3 of the gradient's size
/// (measured 3.1e-5 and 2.5e-7).
#[test]
fn strains_of_1e_minus_23_in_f32_are_rescaled_and_agree_with_f64() {
    let model = Model::from_source("w.gw", SOURCE).unwrap();
    let run_in = |precision: Precision| -> gwml::Outputs {
        let scene = model.scene_with(None, Options { precision: Some(precision), math: None, ..Default::default() }).unwrap();
        let mut run = scene.bind();
        run.param("mc", 20.05).unwrap().param("q", 0.85).unwrap();
        run.value_and_grad().unwrap()
    };
    let reference = run_in(Precision::F64);
    let params = ["mc", "q", "tc", "phic"];
    let g64: Vec<f64> = params.iter().map(|p| reference.grad("loss", p).unwrap()).collect();
    let norm = g64.iter().map(|g| g * g).sum::<f64>().sqrt();
    let l64 = reference.scalar("loss").unwrap();
    assert!(l64 > 1.0, "the loss is not trivially small: {l64}");
    for precision in [Precision::F32, Precision::Mixed] {
        let out = run_in(precision);
        let loss = out.scalar("loss").unwrap();
        assert!(((loss - l64) / l64).abs() <= 1e-4, "loss: {precision} {loss} vs f64 {l64}");
        for (p, g) in params.iter().zip(&g64) {
            let got = out.grad("loss", p).unwrap();
            assert!((got - g).abs() <= 1e-3 * norm, "dloss/d{p}: {precision} {got} vs f64 {g}");
        }
    }
}

/// Phases of 1.4e4 rad (Mc = 1 Msun, q = 1/100, 20-1024 Hz): in f32 the
/// phase itself carries errors of ~1e4 × 2^-24 rad and more from its PN
/// polynomial (measured 1.0e-2 rad at most: bounded here by 0.05); mixed
/// precision keeps the phase and cis(ψ) in f64 automatically, so they
/// agree with f64 to its rounding (measured 3e-11 rad: bounded by 1e-6).
#[test]
fn phases_of_1e4_rad_in_f32_are_bounded_and_mixed_keeps_them_in_f64() {
    let src = "use std::taylorf2::{tf2_psi_pn}
scene w {
    grid f = frequencies(from: 20 Hz, to: 1024 Hz, step: 0.125 Hz)
    param mc: Msun = 1.0
    param q = 0.01
    output z = cis(tf2_psi_pn(f, mc, q))
}";
    let model = Model::from_source("psi.gw", src).unwrap();
    let z_in = |precision: Precision| {
        let scene = model.scene_with(None, Options { precision: Some(precision), math: None, ..Default::default() }).unwrap();
        // The rule marks cis (and the phase under it) f64; f64 and f32 mark nothing.
        let wide = gwml::compiler::passes::precision::wide_values(scene.forward_ir());
        if precision == Precision::Mixed {
            let cis = scene
                .forward_ir()
                .insts
                .iter()
                .position(|i| matches!(i.op, gwml::compiler::ir::Op::Unary(gwml::compiler::ir::UnOp::Cis, _)));
            assert!(wide[cis.expect("a cis")], "cis is computed in f64");
        } else {
            assert!(wide.iter().all(|w| !w));
        }
        let Ok(Value::ComplexArray(z)) = scene.bind().forward().unwrap().value("z").cloned() else { panic!("z") };
        z
    };
    let reference = z_in(Precision::F64);
    let phase_error = |z: &[num_complex::Complex64]| z.iter().zip(&reference).map(|(a, b)| (a / b).arg().abs()).fold(0.0, f64::max);
    let (e32, emixed) = (phase_error(&z_in(Precision::F32)), phase_error(&z_in(Precision::Mixed)));
    assert!(e32 > 1e-4 && e32 <= 0.05, "f32 phase error {e32}");
    assert!(emixed <= 1e-6, "mixed phase error {emixed}");
}

/// A PSD at and beyond the band edges: the analytic aLIGO PSD evaluated on
/// the whole spectrum grid from 0 Hz (infinite or NaN there, ~1e-40 and
/// rising steeply toward 10 Hz), and a measured-style curve that is zero
/// outside 20-2000 Hz. `std::detector` masks those bins (`masked_div`):
/// sigma, the peak matched-filter SNR and their gradient are finite, equal
/// those with the PSD evaluated only where it is valid, and the gradient
/// matches central differences, in f64 and mixed precision.
#[test]
fn psds_that_are_infinite_or_zero_outside_the_band_are_masked() {
    let src = |psd: &str| {
        format!(
            "use std::detector::{{sigma, snr_series}}
use std::psd::{{psd_aligo_zerodet_highpower}}
use std::burst::{{sine_gaussian_fd}}
scene e {{
    grid t = times(rate: 4096 Hz, duration: 1 s)
    grid f = spectrum(t)
    param f0: Hz = 150.0
    let psd = {psd}
    let h = sine_gaussian_fd(f, 0.5 s, f0, 5.0, 1e-21)
    output s = sigma(h, psd, f, 20 Hz, 2000 Hz)
    output rho = max(snr_series(h, h, psd, t, f, 20 Hz, 2000 Hz))
    grad s wrt [f0]
}}"
        )
    };
    let valid = Model::from_source("valid.gw", &src("psd_aligo_zerodet_highpower(max(f, 10 Hz))")).unwrap();
    let reference = valid.scene(None).unwrap().bind().value_and_grad().unwrap();
    let (s_ref, g_ref) = (reference.scalar("s").unwrap(), reference.grad("s", "f0").unwrap());
    assert!(s_ref > 10.0 && g_ref.is_finite() && g_ref != 0.0);
    for psd in [
        "psd_aligo_zerodet_highpower(f)",
        "select(f < 20 Hz, 0.0 s, select(f > 2000 Hz, 0.0 s, psd_aligo_zerodet_highpower(max(f, 10 Hz))))",
    ] {
        let model = Model::from_source("edge.gw", &src(psd)).unwrap();
        for precision in [Precision::F64, Precision::Mixed] {
            let scene = model.scene_with(None, Options { precision: Some(precision), math: None, ..Default::default() }).unwrap();
            let out = scene.bind().value_and_grad().unwrap();
            let (s, g, rho) = (out.scalar("s").unwrap(), out.grad("s", "f0").unwrap(), out.scalar("rho").unwrap());
            let tol = if precision == Precision::F64 { 1e-12 } else { 1e-5 };
            assert!(
                (s / s_ref - 1.0).abs() <= tol && (rho / s_ref - 1.0).abs() <= 1e-5,
                "{psd} in {precision}: sigma {s}, rho {rho} vs {s_ref}"
            );
            assert!((g / g_ref - 1.0).abs() <= 100.0 * tol, "{psd} in {precision}: ds/df0 {g} vs {g_ref}");
        }
        // The masked division's gradient against central differences.
        let scene = model.scene(None).unwrap();
        let at = |f0: f64| {
            let mut run = scene.bind();
            run.param("f0", f0).unwrap();
            run.forward().unwrap().scalar("s").unwrap()
        };
        let h = 1e-4;
        let fd = (at(150.0 + h) - at(150.0 - h)) / (2.0 * h);
        let g = scene.bind().value_and_grad().unwrap().grad("s", "f0").unwrap();
        assert!((g - fd).abs() <= 1e-6 * g.abs(), "{psd}: ds/df0 {g} vs difference {fd}");
    }
}
