//! Snapshot tests of rendered diagnostics: one test per kind of mistake,
//! named after what it guards. Every diagnostic must point at a span, say
//! what is wrong and carry a help line.
//!
//! Regenerate with `INSTA_UPDATE=always cargo test -p gwml-compiler --test diagnostics`
//! and review every changed `.snap` file.

use gwml_compiler::{CompileError, Program};

/// Compiles `src`, which must fail; checks that every diagnostic has a
/// message, a non-empty span inside the file and a help line, and returns
/// the error.
fn fail(src: &str) -> CompileError {
    let err = match Program::parse("test.gw", src) {
        Ok(p) => panic!("expected a compile error, but it compiled; scenes: {:?}", p.scene_names()),
        Err(e) => e,
    };
    assert!(!err.diagnostics.is_empty());
    for d in &err.diagnostics {
        assert!(!d.message.is_empty(), "diagnostic without a message: {d:?}");
        assert!(d.help.is_some(), "diagnostic without help: {d:?}");
        let len = err.sources.get(d.span.file).text.len();
        assert!(d.span.start <= d.span.end && d.span.end <= len, "span {:?} outside the file: {d:?}", d.span);
    }
    err
}

/// The messages of `err`, in order.
fn messages(err: &CompileError) -> Vec<&str> {
    err.diagnostics.iter().map(|d| d.message.as_str()).collect()
}

/// Asserts that some diagnostic's message contains `needle`.
fn assert_reports(err: &CompileError, needle: &str) {
    assert!(messages(err).iter().any(|m| m.contains(needle)), "no diagnostic mentions {needle:?}; got {:#?}", messages(err));
}

/// Asserts that some diagnostic's help contains `needle`.
fn assert_helps(err: &CompileError, needle: &str) {
    assert!(
        err.diagnostics.iter().any(|d| d.help.as_deref().is_some_and(|h| h.contains(needle))),
        "no help mentions {needle:?}; got {:#?}",
        err.diagnostics.iter().map(|d| &d.help).collect::<Vec<_>>()
    );
}

