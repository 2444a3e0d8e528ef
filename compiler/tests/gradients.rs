//! Gradient tests: the adjoint of every builtin and operator, interpreted in
//! f64 from the optimized IR, against
//!
//! - central finite differences of the interpreted forward (pruned) IR, and
//! - the complex step `Im f(x + ih) / h`, evaluated by an independent walker
//!   of the pruned forward IR defined in this file (only for programs whose
//!   values are all real and whose ops are real-analytic).
//!
//! Every formula is wrapped in a tiny scene with params `x` and `y` and a
//! four-point grid `g` (1, 2, 3, 4 Hz).

use gwml_compiler::ir::{BinOp, Elem, Function, Op, Reduce, UnOp, Value};
use gwml_compiler::kernels::interp::{self, Tensor};
use gwml_compiler::{Program, ScenePipeline};
use num_complex::Complex64 as C64;

// ---------------------------------------------------------------------------
// Infrastructure
// ---------------------------------------------------------------------------

/// Relative tolerance of the finite-difference comparison.
const FD_TOL: f64 = 1e-6;
/// Relative step of the central finite differences.
const FD_STEP: f64 = 1e-6;
/// Relative tolerance of the complex-step comparison.
const CS_TOL: f64 = 1e-12;
/// The complex step.
const CS_H: f64 = 1e-30;

/// A tiny xorshift64* generator (fixed seeds, no dependency).
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Rng {
        Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1)
    }
    fn next_u64(&mut self) -> u64 {
        let mut x = self.0;
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        self.0 = x;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    /// Uniform in [0, 1).
    fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
    /// Uniform magnitude in [lo, hi) with a random sign.
    fn signed(&mut self, lo: f64, hi: f64) -> f64 {
        let m = self.uniform(lo, hi);
        if self.next_u64() & 1 == 0 {
            m
        } else {
            -m
        }
    }
}

/// The test scene around `formula`, after `prelude` (modules).
fn scene_source(prelude: &str, formula: &str) -> String {
    format!(
        "{prelude}\nscene t {{\n  grid g = frequencies(from: 1 Hz, to: 4 Hz, step: 1 Hz)\n  param x = 0.3\n  param y = 0.7\n  output out = {formula}\n  grad out wrt [x, y]\n}}\n"
    )
}

fn compile_source(name: &str, src: &str, scene: Option<&str>) -> ScenePipeline {
    let program = match Program::parse(name, src) {
        Ok(p) => p,
        Err(e) => panic!("`{name}` does not compile:\n{}\nsource:\n{src}", e.render(false)),
    };
    program.pipeline(scene, Default::default()).unwrap_or_else(|e| panic!("pipeline of `{name}`: {e}"))
}

fn compile_formula(prelude: &str, formula: &str) -> ScenePipeline {
    compile_source("formula.gw", &scene_source(prelude, formula), Some("t"))
}

/// The real scalar output `out` of `func` at `params`.
fn eval_output(func: &Function, params: &[f64], inputs: &[Tensor], output: &str) -> f64 {
    let r = interp::interpret(func, params, inputs);
    let v = r.output(func, output).unwrap_or_else(|| panic!("no output `{output}`"));
    assert_eq!(v.len(), 1, "output `{output}` is not a scalar");
    assert_eq!(v[0].im, 0.0, "output `{output}` is not real: {:?}", v[0]);
    v[0].re
}

/// The adjoint gradients d`output`/d`names[i]` interpreted from `func`.
fn adjoint_grads(func: &Function, params: &[f64], inputs: &[Tensor], output: &str, names: &[&str]) -> Vec<f64> {
    let r = interp::interpret(func, params, inputs);
    names.iter().map(|n| r.grad(func, output, n).unwrap_or_else(|| panic!("no gradient d{output}/d{n}"))).collect()
}

/// How to choose the finite-difference step.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Fd {
    /// `FD_STEP` relative to the param (absolute at 0).
    Relative,
    /// This absolute step for every param (near poles and branch cuts, where
    /// the step must stay well inside the smooth region).
    Step(f64),
}

impl Fd {
    fn step(self, x: f64) -> f64 {
        match self {
            Fd::Step(h) => h,
            Fd::Relative if x == 0.0 => FD_STEP,
            Fd::Relative => FD_STEP * x.abs(),
        }
    }
}

/// The complex step for a param at `x`: `CS_H`, relative for |x| > 1 so
/// that it never underflows next to x.
fn cs_step(x: f64) -> f64 {
    CS_H * x.abs().max(1.0)
}

/// Central finite difference of `output` with respect to param `k`.
fn central_difference(func: &Function, params: &[f64], inputs: &[Tensor], output: &str, k: usize, h: f64) -> f64 {
    let mut p = params.to_vec();
    p[k] = params[k] + h;
    let up = eval_output(func, &p, inputs, output);
    p[k] = params[k] - h;
    let down = eval_output(func, &p, inputs, output);
    // Divide by the step actually taken (x ± h is rounded).
    (up - down) / ((params[k] + h) - (params[k] - h))
}

/// `|a - b| <= rel * max(|a|, |b|) + floor`.
fn close(a: f64, b: f64, rel: f64, floor: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()) + floor
}

// ---------------------------------------------------------------------------
// The complex-step evaluator: an independent walk over the pruned forward IR
// that carries every real value as x + ih and applies each real operation's
// analytic extension.
// ---------------------------------------------------------------------------

fn cs_tanh(z: C64) -> C64 {
    if z.re.abs() < 1.0 {
        z.tanh()
    } else {
        // tanh z = s (1 - e) / (1 + e) with e = exp(-2 s z): no overflow for large |re z|.
        let s = z.re.signum();
        let e = (z * (-2.0 * s)).exp();
        (C64::new(1.0, 0.0) - e) / (C64::new(1.0, 0.0) + e) * s
    }
}

fn cs_cbrt(z: C64) -> C64 {
    // The odd real cube root, extended analytically off the real axis.
    if z.re < 0.0 {
        -(-z).cbrt()
    } else {
        z.cbrt()
    }
}

