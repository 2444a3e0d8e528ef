//! The REPL, driven through piped standard input (golden transcripts) and
//! through a pseudo-terminal (line editing: completion, multi-line, Ctrl-C).

use std::io::Write;
use std::process::{Command, Stdio};

fn piped(input: &str) -> (bool, String) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_gwml"))
        .arg("repl")
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("gwml starts");
    child.stdin.take().expect("stdin").write_all(input.as_bytes()).expect("write");
    let out = child.wait_with_output().expect("gwml exits");
    (out.status.success(), String::from_utf8_lossy(&out.stdout).into_owned())
}

/// `:qscan EXPR`: the loudest tile of a sine-Gaussian at 1 s, 200 Hz, Q 9 is
/// found where it is; arrays over other grids, scalars and bad strain
/// arguments are errors that keep the session.
#[test]
fn qscan_of_an_expression_and_of_a_strain_file() {
    let scratch = tempfile::Builder::new().prefix("gwml-repl-qscan-").tempdir().unwrap();
    let png = scratch.path().join("qscan.png");
    let (ok, out) = piped(&format!(
        "grid t = times(rate: 4096 Hz, duration: 2 s)
let x = exp(-((t - 1 s) / 7 ms)^2) * sin(2.0 * pi * 200 Hz * (t - 1 s))
:qscan x to {}
:qscan 3.0
grid f = frequencies(from: 20 Hz, to: 512 Hz, step: 0.25 Hz)
:qscan f
:qscan missing.hdf5 --gps 1264000000
:qscan missing.hdf5 --gpss 3
",
        png.display()
    ));
    assert!(!ok, "the failed lines set the exit status");
    let line = out.lines().find(|l| l.starts_with("Q ")).unwrap_or_else(|| panic!("a Q-scan line: {out}"));
    let number_after = |key: &str| -> f64 {
        let rest = &line[line.find(key).unwrap_or_else(|| panic!("`{key}` in {line}")) + key.len()..];
        rest.trim_start().split([' ', ',']).next().unwrap().parse().unwrap()
    };
    let (time, freq) = (number_after("loudest tile at"), number_after("s,"));
    assert!((time - 1.0).abs() < 0.01, "peak time {time} s: {line}");
    assert!((freq - 200.0).abs() < 0.1 * 200.0, "peak frequency {freq} Hz: {line}");
    assert_eq!(&std::fs::read(&png).expect("Q-scan written")[1..4], b"PNG");
    assert!(out.contains(":qscan needs a real array over a time grid"), "{out}");
    assert!(out.contains("`f` is in Hz"), "{out}");
    assert!(out.contains("missing.hdf5"), "the strain form reads the file as gwml qscan does: {out}");
    assert!(out.contains("unexpected argument '--gpss'"), "{out}");
}

/// An entry whose checking or evaluation fails changes nothing (issue
/// #27): a param without a default and a `let` that evaluates to -inf are
/// reported and forgotten; `:undef` refuses a name still in use and forgets
/// an unused one; `:reset` forgets everything but the precision, which
/// `:save` writes into the scene.
#[test]
fn failed_entries_roll_back_and_definitions_can_be_forgotten() {
    let scratch = tempfile::Builder::new().prefix("gwml-repl-undef-").tempdir().unwrap();
    let saved = scratch.path().join("saved.gw");
    let (ok, out) = piped(&format!(
        "param m: Msun
1 + 1
param q = 0.0
let z = log(q)
:defs
let y = q + 1
let w = y * 2
:undef y
:undef w
:undef y
:undef nope
:precision f32
param k = 3.0
:save {}
:reset
:defs
k
2 + 2
",
        saved.display()
    ));
    assert!(!ok, "failed entries set the exit status");
    assert!(out.contains("param `m` has no default"), "{out}");
    assert!(out.contains("gw> 1 + 1\n2\n"), "a failed param does not break later entries: {out}");
    assert!(out.contains("error: `z` is not finite"), "the error names what was typed: {out}");
    let defs = out.split("gw> :defs\n").nth(1).unwrap().split("gw>").next().unwrap();
    assert_eq!(defs.trim(), "param q = 0.0", "only the entries that succeeded are kept: {out}");
    assert!(out.contains("`y` is still used"), "{out}");
    assert!(out.contains("forgot w") && out.contains("forgot y"), "{out}");
    assert!(out.contains("the session defines no `nope`"), "{out}");
    let text = std::fs::read_to_string(&saved).expect(":save wrote the session");
    assert!(text.contains("precision: f32") && text.contains("param k = 3.0"), "{text}");
    let after_reset = out.split("gw> :reset\n").nth(1).unwrap();
    assert!(after_reset.contains("unknown name `k`") && after_reset.contains("gw> 2 + 2\n4\n"), "{after_reset}");
    // `:run` takes values with units, as `--set` does.
    let (_, out) = piped(":load examples/chirp_fit.gw\n:run chirp_fit tc=2 ms mc=30 Msun\n:run chirp_fit tc=2 Hz\n");
    let with_units: f64 =
        out.lines().find_map(|l| l.strip_prefix("loss = ")).and_then(|v| v.split_whitespace().next()?.parse().ok()).unwrap();
    let (_, plain) = piped(":load examples/chirp_fit.gw\n:run chirp_fit tc=0.002 mc=30\n");
    let without: f64 =
        plain.lines().find_map(|l| l.strip_prefix("loss = ")).and_then(|v| v.split_whitespace().next()?.parse().ok()).unwrap();
    assert_eq!(with_units, without, "{out}");
    assert!(out.contains("param `tc` is in s"), "{out}");
    let _ = std::fs::remove_file(&saved);
}

