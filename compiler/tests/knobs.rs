//! Scene knobs (`knob NAME = VALUE`): named compile-time constants that the
//! grid, module arguments and expressions of a scene may use, overridden by
//! `Options::knobs` (the command line's `--knob NAME=VALUE`), which checks and
//! lowers the scene again. Errors in an override point into its own text.
//!
//! Regenerate the snapshots with `INSTA_UPDATE=always cargo test -p gwml-compiler --test knobs`.

use gwml_compiler::kernels::interp;
use gwml_compiler::{Options, PipelineError, Program};

const SCENE: &str = "module scaled(x, k = 1.0) {
  if k >= 2.0 { 2.0 * x } else { x }
}
scene s {
  knob df = 0.25 Hz
  knob order = 1
  knob width = 4.0 * df
  grid f = frequencies(from: 10 Hz, to: 20 Hz, step: df)
  param a = 1.5
  output total = sum(a * f / f) * df
  output twice = scaled(a, k: order)
  output w = width
}
";

fn with_knobs(knobs: &[(&str, &str)]) -> Options {
    Options { knobs: knobs.iter().map(|(n, v)| (n.to_string(), v.to_string())).collect(), ..Default::default() }
}

/// The real scalar output `name` of scene `s` compiled with `knobs`.
fn output(knobs: &[(&str, &str)], name: &str) -> f64 {
    let program = Program::parse("knobs.gw", SCENE).unwrap_or_else(|e| panic!("{}", e.render(false)));
    let p = program.pipeline(Some("s"), with_knobs(knobs)).unwrap_or_else(|e| panic!("{e}"));
    let f = &p.optimized;
    let r = interp::interpret(f, &[1.5], &[]);
    let v = r.output(f, name).unwrap_or_else(|| panic!("no output `{name}`"));
    v[0].re
}

#[test]
fn knobs_set_the_grid_module_arguments_and_later_knobs() {
    // 41 points of 0.25 Hz: sum(a) · df = 1.5 · 41 · 0.25.
    assert_eq!(output(&[], "total"), 1.5 * 41.0 * 0.25);
    assert_eq!(output(&[], "twice"), 1.5);
    assert_eq!(output(&[], "w"), 1.0);
}

#[test]
fn overrides_relower_the_scene() {
    let program = Program::parse("knobs.gw", SCENE).unwrap();
    let p = program.pipeline(Some("s"), with_knobs(&[("df", "0.5 Hz")])).unwrap();
    assert_eq!(p.checked.grids[0].len, 21, "the grid follows the knob");
    // `--emit ir` shows the values compiled in, through every stage.
    for stage in [&p.checked, &p.optimized] {
        let text = stage.to_string();
        assert!(
            text.contains("knob df = 0.5 [Hz]") && text.contains("knob width = 2.0 [Hz]") && text.contains("knob order = 1.0 [1]"),
            "{text}"
        );
    }
    assert_eq!(output(&[("df", "0.5 Hz")], "total"), 1.5 * 21.0 * 0.5);
    // A later knob computed from an overridden one sees the new value.
    assert_eq!(output(&[("df", "0.5 Hz")], "w"), 2.0);
    // `if` on a knob is decided at compile time, either way.
    assert_eq!(output(&[("order", "2")], "twice"), 3.0);
    // Units convert: 0.0005 kHz is 0.5 Hz.
    assert_eq!(output(&[("df", "0.0005 kHz")], "total"), 1.5 * 21.0 * 0.5);
    // The program itself is unchanged.
    assert_eq!(output(&[], "total"), 1.5 * 41.0 * 0.25);
}

fn override_error(knobs: &[(&str, &str)]) -> String {
    let program = Program::parse("knobs.gw", SCENE).unwrap();
    match program.pipeline(Some("s"), with_knobs(knobs)) {
        Ok(_) => panic!("override {knobs:?} was accepted"),
        // Diagnostics with their sources, which the CLI renders in colour.
        Err(PipelineError::Compile(e)) => e.render(false),
        Err(e) => panic!("override {knobs:?}: not a diagnostic: {e}"),
    }
}

#[test]
fn an_override_of_a_misspelt_knob_suggests_the_name() {
    let e = override_error(&[("dff", "0.5 Hz")]);
    assert!(e.contains("scene `s` has no knob `dff`") && e.contains("did you mean `df`?"), "{e}");
    insta::assert_snapshot!(e);
}

#[test]
fn an_override_in_the_wrong_unit_points_into_its_text() {
    let e = override_error(&[("df", "2 s")]);
    assert!(e.contains("unit mismatch: knob `df` needs Hz, found s") && e.contains("--knob df"), "{e}");
    insta::assert_snapshot!(e);
}

#[test]
fn an_override_that_does_not_parse_is_a_syntax_error() {
    let e = override_error(&[("df", "0.5 Hz +")]);
    assert!(e.contains("--knob df"), "{e}");
    let e = override_error(&[("order", "mc")]);
    assert!(e.contains("`mc` is not a constant"), "{e}");
}

#[test]
fn bad_knob_declarations_are_reported() {
    let err = match Program::parse(
        "bad.gw",
        "scene s {\n  knob pi = 3.0\n  knob df: Hz = 0.5 Hz\n  knob x = 1.0\n  knob x = 2.0\n  param a = 1.0\n  output y = a\n}\n",
    ) {
        Ok(_) => panic!("bad knobs compiled"),
        Err(e) => e,
    };
    let text = err.render(false);
    for needle in ["knob `pi` would hide the constant `pi`", "a knob takes its unit from its value", "`x` is declared twice"] {
        assert!(text.contains(needle), "no {needle:?} in\n{text}");
    }
    assert!(err.diagnostics.iter().all(|d| d.help.is_some()));
    insta::assert_snapshot!(text);
}