fn cs_atan(w: C64) -> C64 {
    // num-complex's atan goes through log(1 ± iw), which rounds a tiny w away.
    if w.norm() < 1e-4 {
        let w2 = w * w;
        w * (C64::new(1.0, 0.0) - w2 / 3.0 + w2 * w2 / 5.0 - w2 * w2 * w2 / 7.0)
    } else {
        w.atan()
    }
}

fn cs_atan2(y: C64, x: C64) -> C64 {
    // atan2(y, x) = atan2(y0, x0) + atan((y x0 - x y0) / (x x0 + y y0)): the
    // second term is the (analytic) angle between (x, y) and (x0, y0).
    let (x0, y0) = (x.re, y.re);
    C64::new(y0.atan2(x0), 0.0) + cs_atan((y * x0 - x * y0) / (x * x0 + y * y0))
}

fn cs_unary(u: UnOp, z: C64) -> Result<C64, String> {
    Ok(match u {
        UnOp::Neg => -z,
        UnOp::Sqrt => z.sqrt(),
        UnOp::Cbrt => cs_cbrt(z),
        UnOp::Exp => z.exp(),
        UnOp::Log => z.ln(),
        UnOp::Sin => z.sin(),
        UnOp::Cos => z.cos(),
        // num-complex's tan divides by cos(2a) + cosh(2b), which cancels near the poles.
        UnOp::Tan => z.sin() / z.cos(),
        UnOp::Tanh => cs_tanh(z),
        // Locally constant.
        UnOp::Sign => C64::new(gwml_compiler::ir::eval::sign(z.re), 0.0),
        other => return Err(format!("unary {other:?} is not real-analytic")),
    })
}

fn cs_binary(b: BinOp, x: C64, y: C64) -> Result<C64, String> {
    Ok(match b {
        BinOp::Add => x + y,
        BinOp::Sub => x - y,
        BinOp::Mul => x * y,
        BinOp::Div => x / y,
        BinOp::Pow => (y * x.ln()).exp(),
        BinOp::Atan2 => cs_atan2(x, y),
        other => return Err(format!("binary {other:?} is not real-analytic")),
    })
}

fn cs_pow_const(z: C64, c: f64) -> C64 {
    if c == c.trunc() && c.abs() <= 16.0 {
        z.powi(c as i32)
    } else {
        z.powf(c)
    }
}

/// Evaluates output `output` of the forward IR `func` with param `k`
/// perturbed by `ih`; returns (value, derivative).
fn complex_step(func: &Function, params: &[f64], output: &str, k: usize, h: f64) -> Result<(f64, f64), String> {
    let mut values: Vec<Vec<C64>> = Vec::with_capacity(func.insts.len());
    for (i, inst) in func.insts.iter().enumerate() {
        if inst.ty.elem != Elem::Real {
            return Err(format!("%{i} has element kind {:?}", inst.ty.elem));
        }
        let len = func.len_of(inst.ty.shape);
        let get = |v: Value, j: usize| -> C64 {
            let t = &values[v.index()];
            if t.len() == 1 {
                t[0]
            } else {
                t[j]
            }
        };
        let t: Vec<C64> = match inst.op {
            Op::Const(b) => vec![C64::new(f64::from_bits(b), 0.0)],
            Op::Param(p) => vec![C64::new(params[p as usize], if p as usize == k { h } else { 0.0 })],
            Op::GridCoord(g) => {
                let gr = &func.grids[g.0 as usize];
                (0..gr.len).map(|j| C64::new(gr.start + j as f64 * gr.step, 0.0)).collect()
            }
            Op::Unary(u, a) => (0..len).map(|j| cs_unary(u, get(a, j))).collect::<Result<_, _>>()?,
            Op::Binary(b, x, y) => (0..len).map(|j| cs_binary(b, get(x, j), get(y, j))).collect::<Result<_, _>>()?,
            Op::PowConst(a, c) => (0..len).map(|j| cs_pow_const(get(a, j), f64::from_bits(c))).collect(),
            Op::Broadcast(a, _) => vec![get(a, 0); len],
            Op::Reduce(Reduce::Sum, a) => vec![values[a.index()].iter().sum()],
            other => return Err(format!("{other:?} is not real-analytic")),
        };
        values.push(t);
    }
    let o = func.outputs.iter().find(|o| o.name == output).ok_or("no such output")?;
    let z = values[o.value.index()][0];
    Ok((z.re, z.im / h))
}

/// Whether to compare with the complex step as well as finite differences.
#[derive(Clone, Copy, PartialEq, Debug)]
enum Cs {
    /// The program is real-analytic: complex step must apply.
    Yes,
    /// Complex values, abs, min/max, select or comparisons: finite differences only.
    No,
}

/// Checks d out / d{x, y} of `formula` at every point.
fn check_formula(formula: &str, points: &[(f64, f64)], cs: Cs) {
    check_with(formula, "", points, cs, Fd::Relative);
}

fn check_with(formula: &str, prelude: &str, points: &[(f64, f64)], cs: Cs, fd: Fd) {
    let pl = compile_formula(prelude, formula);
    for &(x, y) in points {
        check_point(&pl, formula, &[x, y], &[], "out", &["x", "y"], cs, fd);
    }
}

