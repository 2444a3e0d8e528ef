//! Differential tests: the JIT kernels agree with the reference interpreter
//! (`gwml_compiler::kernels::interp`), on the examples and on random programs.

use gwml_compiler::ir::{MathMode, Precision};
use gwml_compiler::kernels::interp;
use gwml_compiler::Options;
use gwml_runtime::{Model, Value};
use proptest::prelude::*;

fn example(name: &str) -> String {
    std::fs::read_to_string(format!("{}/../examples/{name}", env!("CARGO_MANIFEST_DIR"))).expect("example exists")
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

#[test]
fn chirp_fit_jit_matches_interpreter() {
    let model = Model::from_source("chirp_fit.gw", &example("chirp_fit.gw")).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.param("mc", 29.0).unwrap().param("tc", 0.001).unwrap().param("phic", 0.2).unwrap();
    let out = run.value_and_grad().unwrap();
    let f = scene.ir();
    let d = f.inputs[0].default.clone().unwrap();
    let r = interp::interpret(f, &[29.0, 0.001, 0.2], &[d]);
    let loss = r.output(f, "loss").unwrap()[0].re;
    assert!(rel(out.scalar("loss").unwrap(), loss) < 1e-12, "{} vs {loss}", out.scalar("loss").unwrap());
    for p in ["mc", "tc", "phic"] {
        let g = r.grad(f, "loss", p).unwrap();
        assert!(rel(out.grad("loss", p).unwrap(), g) < 1e-10, "{p}: {} vs {g}", out.grad("loss", p).unwrap());
    }
    let fwd = run.forward().unwrap();
    assert!(rel(fwd.scalar("loss").unwrap(), loss) < 1e-12);
    assert_eq!(scene.gradient_kernel().unwrap().layout.loops, 1, "forward and adjoint fuse into one loop");
    assert!(matches!(fwd.value("loss"), Ok(Value::Real(_))));
}

/// A scene whose adjoint needs a reduction's result (max) inside a later
/// loop: exercises scratch buffers between loops, array outputs and complex outputs.
#[test]
fn multi_loop_scene_matches_interpreter() {
    let src = "scene s {
        grid t = times(rate: 64 Hz, duration: 1 s)
        param a = 1.3
        param w = 2.0
        let u = t / 1 s
        let x = sin(w * u * 6.0) * a
        let peak = max(x)
        output soft = sum(exp(x - peak)) + peak
        output z = complex(x, u) * 2.0i
        output c = sum(complex(x, a))
        grad soft wrt [a, w]
    }";
    let model = Model::from_source("s.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let out = scene.bind().value_and_grad().unwrap();
    let f = scene.ir();
    let r = interp::interpret(f, &[1.3, 2.0], &[]);
    assert!(rel(out.scalar("soft").unwrap(), r.output(f, "soft").unwrap()[0].re) < 1e-12);
    for p in ["a", "w"] {
        assert!(rel(out.grad("soft", p).unwrap(), r.grad(f, "soft", p).unwrap()) < 1e-10, "{p}");
    }
    let Ok(Value::ComplexArray(z)) = out.value("z") else { panic!("z is a complex array") };
    for (got, want) in z.iter().zip(r.output(f, "z").unwrap()) {
        assert!((got - want).norm() <= 1e-12 * want.norm().max(1.0));
    }
    let Ok(Value::Complex(c)) = out.value("c") else { panic!("c is a complex scalar") };
    assert!((c - r.output(f, "c").unwrap()[0]).norm() < 1e-10);
    assert!(scene.gradient_kernel().unwrap().layout.loops >= 2, "max's adjoint needs a second loop");
}

#[test]
fn runtime_errors_name_the_problem() {
    let src = "scene s {
        grid f = frequencies(from: 1 Hz, to: 4 Hz, step: 1 Hz)
        input d: real[f]
        param k = 2.0
        output y = sum(d * k)
    }";
    let model = Model::from_source("s.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    let e = run.forward().unwrap_err().to_string();
    assert!(e.contains("input `d` is not bound"), "{e}");
    let e = run.input_real("d", &[1.0, 2.0]).err().unwrap().to_string();
    assert!(e.contains("needs 4 values") && e.contains("2 were given"), "{e}");
    let e = run.input_real("d", &[1.0, f64::NAN, 3.0, 4.0]).err().unwrap().to_string();
    assert!(e.contains("non-finite") && e.contains("index 1"), "{e}");
    let e = run.input_real("dd", &[1.0; 4]).err().unwrap().to_string();
    assert!(e.contains("no input `dd`") && e.contains("did you mean `d`"), "{e}");
    let e = run.param("kk", 1.0).err().unwrap().to_string();
    assert!(e.contains("did you mean `k`"), "{e}");
    run.input_real("d", &[1.0, 2.0, 3.0, 4.0]).unwrap();
    assert_eq!(run.forward().unwrap().scalar("y").unwrap(), 20.0);
}

#[test]
fn f32_precision_runs_and_agrees() {
    let model = Model::from_source("chirp_fit.gw", &example("chirp_fit.gw")).unwrap();
    let s64 = model.scene(None).unwrap();
    let s32 = model.scene_with(None, Options { precision: Some(Precision::F32), ..Default::default() }).unwrap();
    let a = s64.bind().value_and_grad().unwrap();
    let b = s32.bind().value_and_grad().unwrap();
    assert!(rel(b.scalar("loss").unwrap(), a.scalar("loss").unwrap()) < 1e-3);
    assert!(rel(b.grad("loss", "phic").unwrap(), a.grad("loss", "phic").unwrap()) < 1e-2);
    // Mixed precision keeps the chirp's phase in f64: far closer than f32.
    let smx = model.scene_with(None, Options { precision: Some(Precision::Mixed), ..Default::default() }).unwrap();
    let m = smx.bind().value_and_grad().unwrap();
    // Measured: loss 4e-8 (f32 1.3e-7); d/dmc 5.6e-7 (f32 2.5e-5).
    assert!(rel(m.scalar("loss").unwrap(), a.scalar("loss").unwrap()) < 1e-6);
    for p in ["mc", "tc", "phic"] {
        assert!(rel(m.grad("loss", p).unwrap(), a.grad("loss", p).unwrap()) < 5e-6, "mixed dloss/d{p}");
    }
    assert!(
        rel(m.grad("loss", "mc").unwrap(), a.grad("loss", "mc").unwrap())
            < rel(b.grad("loss", "mc").unwrap(), a.grad("loss", "mc").unwrap())
    );
}

/// Random expression programs over a grid, built from safe compositions of
/// every builtin (domains kept valid so values are finite).
fn expr() -> impl Strategy<Value = String> {
    let leaf =
        prop_oneof![Just("x".to_string()), Just("y".to_string()), Just("u".to_string()), (-3.0f64..3.0).prop_map(|c| format!("({c:.3})"))];
    leaf.prop_recursive(4, 24, 2, |inner| {
        prop_oneof![
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("({a} + {b})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("({a} - {b})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("({a} * {b})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("({a} / (abs({b}) + 0.5))")),
            inner.clone().prop_map(|a| format!("(-{a})")),
            inner.clone().prop_map(|a| format!("sin({a})")),
            inner.clone().prop_map(|a| format!("cos({a})")),
            inner.clone().prop_map(|a| format!("tanh({a})")),
            inner.clone().prop_map(|a| format!("exp(tanh({a}))")),
            inner.clone().prop_map(|a| format!("log(abs({a}) + 1.0)")),
            inner.clone().prop_map(|a| format!("sqrt(abs({a}) + 0.1)")),
            inner.clone().prop_map(|a| format!("cbrt({a})")),
            inner.clone().prop_map(|a| format!("tan(tanh({a}))")),
            inner.clone().prop_map(|a| format!("(tanh({a}) + 2.0) ^ 1.5")),
            inner.clone().prop_map(|a| format!("({a}) ^ 3.0")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("atan2({a}, {b})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("min({a}, {b})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("max({a}, {b})")),
            (inner.clone(), inner.clone(), inner.clone()).prop_map(|(a, b, c)| format!("clamp({a}, {b}, {b} + abs({c}))")),
            (inner.clone(), inner.clone(), inner.clone()).prop_map(|(c, a, b)| format!("(if {c} > 0.0 {{ {a} }} else {{ {b} }})")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("abs2(complex({a}, {b}))")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("re(cis({a}) * complex({b}, 0.5))")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("im(exp(complex(tanh({a}), {b})))")),
            (inner.clone(), inner.clone()).prop_map(|(a, b)| format!("abs(complex({a}, {b}) / complex(1.0, {b}))")),
            inner.clone().prop_map(|a| format!("abs({a})")),
            inner.prop_map(|a| format!("mean({a} * u)")),
        ]
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, ..ProptestConfig::default() })]

    #[test]
    fn random_programs_jit_agrees_with_interpreter(e in expr(), x in -2.0f64..2.0, y in -2.0f64..2.0) {
        let src = format!("scene r {{
            grid g = frequencies(from: 1 Hz, to: 8 Hz, step: 0.5 Hz)
            param x = 0.0
            param y = 0.0
            let u = g / 4 Hz
            output out = sum({e} + 0.0 * u) + 0.0 * x
            grad out wrt [x, y]
        }}");
        let model = Model::from_source("r.gw", &src).map_err(|e| TestCaseError::fail(e.to_string()))?;
        let scene = model.scene(None).unwrap();
        let mut run = scene.bind();
        run.param("x", x).unwrap().param("y", y).unwrap();
        let f = scene.ir();
        let r = interp::interpret(f, &[x, y], &[]);
        let want = r.output(f, "out").unwrap()[0].re;
        prop_assume!(want.is_finite());
        if ["x", "y"].iter().any(|p| !r.grad(f, "out", p).unwrap().is_finite()) {
            // No finite derivative here (e.g. cbrt at 0): the run must say so.
            let e = run.value_and_grad().err().map(|e| e.to_string()).unwrap_or_default();
            prop_assert!(e.contains("gradient dout/d"), "non-finite gradient not reported: {e}");
            return Ok(());
        }
        let out = run.value_and_grad().map_err(|e| TestCaseError::fail(e.to_string()))?;
        let got = out.scalar("out").unwrap();
        prop_assert!((got - want).abs() <= 1e-9 * want.abs().max(1.0), "value {got} vs {want} for {e}");
        for p in ["x", "y"] {
            let (g, w) = (out.grad("out", p).unwrap(), r.grad(f, "out", p).unwrap());
            prop_assert!((g - w).abs() <= 1e-8 * w.abs().max(1.0), "d/d{p}: {g} vs {w} for {e}");
        }
        let fwd = run.forward().unwrap().scalar("out").unwrap();
        prop_assert!((fwd - want).abs() <= 1e-9 * want.abs().max(1.0));
    }
}

/// Specialisation folds what the grid fixes: in chirp_fit no pow is left per
/// frequency bin (only scalar pows of the chirp mass), and results agree
/// with the unspecialised IR run by the interpreter.
#[test]
fn grid_only_work_is_folded_into_tables() {
    use gwml_compiler::ir::{Op, Shape};
    let model = Model::from_source("chirp_fit.gw", &example("chirp_fit.gw")).unwrap();
    let scene = model.scene(None).unwrap();
    let f = scene.ir();
    assert!(!f.tables.is_empty());
    let per_bin_pows = f
        .insts
        .iter()
        .filter(|i| matches!(i.op, Op::PowConst(..) | Op::Binary(gwml_compiler::ir::BinOp::Pow, ..)) && i.ty.shape != Shape::Scalar)
        .count();
    assert_eq!(per_bin_pows, 0, "{f}");
    let plain = &scene.pipeline.adjoint;
    let d = f.inputs[0].default.clone().unwrap();
    let a = interp::interpret(plain, &[29.0, 0.001, 0.2], std::slice::from_ref(&d));
    let out = scene.bind().param("mc", 29.0).unwrap().param("tc", 0.001).unwrap().param("phic", 0.2).unwrap().value_and_grad().unwrap();
    assert!(rel(out.scalar("loss").unwrap(), a.output(plain, "loss").unwrap()[0].re) < 1e-12);
    assert!(rel(out.grad("loss", "mc").unwrap(), a.grad(plain, "loss", "mc").unwrap()) < 1e-9);
}

/// A branch removed at compile time leaves no adjoint behind that could turn
/// a finite gradient into NaN (here `log(0)` in the dead branch).
#[test]
fn folded_branch_leaves_no_nan_in_gradients() {
    let src = "scene s {
        grid f = frequencies(from: 1 Hz, to: 4 Hz, step: 1 Hz)
        param a = 0.0
        param b = 1.0
        output y = sum(b * f / 1 Hz + (if 1.0 > 2.0 { log(a) * f / 1 Hz } else { 0.0 }))
        grad y wrt [a, b]
    }";
    let model = Model::from_source("s.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let out = scene.bind().value_and_grad().unwrap();
    assert_eq!(out.grad("y", "a").unwrap(), 0.0);
    assert_eq!(out.grad("y", "b").unwrap(), 10.0);
}

/// Transforms run as library calls between loops: operands from inputs,
/// grid-only tables, broadcasts and computed arrays; results as outputs,
/// read by later loops, and transformed again.
#[test]
fn transforms_match_interpreter_in_both_precisions() {
    let src = "scene s {
        grid t = times(rate: 128 Hz, duration: 0.5 s)
        grid f = spectrum(t)
        input d: real[t] = sin(t * 40 Hz) * 1e-3
        param a = 1.3
        param w: Hz = 9.0
        let u = t / 1 s
        let x = a * sin(2.0 * pi * w * t) * exp(-((u - 0.25) / 0.05)^2)
        let X = rfft(x, f)
        let D = rfft(d, f)
        let G = rfft(exp(-u * 3.0), f)
        let C = rfft(a * 1 s / 1 s + 0.0 * u, f)
        let y = irfft(X * exp(-f / 20 Hz) + D * G / 1 s, t)
        output spectrum = X
        output filtered = y
        output back = irfft(rfft(y, f), t)
        output e = sum(abs2(X - D)) * 1 Hz * 1 Hz + re(sum(C)) * 1 Hz
        output r = sum(y * y * u)
        grad e wrt [a, w]
        grad r wrt [a, w]
    }";
    let model = Model::from_source("s.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let out = scene.bind().value_and_grad().unwrap();
    let f = scene.ir();
    let d: interp::Tensor = (0..64).map(|i| num_complex::Complex64::new((i as f64 / 128.0 * 40.0).sin() * 1e-3, 0.0)).collect();
    let r = interp::interpret(f, &[1.3, 9.0], &[d]);
    for o in ["e", "r"] {
        assert!(rel(out.scalar(o).unwrap(), r.output(f, o).unwrap()[0].re) < 1e-12, "{o}");
        for p in ["a", "w"] {
            assert!(rel(out.grad(o, p).unwrap(), r.grad(f, o, p).unwrap()) < 1e-10, "d{o}/d{p}");
        }
    }
    let Ok(Value::ComplexArray(x)) = out.value("spectrum") else { panic!("spectrum is a complex array") };
    assert_eq!(x.len(), 33);
    for (got, want) in x.iter().zip(r.output(f, "spectrum").unwrap()) {
        assert!((got - want).norm() <= 1e-14, "{got} vs {want}");
    }
    let (Ok(Value::RealArray(y)), Ok(Value::RealArray(back))) = (out.value("filtered"), out.value("back")) else { panic!("real arrays") };
    for ((got, want), b) in y.iter().zip(r.output(f, "filtered").unwrap()).zip(back) {
        assert!((got - want.re).abs() <= 1e-14, "{got} vs {want}");
        assert!((b - got).abs() <= 1e-14, "irfft(rfft(y)) = {b} != y = {got}");
    }
    let s32 = model.scene_with(None, Options { precision: Some(Precision::F32), ..Default::default() }).unwrap();
    let o32 = s32.bind().value_and_grad().unwrap();
    for o in ["e", "r"] {
        assert!(rel(o32.scalar(o).unwrap(), out.scalar(o).unwrap()) < 1e-4, "f32 {o}");
        for p in ["a", "w"] {
            assert!(rel(o32.grad(o, p).unwrap(), out.grad(o, p).unwrap()) < 1e-3, "f32 d{o}/d{p}");
        }
    }
}

/// The `math` knob: inline polynomials agree with libm (and the
/// interpreter) within their documented accuracy, on a scene that uses
/// every function the inline code covers, at arguments up to 1e6 rad.
#[test]
fn math_modes_agree_with_the_interpreter_within_their_accuracy() {
    let src = "scene s {
        grid g = frequencies(from: 1 Hz, to: 4000 Hz, step: 0.5 Hz)
        param a = 1.3
        param w = 0.37
        let u = g / 1 Hz
        let phase = w * u * u / 13.0
        output v = sum(sin(phase) * cos(a * u) + cbrt(u - 2000.5) * exp(-a * u / 3000.0) + log(u * a) * u ^ w) / 8000.0
        output z = sum(exp(complex(w / u, phase)) * cis(phase * 0.5) + (a * u) ^ (w + 0.5)) / 8000.0
        grad v wrt [a, w]
    }";
    let model = Model::from_source("s.gw", src).unwrap();
    let f = model.scene(None).unwrap().ir().clone();
    let r = interp::interpret(&f, &[1.3, 0.37], &[]);
    let want_v = r.output(&f, "v").unwrap()[0].re;
    let want_z = r.output(&f, "z").unwrap()[0];
    for (math, tol) in [(MathMode::Exact, 1e-13), (MathMode::Fast, 1e-10), (MathMode::Fastest, 1e-5)] {
        let scene = model.scene_with(None, Options { math: Some(math), ..Default::default() }).unwrap();
        let out = scene.bind().value_and_grad().unwrap();
        assert!(rel(out.scalar("v").unwrap(), want_v) < tol, "{math}: v {} vs {want_v}", out.scalar("v").unwrap());
        let Ok(Value::Complex(z)) = out.value("z") else { panic!("z is a complex scalar") };
        assert!((z - want_z).norm() < tol * want_z.norm(), "{math}: z {z} vs {want_z}");
        for p in ["a", "w"] {
            let (got, want) = (out.grad("v", p).unwrap(), r.grad(&f, "v", p).unwrap());
            assert!(rel(got, want) < 10.0 * tol, "{math}: dv/d{p} {got} vs {want}");
        }
    }
}

/// TaylorF2's `v = cbrt(π M f)` and `log v`: specialisation splits them into
/// a scalar per call and a table, leaving no per-bin cbrt or log, and the
/// kernel still agrees with the unspecialised IR (values and gradients).
#[test]
fn cbrt_and_log_of_scalar_times_grid_are_split() {
    use gwml_compiler::ir::{Op, Shape, UnOp};
    let src = "scene s {
        grid f = frequencies(from: 20 Hz, to: 500 Hz, step: 0.5 Hz)
        param m: Msun = 30.0
        param k = 0.7
        let v = cbrt(pi * m * MTSUN * f)
        let w = cbrt(-k * f / 1 Hz)
        output out = sum(log(v) * v ^ 2 + sin(k * log(v)) * w + log(k * f / 1 Hz))
        grad out wrt [m, k]
    }";
    let model = Model::from_source("s.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let f = scene.ir();
    let per_bin = f.insts.iter().filter(|i| matches!(i.op, Op::Unary(UnOp::Cbrt | UnOp::Log, _)) && i.ty.shape != Shape::Scalar).count();
    assert_eq!(per_bin, 0, "{f}");
    let plain = &scene.pipeline.adjoint;
    let r = interp::interpret(plain, &[30.0, 0.7], &[]);
    let out = scene.bind().value_and_grad().unwrap();
    assert!(rel(out.scalar("out").unwrap(), r.output(plain, "out").unwrap()[0].re) < 1e-12);
    for p in ["m", "k"] {
        assert!(rel(out.grad("out", p).unwrap(), r.grad(plain, "out", p).unwrap()) < 1e-10, "d/d{p}");
    }
}

/// Loops of arithmetic, comparisons, selects, `sqrt`/`abs` (and `sign`, its derivative),
/// `min`/`max`, integer powers and reductions are vectorised (f64x2 or
/// f32x4) with a scalar tail: on a grid of 61 points (a tail in both
/// widths) they agree with the interpreter, value and gradient, and the
/// kernel holds vector code.
#[test]
fn vectorised_loops_with_tails_match_interpreter() {
    let src = "scene v {
        grid t = times(rate: 61 Hz, duration: 1 s)
        input d: real[t] = 0.0
        param a = 0.7
        param b = -0.3
        let u = t / 1 s
        let h = a * u - b * d
        let r = max(h, 0.0) + min(h, 0.25) * abs(d - h)
        let s = if h > 0.1 { sqrt(abs(h) + 1.0) } else { h ^ 3.0 }
        output loss = sum(r * r + s) + max(s * b)
        grad loss wrt [a, b]
    }";
    let model = Model::from_source("v.gw", src).unwrap();
    let d: Vec<f64> = (0..61).map(|k| ((k * 37 % 61) as f64 / 30.0 - 1.0) * 0.8).collect();
    for (precision, lanes, tol) in [(Precision::F64, "f64x2", 1e-13), (Precision::F32, "f32x4", 2e-5)] {
        let scene = model.scene_with(None, Options { precision: Some(precision), ..Default::default() }).unwrap();
        assert!(scene.gradient_kernel().unwrap().clif.contains(lanes), "{precision:?}: no {lanes} code");
        let mut run = scene.bind();
        run.param("a", 0.7).unwrap().param("b", -0.3).unwrap().input_real("d", &d).unwrap();
        let out = run.value_and_grad().unwrap();
        let f = scene.ir();
        let input = d.iter().map(|&x| num_complex::Complex64::new(x, 0.0)).collect();
        let r = interp::interpret(f, &[0.7, -0.3], &[input]);
        let want = r.output(f, "loss").unwrap()[0].re;
        assert!(rel(out.scalar("loss").unwrap(), want) < tol, "{precision:?}: loss {} vs {want}", out.scalar("loss").unwrap());
        for p in ["a", "b"] {
            let (g, w) = (out.grad("loss", p).unwrap(), r.grad(f, "loss", p).unwrap());
            assert!((g - w).abs() <= tol * w.abs().max(1.0), "{precision:?}: d/d{p} {g} vs {w}");
        }
    }
}

