//! Scheduling: each value's epoch, the fused loops per epoch and grid, library calls, and which arrays get buffers.

use super::abi::{BufferInfo, BufferKind, Layout, PlanBox};
use crate::ir::*;
use crate::kernels::band::BandPlan;
use std::collections::HashMap;

/// Per-value scheduling decisions.
pub(super) struct Schedule {
    pub(super) epoch: Vec<u32>,
    /// Loops in emission order: (epoch, grid, member instructions).
    pub(super) loops: Vec<(u32, GridId, Vec<usize>)>,
    /// Scalar instructions per epoch (excluding reductions).
    pub(super) scalars: Vec<Vec<usize>>,
    /// Array values stored to a buffer: value index → buffer index.
    pub(super) stored: HashMap<usize, usize>,
    /// Library calls (transforms and tensor ops) per epoch, run before that epoch's loops.
    pub(super) calls: Vec<Vec<usize>>,
    /// Per call: its plan (index into the kernel's plans) and work buffer.
    pub(super) call_plans: HashMap<usize, (usize, Option<usize>)>,
    /// Per loop: the interval condition it is split on, if any, and whether
    /// it holds on the grid's first points (see [`Gen::emit_loop`](super::Gen::emit_loop)).
    pub(super) splits: Vec<Option<(usize, bool)>>,
}

impl Schedule {
    /// Whether array value `i` is read from the buffer an earlier loop
    /// stored it to, in a loop of `epoch`.
    pub(super) fn reloaded(&self, i: usize, epoch: u32) -> bool {
        self.stored.contains_key(&i) && self.epoch[i] < epoch
    }

    /// The interval condition loop `l` is split on, if any: the first (by
    /// instruction) that a select computed in the loop tests, on the
    /// loop's grid, with whether it holds on the grid's first points.
    fn split_condition(&self, func: &Function, l: usize) -> Option<(usize, bool)> {
        let (epoch, grid, ref members) = self.loops[l];
        let mut seen = std::collections::HashSet::new();
        let mut stack: Vec<usize> = members.clone();
        let mut best: Option<(usize, bool)> = None;
        while let Some(i) = stack.pop() {
            let inst = func.insts[i];
            if inst.ty.shape == Shape::Scalar && !matches!(inst.op, Op::Reduce(..)) || !seen.insert(i) {
                continue;
            }
            if on_demand(&inst.op) || is_call(&inst.op) || self.reloaded(i, epoch) {
                continue;
            }
            if let Op::Select(c, ..) = inst.op {
                if let Some((g, first)) = func.interval_condition(c) {
                    if g == grid && best.is_none_or(|(b, _)| c.index() < b) {
                        best = Some((c.index(), first));
                    }
                }
            }
            stack.extend(inst.op.operands().iter().map(|v| v.index()));
        }
        best
    }
}

fn on_demand(op: &Op) -> bool {
    matches!(op, Op::Broadcast(..) | Op::GridCoord(_) | Op::Input(_) | Op::Table(_))
}

/// Ops computed by a library call on whole buffers, between fused loops.
fn is_call(op: &Op) -> bool {
    matches!(op, Op::Dft(..) | Op::Tensor(..) | Op::Band(..))
}

/// Library calls whose buffers are all in the storage precision (band
/// calls take each buffer in its own).
fn in_storage_precision(op: &Op) -> bool {
    matches!(op, Op::Dft(..) | Op::Tensor(..))
}

/// Values that already live in a buffer of their own (no store needed).
fn in_buffer(op: &Op) -> bool {
    matches!(op, Op::Input(_) | Op::Table(_)) || is_call(op)
}