/// Checks the gradients of `output` with respect to the params `names` (the
/// scene's params, in order) at `params`.
#[allow(clippy::too_many_arguments)]
fn check_point(pl: &ScenePipeline, what: &str, params: &[f64], inputs: &[Tensor], output: &str, names: &[&str], cs: Cs, fd: Fd) {
    let f = eval_output(&pl.pruned, params, inputs, output);
    assert!(f.is_finite(), "{what}: output {f} at {params:?} is not finite");
    let ad = adjoint_grads(&pl.optimized, params, inputs, output, names);
    // The unsimplified adjoint IR must agree with the optimized one.
    let ad_raw = adjoint_grads(&pl.adjoint, params, inputs, output, names);
    // And the optimized IR must compute the same output.
    let f_opt = eval_output(&pl.optimized, params, inputs, output);
    assert!(close(f, f_opt, 1e-13, 0.0), "{what}: optimized output {f_opt} != pruned output {f} at {params:?}");
    for (k, name) in names.iter().enumerate() {
        let g = ad[k];
        assert!(g.is_finite(), "{what}: adjoint d{output}/d{name} = {g} at {params:?} is not finite");
        assert!(
            close(g, ad_raw[k], 1e-13, 0.0),
            "{what}: optimized d{output}/d{name} = {g} but unsimplified adjoint gives {} at {params:?}",
            ad_raw[k]
        );
        // Finite differences. The floor allows for rounding in f(x ± h).
        let h = fd.step(params[k]);
        let fd = central_difference(&pl.pruned, params, inputs, output, k, h);
        assert!(fd.is_finite(), "{what}: finite difference d{output}/d{name} = {fd} at {params:?} is not finite");
        let floor = 1e-9 * f.abs() / params[k].abs().max(1.0) + 8.0 * f64::EPSILON * f.abs() / h;
        assert!(
            close(g, fd, FD_TOL, floor),
            "{what}: d{output}/d{name} at {params:?}: adjoint {g:e}, finite difference {fd:e} (rel. error {:e})",
            (g - fd).abs() / g.abs().max(fd.abs())
        );
        if cs == Cs::Yes {
            let (v, d) = complex_step(&pl.pruned, params, output, k, cs_step(params[k]))
                .unwrap_or_else(|e| panic!("{what}: complex step does not apply: {e}"));
            assert!(close(v, f, 1e-13, 0.0), "{what}: complex-step value {v} != interpreted value {f} at {params:?}");
            assert!(d.is_finite(), "{what}: complex-step d{output}/d{name} = {d} at {params:?} is not finite");
            let floor = 1e-15 * f.abs().max(1e-300) / params[k].abs().max(1.0);
            assert!(
                close(g, d, CS_TOL, floor),
                "{what}: d{output}/d{name} at {params:?}: adjoint {g:e}, complex step {d:e} (rel. error {:e})",
                (g - d).abs() / g.abs().max(d.abs())
            );
        }
    }
}

/// `n` random points with x drawn by `fx` and y by `fy`.
fn random_points(seed: u64, n: usize, mut fx: impl FnMut(&mut Rng) -> f64, mut fy: impl FnMut(&mut Rng) -> f64) -> Vec<(f64, f64)> {
    let mut rng = Rng::new(seed);
    (0..n).map(|_| (fx(&mut rng), fy(&mut rng))).collect()
}

/// 24 random points with x and y of either sign, magnitudes in [0.1, 2].
fn signed_points(seed: u64) -> Vec<(f64, f64)> {
    random_points(seed, 24, |r| r.signed(0.1, 2.0), |r| r.signed(0.1, 2.0))
}

/// 24 random points with x and y in [0.1, 3].
fn positive_points(seed: u64) -> Vec<(f64, f64)> {
    random_points(seed, 24, |r| r.uniform(0.1, 3.0), |r| r.uniform(0.1, 3.0))
}

// ---------------------------------------------------------------------------
// Sanity of the harness itself
// ---------------------------------------------------------------------------

#[test]
fn harness_complex_step_matches_known_derivatives() {
    let pl = compile_formula("", "sin(x) * exp(y) + atan2(y, x) + cbrt(-x) + tanh(40.0 * y)");
    let (x, y) = (0.4_f64, -0.3_f64);
    let (v, dx) = complex_step(&pl.pruned, &[x, y], "out", 0, CS_H).unwrap();
    let (_, dy) = complex_step(&pl.pruned, &[x, y], "out", 1, CS_H).unwrap();
    let r = x * x + y * y;
    let want_dx = x.cos() * y.exp() - y / r - (1.0 / 3.0) * x.powf(-2.0 / 3.0);
    let want_dy = x.sin() * y.exp() + x / r + 40.0 / (40.0 * y).cosh().powi(2);
    assert!(close(v, x.sin() * y.exp() + y.atan2(x) + (-x).cbrt() + (40.0 * y).tanh(), 1e-15, 0.0));
    assert!(close(dx, want_dx, 1e-14, 0.0), "{dx} vs {want_dx}");
    assert!(close(dy, want_dy, 1e-14, 0.0), "{dy} vs {want_dy}");
    // And the complex step refuses non-analytic programs.
    for f in ["abs(x)", "max(x, y)", "if x > y { x } else { y }", "re(complex(x, y))", "max(x * (g / 1 Hz))"] {
        let pl = compile_formula("", f);
        assert!(complex_step(&pl.pruned, &[0.3, 0.7], "out", 0, CS_H).is_err(), "{f}");
    }
}

#[test]
fn harness_rng_is_deterministic_and_uniform() {
    let mut a = Rng::new(7);
    let mut b = Rng::new(7);
    let xs: Vec<f64> = (0..1000).map(|_| a.unit()).collect();
    assert!(xs.iter().all(|&x| (0.0..1.0).contains(&x)));
    assert_eq!(xs[999], (0..1000).map(|_| b.unit()).last().unwrap());
    let mean = xs.iter().sum::<f64>() / xs.len() as f64;
    assert!((mean - 0.5).abs() < 0.05, "{mean}");
}

// ---------------------------------------------------------------------------
// Arithmetic operators
// ---------------------------------------------------------------------------

#[test]
fn grad_add_and_sub() {
    let pts = signed_points(1);
    check_formula("x + y", &pts, Cs::Yes);
    check_formula("x - y", &pts, Cs::Yes);
    check_formula("x * x - y + 3.0 - x * y", &pts, Cs::Yes);
    check_formula("(x + y) - (x - y) + x", &pts, Cs::Yes);
}

#[test]
fn grad_mul() {
    let pts = signed_points(2);
    check_formula("x * y", &pts, Cs::Yes);
    check_formula("x * x * x * y", &pts, Cs::Yes);
    check_formula("2.5 * x * (y * -3.0)", &pts, Cs::Yes);
}

#[test]
fn grad_div() {
    let pts = signed_points(3);
    check_formula("x / y", &pts, Cs::Yes);
    check_formula("1.0 / x", &pts, Cs::Yes);
    check_formula("(x * y) / (x + 3.0)", &pts, Cs::Yes);
    check_formula("x / (y * y)", &pts, Cs::Yes);
}

