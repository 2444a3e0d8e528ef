//! The gradient of a scene's scalar output against central differences.

use gwml::Scene;

/// Central difference of scalar `output` in `param`, the others at `params`.
pub fn central_difference(scene: &Scene, params: &[(&str, f64)], output: &str, param: &str, h: f64) -> f64 {
    let eval = |delta: f64| {
        let mut run = scene.bind();
        for (name, v) in params {
            run.param(name, if *name == param { v + delta } else { *v }).unwrap();
        }
        run.forward().unwrap().scalar(output).unwrap()
    };
    (eval(h) - eval(-h)) / (2.0 * h)
}

/// Asserts that the gradient of `output` at `params` is finite and agrees
/// with central differences to `rel` (relative), for each `(param, step)`.
pub fn assert_gradient_matches(scene: &Scene, params: &[(&str, f64)], output: &str, steps: &[(&str, f64)], rel: f64) {
    let mut run = scene.bind();
    for (n, v) in params {
        run.param(n, *v).unwrap();
    }
    let out = run.value_and_grad().unwrap();
    for (param, h) in steps {
        let g = out.grad(output, param).unwrap();
        let fd = central_difference(scene, params, output, param, *h);
        assert!(g.is_finite() && (g - fd).abs() <= rel * fd.abs(), "d {output} / d {param}: {g} vs FD {fd}");
    }
}