/// Complex values in vectorised loops: interleaved complex inputs and
/// outputs are split into re/im vectors and stored back interleaved;
/// complex sums (f64) keep re and im accumulators. Grid of 61 points.
#[test]
fn vectorised_complex_loops_match_interpreter() {
    let src = "scene c {
        grid t = times(rate: 61 Hz, duration: 1 s)
        input z: complex[t] = 0.0
        param a = 0.7
        let u = t / 1 s
        let h = complex(a * u, 1.0 - u) * 2.0i
        output w = conj(z) * h - z / complex(1.0, a)
        output loss = sum(abs2(z - h) * a) + sum(re(w) * im(w))
        output s = sum(z * h)
        grad loss wrt [a]
    }";
    let model = Model::from_source("c.gw", src).unwrap();
    let z: Vec<num_complex::Complex64> =
        (0..61).map(|k| num_complex::Complex64::new((k * 37 % 61) as f64 / 30.0 - 1.0, (k * 11 % 61) as f64 / 61.0)).collect();
    for (precision, tol) in [(Precision::F64, 1e-13), (Precision::F32, 2e-5)] {
        let scene = model.scene_with(None, Options { precision: Some(precision), ..Default::default() }).unwrap();
        if precision == Precision::F64 {
            assert!(scene.gradient_kernel().unwrap().clif.contains("f64x2"), "no vector code");
        }
        let mut run = scene.bind();
        run.param("a", 0.7).unwrap().input_complex("z", &z).unwrap();
        let out = run.value_and_grad().unwrap();
        let f = scene.ir();
        let r = interp::interpret(f, &[0.7], std::slice::from_ref(&z));
        let want = r.output(f, "loss").unwrap()[0].re;
        assert!(rel(out.scalar("loss").unwrap(), want) < tol, "{precision:?}: loss {} vs {want}", out.scalar("loss").unwrap());
        let (g, w) = (out.grad("loss", "a").unwrap(), r.grad(f, "loss", "a").unwrap());
        assert!((g - w).abs() <= tol * w.abs().max(1.0), "{precision:?}: d/da {g} vs {w}");
        let Ok(Value::ComplexArray(got)) = out.value("w") else { panic!("w is a complex array") };
        for (k, (g, w)) in got.iter().zip(r.output(f, "w").unwrap()).enumerate() {
            assert!((g - w).norm() <= tol * w.norm().max(1.0), "{precision:?}: w[{k}] {g} vs {w}");
        }
        let Ok(Value::Complex(s)) = out.value("s") else { panic!("s is a complex scalar") };
        let want_s = r.output(f, "s").unwrap()[0];
        assert!((s - want_s).norm() <= tol * want_s.norm(), "{precision:?}: s {s} vs {want_s}");
    }
}

