//! Golden tests: snapshots of the AST dump and of the IR after each stage for
//! examples/chirp_fit.gw, and a small scene whose IR shows pruning and
//! activity analysis at work (with explicit assertions, not only snapshots).
//!
//! Regenerate with `INSTA_UPDATE=always cargo test -p gwml-compiler --test golden`
//! and review every changed `.snap` file.

use gwml_compiler::front::source::FileId;
use gwml_compiler::front::syntax::{parse, print_ast};
use gwml_compiler::ir::{Function, Op, UnOp, Value};
use gwml_compiler::{Program, ScenePipeline};
use std::collections::HashSet;

const CHIRP_FIT: &str = include_str!("../../examples/chirp_fit.gw");

fn pipeline(name: &str, src: &str, scene: &str) -> ScenePipeline {
    let program = Program::parse(name, src).unwrap_or_else(|e| panic!("{}", e.render(false)));
    program.pipeline(Some(scene), Default::default()).unwrap()
}

#[test]
fn chirp_fit_ast() {
    let (ast, diags) = parse(CHIRP_FIT, FileId(0));
    assert!(diags.is_empty(), "{diags:?}");
    // The driver's AST is the same tree.
    let program = Program::parse("chirp_fit.gw", CHIRP_FIT).unwrap();
    assert_eq!(print_ast(&program.ast), print_ast(&ast));
    insta::assert_snapshot!(print_ast(&ast));
}

#[test]
fn chirp_fit_checked_ir() {
    insta::assert_snapshot!(pipeline("chirp_fit.gw", CHIRP_FIT, "chirp_fit").checked.to_string());
}

#[test]
fn chirp_fit_pruned_ir() {
    insta::assert_snapshot!(pipeline("chirp_fit.gw", CHIRP_FIT, "chirp_fit").pruned.to_string());
}

#[test]
fn chirp_fit_adjoint_ir() {
    insta::assert_snapshot!(pipeline("chirp_fit.gw", CHIRP_FIT, "chirp_fit").adjoint.to_string());
}

#[test]
fn chirp_fit_optimized_ir() {
    let pl = pipeline("chirp_fit.gw", CHIRP_FIT, "chirp_fit");
    for f in [&pl.checked, &pl.pruned, &pl.adjoint, &pl.optimized] {
        f.verify().unwrap();
    }
    // Every requested gradient is computed, in request order.
    let grads: Vec<_> = pl.optimized.grads.iter().map(|g| (pl.optimized.params[g.param].name.as_str(), g.value.is_some())).collect();
    assert_eq!(grads, [("mc", true), ("tc", true), ("phic", true)]);
    assert!(pl.stats.optimized_ops < pl.stats.adjoint_ops, "simplify removed nothing: {:?}", pl.stats);
    insta::assert_snapshot!(pl.optimized.to_string());
}

#[test]
fn chirp_fit_is_deterministic() {
    // Module tables are hash maps: the IR must not depend on their order.
    let first = pipeline("chirp_fit.gw", CHIRP_FIT, "chirp_fit");
    for _ in 0..10 {
        let again = pipeline("chirp_fit.gw", CHIRP_FIT, "chirp_fit");
        assert_eq!(again.checked, first.checked);
        assert_eq!(again.optimized, first.optimized);
    }
}

/// A scene with dead code (an unused `let`, a `let` calling a module no
/// output needs, a module nobody calls) and a param `c` that the output
/// depends on but no gradient is requested for.
const PRUNE_DEMO: &str = "module used_helper(a) {
  a + 1.0
}

// Only reached from an unused let.
module unused_helper(a) {
  tanh(a) * 3.0
}

// Never called at all.
module never_called(a) {
  cbrt(a) * 5.0
}

scene prune_demo {
  grid f = frequencies(from: 1 Hz, to: 8 Hz, step: 1 Hz)
  param a = 0.5
  param b = 2.0
  param c = 1.5
  let unused = exp(a) * 42.0
  let also_unused = unused_helper(b)
  let w = used_helper(a) * sum(f / 1 Hz)
  output y = 2.0 * (w * b) + sin(c) * c
  grad y wrt [a]
}
";

fn has_unary(f: &Function, u: UnOp) -> bool {
    f.insts.iter().any(|i| matches!(i.op, Op::Unary(op, _) if op == u))
}

