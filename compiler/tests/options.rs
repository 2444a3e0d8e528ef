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

/// A bump whose centre is a param, as a classifier's template frequency is.
const BUMP: &str = "scene s {
  grid t = times(rate: 64 Hz, duration: 1 s)
  grid f = spectrum(t)
  param lf = 2.5
  param g = 2.0
  let h = exp(-((f - exp(lf) * 1 Hz) / 4 Hz) ^ 2)
  output y = sum(g * h * h)
  grad y wrt [g]
}
";

fn frozen(source: &str, values: &[(&str, f64)]) -> Result<gwml_compiler::ir::Function, String> {
    let program = Program::parse("s.gw", source).unwrap();
    let frozen_params = values.iter().map(|(n, v)| (n.to_string(), *v)).collect();
    program.pipeline(None, Options { frozen_params, ..Default::default() }).map(|p| p.optimized).map_err(|e| e.to_string())
}

#[test]
fn a_frozen_param_is_compiled_in_and_what_it_alone_determines_becomes_a_table() {
    let program = Program::parse("s.gw", BUMP).unwrap();
    let free = program.pipeline(None, Options::default()).unwrap().optimized;
    let fixed = frozen(BUMP, &[("lf", 2.5)]).unwrap();
    let names: Vec<&str> = fixed.params.iter().map(|p| p.name.as_str()).collect();
    assert_eq!(names, ["g"], "`lf` leaves the params; `g` is renumbered to 0");
    assert_eq!(fixed.grads.iter().map(|g| g.param).collect::<Vec<_>>(), [0]);
    // With `lf` free the bump is computed per call; frozen, it is a table.
    assert!(free.tables.is_empty(), "{} tables", free.tables.len());
    assert!(!fixed.tables.is_empty());
    assert!(!fixed.insts.iter().any(|i| matches!(i.op, gwml_compiler::ir::Op::Unary(gwml_compiler::ir::UnOp::Exp, _))));
    for g in [0.5, 2.0, 7.0] {
        let (rf, rx) = (interp::interpret(&free, &[2.5, g], &[]), interp::interpret(&fixed, &[g], &[]));
        let (yf, yx) = (rf.output(&free, "y").unwrap()[0].re, rx.output(&fixed, "y").unwrap()[0].re);
        assert!((yf - yx).abs() <= 1e-12 * yf.abs(), "y at g = {g}: {yf} free, {yx} frozen");
        let (df, dx) = (rf.grad(&free, "y", "g").unwrap(), rx.grad(&fixed, "y", "g").unwrap());
        assert!((df - dx).abs() <= 1e-12 * df.abs(), "dy/dg at g = {g}: {df} free, {dx} frozen");
    }
}

#[test]
fn freezing_an_unknown_param_a_non_finite_value_or_a_differentiated_param_is_an_error() {
    let e = frozen(BUMP, &[("lff", 2.5)]).unwrap_err();
    assert!(e.contains("no param `lff` to freeze") && e.contains("params: lf, g"), "{e}");
    let e = frozen(BUMP, &[("lf", f64::NAN)]).unwrap_err();
    assert!(e.contains("cannot freeze param `lf` at NaN"), "{e}");
    let e = frozen(BUMP, &[("g", 1.0)]).unwrap_err();
    assert!(e.contains("cannot freeze param `g`: a gradient with respect to it is requested"), "{e}");
}
