//! `Options::outputs`: compiling a subset of a scene's outputs (what
//! `gwml tradeoff` times value-and-gradient with).

use gwml_compiler::kernels::interp;
use gwml_compiler::{Options, Program};

const SCENE: &str = "scene s {
  grid t = times(rate: 16 Hz, duration: 1 s)
  param a = 1.5
  param b = 0.5
  let h = a * sin(6.0 * t / 1 s) + b
  output wave = h
  output first = sum(h * h)
  output second = sum(h) * b
  grad first wrt [a]
  grad second wrt [a, b]
}
";

#[test]
fn a_subset_of_outputs_keeps_their_values_and_gradients_only() {
    let program = Program::parse("s.gw", SCENE).unwrap();
    let all = program.pipeline(None, Options::default()).unwrap().optimized;
    let only = program.pipeline(None, Options { outputs: Some(vec!["second".into()]), ..Default::default() }).unwrap().optimized;
    let names: Vec<&str> = only.outputs.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["second"]);
    // Both gradients of `second`, now pointing at output 0; `first`'s is gone.
    let grads: Vec<(usize, usize)> = only.grads.iter().map(|g| (g.output, g.param)).collect();
    assert_eq!(grads, [(0, 0), (0, 1)]);
    assert!(only.insts.len() < all.insts.len(), "the wave and `first` are pruned away");
    let (ra, ro) = (interp::interpret(&all, &[1.5, 0.5], &[]), interp::interpret(&only, &[1.5, 0.5], &[]));
    assert_eq!(ra.output(&all, "second").unwrap(), ro.output(&only, "second").unwrap());
    for p in ["a", "b"] {
        assert_eq!(ra.grad(&all, "second", p), ro.grad(&only, "second", p), "d second / d {p}");
    }
}

#[test]
fn an_unknown_output_is_an_error() {
    let program = Program::parse("s.gw", SCENE).unwrap();
    let e = program.pipeline(None, Options { outputs: Some(vec!["secnd".into()]), ..Default::default() }).err().unwrap().to_string();
    assert!(e.contains("has no output `secnd`"), "{e}");
}