#[test]
fn transcript_definitions_values_and_gradients() {
    let (ok, out) = piped(
        "let a = 2.0 * pi
param x = 0.5
sin(x) * a
:grad sin(x) * x wrt x
grid f = frequencies(from: 20 Hz, to: 24 Hz, step: 1 Hz)
f * 2.0 s
:type f * 2.0
module sq(y) {
    y * y
}
sq(x) + 1.0
cis(x)
let a = 3.0
a * x
:precision f32
sum(f / 1 Hz)
",
    );
    assert!(ok, "{out}");
    insta::assert_snapshot!(out);
}

/// A `knob` is a named constant a grid may use, shown like a `let`.
#[test]
fn knob_sets_a_grid_step() {
    let (ok, out) = piped("knob df = 0.5 Hz\ngrid g = frequencies(from: 1 Hz, to: 3 Hz, step: df)\nsum(g / 1 Hz)\n");
    assert!(ok, "{out}");
    assert!(out.contains("df = 0.5"), "{out}");
    // 1 + 1.5 + 2 + 2.5 + 3.
    assert!(out.lines().any(|l| l.trim() == "10"), "{out}");
}

#[test]
fn transcript_learned_component() {
    let (ok, out) = piped(
        "use std::nn::{relu}
grid c = index(3)
learned net(v) {
    weight w: [2, 3] = ones
    weight b: [2] = zeros
    relu(dense(v, w, b))
}
let v = c - 1.0
sum(net(v))
net(v + 1.0)
:type net(v)
",
    );
    assert!(ok, "{out}");
    insta::assert_snapshot!(out);
}

#[test]
fn errors_keep_the_session_and_set_the_exit_status() {
    let (ok, out) = piped("let a = 1.5\nfoo + a\nlet b = a +\na * 2.0\n:bogus\n");
    assert!(!ok, "a failed line makes the exit status non-zero");
    insta::assert_snapshot!(out);
}

/// Compile errors point at the text typed (`<input>`), or at the earlier
/// definition an entry breaks (`<session NAME>`), never at the program the
/// REPL builds or its generated names.
#[test]
fn errors_point_at_the_typed_text() {
    let (ok, out) = piped("param a = 1.0\nlet b = sin(a)\n:grad a * x wrt a, x\n:grad a * 2.0 wrt q\nlet a = 1 Hz\n:grad cis(a) wrt a\n");
    assert!(!ok);
    assert!(out.contains("╭─[ <input>:1:11 ]\n   │\n 1 │ :grad a * x wrt a, x\n"), "the unknown `x` of the expression: {out}");
    assert!(out.contains("╭─[ <input>:1:19 ]\n   │\n 1 │ :grad a * 2.0 wrt q\n"), "the `q` after wrt: {out}");
    assert!(out.contains("╭─[ <session b>:1:13 ]") && out.contains("<session b> was defined earlier"), "the definition broken: {out}");
    assert!(out.contains("cannot differentiate the entry: it is complex"), "{out}");
    assert!(!out.contains("<repl>") && !out.contains("__value") && !out.contains("__repl"), "{out}");
    assert!(out.contains("gw> :grad cis(a) wrt a"), "{out}");
    // A loaded file's modules keep their own lines.
    let scratch = tempfile::Builder::new().prefix("gwml-repl-lines-").tempdir().unwrap();
    let dir = scratch.path();
    let file = dir.join("m.gw");
    std::fs::write(
        &file,
        "scene s {\n    // µs: the scene is blanked byte for byte\n    output y = 1.0\n}\nmodule wave(x) {\n    sin(x)\n}\n",
    )
    .unwrap();
    let (_, out) = piped(&format!(":load {}\nwave(1 Hz)\nwave(0.0)\n", file.display()));
    assert!(out.contains(&format!("╭─[ {}:6:9 ]", file.display())), "an error inside the file names its line: {out}");
    assert!(out.contains("gw> wave(0.0)\n0\n"), "{out}");
}