#[test]
fn grad_unary_neg() {
    let pts = signed_points(4);
    check_formula("-x", &pts, Cs::Yes);
    check_formula("-(x * y)", &pts, Cs::Yes);
    check_formula("-(-x) * -y", &pts, Cs::Yes);
}

#[test]
fn grad_pow_integer_exponents() {
    let pts = signed_points(5);
    for e in ["2.0", "3.0", "5.0", "1.0", "0.0", "(-1.0)", "(-2.0)", "(-3.0)"] {
        check_formula(&format!("x ^ {e} + y ^ {e}"), &pts, Cs::Yes);
    }
}

#[test]
fn grad_pow_fractional_exponents() {
    let pts = positive_points(6);
    for e in ["0.5", "2.5", "(1.0 / 3.0)", "(-0.5)", "(-5.0 / 3.0)", "(-7.0 / 6.0)", "17.5", "(-1.0 / 7.0)"] {
        check_formula(&format!("x ^ {e} * y"), &pts, Cs::Yes);
    }
    // As in the chirp phase: a scaled base and a negative fractional power.
    check_formula("3.0 / 128.0 * (pi * x * y) ^ (-5.0 / 3.0)", &pts, Cs::Yes);
}

#[test]
fn grad_pow_large_integer_exponent_uses_powf() {
    // |c| > 16 goes through powf in the evaluator: check both sides of it.
    let pts = random_points(7, 16, |r| r.uniform(0.5, 1.5), |r| r.uniform(0.5, 1.5));
    check_formula("x ^ 16.0 * y", &pts, Cs::Yes);
    check_formula("x ^ 17.0 * y", &pts, Cs::Yes);
    check_formula("x ^ (-20.0) * y", &pts, Cs::Yes);
}

#[test]
fn grad_pow_variable_exponent() {
    let pts = positive_points(8);
    check_formula("x ^ y", &pts, Cs::Yes);
    check_formula("(x + 1.0) ^ (y * x)", &pts, Cs::Yes);
    check_formula("2.0 ^ x + y ^ 3.5", &pts, Cs::Yes);
}

// ---------------------------------------------------------------------------
// Elementary functions
// ---------------------------------------------------------------------------

#[test]
fn grad_sqrt() {
    check_formula("sqrt(x) * sqrt(x * y + 1.0)", &positive_points(10), Cs::Yes);
}

#[test]
fn grad_sqrt_near_zero() {
    check_formula("sqrt(x) + sqrt(y)", &[(1e-8, 1e-12), (1e-8, 1e-8), (2e-8, 3.0)], Cs::Yes);
    // Below the complex step's reach (h = 1e-30 is not small next to x).
    check_formula("sqrt(x) * sqrt(y)", &[(1e-300, 2.0), (1e-200, 1e-250)], Cs::No);
}

#[test]
fn grad_cbrt() {
    // cbrt is odd: defined and smooth for negative arguments too.
    check_formula("cbrt(x) * y + cbrt(x * y - 0.05)", &signed_points(11), Cs::Yes);
    check_formula("cbrt(x) + cbrt(y)", &[(1e-9, -1e-9), (-8.0, 27.0), (-1e-20, 1e300)], Cs::Yes);
    check_formula("cbrt(x) + cbrt(y)", &[(-1e-300, 1e-290)], Cs::No);
}

#[test]
fn grad_exp() {
    check_formula("exp(x) * y + exp(-x * y)", &signed_points(12), Cs::Yes);
}

#[test]
fn grad_exp_large_argument() {
    check_formula("exp(x) + y", &[(700.0, 0.0), (709.0, 1.0), (-700.0, 1.0), (-745.0, 1.0)], Cs::Yes);
}

#[test]
fn grad_log() {
    check_formula("log(x) * y + log(x * y + 2.0)", &positive_points(13), Cs::Yes);
}

#[test]
fn grad_log_near_zero() {
    check_formula("log(x) + log(y)", &[(1e-8, 1e-12), (1e-8, 1e300), (1e-8, 1.0)], Cs::Yes);
    check_formula("log(x) + log(y)", &[(1e-300, 1e300), (1e-300, 1e-290)], Cs::No);
}

#[test]
fn grad_sin_cos() {
    let pts = random_points(14, 24, |r| r.uniform(-6.0, 6.0), |r| r.uniform(-6.0, 6.0));
    check_formula("sin(x) * y", &pts, Cs::Yes);
    check_formula("cos(x) * y", &pts, Cs::Yes);
    check_formula("sin(cos(x * y)) + cos(sin(x) - y)", &pts, Cs::Yes);
}

#[test]
fn grad_tan() {
    let pts = random_points(15, 24, |r| r.uniform(-1.4, 1.4), |r| r.uniform(-1.4, 1.4));
    check_formula("tan(x) * y + tan(y)", &pts, Cs::Yes);
    // Steep but finite 1e-4 from the pole at pi/2: the step must be far smaller.
    let p = std::f64::consts::FRAC_PI_2 - 1e-4;
    let near_pole = [(p, 0.0), (-p, 0.0)];
    check_with("tan(x) + y", "", &near_pole, Cs::Yes, Fd::Step(1e-10));
}

#[test]
fn grad_tanh() {
    let pts = random_points(16, 24, |r| r.uniform(-3.0, 3.0), |r| r.uniform(-3.0, 3.0));
    check_formula("tanh(x) * y + tanh(x * y)", &pts, Cs::Yes);
}

#[test]
fn grad_tanh_saturated_is_finite() {
    // Finite differences see a flat function here (tanh rounds to ±1), so
    // require finite, non-negative, tiny gradients; the tails test checks
    // their accuracy against 1/cosh².
    let pl = compile_formula("", "tanh(x) + tanh(y)");
    for (x, y) in [(20.0, -20.0), (400.0, -400.0), (-400.0, 20.0), (1e300, -1e300)] {
        let g = adjoint_grads(&pl.optimized, &[x, y], &[], "out", &["x", "y"]);
        for d in g {
            assert!(d.is_finite() && (0.0..1e-15).contains(&d), "tanh gradient {d} at ({x}, {y})");
        }
    }
}