/// A loop of a few arithmetic operations runs two copies of its body per
/// vectorised iteration, each with its own accumulators (so the adds do
/// not wait on each other), and the scalar tail takes what is left: sums
/// and maxima over lengths around multiples of the chunk (4 in f64, 8 in
/// f32) agree with the interpreter.
#[test]
fn small_loops_run_two_copies_per_iteration() {
    for n in [3, 4, 5, 8, 9, 15, 16, 17, 61] {
        let src = format!(
            "scene c {{
                grid t = times(rate: {n} Hz, duration: 1 s)
                input x: real[t] = 0.0
                output s = sum(x * x - 0.25 * x)
                output m = max(x)
            }}"
        );
        let model = Model::from_source("c.gw", &src).unwrap();
        let x: Vec<f64> = (0..n).map(|k| ((k * 37 % 61) as f64 / 30.0 - 1.0) * 0.8).collect();
        let input = vec![x.iter().map(|&v| num_complex::Complex64::new(v, 0.0)).collect()];
        for (precision, lanes, chunk, tol) in [(Precision::F64, "f64x2", 4, 1e-15), (Precision::F32, "f32x4", 8, 1e-6)] {
            let scene = model.scene_with(None, Options { precision: Some(precision), ..Default::default() }).unwrap();
            let clif = &scene.forward_kernel().clif;
            // Grids shorter than a chunk run the scalar loop only.
            let copies = if n >= chunk { 2 } else { 0 };
            assert_eq!(clif.matches(&format!("load.{lanes}")).count(), copies, "{precision:?}, n = {n}\n{clif}");
            let mut run = scene.bind();
            run.input_real("x", &x).unwrap();
            let out = run.forward().unwrap();
            let f = scene.ir();
            let r = interp::interpret(f, &[], &input);
            for name in ["s", "m"] {
                let (got, want) = (out.scalar(name).unwrap(), r.output(f, name).unwrap()[0].re);
                assert!((got - want).abs() <= tol * want.abs().max(1.0), "{precision:?}, n = {n}: {name} {got} vs {want}");
            }
        }
    }
}

