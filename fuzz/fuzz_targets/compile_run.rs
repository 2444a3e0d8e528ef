//! Differential: every scene of a program that checks is JIT-compiled and
//! run (value and gradient, at the params' and inputs' defaults), and what
//! it returns is compared with the reference interpreter on the same IR
//! (`kernels::interp`, which evaluates each op by its definition in
//! `ir::eval`). Scenes in f64 with exact math must agree to 1e-7 relative;
//! others must only not panic.
#![no_main]
use gwml_compiler::ir::{MathMode, Precision};
use gwml_compiler::kernels::interp;
use gwml_runtime::{Model, Value};
use libfuzzer_sys::fuzz_target;

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-7 * a.abs().max(b.abs()) + 1e-12 || (a.is_nan() && b.is_nan())
}

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let Ok(model) = Model::from_source("fuzz.gw", text) else { return };
    for name in model.program.scene_names() {
        let Ok(scene) = model.scene(Some(name)) else { continue };
        let func = scene.ir();
        if func.grids.iter().any(|g| g.len > 50_000) {
            continue;
        }
        let Some(params) = func.params.iter().map(|p| p.default.map(|d| d * p.scale)).collect::<Option<Vec<f64>>>() else { continue };
        let Some(inputs) = func.inputs.iter().map(|i| i.default.clone()).collect::<Option<Vec<_>>>() else { continue };
        let Ok(out) = scene.bind().value_and_grad() else { continue };
        if func.precision != Precision::F64 || func.math != MathMode::Exact {
            continue;
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
            for (k, ((re, im), w)) in got.iter().zip(&want).enumerate() {
                assert!(close(*re, w.re) && close(*im, w.im), "output `{output}`[{k}] of scene `{name}`: JIT {re}+{im}i, interpreter {w}");
            }
        }
        for (output, param, g) in &out.grads {
            let p = func.params.iter().find(|p| &p.name == param).expect("a param of the scene");
            if let Some(want) = reference.grad(func, output, param) {
                let want = want * p.scale;
                assert!(close(*g, want), "d{output}/d{param} of scene `{name}`: JIT {g}, interpreter {want}");
            }
        }
    }
});
