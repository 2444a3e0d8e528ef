//! Unit tests of scheduling and the kernel layout: fusion, scratch buffers, epochs and buffer lengths.

use super::abi::{BufferInfo, BufferKind, Layout, PlanBox};
use super::compile;
use super::schedule::{schedule, Schedule};
use crate::ir::*;
use crate::Program;

/// The optimised IR of scene `scene` of `src` (forward and adjoint).
fn optimized(src: &str, scene: &str) -> Function {
    let program = Program::parse("test.gw", src).unwrap_or_else(|e| panic!("{}", e.render(false)));
    program.pipeline(Some(scene), Default::default()).unwrap().optimized
}

/// The schedule of `func`, with the buffers it adds to an empty layout.
fn schedule_of(func: &Function) -> (Schedule, Layout) {
    let mut layout = Layout::empty(func.precision);
    let mut plans: Vec<PlanBox> = Vec::new();
    let sched = schedule(func, &crate::passes::precision::wide_values(func), &mut layout, &mut plans);
    (sched, layout)
}

/// The index of the grid called `name`.
fn grid(func: &Function, name: &str) -> GridId {
    GridId(func.grids.iter().position(|g| g.name == name).expect("grid exists") as u32)
}

/// How many members of `members` are reductions.
fn reductions(func: &Function, members: &[usize]) -> usize {
    members.iter().filter(|&&m| matches!(func.insts[m].op, Op::Reduce(..))).count()
}

fn scratch(layout: &Layout) -> Vec<&BufferInfo> {
    layout.buffers.iter().filter(|b| b.kind == BufferKind::Scratch).collect()
}

/// A sum of an elementwise chain, with its gradient.
const CHAIN: &str = "scene chain {
  grid f = frequencies(from: 1 Hz, to: 64 Hz, step: 1 Hz)
  param a = 0.5
  output y = sum(sin(a * f / 1 Hz) ^ 2.0)
  grad y wrt [a]
}";

#[test]
fn chain_its_sum_and_its_adjoint_share_one_loop() {
    let func = optimized(CHAIN, "chain");
    let (sched, _) = schedule_of(&func);
    // One loop computes sin(a·f)², its sum, the adjoint 2·sin·cos·f and
    // the gradient's sum: the seed dy/dsum = 1 needs no earlier reduction.
    assert_eq!(sched.loops.len(), 1, "{func}");
    let (epoch, g, ref members) = sched.loops[0];
    assert_eq!((epoch, g), (0, grid(&func, "f")));
    assert_eq!(reductions(&func, members), 2, "the value's and the gradient's sums: {func}");
    let kernel = compile(&func).unwrap();
    assert_eq!(kernel.layout.loops, 1);
}

#[test]
fn array_used_only_inside_its_loop_gets_no_buffer() {
    let func = optimized(CHAIN, "chain");
    let (sched, layout) = schedule_of(&func);
    // sin(a·f) is read by the forward and the adjoint, both in the loop:
    // it stays in registers.
    assert!(sched.stored.is_empty(), "stored {:?}: {func}", sched.stored);
    assert!(layout.buffers.is_empty(), "{:?}", layout.buffers);
    assert!(scratch(&compile(&func).unwrap().layout).is_empty());
}

#[test]
fn array_read_by_a_later_loop_gets_a_scratch_buffer() {
    // The variance reads x again after its mean (a reduction) is known: in
    // a second loop, from the buffer the first one stored x to.
    let src = "scene spread {
      grid f = frequencies(from: 1 Hz, to: 64 Hz, step: 1 Hz)
      param a = 0.5
      let x = sin(a * f / 1 Hz)
      let m = sum(x) / 64.0
      output v = sum((x - m) ^ 2.0)
    }";
    let func = optimized(src, "spread");
    let (sched, layout) = schedule_of(&func);
    assert_eq!(sched.loops.iter().map(|l| l.0).collect::<Vec<_>>(), [0, 1], "{func}");
    let x = func.insts.iter().position(|i| matches!(i.op, Op::Unary(UnOp::Sin, _))).expect("sin");
    let buf = sched.stored[&x];
    assert_eq!(layout.buffers[buf], BufferInfo { kind: BufferKind::Scratch, len: 64, complex: false, precision: Precision::F64 });
    assert!(sched.reloaded(x, 1) && !sched.reloaded(x, 0));
    assert_eq!(scratch(&layout).len(), 1, "{:?}", layout.buffers);
}

#[test]
fn transform_ends_an_epoch_and_reads_its_operand_from_a_buffer() {
    let src = "scene spectrum_power {
      grid t = times(rate: 64 Hz, duration: 1 s)
      grid f = spectrum(t)
      param a = 0.5
      let x = a * sin(2.0 * pi * 8 Hz * t)
      output p = sum(abs2(rfft(x, f)) / 1 s^2)
    }";
    let func = optimized(src, "spectrum_power");
    let (sched, layout) = schedule_of(&func);
    let d = func.insts.iter().position(|i| matches!(i.op, Op::Dft(..))).expect("a transform");
    let Op::Dft(_, x) = func.insts[d].op else { unreachable!() };
    // x is computed and stored in a loop over t; the transform runs
    // before the next epoch, whose loop over f reads its result.
    assert_eq!(sched.epoch[d], sched.epoch[x.index()] + 1);
    assert_eq!(sched.calls[sched.epoch[d] as usize], [d]);
    let loops: Vec<(u32, GridId)> = sched.loops.iter().map(|l| (l.0, l.1)).collect();
    assert_eq!(loops, [(0, grid(&func, "t")), (1, grid(&func, "f"))], "{func}");
    let operand = &layout.buffers[sched.stored[&x.index()]];
    assert_eq!((operand.kind.clone(), operand.len, operand.complex), (BufferKind::Scratch, 64, false));
    let result = &layout.buffers[sched.stored[&d]];
    assert_eq!((result.kind.clone(), result.len, result.complex), (BufferKind::Scratch, 33, true));
}

#[test]
fn layout_lists_inputs_outputs_and_scalar_slots() {
    let src = "scene shapes {
      grid f = frequencies(from: 1 Hz, to: 16 Hz, step: 1 Hz)
      input d: complex[f] = 1.0
      param a = 0.5
      output h = a * d
      output s = sum(d)
      output n = a * 2.0
    }";
    let func = optimized(src, "shapes");
    let layout = compile(&func).unwrap().layout.clone();
    let input = BufferInfo { kind: BufferKind::Input(0), len: 16, complex: true, precision: Precision::F64 };
    assert_eq!(layout.buffers[0], input);
    // The array output has a buffer of the grid's length; the scalars have
    // slots, two for the complex sum.
    let h = layout.outputs[0].expect("an array output has a buffer");
    assert_eq!(layout.buffers[h], BufferInfo { kind: BufferKind::Output(0), len: 16, complex: true, precision: Precision::F64 });
    assert_eq!(&layout.outputs[1..], [None, None]);
    let slot = |o: usize| layout.scalars.iter().find(|s| s.value == func.outputs[o].value).cloned();
    let (s, n) = (slot(1).expect("slot of s"), slot(2).expect("slot of n"));
    assert!(s.complex && !n.complex);
    assert_eq!(layout.scalar_slots, 3);
    let mut slots = [s.slot, s.slot + 1, n.slot];
    slots.sort();
    assert_eq!(slots, [0, 1, 2]);
}