#[test]
fn grad_tanh_is_relatively_accurate_in_the_tails() {
    let pl = compile_formula("", "tanh(x) + tanh(y)");
    for (x, y) in [(10.0, -10.0), (20.0, -20.0)] {
        let g = adjoint_grads(&pl.optimized, &[x, y], &[], "out", &["x", "y"]);
        for (k, v) in [x, y].iter().enumerate() {
            let exact = 1.0 / v.cosh().powi(2);
            assert!(close(g[k], exact, 1e-10, 0.0), "d tanh/dx at {v}: adjoint {:e}, exact {exact:e}", g[k]);
        }
    }
}

#[test]
fn grad_atan2_four_quadrants() {
    // y, x both positive, y > 0 > x, both negative, x > 0 > y.
    for (seed, sy, sx) in [(20, 1.0, 1.0), (21, 1.0, -1.0), (22, -1.0, -1.0), (23, -1.0, 1.0)] {
        let pts = random_points(seed, 12, |r| sy * r.uniform(0.05, 3.0), |r| sx * r.uniform(0.05, 3.0));
        // Scene params are (x, y): here x plays atan2's first argument.
        check_formula("atan2(x, y)", &pts, Cs::Yes);
        check_formula("atan2(x * 2.0, y + x) * y", &pts, Cs::Yes);
    }
    // On the axes (but not on the cut x = 0 > y: see the next test).
    check_formula("atan2(x, y)", &[(0.0, 1.0), (1.0, 0.0), (-1.0, 0.0)], Cs::Yes);
}

#[test]
fn grad_atan2_near_branch_cut() {
    // x < 0, y -> ±0: the value jumps by 2π across the cut, but on each side
    // the gradient is smooth: d/dy ≈ 1/x, d/dx ≈ -y/x².
    // The value is ±π there, so the finite-difference step must be smaller
    // than the distance to the cut yet large against ulp(π) / gradient.
    let groups = [([(1e-8, -1.0), (-1e-8, -1.0), (2e-8, -3.0)], 5e-9), ([(1e-12, -1e-6), (-1e-12, -1e-6), (3e-12, -2e-6)], 5e-13)];
    for (pts, step) in groups {
        check_with("atan2(x, y)", "", &pts, Cs::Yes, Fd::Step(step));
        check_with("atan2(x, y) * 3.0 + y", "", &pts, Cs::Yes, Fd::Step(step));
    }
    // Closer still, the complex step is the only reference.
    let pl = compile_formula("", "atan2(x, y)");
    for (x, y) in [(1e-300, -2.0), (-1e-300, -2.0), (1e-20, -1e-3), (-1e-20, -1e-3)] {
        let g = adjoint_grads(&pl.optimized, &[x, y], &[], "out", &["x", "y"]);
        // d/dy = -x / r is below what the step resolves: compare against |∇|.
        let floor = CS_TOL * (g[0].abs() + g[1].abs());
        for (k, gk) in g.iter().enumerate() {
            let (_, d) = complex_step(&pl.pruned, &[x, y], "out", k, cs_step(y)).unwrap();
            assert!(
                gk.is_finite() && close(*gk, d, CS_TOL, floor),
                "atan2 at ({x:e}, {y:e}), param {k}: adjoint {gk:e}, complex step {d:e}"
            );
        }
    }
    // Exactly on the cut, (±0, -1): finite differences would straddle the
    // jump, but the gradient (-1, 0) is the same from both sides.
    let pl = compile_formula("", "atan2(x, y)");
    for x in [0.0, -0.0] {
        let g = adjoint_grads(&pl.optimized, &[x, -1.0], &[], "out", &["x", "y"]);
        assert_eq!(g, vec![-1.0, 0.0], "gradient of atan2 on the cut at x = {x}");
        for (k, want) in [(0, -1.0), (1, 0.0)] {
            let (_, d) = complex_step(&pl.pruned, &[x, -1.0], "out", k, CS_H).unwrap();
            assert_eq!(d, want, "complex step on the cut, param {k}");
        }
    }
    // Close to the branch point (0, 0) from every direction.
    let near = [(1e-8, 1e-8), (-1e-8, 1e-8), (-1e-8, -1e-8), (1e-8, -1e-8), (1e-12, -3e-12)];
    check_formula("atan2(x, y)", &near, Cs::Yes);
    check_formula("atan2(x, y)", &[(1e-150, -3e-150), (-2e-150, -1e-150)], Cs::No);
}

#[test]
fn grad_atan2_tiny_arguments_do_not_underflow() {
    let pl = compile_formula("", "atan2(x, y)");
    let g = adjoint_grads(&pl.optimized, &[1e-200, 1e-200], &[], "out", &["x", "y"]);
    assert!(g.iter().all(|d| d.is_finite()), "{g:?}");
    assert!(close(g[0], 5e199, 1e-12, 0.0) && close(g[1], -5e199, 1e-12, 0.0), "{g:?}");
}

#[test]
fn grad_abs() {
    check_formula("abs(x) * y + abs(x * y - 0.5)", &signed_points(24), Cs::No);
}

#[test]
fn grad_abs_near_and_at_zero() {
    check_formula("abs(x) + abs(y)", &[(1e-8, -1e-8), (1e-300, -1e-300)], Cs::No);
    // At exactly 0 the gradient is the subgradient 0, never NaN.
    let pl = compile_formula("", "abs(x) + abs(y - 0.7) * 2.0");
    for (x, y) in [(0.0, 0.7), (-0.0, 0.7)] {
        let g = adjoint_grads(&pl.optimized, &[x, y], &[], "out", &["x", "y"]);
        assert_eq!(g, vec![0.0, 0.0], "abs gradient at 0");
        check_point(&pl, "abs at 0", &[x, y], &[], "out", &["x", "y"], Cs::No, Fd::Relative);
    }
}

// ---------------------------------------------------------------------------
// min, max, clamp, select / if
// ---------------------------------------------------------------------------

#[test]
fn grad_min_max_binary() {
    let pts = signed_points(30);
    check_formula("min(x, y)", &pts, Cs::No);
    check_formula("max(x, y)", &pts, Cs::No);
    check_formula("max(x * y, sin(x)) - min(exp(y), x * x)", &pts, Cs::No);
    // A scalar against an array: the scalar's gradient sums over the grid.
    check_formula("sum(max(x, y * (g / 1 Hz))) + sum(min(x * (g / 1 Hz), y))", &pts, Cs::No);
}