#[test]
fn several_syntax_errors_are_reported_in_one_run() {
    let err = fail(
        "scene broken {
  param x = 0.3 +
  let a = x * * 2.0
  output y = (x + 1.0
  output z = x
}
",
    );
    assert!(err.diagnostics.len() >= 3, "{:#?}", messages(&err));
    let syntax_level = |m: &&str| m.starts_with("syntax error") || m.starts_with("unclosed") || m.contains("is missing an operand");
    assert!(messages(&err).iter().all(syntax_level), "{:#?}", messages(&err));
    assert!(messages(&err).contains(&"unclosed `(`"), "{:#?}", messages(&err));
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unexpected_character_is_reported_and_skipped() {
    let err = fail("scene s {\n  param x = 0.3\n  output y = x # 2.0\n}\n");
    assert_reports(&err, "unexpected character `#`");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unknown_name_suggests_a_close_match() {
    let err = fail("scene s {\n  param phic = 0.1\n  output y = 2.0 * phci\n}\n");
    assert_reports(&err, "unknown name `phci`");
    assert_helps(&err, "did you mean `phic`?");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unknown_name_without_a_close_match_says_how_to_define_it() {
    let err = fail("scene s {\n  param x = 0.1\n  output y = x * amplitude\n}\n");
    assert_reports(&err, "unknown name `amplitude`");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unknown_function_suggests_a_builtin() {
    let err = fail("scene s {\n  param x = 0.1\n  output y = sqr(x) + frobnicate(x)\n}\n");
    assert_reports(&err, "unknown function `sqr`");
    assert_reports(&err, "unknown function `frobnicate`");
    assert_helps(&err, "did you mean `sqrt`?");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unknown_unit_in_a_param_and_an_input_type() {
    let err = fail(
        "scene s {
  grid f = frequencies(from: 20 Hz, to: 30 Hz, step: 1 Hz)
  param m: Msn = 30.0
  input d: real[f] sec
  output y = m * sum(d)
}
",
    );
    assert_reports(&err, "unknown unit `Msn`");
    assert_reports(&err, "unknown unit `sec`");
    assert_helps(&err, "did you mean `Msun`?");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn builtin_arity_mismatch() {
    let err = fail("scene s {\n  param x = 0.1\n  output y = sin(x, x) + atan2(x)\n}\n");
    assert_reports(&err, "`sin` takes 1 argument, but 2 were given");
    assert_reports(&err, "`atan2` takes 2 arguments, but 1 was given");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn module_arity_mismatch() {
    let err = fail(
        "module add(a, b) {
  a + b
}

scene s {
  param x = 0.1
  output too_many = add(x, x, x)
  output too_few = add(x)
}
",
    );
    assert_reports(&err, "module `add` takes 2 arguments, but more were given");
    assert_reports(&err, "missing argument `b` in call to `add`");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn complex_value_where_a_real_is_needed() {
    let err = fail("scene s {\n  param x = 0.1\n  let z = x + 2.0i\n  output y = sin(z)\n}\n");
    assert_reports(&err, "`sin` needs a real value, found complex");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn shape_mismatch_between_arrays_on_two_grids() {
    let err = fail(
        "scene s {
  grid f = frequencies(from: 20 Hz, to: 30 Hz, step: 1 Hz)
  grid t = times(rate: 16 Hz, duration: 1 s)
  output y = sum(f * t)
}
",
    );
    assert_reports(&err, "shape mismatch: real[f] and real[t]");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unit_mismatch_adding_msun_to_mpc() {
    let err = fail("scene s {\n  param m: Msun = 30.0\n  param d: Mpc = 400.0\n  output y = m + d\n}\n");
    assert_reports(&err, "unit mismatch: cannot add Msun and m");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unit_mismatch_in_a_grid_argument() {
    let err = fail(
        "scene s {
  grid f = frequencies(from: 20 s, to: 1024 Hz, step: 0.125 Hz)
  param x = 1.0
  output y = x
}
",
    );
    assert_reports(&err, "unit mismatch: `from` of `frequencies` needs Hz, found s");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn grad_with_respect_to_an_input() {
    let err = fail(
        "scene s {
  grid f = frequencies(from: 20 Hz, to: 30 Hz, step: 1 Hz)
  input d: real[f]
  param a = 1.0
  output loss = sum((d - a) ^ 2.0)
  grad loss wrt [a, d]
}
",
    );
    assert_reports(&err, "cannot take a gradient with respect to `d`");
    assert_helps(&err, "declare it as `param d`");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn grad_with_respect_to_a_misspelt_param() {
    let err = fail("scene s {\n  param phic = 0.1\n  output loss = phic * phic\n  grad loss wrt [phci]\n}\n");
    assert_reports(&err, "cannot take a gradient with respect to `phci`");
    assert_helps(&err, "did you mean `phic`?");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn grad_of_a_non_scalar_output() {
    let err = fail(
        "scene s {
  grid f = frequencies(from: 20 Hz, to: 30 Hz, step: 1 Hz)
  param a = 1.0
  output spectrum = a * f / 1 Hz
  grad spectrum wrt [a]
}
",
    );
    assert_reports(&err, "cannot differentiate `spectrum`: it is real[f], not a real scalar");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn grad_of_a_complex_output() {
    let err = fail("scene s {\n  param a = 1.0\n  output z = a * 1.0i\n  grad z wrt [a]\n}\n");
    assert_reports(&err, "cannot differentiate `z`: it is complex, not a real scalar");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn cyclic_let_definitions() {
    let err = fail(
        "scene s {
  param x = 1.0
  let a = b + x
  let b = 2.0 * a
  output y = a
}
",
    );
    assert_reports(&err, "cyclic definition");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn module_that_calls_itself() {
    let err = fail(
        "module fact(n) {
  n * fact(n - 1.0)
}

scene s {
  param x = 3.0
  output y = fact(x)
}
",
    );
    assert_reports(&err, "cyclic definition: module `fact` calls itself");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn modules_that_call_each_other() {
    let err = fail(
        "module ping(a) {
  pong(a) + 1.0
}

module pong(a) {
  ping(a) * 2.0
}

scene s {
  param x = 3.0
  output y = ping(x)
}
",
    );
    assert_reports(&err, "cyclic definition: module `ping` calls itself");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn use_of_a_path_outside_the_standard_library() {
    let err = fail("use foo::bar::{baz}\n\nscene s {\n  param x = 1.0\n  output y = x\n}\n");
    assert_reports(&err, "cannot import from `foo::bar`");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn use_of_a_misspelt_standard_library_file() {
    let err = fail("use std::detectr::{inner}\n\nscene s {\n  param x = 1.0\n  output y = x\n}\n");
    assert_reports(&err, "no standard library file `detectr`");
    assert_helps(&err, "did you mean `std::detector`?");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn use_of_a_missing_standard_library_module() {
    let err = fail("use std::detector::{innr, norm2}\n\nscene s {\n  param x = 1.0\n  output y = x\n}\n");
    assert_reports(&err, "`std::detector` has no module `innr`");
    assert_helps(&err, "did you mean `inner`?");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn param_default_outside_its_bounds() {
    let err = fail("scene s {\n  param mc: Msun = 200.0 in 5.0..100.0\n  output y = mc\n}\n");
    assert_reports(&err, "default 200 of `mc` is outside its bounds 5..100");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn param_with_empty_bounds() {
    let err = fail("scene s {\n  param tc: s = 0.0 in 0.1..-0.1\n  output y = tc\n}\n");
    assert_reports(&err, "empty bounds");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn diagnostics_come_out_in_a_stable_order() {
    let src = "module a1(x) { x + u1 }\nmodule a2(x) { x + u2 }\nmodule a3(x) { x + u3 }\nmodule a4(x) { x + u4 }\nmodule a5(x) { x + u5 }\n\nscene s {\n  param x = 1.0\n  output y = x\n}\n";
    let first = messages(&fail(src)).iter().map(|s| s.to_string()).collect::<Vec<_>>();
    for _ in 0..20 {
        let again = messages(&fail(src)).iter().map(|s| s.to_string()).collect::<Vec<_>>();
        assert_eq!(again, first, "diagnostic order changed between two parses of the same file");
    }
    let want: Vec<String> = (1..=5).map(|i| format!("unknown name `u{i}`")).collect();
    assert_eq!(first, want, "diagnostics are not in source order");
}

#[test]
fn rfft_onto_a_grid_that_is_not_the_spectrum() {
    let err = fail(
        "scene s {\n  grid t = times(rate: 64 Hz, duration: 1 s)\n  grid f = frequencies(from: 0 Hz, to: 32 Hz, step: 2 Hz)\n  param a = 1.0\n  output y = sum(abs(rfft(a * t, f)))\n}\n",
    );
    assert_reports(&err, "not a time grid and its spectrum");
    assert_helps(&err, "grid f = spectrum(t)");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn irfft_needs_a_time_grid() {
    let err = fail(
        "scene s {\n  grid t = times(rate: 64 Hz, duration: 1 s)\n  grid f = spectrum(t)\n  param a = 1.0\n  output y = sum(irfft(a * f, f))\n}\n",
    );
    assert_reports(&err, "needs a time grid here");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn spectrum_of_a_frequency_grid() {
    let err = fail(
        "scene s {\n  grid f = frequencies(from: 0 Hz, to: 32 Hz, step: 1 Hz)\n  grid g = spectrum(f)\n  param a = 1.0\n  output y = a\n}\n",
    );
    assert_reports(&err, "is not a time grid");
    insta::assert_snapshot!(err.render(false));
}

/// The scene every learned-component test below calls `net` from.
fn learned_scene(body: &str) -> String {
    format!(
        "learned net(x) {{\n{body}\n}}\nscene s {{\n  grid t = times(rate: 16 Hz, duration: 1 s)\n  input x: real[t] = 0.0\n  output y = net(x)\n  grad y wrt net\n}}\n"
    )
}

#[test]
fn dense_weight_of_the_wrong_shape() {
    let err = fail(&learned_scene("  weight w: [3, 15] = glorot\n  sum(dense(x, w))"));
    assert_reports(&err, "the weight of `dense` has shape [3, 15], but the layer needs [3, 16]");
    assert_helps(&err, "weight NAME: [3, 16]");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn conv1d_kernel_longer_than_its_input_and_bad_channels() {
    let err = fail(&learned_scene(
        "  weight k: [2, 1, 9] = he\n  weight k2: [4, 3, 2] = he\n  let h = conv1d(x, k, dilation: 3)\n  sum(h) + sum(conv1d(conv1d(x, k), k2))",
    ));
    assert_reports(&err, "the kernel spans 25 samples but the input has 16");
    assert_reports(&err, "the weight of `conv1d` has shape [4, 3, 2], but the layer needs [4, 2, 2]");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn conv2d_of_a_time_series_and_a_kernel_taller_than_the_image() {
    let err = fail(&learned_scene(
        "  weight k: [2, 1, 3, 3] = he\n  weight k2: [1, 1, 5, 2] = he\n  sum(conv2d(x, k)) + sum(conv2d(reshape(x, 4, 4), k2))",
    ));
    assert_reports(&err, "`conv2d` needs an image [channels, rows, columns] or [rows, columns], but this has shape [16]");
    assert_helps(&err, "reshape(x, c, h, w)");
    assert_reports(&err, "the kernel spans 5 rows but the input has 4 (with padding)");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn stack_of_arrays_of_different_lengths() {
    let err = fail(&learned_scene("  sum(stack(x, max_pool(x, 2)))"));
    assert_reports(&err, "`stack` needs arrays of the same length, but this one has 8 positions");
    assert_helps(&err, "pool or resample");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn weight_with_an_unknown_initialiser_or_bad_dimension() {
    let err = fail(&learned_scene(
        "  weight a: [4] = glorrot\n  weight b: [2.5] = zeros\n  weight c: [3] = normal(seed: 1)\n  sum(a) + sum(b) + sum(c)",
    ));
    assert_helps(&err, "did you mean `glorot`?");
    assert_reports(&err, "a weight dimension must be a whole number");
    assert_reports(&err, "`normal` needs `std`");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn weight_in_a_plain_module() {
    let err = fail("module m(x) {\n  weight w: [2] = zeros\n  x\n}\nscene s {\n  param p = 1.0\n  output y = m(p)\n}\n");
    assert_reports(&err, "module `m` declares a weight");
    assert_helps(&err, "learned m(...)");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn gradient_with_respect_to_an_unused_learned_component() {
    let err = fail(
        "learned net(x) {\n  weight w: [2] = zeros\n  sum(w) * x\n}\nscene s {\n  param p = 1.0\n  output y = p * p\n  grad y wrt net\n}\n",
    );
    assert_reports(&err, "learned component `net` has no weights in this scene");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn layer_on_a_value_with_units() {
    let err = fail(&learned_scene("  weight w: [2, 16] = glorot\n  sum(dense(x * 3 Hz, w))"));
    assert_reports(&err, "`dense` needs a dimensionless real array here");
    insta::assert_snapshot!(err.render(false));
}

#[test]
fn unknown_precision_and_math_settings_name_the_valid_spellings() {
    let err = fail("scene s {\n    precision: f16\n    math: quick\n    output y = 1.0\n}\n");
    assert_reports(&err, "unknown precision `f16`");
    assert_reports(&err, "unknown math mode `quick`");
    assert_helps(&err, "f64, f32 or mixed");
    assert_helps(&err, "exact");
    let spans: Vec<&str> = err.diagnostics.iter().map(|d| &err.sources.get(d.span.file).text[d.span.start..d.span.end]).collect();
    assert_eq!(spans, ["f16", "quick"]);
}

#[test]
fn transposed_convolution_upsampling_reshape_and_noise_misuse() {
    let err = fail(&learned_scene(
        "  weight k: [1, 2, 3] = he\n  weight k2: [3, 1, 2] = he\n  \
         let a = conv_transpose1d(x, k, stride: 2, output_padding: 2)\n  \
         let b = conv_transpose1d(x, k, padding: 40)\n  \
         let c = conv_transpose1d(conv_transpose1d(x, k), k2)\n  \
         let d = reshape(x, 7)\n  \
         let e = randn(2.5)\n  \
         let f = upsample(x, 0)\n  \
         sum(a) + sum(b) + sum(c) + sum(d) + sum(e) + sum(f)",
    ));
    assert_reports(&err, "`output_padding` (2) must be smaller than the stride or the dilation");
    assert_reports(&err, "the output would have -62 positions: the padding (40) is too large");
    assert_reports(&err, "the weight of `conv_transpose1d` has shape [3, 1, 2], but the layer needs [2, 1, 2]");
    assert_reports(&err, "`reshape` needs as many values as shape [7] holds (7), but this has 16");
    assert_reports(&err, "the number of values of `randn` must be a whole number ≥ 1");
    assert_reports(&err, "an upsampling factor must be a whole number ≥ 1");
    insta::assert_snapshot!(err.render(false));
}