/// Runs `src` (input `x`, param `a` = 0.7) in each math mode: checks the
/// number of divisions left in its IR with `divisions_ok(mode, count)`, and
/// that every real output in `names` (array or scalar) agrees with
/// `exact`'s within 4 ulp.
fn check_quotients_in_math_modes(src: &str, names: &[&str], divisions_ok: impl Fn(MathMode, usize) -> bool) {
    let model = Model::from_source("c.gw", src).unwrap();
    let x: Vec<f64> = (0..61).map(|k| (k * 37 % 61) as f64 / 30.0 - 1.0).collect();
    let mut results: Vec<Vec<Vec<f64>>> = Vec::new();
    for math in [MathMode::Exact, MathMode::Fast, MathMode::Fastest] {
        let scene = model.scene_with(None, Options { math: Some(math), ..Default::default() }).unwrap();
        let ir = scene.ir().to_string();
        assert!(divisions_ok(math, ir.matches(" div ").count()), "{math:?}\n{ir}");
        let mut run = scene.bind();
        run.param("a", 0.7).unwrap().input_real("x", &x).unwrap();
        let out = run.forward().unwrap();
        results.push(
            names
                .iter()
                .map(|n| match out.value(n) {
                    Ok(Value::RealArray(v)) => v.clone(),
                    Ok(Value::Real(v)) => vec![*v],
                    _ => panic!("{n} is real"),
                })
                .collect(),
        );
    }
    for outputs in &results[1..] {
        for (name, (got, want)) in names.iter().zip(outputs.iter().zip(&results[0])) {
            for (k, (a, b)) in got.iter().zip(want).enumerate() {
                assert!((a - b).abs() <= 4.0 * f64::EPSILON * b.abs(), "{name}[{k}]: {a} vs exact {b}");
            }
        }
    }
}

