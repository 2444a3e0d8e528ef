//! Helpers shared by the learned-component tests: deterministic data,
//! scalar outputs, and gradient checks of weights against finite
//! differences and of the JIT against the reference interpreter.
#![allow(dead_code)]

use gwml_compiler::kernels::interp;
use gwml_runtime::{Model, Outputs, Value};
use num_complex::Complex64 as C64;

/// Deterministic values in [-1, 1).
pub fn pseudo_random(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s >> 12;
            s ^= s << 25;
            s ^= s >> 27;
            ((s.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
        })
        .collect()
}

pub fn scalar(out: &Outputs, name: &str) -> f64 {
    match out.value(name).unwrap() {
        Value::Real(x) => *x,
        v => panic!("{name} is {v:?}"),
    }
}

/// Checks d`output`/d(every element of every trainable input) against
/// central differences, with the given inputs bound (weights start from
/// their initialisers, or from the values `data` binds to them). Returns
/// the loss.
pub fn check_weight_gradients(src: &str, data: &[(&str, Vec<f64>)], output: &str) -> f64 {
    let model = Model::from_source("learned.gw", src).unwrap_or_else(|e| panic!("{e}\n{src}"));
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    for (name, values) in data {
        run.input_real(name, values).unwrap();
    }
    let out = run.value_and_grad().unwrap();
    let loss = scalar(&out, output);
    assert!(!out.input_grads.is_empty(), "the scene asks for weight gradients");
    let weights: Vec<(String, Vec<f64>)> = scene
        .ir()
        .inputs
        .iter()
        .filter(|i| i.is_weight())
        .map(|i| match data.iter().find(|d| d.0 == i.name) {
            Some((_, bound)) => (i.name.clone(), bound.clone()),
            None => (i.name.clone(), i.default.as_ref().unwrap().iter().map(|z| z.re).collect()),
        })
        .collect();
    for (name, w0) in &weights {
        let grad = out.input_grad(output, name).unwrap().to_vec();
        assert_eq!(grad.len(), w0.len(), "{name}");
        let norm = grad.iter().map(|g| g * g).sum::<f64>().sqrt();
        for k in 0..w0.len() {
            let h = 1e-6 * w0[k].abs().max(1.0);
            let mut at = |x: f64| {
                let mut w = w0.clone();
                w[k] = x;
                run.input_real(name, &w).unwrap();
                scalar(&run.forward().unwrap(), output)
            };
            let fd = (at(w0[k] + h) - at(w0[k] - h)) / (2.0 * h);
            run.input_real(name, w0).unwrap();
            let tol = 1e-6 * fd.abs().max(grad[k].abs()) + 1e-8 * norm.max(1e-3);
            assert!((fd - grad[k]).abs() <= tol, "d{output}/d{name}[{k}]: adjoint {} vs finite difference {fd}\n{src}", grad[k]);
        }
    }
    loss
}

/// The JIT's outputs and weight gradients equal the interpreter's.
pub fn check_against_interpreter(src: &str, data: &[(&str, Vec<f64>)]) {
    let model = Model::from_source("learned.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    for (name, values) in data {
        run.input_real(name, values).unwrap();
    }
    let out = run.value_and_grad().unwrap();
    let func = scene.ir();
    let inputs: Vec<interp::Tensor> = func
        .inputs
        .iter()
        .map(|i| match data.iter().find(|d| d.0 == i.name) {
            Some((_, v)) => v.iter().map(|x| C64::new(*x, 0.0)).collect(),
            None => i.default.clone().unwrap(),
        })
        .collect();
    let r = interp::interpret(func, &[], &inputs);
    for g in &func.input_grads {
        let want = &r.values[g.value.unwrap().index()];
        let have = out.input_grad(&func.outputs[g.output].name, &func.inputs[g.input].name).unwrap();
        for (a, b) in have.iter().zip(want) {
            assert!((a - b.re).abs() <= 1e-13 * (1.0 + b.re.abs()), "{a} vs {}", b.re);
        }
    }
}