fn has_const(f: &Function, x: f64) -> bool {
    f.insts.iter().any(|i| i.op == Op::constant(x))
}

/// The values of `f` that depend on nothing but param `p` (and constants).
fn only_from_param(f: &Function, p: u32) -> HashSet<Value> {
    let mut set = HashSet::new();
    for (i, inst) in f.insts.iter().enumerate() {
        let ops = inst.op.operands();
        let from_p = match inst.op {
            Op::Param(q) => q == p,
            _ => {
                !ops.is_empty()
                    && ops.iter().all(|v| set.contains(v) || matches!(f.insts[v.index()].op, Op::Const(_)))
                    && ops.iter().any(|v| set.contains(v))
            }
        };
        if from_p {
            set.insert(Value(i as u32));
        }
    }
    set
}

/// Instructions appended by the adjoint pass (those after the forward ones,
/// which are the pruned IR's after `passes::split_powers`) that read a value
/// computed from param `p` alone.
fn adjoint_uses_of_param(pl: &ScenePipeline, p: u32) -> Vec<String> {
    let fwd = only_from_param(&pl.adjoint, p);
    let forward_len = gwml_compiler::passes::split_powers(&pl.pruned).insts.len();
    pl.adjoint.insts[forward_len..]
        .iter()
        .filter(|i| i.op.operands().iter().any(|v| fwd.contains(v)))
        .map(|i| format!("{:?}", i.op))
        .collect()
}

#[test]
fn pruning_removes_unused_lets_and_modules() {
    let pl = pipeline("prune_demo.gw", PRUNE_DEMO, "prune_demo");
    // Checked IR elaborates every definition (so errors in them are reported)...
    assert!(has_unary(&pl.checked, UnOp::Exp) && has_const(&pl.checked, 42.0), "unused let missing from checked IR");
    assert!(has_unary(&pl.checked, UnOp::Tanh) && has_const(&pl.checked, 3.0), "unused_helper missing from checked IR");
    // ...and pruning drops what no output or gradient needs.
    for f in [&pl.pruned, &pl.adjoint, &pl.optimized] {
        assert!(!has_unary(f, UnOp::Exp) && !has_const(f, 42.0), "unused let survives pruning:\n{f}");
        assert!(!has_unary(f, UnOp::Tanh) && !has_const(f, 3.0), "unused_helper survives pruning:\n{f}");
    }
    // A module nobody calls is never lowered at all.
    for f in [&pl.checked, &pl.pruned, &pl.adjoint, &pl.optimized] {
        assert!(!has_unary(f, UnOp::Cbrt) && !has_const(f, 5.0), "never_called was lowered:\n{f}");
    }
    // What is used stays: used_helper's `+ 1.0`.
    assert!(has_const(&pl.pruned, 1.0));
    assert!(pl.stats.pruned_ops < pl.stats.checked_ops);
    insta::assert_snapshot!("prune_demo_checked_ir", pl.checked.to_string());
    insta::assert_snapshot!("prune_demo_pruned_ir", pl.pruned.to_string());
}

#[test]
fn activity_analysis_builds_no_adjoint_for_unrequested_params() {
    let pl = pipeline("prune_demo.gw", PRUNE_DEMO, "prune_demo");
    let c = pl.pruned.params.iter().position(|p| p.name == "c").unwrap() as u32;
    // Only dy/da is requested.
    assert_eq!(pl.adjoint.grads.len(), 1);
    assert_eq!(pl.adjoint.params[pl.adjoint.grads[0].param].name, "a");
    // sin(c) * c is part of y, but nothing in the adjoint sweep reads it:
    // no cos(c), no instruction on values computed from c alone.
    assert!(!has_unary(&pl.adjoint, UnOp::Cos), "an adjoint of sin(c) was built:\n{}", pl.adjoint);
    assert_eq!(adjoint_uses_of_param(&pl, c), Vec::<String>::new(), "adjoint instructions for the unrequested param c:\n{}", pl.adjoint);
    // Op counts of each stage.
    let counts = |pl: &ScenePipeline| (pl.stats.checked_ops, pl.stats.pruned_ops, pl.stats.adjoint_ops, pl.stats.optimized_ops);
    assert_eq!(counts(&pl), (23, 17, 16, 16), "{:?}", pl.stats);
    // Asking for dy/dc as well adds exactly the adjoint of sin(c) * c.
    let with_c = pipeline("prune_demo.gw", &PRUNE_DEMO.replace("grad y wrt [a]", "grad y wrt [a, c]"), "prune_demo");
    assert!(has_unary(&with_c.adjoint, UnOp::Cos));
    assert!(!adjoint_uses_of_param(&with_c, c).is_empty());
    assert_eq!(counts(&with_c), (23, 17, 19, 19), "{:?}", with_c.stats);
    insta::assert_snapshot!("prune_demo_adjoint_ir", pl.adjoint.to_string());
    insta::assert_snapshot!("prune_demo_optimized_ir", pl.optimized.to_string());
}