/// In `fast` and `fastest` math a division by a grid-only array (a PSD) is
/// a multiplication by a table of its reciprocals, within an ulp or two of
/// the division `exact` keeps.
#[test]
fn fast_math_divides_by_grid_arrays_through_reciprocal_tables() {
    let src = "scene c {
        grid t = times(rate: 61 Hz, duration: 1 s)
        input x: real[t] = 0.0
        param a = 0.7
        let psd = 1.0 + (t / 1 s) ^ 2.0
        output w = (a * x) / psd
        output s = sum(x * x / psd)
    }";
    check_quotients_in_math_modes(src, &["w", "s"], |math, divisions| (divisions > 0) == (math == MathMode::Exact));
}

/// In `fast` and `fastest` math an array dividing two values is inverted
/// once per bin and the quotients are products; `exact` divides twice.
#[test]
fn fast_math_shares_one_reciprocal_between_divisions() {
    let src = "scene c {
        grid t = times(rate: 61 Hz, duration: 1 s)
        input x: real[t] = 0.0
        param a = 0.7
        let u = 1.0 + a * t / 1 s
        output p = x / u
        output q = (x * x) / u
    }";
    check_quotients_in_math_modes(src, &["p", "q"], |math, divisions| divisions == if math == MathMode::Exact { 2 } else { 1 });
}

/// Two outputs of the same array (merged by CSE) both hold it: they share
/// one buffer (before, only the last one was written and the other read
/// back as zeros).
#[test]
fn outputs_of_the_same_array_both_hold_it() {
    let src = "scene c {
        grid t = times(rate: 8 Hz, duration: 1 s)
        param a = 0.7
        output r = a * t / 1 s
        output s = sum(t) / 1 s
        output r2 = a * t / 1 s
    }";
    let scene = Model::from_source("c.gw", src).unwrap().scene(None).unwrap();
    let out = scene.bind().forward().unwrap();
    for name in ["r", "r2"] {
        let Ok(Value::RealArray(r)) = out.value(name) else { panic!("{name} is a real array") };
        let want: Vec<f64> = (0..8).map(|k| 0.7 * (k as f64 / 8.0)).collect();
        assert_eq!(r, &want, "{name}");
    }
    assert_eq!(out.scalar("s").unwrap(), 3.5);
}

/// `z · conj(z)` becomes `abs2 z` in the IR, and a complex value times a
/// real one scales both parts (two multiplications, not a full complex
/// product): in f64 both agree with the interpreter's complex arithmetic
/// exactly, in the vector loop and its scalar tail.
#[test]
fn abs2_and_real_factors_are_exact() {
    let src = "scene c {
        grid t = times(rate: 61 Hz, duration: 1 s)
        input z: complex[t] = 0.0
        param a = 0.7
        let u = a * t / 1 s
        output p = z * u
        output q = u * z
        output n = z * conj(z)
        output m = conj(z) * z
    }";
    let model = Model::from_source("c.gw", src).unwrap();
    let z: Vec<num_complex::Complex64> =
        (0..61).map(|k| num_complex::Complex64::new((k * 37 % 61) as f64 / 30.0 - 1.0, (k * 11 % 61) as f64 / 61.0 - 0.3)).collect();
    let scene = model.scene_with(None, Options { precision: Some(Precision::F64), ..Default::default() }).unwrap();
    let ir = scene.ir().to_string();
    assert_eq!(ir.matches("abs2").count(), 1, "{ir}");
    assert!(!ir.contains("conj"), "{ir}");
    let mut run = scene.bind();
    run.param("a", 0.7).unwrap().input_complex("z", &z).unwrap();
    let out = run.forward().unwrap();
    let f = scene.ir();
    let r = interp::interpret(f, &[0.7], std::slice::from_ref(&z));
    for name in ["p", "q", "n", "m"] {
        let Ok(Value::ComplexArray(got)) = out.value(name) else { panic!("{name} is a complex array") };
        let want = r.output(f, name).unwrap();
        assert_eq!(got.len(), 61);
        for (k, (g, w)) in got.iter().zip(&want).enumerate() {
            assert!(g.re == w.re && g.im == w.im, "{name}[{k}]: {g} vs interpreter {w}");
        }
    }
}

/// sin, cos and cis in vectorised f64 loops run the inline code on f64x2
/// and fall back to libm lane by lane outside its domain (|x| > 1.6e6):
/// every lane agrees with Rust's (glibc's) sin/cos within each math mode's
/// tolerance (1 ulp in `exact`), pairs that mix in- and out-of-domain
/// lanes included.
#[test]
fn vectorised_sincos_matches_libm_in_every_lane() {
    let src = "scene s {
        grid g = index(24)
        input x: real[g] = 0.0
        output sn = sin(x)
        output cs = cos(x)
        output z = cis(x)
    }";
    let halfpi = std::f64::consts::FRAC_PI_2;
    let x: Vec<f64> = vec![
        0.0,
        -0.0,
        1e-300,
        -3.7,
        12.5,
        1e5,
        halfpi * 7.0,
        -halfpi * 1e5,
        1.5e6,
        -1.6e6, // in domain
        2e6,
        0.3, // out, in (one vector)
        3e6,
        1e300,
        -1e300,
        -2.5, // out
        0.5,
        0.75,
        1e22,
        3.0,
        -1e-10,
        7e5,
        1234.5678,
        -98765.4321,
    ];
    let model = Model::from_source("s.gw", src).unwrap();
    for (math, tol) in [(MathMode::Exact, 2.3e-16), (MathMode::Fast, 1e-12), (MathMode::Fastest, 1e-7)] {
        let scene = model.scene_with(None, Options { math: Some(math), ..Default::default() }).unwrap();
        let clif = &scene.forward_kernel().clif;
        assert!(clif.contains("f64x2") && clif.contains("vall_true"), "{math:?}: sincos not vectorised");
        let mut run = scene.bind();
        run.input_real("x", &x).unwrap();
        let out = run.forward().unwrap();
        let (Ok(Value::RealArray(sn)), Ok(Value::RealArray(cs)), Ok(Value::ComplexArray(z))) =
            (out.value("sn"), out.value("cs"), out.value("z"))
        else {
            panic!("array outputs")
        };
        let close = |got: f64, want: f64| {
            (got.is_nan() && want.is_nan()) || got == want || (got - want).abs() <= tol * want.abs().max(f64::MIN_POSITIVE * 1e10)
        };
        for (k, &xk) in x.iter().enumerate() {
            let (s, c) = xk.sin_cos();
            assert!(close(sn[k], s) && close(z[k].im, s), "{math:?}: sin({xk:e}) = {} / {} vs {s}", sn[k], z[k].im);
            assert!(close(cs[k], c) && close(z[k].re, c), "{math:?}: cos({xk:e}) = {} / {} vs {c}", cs[k], z[k].re);
            assert!(sn[k].to_bits() != (-0.0f64).to_bits() || xk.to_bits() == (-0.0f64).to_bits(), "sign of zero");
        }
    }
}

