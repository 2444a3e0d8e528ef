//! The differential check shared by `compile_run` and `generated`: a
//! scene's JIT value and gradient against the reference interpreter on the
//! same IR (`kernels::interp`, each op by its definition in `ir::eval`).

use gwml_compiler::ir::{MathMode, Precision};
use gwml_compiler::kernels::interp;
use gwml_runtime::{Scene, Value};

/// Equal to 1e-7 relative, or within 1e-12 of `scale` (the largest
/// magnitude among the values compared with it): a result that cancels to
/// rounding noise in one evaluation may be exactly 0 in the other.
fn close(a: f64, b: f64, scale: f64) -> bool {
    (a - b).abs() <= 1e-7 * a.abs().max(b.abs()) + 1e-12 * (1.0 + scale) || (a.is_nan() && b.is_nan())
}

fn largest(values: impl Iterator<Item = f64>) -> f64 {
    values.filter(|v| v.is_finite()).fold(0.0, |m, v| m.max(v.abs()))
}

/// What [`check`] compared.
pub enum Checked {
    /// Not run: a grid too large, a param or input without default, or a
    /// run-time error (a value not finite).
    Skipped,
    /// Run, but not compared: not f64 with exact math.
    RunOnly,
    /// Run and compared with the interpreter; the params (internal units)
    /// and the interpreter's loss-gradient for finite differences.
    Compared {
        #[allow(dead_code)] // read by `generated` only
        params: Vec<f64>,
    },
}

/// Runs `scene` (value and gradient at the defaults) and, in f64 with
/// exact math, asserts that every output and gradient equals the
/// interpreter's to 1e-7 relative.
pub fn check(scene: &Scene, name: &str) -> Checked {
    let func = scene.ir();
    if func.grids.iter().any(|g| g.len > 50_000) {
        return Checked::Skipped;
    }
    let Some(params) = func.params.iter().map(|p| p.default.map(|d| d * p.scale)).collect::<Option<Vec<f64>>>() else {
        return Checked::Skipped;
    };
    let Some(inputs) = func.inputs.iter().map(|i| i.default.clone()).collect::<Option<Vec<_>>>() else { return Checked::Skipped };
    let Ok(out) = scene.bind().value_and_grad() else { return Checked::Skipped };
    if func.precision != Precision::F64 || func.math != MathMode::Exact {
        return Checked::RunOnly;
    }
    let reference = interp::interpret(func, &params, &inputs);
    for (output, value) in &out.values {
        let Some(want) = reference.output(func, output) else { continue };
        let got: Vec<(f64, f64)> = match value {
            Value::Real(x) => vec![(*x, 0.0)],
            Value::Complex(z) => vec![(z.re, z.im)],
            Value::RealArray(a) => a.iter().map(|x| (*x, 0.0)).collect(),
            Value::ComplexArray(a) => a.iter().map(|z| (z.re, z.im)).collect(),
        };
        assert_eq!(got.len(), want.len(), "output `{output}` of scene `{name}`: lengths differ");
        let scale = largest(want.iter().flat_map(|w| [w.re, w.im]));
        for (k, ((re, im), w)) in got.iter().zip(&want).enumerate() {
            assert!(close(*re, w.re, scale) && close(*im, w.im, scale), "output `{output}`[{k}] of scene `{name}`: JIT {re}+{im}i, interpreter {w}");
        }
    }
    // A gradient is compared at the scale of its output's other gradients.
    let grad_scale = |output: &str| largest(out.grads.iter().filter(|(o, _, _)| o == output).map(|(_, _, g)| *g));
    for (output, param, g) in &out.grads {
        let p = func.params.iter().find(|p| &p.name == param).expect("a param of the scene");
        if let Some(want) = reference.grad(func, output, param) {
            let want = want * p.scale;
            assert!(close(*g, want, grad_scale(output)), "d{output}/d{param} of scene `{name}`: JIT {g}, interpreter {want}");
        }
    }
    Checked::Compared { params }
}
