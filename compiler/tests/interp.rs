//! The reference interpreter's streaming form, which the compiler's
//! compile-time evaluations (grid folding, f32 rescaling) use: it must see
//! the same values as the plain interpreter and free what it does not keep.

use gwml_compiler::kernels::interp;
use gwml_compiler::{Options, Program};

const SCENE: &str = "scene s {
  grid t = times(rate: 64 Hz, duration: 2 s)
  grid f = spectrum(t)
  param a = 1.5
  param b = 0.5
  let h = a * sin(6.0 * t / 1 s) + b * cos(t * t / 1 s^2)
  let hf = rfft(h, f)
  output wave = h
  output power = sum(abs(hf)^2)
  grad power wrt [a, b]
}
";

#[test]
fn streaming_sees_every_value_and_keeps_only_what_it_is_asked_to() {
    let program = Program::parse("s.gw", SCENE).unwrap();
    let func = program.pipeline(None, Options::default()).unwrap().optimized;
    let params = [1.3, 0.7];
    let plain = interp::interpret(&func, &params, &[]);
    let wanted = vec![true; func.insts.len()];
    let keep = func.outputs[0].value.index();
    let mut seen = vec![false; func.insts.len()];
    let streamed = interp::interpret_streaming(&func, &params, &[], &wanted, |i, t| {
        assert_eq!(t, &plain.values[i], "instruction {i}");
        seen[i] = true;
        i == keep
    });
    assert!(seen.iter().all(|s| *s), "every wanted instruction is visited");
    assert_eq!(streamed.values[keep], plain.values[keep]);
    let arrays = func.insts.iter().filter(|inst| func.len_of(inst.ty.shape) > 1).count();
    let freed = (0..func.insts.len()).filter(|&i| i != keep && streamed.values[i].is_empty()).count();
    assert!(arrays > 3 && freed == func.insts.len() - 1, "{freed} of {} values freed", func.insts.len() - 1);
}

#[test]
fn streaming_evaluates_only_the_wanted_instructions() {
    let program = Program::parse("s.gw", SCENE).unwrap();
    let func = program.pipeline(None, Options::default()).unwrap().optimized;
    // Grid coordinates and constants only: nothing that reads a param.
    let wanted: Vec<bool> =
        func.insts.iter().map(|inst| inst.op.operands().is_empty() && !matches!(inst.op, gwml_compiler::ir::Op::Param(_))).collect();
    let mut visited = Vec::new();
    let r = interp::interpret_streaming(&func, &[f64::NAN, f64::NAN], &[], &wanted, |i, _| {
        visited.push(i);
        true
    });
    let expected: Vec<usize> = (0..func.insts.len()).filter(|i| wanted[*i]).collect();
    assert_eq!(visited, expected);
    assert!((0..func.insts.len()).all(|i| wanted[i] != r.values[i].is_empty()));
}