/// In `fast` and `fastest`, exp is inline and vectorised too (f64x2):
/// every lane agrees with glibc's exp within the mode's tolerance, and
/// arguments outside the inline domain (|x| ≥ 708, up to the largest
/// finite result and down to subnormals and 0) take libm lane by lane.
#[test]
fn vectorised_exp_matches_libm_in_fast_modes() {
    let src = "scene e {
        grid g = index(13)
        input x: real[g] = 0.0
        output ex = exp(x)
        output ez = exp(complex(0.01 * x, x))
    }";
    let x: Vec<f64> = vec![0.0, -0.0, 1e-300, -3.7, 12.5, 707.0, -707.5, 709.0, 0.3, -745.0, -800.0, -1e3, 2.5];
    let model = Model::from_source("e.gw", src).unwrap();
    for (math, tol) in [(MathMode::Fast, 1e-12), (MathMode::Fastest, 1e-7)] {
        let scene = model.scene_with(None, Options { math: Some(math), ..Default::default() }).unwrap();
        let clif = &scene.forward_kernel().clif;
        assert!(clif.contains("f64x2") && clif.contains("vall_true"), "{math:?}: exp not vectorised");
        let mut run = scene.bind();
        run.input_real("x", &x).unwrap();
        let out = run.forward().unwrap();
        let (Ok(Value::RealArray(ex)), Ok(Value::ComplexArray(ez))) = (out.value("ex"), out.value("ez")) else { panic!("array outputs") };
        for (k, &xk) in x.iter().enumerate() {
            let want = xk.exp();
            let ok = ex[k] == want || (ex[k] - want).abs() <= tol * want;
            assert!(ok, "{math:?}: exp({xk:e}) = {:e} vs {want:e}", ex[k]);
            let wz = num_complex::Complex64::new(0.01 * xk, xk).exp();
            assert!((ez[k] - wz).norm() <= 2.0 * tol * wz.norm(), "{math:?}: exp(0.01x + ix) at {xk:e} = {} vs {wz}", ez[k]);
        }
    }
}

/// `exact` exp calls libm (`exp`, f32 `expf`) except where e^x rounds to
/// +0, which it answers inline: the same bits as libm on both sides of
/// that edge (−745.13 in f64, −103.97 in f32) and far below it.
#[test]
fn exact_exp_matches_libm_bit_for_bit_around_underflow() {
    let src = "scene e {
        grid g = index(16)
        input x: real[g] = 0.0
        output ex = exp(x)
    }";
    let f64_edge = [-708.5, -745.0, -745.13, -745.1332, -745.2, -745.2000001, -745.3, -800.0, -1e5, -1e300];
    let f32_edge = [-87.0, -103.0, -103.9, -103.97, -103.98, -104.0, -104.01, -110.0, -1e5, -1e30];
    let shared = [0.0, -1.0, 1.0, 80.0, 0.5, -3e38];
    let model = Model::from_source("e.gw", src).unwrap();
    for (precision, edge) in [(Precision::F64, f64_edge), (Precision::F32, f32_edge)] {
        let x: Vec<f64> = shared.iter().chain(&edge).copied().collect();
        let options = Options { precision: Some(precision), math: Some(MathMode::Exact), ..Default::default() };
        let scene = model.scene_with(None, options).unwrap();
        let mut run = scene.bind();
        run.input_real("x", &x).unwrap();
        let out = run.forward().unwrap();
        let Ok(Value::RealArray(ex)) = out.value("ex") else { panic!("a real array output") };
        for (k, &xk) in x.iter().enumerate() {
            let want = if precision == Precision::F32 { f64::from((xk as f32).exp()) } else { xk.exp() };
            assert_eq!(ex[k].to_bits(), want.to_bits(), "{precision:?}: exp({xk:e}) = {:e} vs libm {want:e}", ex[k]);
        }
    }
}

/// f32 rescaling (`passes::rescale`) on values far outside f32's range at
/// their true scale: strains of ~1e-25, a PSD of ~1e-46, their squares and
/// quotients, through logs, roots, fractional powers, min/max, atan2,
/// comparisons with constants and a select. The rescaled IR computes the
/// same values as the unrescaled one (run in f64 by the interpreter: only
/// exact power-of-two factors and `log`'s shift differ); every value it
/// stores at the defaults is within 2^-80..2^80; and the f32 kernel agrees
/// with f64 to f32's accuracy, value and gradient.
#[test]
fn f32_rescaling_keeps_tiny_strains_in_range_and_exact() {
    let src = "scene s {
        grid f = frequencies(from: 20 Hz, to: 500 Hz, step: 0.5 Hz)
        param a = 1.3
        let u = f / 100 Hz
        let x = a * 1e-23 * u ^ (-7.0 / 6.0)
        let p = 1e-46 * (u ^ (-4.0) + 2.0 + u ^ 2.0)
        let w = if x > 1e-23 { x ^ 1.5 } else { 3e-35 * cbrt(u) }
        output y = sum(x * x / p) + log(sum(x * x)) + sum(sqrt(p) * 1e23)
            + sum(cbrt(x) * 1e7 + max(x, 2e-23) / min(x, 1e-23) + atan2(x, p * 1e22))
            + sum(w) * 1e35
        grad y wrt [a]
    }";
    let model = Model::from_source("s.gw", src).unwrap();
    let s64 = model.scene(None).unwrap();
    let s32 = model.scene_with(None, Options { precision: Some(Precision::F32), ..Default::default() }).unwrap();
    let f = s32.ir();
    let plain = &s32.pipeline.adjoint;
    let r = interp::interpret(f, &[1.3], &[]);
    let r0 = interp::interpret(plain, &[1.3], &[]);
    let (y, y0) = (r.output(f, "y").unwrap()[0].re, r0.output(plain, "y").unwrap()[0].re);
    assert!(rel(y, y0) < 1e-12, "rescaled {y} vs plain {y0}");
    let (g, g0) = (r.grad(f, "y", "a").unwrap(), r0.grad(plain, "y", "a").unwrap());
    assert!(rel(g, g0) < 1e-12, "rescaled d/da {g} vs plain {g0}");
    let magnitudes = gwml_compiler::passes::precision::default_magnitudes(f).unwrap();
    for (i, m) in magnitudes.iter().enumerate() {
        let constant = matches!(f.insts[i].op, gwml_compiler::ir::Op::Const(_) | gwml_compiler::ir::Op::Broadcast(..));
        assert!(constant || *m == 0.0 || (2f64.powi(-80)..2f64.powi(80)).contains(m), "%{i} stored at {m:e}:\n{f}");
    }
    for t in &f.tables {
        let m = t.data.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!((2f64.powi(-80)..2f64.powi(80)).contains(&m), "a table stored at {m:e}");
    }
    let (a, b) = (s64.bind().value_and_grad().unwrap(), s32.bind().value_and_grad().unwrap());
    assert!(rel(b.scalar("y").unwrap(), a.scalar("y").unwrap()) < 1e-5, "f32 {} vs f64 {}", b.scalar("y").unwrap(), a.scalar("y").unwrap());
    assert!(rel(b.grad("y", "a").unwrap(), a.grad("y", "a").unwrap()) < 1e-4);
}

