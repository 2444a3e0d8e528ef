//! Differential tests: the JIT kernels agree with the reference interpreter.

use gwml_compiler::interp;
use gwml_runtime::{Model, Value};

fn example(name: &str) -> String {
    std::fs::read_to_string(format!("{}/../examples/{name}", env!("CARGO_MANIFEST_DIR")))
        .expect("example exists")
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs().max(1e-300)
}

#[test]
fn chirp_fit_jit_matches_interpreter() {
    let model = Model::from_source("chirp_fit.gw", &example("chirp_fit.gw")).unwrap();
    let scene = model.scene(None).unwrap();
    let mut run = scene.bind();
    run.param("mc", 29.0)
        .unwrap()
        .param("tc", 0.001)
        .unwrap()
        .param("phic", 0.2)
        .unwrap();
    let out = run.value_and_grad().unwrap();
    let f = scene.ir();
    let d = f.inputs[0].default.clone().unwrap();
    let r = interp::interpret(f, &[29.0, 0.001, 0.2], &[d]);
    let loss = r.output(f, "loss").unwrap()[0].re;
    assert!(
        rel(out.scalar("loss").unwrap(), loss) < 1e-12,
        "{} vs {loss}",
        out.scalar("loss").unwrap()
    );
    for p in ["mc", "tc", "phic"] {
        let g = r.grad(f, "loss", p).unwrap();
        assert!(
            rel(out.grad("loss", p).unwrap(), g) < 1e-10,
            "{p}: {} vs {g}",
            out.grad("loss", p).unwrap()
        );
    }
    let fwd = run.forward().unwrap();
    assert!(rel(fwd.scalar("loss").unwrap(), loss) < 1e-12);
    assert_eq!(
        scene.gradient_kernel().unwrap().layout.loops,
        1,
        "forward and adjoint fuse into one loop"
    );
    assert!(matches!(fwd.value("loss"), Ok(Value::Real(_))));
}
