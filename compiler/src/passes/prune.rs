//! Dead-code elimination: keep the instructions the outputs and computed
//! gradients reach, renumbered densely in their original order.

use crate::ir::{Function, Value};

/// Removes every instruction no root (output or gradient) depends on.
pub fn prune(func: &Function) -> Function {
    let mut live = vec![false; func.insts.len()];
    for r in func.roots() {
        live[r.index()] = true;
    }
    for i in (0..func.insts.len()).rev() {
        if live[i] {
            for v in func.insts[i].op.operands() {
                live[v.index()] = true;
            }
        }
    }
    let mut map = vec![Value(u32::MAX); func.insts.len()];
    let mut out = func.clone();
    out.insts.clear();
    for (i, inst) in func.insts.iter().enumerate() {
        if live[i] {
            map[i] = Value(out.insts.len() as u32);
            let op = inst.op.map_operands(|v| map[v.index()]);
            out.insts.push(crate::ir::Inst { op, ty: inst.ty });
        }
    }
    out.remap_roots(|v| map[v.index()]);
    out
}