#[test]
fn grad_min_max_tie_is_a_subgradient() {
    // At x == y exactly one side receives the gradient.
    let pl = compile_formula("", "min(x, y) + 2.0 * max(x, y)");
    let g = adjoint_grads(&pl.optimized, &[0.5, 0.5], &[], "out", &["x", "y"]);
    assert!(g.iter().all(|d| d.is_finite()));
    assert_eq!(g[0] + g[1], 3.0, "{g:?}");
}

#[test]
fn grad_clamp() {
    // x below, inside and above [y, 1.5].
    let mut pts = Vec::new();
    let mut rng = Rng::new(31);
    for _ in 0..8 {
        let lo = rng.uniform(-1.0, 0.5);
        pts.push((rng.uniform(-3.0, lo - 0.01), lo));
        pts.push((rng.uniform(lo + 0.01, 1.49), lo));
        pts.push((rng.uniform(1.51, 3.0), lo));
    }
    check_formula("clamp(x, y, 1.5) * 2.0 + clamp(x * y, -0.5, 0.5)", &pts, Cs::No);
}

#[test]
fn grad_select_and_if() {
    let pts = signed_points(32);
    check_formula("if x > y { x * x * y } else { sin(y) * x }", &pts, Cs::No);
    check_formula("select(x < 0.2, exp(x), y * 3.0) + select(y >= x, x, y)", &pts, Cs::No);
    check_formula("if x <= 0.0 { -x } else { x * y }", &pts, Cs::No);
    check_formula("if x == y { 1.0 } else { x } + if x != 0.5 { y } else { 0.0 }", &pts, Cs::No);
    // Elementwise over the grid, with a scalar condition broadcast.
    check_formula("sum(if (g / 1 Hz) > 2.5 { x * (g / 1 Hz) } else { y })", &pts, Cs::No);
    check_formula("sum(select(x > 0.0, x * (g / 1 Hz), y * (g / 1 Hz)))", &pts, Cs::No);
}

/// A mask on an interval condition (`g <= 2.5 Hz`, `g > 1.5 Hz`) sinks
/// through what keeps zero zero (products, quotients, negation,
/// conjugation, parts, abs, abs2, sqrt, positive powers, sums of arrays
/// masked alike, `complex`): the gradients stay right, and every grid sum of
/// the optimized adjoint reads a select on that condition (which codegen
/// splits its loop on).
#[test]
fn grad_through_sunk_interval_masks() {
    let pts = signed_points(33);
    let prelude = "module m(g: Hz, x, y) { if g <= 2.5 Hz { x * y * (g / 1 Hz) + x } else { 0.0 } }
        module n(g: Hz, x) { if 1.5 Hz < g { 0.0 } else { x * x } }";
    // With whether every grid sum of the gradients is zero outside one mask.
    let formulas = [
        ("sum(re(conj(complex(m(g, x, y), m(g, x, y) * y) * cis(x * (g / 1 Hz)))) / (y * y + 2.0))", true),
        ("sum(abs2(-(m(g, x, y) * 1.0i)) * exp(y) + (m(g, x, y) - m(g, y, x)) ^ 3.0 / x)", true),
        ("sum(sqrt(abs(m(g, x, y)) + 1.0) * y + n(g, x) * sin(y * (g / 1 Hz)))", false),
    ];
    for (formula, all_masked) in formulas {
        let pl = compile_formula(prelude, formula);
        for &(x, y) in &pts {
            check_point(&pl, formula, &[x, y], &[], "out", &["x", "y"], Cs::No, Fd::Relative);
        }
        let f = &pl.optimized;
        let masked_sums = f.grads.iter().filter_map(|g| g.value).all(|g| {
            let mut stack = vec![g];
            let mut seen = std::collections::HashSet::new();
            while let Some(v) = stack.pop() {
                if !seen.insert(v) {
                    continue;
                }
                let op = f.insts[v.index()].op;
                if let Op::Reduce(Reduce::Sum, a) = op {
                    let Op::Select(c, ..) = f.insts[a.index()].op else { return false };
                    if f.interval_condition(c).is_none() {
                        return false;
                    }
                }
                stack.extend(op.operands());
            }
            true
        });
        assert!(masked_sums || !all_masked, "{formula}: a grid sum of the adjoint is not masked:\n{f}");
    }
}

// ---------------------------------------------------------------------------
// Grids: broadcasting and reductions
// ---------------------------------------------------------------------------

#[test]
fn grad_broadcast_scalar_over_grid() {
    let pts = signed_points(40);
    check_formula("sum(x + y * (g / 1 Hz))", &pts, Cs::Yes);
    check_formula("sum((g / 1 Hz) ^ 2.0 * x + y)", &pts, Cs::Yes);
    check_formula("sum(sin(x * g / 1 Hz) * y)", &pts, Cs::Yes);
    check_formula("sum(x * y / (g / 1 Hz + x * x))", &pts, Cs::Yes);
}

#[test]
fn grad_sum_and_mean() {
    let pts = signed_points(41);
    check_formula("sum(exp(-x * (g / 1 Hz)) * cos(y * g / 1 Hz))", &pts, Cs::Yes);
    check_formula("mean(x * (g / 1 Hz) ^ 3.0 - y)", &pts, Cs::Yes);
    check_formula("mean(tanh(x * (g / 1 Hz))) * sum(y * (g / 1 Hz))", &pts, Cs::Yes);
}

#[test]
fn grad_max_min_reduction() {
    let pts = signed_points(42);
    check_formula("max(sin(x * (g / 1 Hz) + y))", &pts, Cs::No);
    check_formula("min(cos(x * (g / 1 Hz)) * y)", &pts, Cs::No);
    check_formula("max(x * (g / 1 Hz)) - min(y * (g / 1 Hz))", &pts, Cs::No);
}