#[test]
fn load_run_save_and_inspect() {
    let scratch = tempfile::Builder::new().prefix("gwml-repl-").tempdir().unwrap();
    let dir = scratch.path();
    let saved = dir.join("session.gw");
    let png = dir.join("plot.png");
    let (ok, out) = piped(&format!(
        ":load examples/chirp_fit.gw
:run chirp_fit mc=30 tc=0.002 phic=0.3
param k = 2.0
grid t = times(rate: 64 Hz, duration: 1 s)
let wave = sin(2.0 * pi * 3 Hz * t) * k
:plot wave to {}
:ir sum(wave)
:adjoint sum(wave) wrt k
:clif k * 2.0
:time k * 2.0
:time sin(k) * k wrt k
toy_psd(100 Hz)
:save {}
",
        png.display(),
        saved.display()
    ));
    assert!(ok, "{out}");
    // Entries are evaluated without the loaded scenes, but with its modules.
    assert!(out.contains("gw> toy_psd(100 Hz)\n"), "{out}");
    assert!(out.contains("loss = 0"), "the chirp at its true parameters has zero loss: {out}");
    assert!(out.contains("dloss/dmc = 0"), "{out}");
    assert!(out.contains("= sum %"), "IR dump: {out}");
    assert!(out.contains("grad d__value/dk"), "adjoint dump: {out}");
    assert!(out.contains("function") && out.contains("return"), "CLIF dump: {out}");
    assert!(out.contains("runs (value)") && out.contains("runs (value and gradient)"), "{out}");
    let png_bytes = std::fs::read(&png).expect("plot written");
    assert_eq!(&png_bytes[1..4], b"PNG");
    let text = std::fs::read_to_string(&saved).expect("session saved");
    gwml::compile_str("session.gw", &text).expect("the saved session compiles");
    assert!(text.contains("let wave") && text.contains("param k"));
    assert!(text.contains("scene chirp_fit {"), "the saved session keeps the loaded scene: {text}");
}

#[test]
fn terminal_completion_multiline_and_ctrl_c() {
    let bin = env!("CARGO_BIN_EXE_gwml");
    let scratch = tempfile::Builder::new().prefix("gwml-pty-").tempdir().unwrap();
    let home = scratch.path();
    let mut cmd = Command::new(bin);
    cmd.arg("repl").env("XDG_DATA_HOME", home).env("TERM", "xterm");
    let mut p = rexpect::session::spawn_command(cmd, Some(10_000)).expect("spawn in a pty");
    // Wait for the prompt, then a moment: the editor prints the prompt before
    // it puts the terminal in raw mode, and keys sent earlier can be lost.
    let prompt = |p: &mut rexpect::session::PtySession| {
        p.exp_string("gw> ").unwrap();
        std::thread::sleep(std::time::Duration::from_millis(200));
    };
    prompt(&mut p);
    // Completion: `let alpha`, then `alp<TAB>` completes the name.
    p.send_line("let alpha = 4.0").unwrap();
    p.exp_string("alpha = 4").unwrap();
    prompt(&mut p);
    p.send("alp\t * 2.0").unwrap();
    p.send_line("").unwrap();
    p.exp_string("8").unwrap();
    prompt(&mut p);
    // Multi-line: the line continues while a brace is open.
    p.send_line("module twice(y) {").unwrap();
    p.send_line("  y * 2.0 }").unwrap();
    p.exp_string("ok").unwrap();
    prompt(&mut p);
    p.send_line("twice(alpha)").unwrap();
    p.exp_string("8").unwrap();
    prompt(&mut p);
    // Ctrl-C cancels the line being typed; the session goes on.
    p.send("1 + ").unwrap();
    p.send_control('c').unwrap();
    prompt(&mut p);
    p.send_line("alpha + 1.0").unwrap();
    p.exp_string("5").unwrap();
    prompt(&mut p);
    // Ctrl-D leaves.
    p.send_control('d').unwrap();
    p.exp_eof().unwrap();
    assert!(home.join("gwml/history").exists(), "history is saved under the data directory");
}