#[test]
fn adjoint_ir_has_no_dead_instructions() {
    let pl = pipeline("prune_demo.gw", PRUNE_DEMO, "prune_demo");
    let pruned_again = gwml_compiler::passes::prune(&pl.adjoint);
    assert_eq!(pruned_again.insts.len(), pl.adjoint.insts.len(), "dead instructions in the adjoint IR:\n{}", pl.adjoint);
}

/// A TaylorF2-like likelihood: a phase of powers of `v = (m f)^(1/3)`, a
/// quotient, and an inner product with a positive PSD.
const POWERS_DEMO: &str = "use std::detector::{inner}

scene powers_demo {
  grid f = frequencies(from: 20 Hz, to: 60 Hz, step: 1 Hz)
  input d: complex[f]
  param m = 2.0
  let v = cbrt(m * f / 1 Hz)
  let phase = (1.0 + 0.3 * v ^ 2.0 - 0.1 * v ^ 3.0) / v ^ 5.0
  let h = -(m * (f / 100 Hz)) * cis(phase)
  output loss = 0.5 * inner(d - h, d - h, 1.0 + f / 100 Hz, 1 Hz)
  grad loss wrt [m]
}
";

/// Whether some instruction of `f` is a per-bin `op` (grid-shaped and, as
/// `pick` says, of that kind).
fn has_per_bin(f: &Function, pick: impl Fn(&Op) -> bool) -> bool {
    f.insts.iter().any(|i| matches!(i.ty.shape, gwml_compiler::ir::Shape::Grid(_)) && pick(&i.op))
}

#[test]
fn powers_of_a_scaled_grid_are_split_before_the_adjoint() {
    let pl = pipeline("powers_demo.gw", POWERS_DEMO, "powers_demo");
    // Before the adjoint: v^k per bin from cbrt(m f).
    assert!(has_per_bin(&pl.pruned, |op| matches!(op, Op::PowConst(..))), "{}", pl.pruned);
    // After: m's powers are scalars, f's a table, so no bin computes a
    // power or a cube root of anything that depends on m.
    let depends = depends_on_params(&pl.optimized);
    let per_bin_pow = pl.optimized.insts.iter().enumerate().any(|(k, i)| {
        matches!(i.ty.shape, gwml_compiler::ir::Shape::Grid(_)) && matches!(i.op, Op::PowConst(..) | Op::Unary(UnOp::Cbrt, _)) && depends[k]
    });
    assert!(!per_bin_pow, "a per-bin power of m remains:\n{}", pl.optimized);
}

#[test]
fn the_gradient_kernel_has_no_per_bin_negation_or_psd_guard() {
    let pl = pipeline("powers_demo.gw", POWERS_DEMO, "powers_demo");
    // The adjoint's negations move out to scalars (or into a subtraction),
    // and the amplitude's −(m·f) is (−m)·f.
    assert!(!has_per_bin(&pl.optimized, |op| matches!(op, Op::Unary(UnOp::Neg, _))), "{}", pl.optimized);
    // `inner` guards `psd > 0`: with a positive PSD the select goes.
    assert!(has_per_bin(&pl.pruned, |op| matches!(op, Op::Select(..))), "{}", pl.pruned);
    assert!(!has_per_bin(&pl.optimized, |op| matches!(op, Op::Select(..))), "{}", pl.optimized);
}

/// Per instruction: whether it depends on a param (through any operand).
fn depends_on_params(f: &Function) -> Vec<bool> {
    let mut depends = vec![false; f.insts.len()];
    for (k, i) in f.insts.iter().enumerate() {
        depends[k] = matches!(i.op, Op::Param(_)) || i.op.operands().iter().any(|v| depends[v.index()]);
    }
    depends
}