#[test]
fn grad_max_reduction_with_ties_is_a_subgradient() {
    let pl = compile_formula("", "max(abs(x * (g / 1 Hz - 2.5))) + y");
    let g = adjoint_grads(&pl.optimized, &[0.4, 0.0], &[], "out", &["x", "y"]);
    assert_eq!(g[0], 1.5, "d max(|x (g - 2.5)|)/dx with a tie");
    let pl = compile_formula("", "max(x + 0.0 * g / 1 Hz) + min(y + 0.0 * g / 1 Hz)");
    let g = adjoint_grads(&pl.optimized, &[0.4, 0.2], &[], "out", &["x", "y"]);
    assert_eq!(g, vec![1.0, 1.0], "max/min over a constant array");
}

// ---------------------------------------------------------------------------
// Complex values
// ---------------------------------------------------------------------------

#[test]
fn grad_re_im_conj() {
    let pts = signed_points(50);
    check_formula("re(complex(x, y) * complex(y, x * x))", &pts, Cs::No);
    check_formula("im(complex(x, y) * complex(y, x * x))", &pts, Cs::No);
    check_formula("re(conj(complex(x, y)) * 2.0i) + im(conj(complex(x * y, y)))", &pts, Cs::No);
    // re/im/conj of a real value.
    check_formula("re(x) * im(y) + conj(x * y)", &pts, Cs::Yes);
}

#[test]
fn grad_abs2() {
    let pts = signed_points(51);
    check_formula("abs2(complex(x, y) * (1.0 + 2.0i) + x)", &pts, Cs::No);
    // abs2 of a real is x * x.
    check_formula("abs2(x * y)", &pts, Cs::Yes);
}

#[test]
fn grad_cis() {
    let pts = signed_points(52);
    check_formula("re(cis(x * y)) + im(cis(x)) * y", &pts, Cs::No);
    check_formula("sum(re(cis(-x * (g / 1 Hz)) * conj(cis(y * (g / 1 Hz)))))", &pts, Cs::No);
}

#[test]
fn grad_complex_constructor_and_modulus() {
    let pts = signed_points(53);
    check_formula("abs(complex(x, y))", &pts, Cs::No);
    check_formula("abs(complex(x * y, sin(x)) * complex(1.0, y))", &pts, Cs::No);
    check_formula("re(complex(x, y) * 3.0i) + im(complex(y, x) + x)", &pts, Cs::No);
}

#[test]
fn grad_complex_modulus_at_zero_is_zero_not_nan() {
    let pl = compile_formula("", "abs(complex(x, y)) + x");
    let g = adjoint_grads(&pl.optimized, &[0.0, 0.0], &[], "out", &["x", "y"]);
    assert_eq!(g, vec![1.0, 0.0], "subgradient of |z| at 0 is 0");
    let pl = compile_formula("", "sum(abs(complex(x * (g / 1 Hz - 2.0), y)))");
    let g = adjoint_grads(&pl.optimized, &[1.0, 0.0], &[], "out", &["x", "y"]);
    assert!(g.iter().all(|d| d.is_finite()), "{g:?}");
}

#[test]
fn grad_complex_builtin_on_scalars_and_arrays() {
    let pts = signed_points(56);
    check_formula("re(complex(x, y) * complex(y, x * x))", &pts, Cs::No);
    check_formula("abs(complex(x * y, sin(x)))", &pts, Cs::No);
    check_formula("im(complex(x, y) * 3.0i) + sum(abs2(complex(x * (g / 1 Hz), y)))", &pts, Cs::No);
}

#[test]
fn grad_complex_mul_div_exp() {
    let pts = signed_points(54);
    check_formula("re(complex(x, y) * complex(y, -x) * complex(x, 1.0))", &pts, Cs::No);
    check_formula("im(complex(x, y) / complex(y, x * x + 0.5))", &pts, Cs::No);
    check_formula("abs2(1.0 / complex(x, y))", &pts, Cs::No);
    check_formula("re(exp(complex(x, y))) + im(exp(complex(x, y) * 0.5i))", &pts, Cs::No);
    check_formula("abs2(exp(complex(x, y) * (0.5 + 1.5i)) / complex(y, x))", &pts, Cs::No);
    check_formula("-re(-complex(x, y) * (x - 2.0i)) + im(complex(x, y) - y * 1.0i)", &pts, Cs::No);
}

#[test]
fn grad_complex_arrays_and_reductions() {
    let pts = signed_points(55);
    check_formula("abs2(sum(complex(x, y) * cis(x * (g / 1 Hz))))", &pts, Cs::No);
    check_formula("re(mean(exp(complex(-x, y) * (g / 1 Hz)) / complex(1.0, x)))", &pts, Cs::No);
    // The noise-weighted inner product shape used by std::detector.
    check_formula("4.0 * sum(re(complex(x, y) * (g / 1 Hz) * conj(cis(y * (g / 1 Hz)))) / (1.0 + (g / 1 Hz) ^ 2.0))", &pts, Cs::No);
}

// ---------------------------------------------------------------------------
// Modules, units and the example scene
// ---------------------------------------------------------------------------

#[test]
fn grad_through_modules_and_units() {
    let prelude = "module sq(a) { a * a }\nmodule phase(f: Hz, t: s, p = 0.25) { let w = 2.0 * pi * f * t\n w - p }";
    let pts = signed_points(60);
    check_with("sq(x) * sq(sq(y))", prelude, &pts, Cs::Yes, Fd::Relative);
    check_with("sum(sin(phase(g, x * 1 ms, p: y)))", prelude, &pts, Cs::Yes, Fd::Relative);
    check_with("sum(cos(phase(g, y * 0.1 s)) * x)", prelude, &pts, Cs::Yes, Fd::Relative);
}