pub(super) fn schedule(func: &Function, wide: &[bool], layout: &mut Layout, plans: &mut Vec<PlanBox>) -> Schedule {
    let n = func.insts.len();
    let storage = func.precision.storage();
    // Library calls read and write their buffers in the storage precision.
    let call_operands: std::collections::HashSet<usize> =
        func.insts.iter().filter(|i| in_storage_precision(&i.op)).flat_map(|i| i.op.operands()).map(|v| v.index()).collect();
    let mut epoch = vec![0u32; n];
    for (i, inst) in func.insts.iter().enumerate() {
        epoch[i] = match inst.op {
            Op::Reduce(_, a) => epoch[a.index()] + 1,
            op if is_call(&op) => op.operands().iter().map(|v| epoch[v.index()] + 1).max().unwrap_or(0),
            op => op.operands().iter().map(|v| epoch[v.index()]).max().unwrap_or(0),
        };
    }
    let max_epoch = epoch.iter().copied().max().unwrap_or(0);
    let mut scalars = vec![Vec::new(); max_epoch as usize + 1];
    let mut calls = vec![Vec::new(); max_epoch as usize + 1];
    let mut loop_map: HashMap<(u32, GridId), Vec<usize>> = HashMap::new();
    let roots: Vec<Value> = func.roots();
    for (i, inst) in func.insts.iter().enumerate() {
        match (inst.op, inst.ty.shape) {
            (Op::Reduce(_, a), _) => {
                let Shape::Grid(g) = func.ty(a).shape else {
                    continue;
                };
                loop_map.entry((epoch[a.index()], g)).or_default().push(i);
            }
            (op, _) if is_call(&op) => {
                calls[epoch[i] as usize].push(i);
                // A call reads its operands from memory: values that are
                // otherwise recomputed on demand get a loop that stores them.
                for a in op.operands() {
                    let op = func.insts[a.index()].op;
                    let Shape::Grid(g) = func.ty(a).shape else { continue };
                    if on_demand(&op) && !in_buffer(&op) {
                        let members = loop_map.entry((epoch[a.index()], g)).or_default();
                        if !members.contains(&a.index()) {
                            members.push(a.index());
                        }
                    }
                }
            }
            (op, Shape::Grid(g)) => {
                if !on_demand(&op) || roots.contains(&Value(i as u32)) {
                    loop_map.entry((epoch[i], g)).or_default().push(i);
                }
            }
            (_, Shape::Scalar) => scalars[epoch[i] as usize].push(i),
        }
    }
    let mut loops: Vec<(u32, GridId, Vec<usize>)> = loop_map.into_iter().map(|((e, g), m)| (e, g, m)).collect();
    loops.sort_by_key(|(e, g, _)| (*e, *g));
    // Which arrays must be stored: outputs, and values read by another loop.
    let mut home: HashMap<usize, usize> = HashMap::new();
    for (li, (_, _, members)) in loops.iter().enumerate() {
        for &m in members {
            if !matches!(func.insts[m].op, Op::Reduce(..)) {
                home.insert(m, li);
            }
        }
    }
    let mut stored = HashMap::new();
    let need_store = |v: usize, kind: BufferKind, layout: &mut Layout, stored: &mut HashMap<usize, usize>| {
        if stored.contains_key(&v) && kind == BufferKind::Scratch {
            return;
        }
        let ty = func.insts[v].ty;
        let kept_wide = wide[v] && !call_operands.contains(&v) && !in_storage_precision(&func.insts[v].op);
        let precision = if kept_wide { Precision::F64 } else { storage };
        layout.buffers.push(BufferInfo { kind, len: func.len_of(ty.shape), complex: ty.elem == Elem::Complex, precision });
        stored.insert(v, layout.buffers.len() - 1);
    };
    // Outputs of the same value (CSE merges `output a = x` and
    // `output b = x`) share the buffer of the first.
    for (oi, o) in func.outputs.iter().enumerate() {
        let buffer = (func.ty(o.value).shape != Shape::Scalar).then(|| match stored.get(&o.value.index()) {
            Some(&buf) => buf,
            None => {
                need_store(o.value.index(), BufferKind::Output(oi), layout, &mut stored);
                layout.buffers.len() - 1
            }
        });
        layout.outputs.push(buffer);
    }
    for (gi, g) in func.input_grads.iter().enumerate() {
        let buffer = match g.value {
            Some(v) if func.ty(v).shape != Shape::Scalar => Some(match stored.get(&v.index()) {
                Some(&buf) => buf,
                None => {
                    need_store(v.index(), BufferKind::InputGrad(gi), layout, &mut stored);
                    stored[&v.index()]
                }
            }),
            _ => None,
        };
        layout.input_grads.push(buffer);
    }
    let mut call_plans = HashMap::new();
    for &d in calls.iter().flatten() {
        need_store(d, BufferKind::Scratch, layout, &mut stored);
        for a in func.insts[d].op.operands() {
            if !in_buffer(&func.insts[a.index()].op) {
                need_store(a.index(), BufferKind::Scratch, layout, &mut stored);
            }
        }
        let plan = match func.insts[d].op {
            Op::Dft(dft, a) => {
                let time = if dft.inverse { func.insts[d].ty.shape } else { func.ty(a).shape };
                PlanBox::new(dft, func.len_of(time), storage)
            }
            Op::Tensor(t, ..) => PlanBox::Tensor(Box::new(t)),
            Op::Band(op, n, _) => PlanBox::Band(Box::new(BandPlan { op, nodes: func.bands[n as usize].nodes.clone() })),
            _ => unreachable!("only library calls are listed"),
        };
        let work = (plan.work_floats() > 0).then(|| {
            layout.buffers.push(BufferInfo { kind: BufferKind::Scratch, len: plan.work_floats(), complex: false, precision: storage });
            layout.buffers.len() - 1
        });
        plans.push(plan);
        call_plans.insert(d, (plans.len() - 1, work));
    }
    for (li, (_, _, members)) in loops.iter().enumerate() {
        for &m in members {
            for v in func.insts[m].op.operands() {
                if let Some(&h) = home.get(&v.index()) {
                    if h != li && !on_demand(&func.insts[v.index()].op) {
                        need_store(v.index(), BufferKind::Scratch, layout, &mut stored);
                    }
                }
            }
        }
    }
    let mut sched = Schedule { epoch, loops, scalars, stored, calls, call_plans, splits: Vec::new() };
    sched.splits = (0..sched.loops.len()).map(|l| sched.split_condition(func, l)).collect();
    layout.split_loops = sched.splits.iter().flatten().count();
    sched
}
