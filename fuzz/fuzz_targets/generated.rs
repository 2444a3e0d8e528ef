//! Differential on generated well-typed programs (`common/program.rs`):
//! each must check and compile (a rejection is a bug in the checker or the
//! generator), its JIT value and gradient must equal the interpreter's
//! (`common/differential.rs`), and where the program is smooth the
//! interpreter's gradient of `loss` must equal central finite differences
//! of its value, which checks the adjoint pass itself. `GWML_FUZZ_SHOW=1`
//! prints each program and how far its check went.
#![no_main]
use gwml_compiler::kernels::interp;
use gwml_runtime::Model;
use libfuzzer_sys::arbitrary::Unstructured;
use libfuzzer_sys::fuzz_target;

#[path = "common/differential.rs"]
mod differential;
#[path = "common/program.rs"]
mod program;

fuzz_target!(|data: &[u8]| {
    let generated = program::program(&mut Unstructured::new(data));
    let model = match Model::from_source("generated.gw", &generated.text) {
        Ok(m) => m,
        Err(gwml_runtime::Error::Compile(e)) => panic!("a well-typed program was rejected:\n{}\n{}", generated.text, e.render(false)),
        Err(e) => panic!("a well-typed program failed to compile:\n{}\n{e}", generated.text),
    };
    let scene = model.scene(Some("fuzzed")).unwrap_or_else(|e| panic!("{}\n{e}", generated.text));
    let show = std::env::var_os("GWML_FUZZ_SHOW").is_some();
    let checked = differential::check(&scene, "fuzzed");
    if show {
        let how = match &checked {
            differential::Checked::Skipped => "skipped",
            differential::Checked::RunOnly => "run only",
            differential::Checked::Compared { .. } if generated.smooth => "compared, finite differences",
            differential::Checked::Compared { .. } => "compared",
        };
        eprintln!("{}// {how}\n", generated.text);
    }
    let differential::Checked::Compared { params } = checked else { return };
    if !generated.smooth {
        return;
    }
    let func = scene.ir();
    let loss = |p: &[f64]| interp::interpret(func, p, &[]).output(func, "loss").map(|v| v[0].re);
    let Some(l0) = loss(&params) else { return };
    let reference = interp::interpret(func, &params, &[]);
    for (i, p) in func.params.iter().enumerate() {
        let Some(g) = reference.grad(func, "loss", &p.name) else { continue };
        let fd = |h: f64| {
            let (mut up, mut down) = (params.clone(), params.clone());
            up[i] += h;
            down[i] -= h;
            Some((loss(&up)? - loss(&down)?) / (2.0 * h))
        };
        let h = 1e-4 * params[i].abs().max(1.0);
        let (Some(a), Some(b)) = (fd(h), fd(h / 2.0)) else { continue };
        // Richardson: the two steps' error is O(h^2); trust the estimate
        // only where they agree, so a rough function is not blamed on the adjoint.
        let estimate = (4.0 * b - a) / 3.0;
        let scale = g.abs().max(estimate.abs()) + 1e-6 * (1.0 + l0.abs());
        if !estimate.is_finite() || (a - b).abs() > 1e-3 * scale {
            continue;
        }
        // The two steps' disagreement also measures rounding noise in the
        // differences (large intermediate values cancelling): allow ten times it.
        assert!(
            (g - estimate).abs() <= 1e-5 * scale + 10.0 * (a - b).abs(),
            "dloss/d{}: adjoint {g}, finite differences {estimate} (steps {a}, {b})\n{}",
            p.name,
            generated.text
        );
    }
});