/// f32 loops with sin, cos, `cis`, exp and grid coordinates vectorise in
/// f32x4: each half is promoted to f64x2, computed by the inline f64 code
/// and rounded back (`Gen::math_in_f64`), and the scalar tail computes the
/// same way. Every
/// lane agrees with the f64 function rounded to f32 (within one f32 ulp,
/// 2^-23 relative, in `exact` and `fast`; `fastest`'s 1.3e-8 adds little),
/// including lanes out of the inline domain that take the libm path.
#[test]
fn f32_transcendental_loops_vectorise_through_f64_halves() {
    let src = "scene trig {
        precision: f32
        grid g = index(23)
        input x: real[g] = 0.0
        output sn = sin(x)
        output cs = cos(x)
        output z = cis(x)
        output sg = sin(x + g)
    }
    scene expo {
        precision: f32
        grid g = index(23)
        input x: real[g] = 0.0
        output e = exp(x / 40000.0)
    }
    scene power {
        precision: f32
        grid g = index(23)
        input x: real[g] = 0.0
        output p = (abs(x) + 1.0) ^ (x / 1e6)
    }";
    let x: Vec<f64> = vec![
        0.0,
        -3.7,
        12.5,
        1e5,
        2e6,
        0.3,
        3e6,
        -2.5,
        0.5,
        0.75,
        3.0,
        -1e-10,
        7e5,
        1234.5678,
        -98765.4321,
        1.5e6,
        42.0,
        -0.001,
        6.0,
        -6.0,
        100.0,
        -100.0,
        2.0,
    ];
    let model = Model::from_source("s.gw", src).unwrap();
    let vectorised = |clif: &str| clif.contains("f32x4") && clif.contains("fvdemote");
    let close = |got: f64, want: f64| (got - want).abs() <= 1.2e-7 * want.abs().max(1e-30);
    for math in [MathMode::Exact, MathMode::Fast, MathMode::Fastest] {
        let opts = Options { math: Some(math), ..Default::default() };
        let trig = model.scene_with(Some("trig"), opts.clone()).unwrap();
        assert!(vectorised(&trig.forward_kernel().clif), "{math:?}: sin/cos not vectorised through f64");
        let mut run = trig.bind();
        run.input_real("x", &x).unwrap();
        let out = run.forward().unwrap();
        let (Ok(Value::RealArray(sn)), Ok(Value::RealArray(cs)), Ok(Value::ComplexArray(z)), Ok(Value::RealArray(sg))) =
            (out.value("sn"), out.value("cs"), out.value("z"), out.value("sg"))
        else {
            panic!("array outputs")
        };
        for (k, &xk) in x.iter().enumerate() {
            // Grid coordinates (0, 1, ...) in every lane and the tail.
            let want = ((xk as f32 + k as f32) as f64).sin();
            assert!(close(sg[k], want), "{math:?}: sin(x + g) at {k}: {} vs {want}", sg[k]);
            // The kernel sees x rounded to f32.
            let xf = xk as f32 as f64;
            let (s, c) = xf.sin_cos();
            assert!(close(sn[k], s) && close(z[k].im, s), "{math:?}: sin({xf:e}) = {} / {} vs {s}", sn[k], z[k].im);
            assert!(close(cs[k], c) && close(z[k].re, c), "{math:?}: cos({xf:e}) = {} / {} vs {c}", cs[k], z[k].re);
        }
        // exp is inline in f64 only in fast/fastest; in exact it stays a
        // libm call. A two-argument pow stays f32 (and keeps its loop scalar).
        let [e, p] = ["expo", "power"].map(|name| {
            let scene = model.scene_with(Some(name), opts.clone()).unwrap();
            let expect = name == "expo" && math != MathMode::Exact;
            assert_eq!(vectorised(&scene.forward_kernel().clif), expect, "{math:?}: {name}");
            let mut run = scene.bind();
            run.input_real("x", &x).unwrap();
            let out = run.forward().unwrap();
            let Ok(Value::RealArray(v)) = out.value(&name[..1]) else { panic!("an array output") };
            v.clone()
        });
        for (k, &xk) in x.iter().enumerate() {
            let xf = xk as f32;
            let want = ((xf / 40000.0f32) as f64).exp();
            assert!(close(e[k], want), "{math:?}: exp({xk:e} / 40000) = {} vs {want}", e[k]);
            let want = ((xf.abs() + 1.0) as f64).powf((xf / 1e6f32) as f64);
            assert!((p[k] - want).abs() <= 1e-6 * want, "{math:?}: pow at {xk:e} = {} vs {want}", p[k]);
        }
    }
}