#[test]
fn grad_params_with_units_are_per_base_unit() {
    // A param declared in ms is held in seconds: the gradient is per second.
    let src = "scene u {\n grid g = frequencies(from: 1 Hz, to: 4 Hz, step: 1 Hz)\n param t: ms = 2.0\n param m: km = 3.0\n output out = sum(sin(2.0 * pi * g * t)) * (m / 1 m)\n grad out wrt [t, m]\n}";
    let pl = compile_source("units.gw", src, Some("u"));
    assert_eq!(pl.optimized.params[0].scale, 1e-3);
    assert_eq!(pl.optimized.params[1].scale, 1e3);
    let p = [2.0e-3, 3.0e3];
    check_point(&pl, "units", &p, &[], "out", &["t", "m"], Cs::Yes, Fd::Relative);
    let g = adjoint_grads(&pl.optimized, &p, &[], "out", &["t", "m"]);
    let want_t: f64 =
        (1..=4).map(|k| 2.0 * std::f64::consts::PI * k as f64 * (2.0 * std::f64::consts::PI * k as f64 * 2e-3).cos()).sum::<f64>() * 3e3;
    assert!(close(g[0], want_t, 1e-12, 0.0), "{} vs {want_t}", g[0]);
}

fn chirp_fit() -> (ScenePipeline, Vec<Tensor>) {
    let src = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../examples/chirp_fit.gw")).expect("examples/chirp_fit.gw");
    let pl = compile_source("chirp_fit.gw", &src, Some("chirp_fit"));
    let d = pl.pruned.inputs[0].default.clone().expect("input `d` has a default");
    (pl, vec![d])
}

#[test]
fn chirp_fit_gradients_match_finite_differences() {
    let (pl, inputs) = chirp_fit();
    let names = ["mc", "tc", "phic"];
    assert_eq!(pl.optimized.params.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(), names);
    // Params in base units (Msun, s, 1); steps suited to each one's scale:
    // the loss varies with tc on the scale 1 / (2π f_max) ~ 1.6e-4 s.
    let points: [[f64; 3]; 4] = [[28.0, 0.0, 0.0], [30.0, 0.002, 0.3], [29.7, 0.0021, 0.25], [35.0, -0.001, 1.0]];
    let steps = [1e-6, 1e-10, 1e-7];
    // Gradient magnitudes away from the minimum, for absolute floors near it.
    let scale = adjoint_grads(&pl.adjoint, &points[0], &inputs, "loss", &names);
    for p in points {
        let f = eval_output(&pl.pruned, &p, &inputs, "loss");
        assert!(f.is_finite() && f >= 0.0, "loss {f} at {p:?}");
        let ad = adjoint_grads(&pl.optimized, &p, &inputs, "loss", &names);
        let ad_raw = adjoint_grads(&pl.adjoint, &p, &inputs, "loss", &names);
        for k in 0..3 {
            let g = ad[k];
            assert!(g.is_finite(), "dloss/d{} = {g} at {p:?}", names[k]);
            // Specialisation folds grid-only factors into tables, which rounds differently.
            assert!(
                close(g, ad_raw[k], 1e-10, 1e-12 * scale[k].abs()),
                "dloss/d{} at {p:?}: optimized {g:e} vs unsimplified {:e}",
                names[k],
                ad_raw[k]
            );
            let h = steps[k];
            let fd = central_difference(&pl.pruned, &p, &inputs, "loss", k, h);
            // The rounding error of the difference, eps f / h.
            let floor = 4.0 * f64::EPSILON * f.max(1.0) / h;
            assert!(
                close(g, fd, FD_TOL, floor),
                "dloss/d{} at {p:?}: adjoint {g:e}, finite difference {fd:e} (rel. error {:e})",
                names[k],
                (g - fd).abs() / g.abs().max(fd.abs())
            );
        }
    }
    // At the true parameters the loss and its gradient vanish.
    let p = [30.0, 0.002, 0.3];
    assert!(eval_output(&pl.pruned, &p, &inputs, "loss").abs() < 1e-20);
    for g in adjoint_grads(&pl.optimized, &p, &inputs, "loss", &names) {
        assert!(g.abs() < 1e-6, "{g}");
    }
}

// ---------------------------------------------------------------------------
// Fourier transforms
// ---------------------------------------------------------------------------

/// A scene with a time grid of `rate` samples over 1 s, its spectrum `f`,
/// params x and y, and `body` (lets) before `output out = formula`.
fn transform_scene(rate: u32, body: &str, formula: &str) -> ScenePipeline {
    let src = format!(
        "scene t {{\n  grid t = times(rate: {rate} Hz, duration: 1 s)\n  grid f = spectrum(t)\n  param x = 0.3\n  param y = 0.7\n  let u = t / 1 s\n  let nu = f / 1 Hz\n{body}\n  output out = {formula}\n  grad out wrt [x, y]\n}}\n"
    );
    compile_source("transform.gw", &src, Some("t"))
}

fn check_transform(body: &str, formula: &str) {
    // Even and odd lengths: the Nyquist bin exists only for even n.
    for rate in [16, 15, 2, 1] {
        let pl = transform_scene(rate, body, formula);
        for (x, y) in signed_points(rate as u64) {
            check_point(&pl, &format!("{formula} (n = {rate})"), &[x, y], &[], "out", &["x", "y"], Cs::No, Fd::Relative);
        }
    }
}

#[test]
fn grad_rfft() {
    let body = "  let s = sin(x * u * 7.0 + y) * exp(-y * y * u)\n  let S = rfft(s, f)";
    check_transform(body, "sum(abs2(S)) * 1 Hz / 1 s");
    check_transform(body, "sum(re(S * cis(x * nu)) + im(S) * y) * 1 Hz / 1 s");
    check_transform(body, "sum(abs(S) * nu) * 1 Hz / 1 s");
}

#[test]
fn grad_irfft() {
    let body = "  let X = complex(x * cos(nu * y), y * sin(nu + x)) * 1 s\n  let r = irfft(X, t)";
    check_transform(body, "sum(r * r * u)");
    check_transform(body, "sum(r * sin(u * x))");
    // Imaginary parts of the DC and Nyquist bins do not reach the result.
    check_transform("  let r = irfft(complex(x * nu, y * x + nu) * 1 s, t)", "sum(r * r)");
}

#[test]
fn grad_rfft_irfft_round_trip_with_a_filter() {
    let body = "  let s = sin(x * u * 5.0) * y + u * x\n  let w = irfft(rfft(s, f) * exp(-nu * y * y / 4.0), t)";
    check_transform(body, "sum(w * w * (1.0 + u))");
    check_transform(body, "max(w) + re(sum(rfft(w, f) * conj(rfft(s, f)))) * 1 Hz * 1 Hz");
}