/// In mixed precision, an f32x4 loop splits the values it computes in f64
/// (phases and their sines) into two f64x2 halves: each half is computed,
/// stored and reloaded as f64 (the scratch array `ph` crosses from the
/// reduction's loop to the next), and rounded to f32 where an f32 value
/// uses it. Every lane, and the scalar tail (23 = 5 · 4 + 3), agrees with
/// that rule applied element by element: with x up to 1e5 the phase
/// computed in f32 would be off by ~1e-2 rad.
#[test]
fn mixed_loops_split_f64_values_into_f64x2_halves() {
    let src = "scene mix {
        precision: mixed
        grid g = index(23)
        input x: real[g] = 0.0
        input a: real[g] = 0.0
        param w = 3.0
        let ph = w * x + g
        let t = sum(a)
        output y = a * sin(ph)
        output z = a * cis(w * x)
        output p = ph
        output s = sum(a * cos(x))
        output u = sin(ph) * t
    }";
    let x: Vec<f64> = (0..23).map(|k| if k % 3 == 0 { 1e5 + 37.3 * k as f64 } else { -2.5 * k as f64 + 0.3 }).collect();
    let a: Vec<f64> = (0..23).map(|k| 0.5 + 0.1 * k as f64).collect();
    let model = Model::from_source("m.gw", src).unwrap();
    for math in [MathMode::Exact, MathMode::Fast] {
        let opts = Options { math: Some(math), ..Default::default() };
        let scene = model.scene_with(Some("mix"), opts).unwrap();
        let clif = &scene.forward_kernel().clif;
        assert!(clif.contains("f32x4") && clif.contains("f64x2"), "{math:?}: mixed loops not split-vectorised");
        let mut run = scene.bind();
        run.input_real("x", &x).unwrap().input_real("a", &a).unwrap();
        let out = run.forward().unwrap();
        let arrays = ["y", "p", "u"].map(|name| match out.value(name) {
            Ok(Value::RealArray(v)) => v.clone(),
            other => panic!("{name}: {other:?}"),
        });
        let [y, p, u] = &arrays;
        let Ok(Value::ComplexArray(z)) = out.value("z") else { panic!("z is a complex array") };
        let f32_close = |got: f64, want: f64| (got - want).abs() <= 1.2e-7 * want.abs().max(1e-30);
        // The kernel sees the inputs rounded to f32; f32 products of f64 values rounded to f32.
        let (xf, af): (Vec<f64>, Vec<f64>) = (x.iter().map(|&v| v as f32 as f64).collect(), a.iter().map(|&v| v as f32 as f64).collect());
        // Sums of the data alone (`t`, `s`) run in the scene's prelude,
        // once per bound input, in f64 on the inputs as given.
        let t: f64 = a.iter().sum::<f64>();
        let mut s = 0.0;
        for k in 0..23 {
            let ph = 3.0 * xf[k] + k as f64;
            let round = |v: f64| v as f32 as f64;
            assert!(f32_close(p[k], ph), "{math:?}: phase at {k}: {} vs {ph}", p[k]);
            let want = round(af[k] * round(ph.sin()));
            assert!(f32_close(y[k], want), "{math:?}: a·sin(ph) at {k}: {} vs {want}", y[k]);
            let want = round(round(ph.sin()) * t);
            assert!(f32_close(u[k], want), "{math:?}: sin(ph)·t at {k}: {} vs {want}", u[k]);
            let (sn, cs) = (3.0 * xf[k]).sin_cos();
            let (re, im) = (round(af[k] * round(cs)), round(af[k] * round(sn)));
            assert!(f32_close(z[k].re, re) && f32_close(z[k].im, im), "{math:?}: a·cis at {k}: {} vs {re} + {im}i", z[k]);
            s += a[k] * x[k].cos();
        }
        let got = out.scalar("s").unwrap();
        assert!((got - s).abs() <= 1e-12 * a.iter().sum::<f64>(), "{math:?}: sum {got} vs {s}");
    }
}

/// A loop whose selects test an interval condition (`t <= cut`) is split
/// where the condition changes, found by a binary search in the kernel,
/// and emitted once per side. Every comparison form, thresholds before,
/// on, between and after the grid's points (and NaN, false everywhere),
/// in f64 (f64x2 + tail), f32 and mixed (f32x4 + tail, whose sides start
/// at unaligned indices): outputs agree with the interpreter point by
/// point, the loss, a maximum, a complex sum and the gradient to rounding.
#[test]
fn loops_split_at_interval_conditions_match_interpreter() {
    let step = 1.0 / 61.0;
    let d: Vec<f64> = (0..61).map(|k| ((k * 37 % 61) as f64 / 30.0 - 1.0) * 0.8).collect();
    let input = vec![d.iter().map(|&x| num_complex::Complex64::new(x, 0.0)).collect()];
    // The last threshold is NaN (a = 0.7): false everywhere.
    for cond in ["t <= cut", "t < cut", "t >= cut", "t > cut", "cut > t", "cut <= t", "t <= cut * sqrt(a - 1.0)"] {
        let src = format!(
            "scene s {{
                grid t = times(rate: 61 Hz, duration: 1 s)
                input d: real[t] = 0.0
                param cut: s = 0.5
                param a = 0.7
                let u = t / 1 s
                let h = if {cond} {{ a * sin(7.0 * u) * u }} else {{ 0.0 }}
                output w = h
                output loss = sum((d - h) ^ 2.0) + sum(h * u)
                output top = max(h + u)
                output z = sum(h * cis(3.0 * u))
                grad loss wrt [a]
            }}"
        );
        let model = Model::from_source("s.gw", &src).unwrap();
        for (precision, tol) in [(Precision::F64, 1e-13), (Precision::F32, 2e-5), (Precision::Mixed, 2e-5)] {
            let scene = model.scene_with(None, Options { precision: Some(precision), ..Default::default() }).unwrap();
            for kernel in [scene.forward_kernel(), scene.gradient_kernel().unwrap()] {
                assert_eq!(kernel.layout.split_loops, 1, "{cond}, {precision:?}: loop not split");
            }
            // `sum(h * u)` and `z` are +0 where h is cut, and not summed
            // there; so is the part of `sum((d - h)^2)` beyond `d^2`, whose
            // sum the prelude computes (`passes::cutsum`); the gradient
            // kernel also skips the terms of d/da.
            assert_eq!(scene.forward_kernel().layout.sums_skipped, 3, "{cond}, {precision:?}");
            assert_eq!(scene.gradient_kernel().unwrap().layout.sums_skipped, 4, "{cond}, {precision:?}");
            for cut in [-1.0, 0.0, 17.0 * step, 0.5, 60.0 * step, 2.0] {
                let mut run = scene.bind();
                run.param("cut", cut).unwrap().param("a", 0.7).unwrap().input_real("d", &d).unwrap();
                let out = run.value_and_grad().unwrap();
                let f = scene.ir();
                let r = interp::interpret(f, &[cut, 0.7], &input);
                let case = format!("{cond}, cut {cut}, {precision:?}");
                let Ok(Value::RealArray(w)) = out.value("w") else { panic!("w is a real array") };
                for (k, (got, want)) in w.iter().zip(r.output(f, "w").unwrap()).enumerate() {
                    assert!((got - want.re).abs() <= tol, "{case}: w[{k}] = {got}, interpreter {}", want.re);
                    assert_eq!(*got == 0.0, want.re == 0.0, "{case}: w[{k}] is cut differently");
                }
                let want = r.output(f, "loss").unwrap()[0].re;
                assert!(rel(out.scalar("loss").unwrap(), want) < tol, "{case}: loss {} vs {want}", out.scalar("loss").unwrap());
                // A maximum and a complex sum, each combined across the two sides.
                let want = r.output(f, "top").unwrap()[0].re;
                assert!(rel(out.scalar("top").unwrap(), want) < tol, "{case}: top {} vs {want}", out.scalar("top").unwrap());
                let Ok(Value::Complex(z)) = out.value("z") else { panic!("z is a complex scalar") };
                let want = r.output(f, "z").unwrap()[0];
                assert!((z - want).norm() <= tol * want.norm().max(1.0), "{case}: z {z} vs {want}");
                let (g, w) = (out.grad("loss", "a").unwrap(), r.grad(f, "loss", "a").unwrap());
                assert!((g - w).abs() <= tol * w.abs().max(1.0), "{case}: d/da {g} vs {w}");
            }
        }
    }
}
