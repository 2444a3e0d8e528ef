//! The IR verifier: SSA order and operand types.

use super::*;

impl Function {
    /// Checks SSA order and operand types; `Err` names the first bad instruction.
    pub fn verify(&self) -> Result<(), String> {
        for (i, inst) in self.insts.iter().enumerate() {
            for v in inst.op.operands() {
                if v.index() >= i {
                    return Err(format!("%{i} uses %{} before it is defined", v.0));
                }
            }
            let t = |v: Value| self.insts[v.index()].ty;
            let ok = match inst.op {
                Op::Binary(BinOp::Complex, a, b) => t(a) == t(b) && t(a).elem == Elem::Real,
                Op::Binary(_, a, b) => t(a) == t(b),
                Op::Select(c, a, b) => t(a) == t(b) && t(c).elem == Elem::Bool && t(c).shape == t(a).shape,
                Op::Broadcast(a, _) => t(a).shape == Shape::Scalar,
                Op::Reduce(_, a) => t(a).shape != Shape::Scalar,
                Op::Dft(d, a) => {
                    let (time, freq) = if d.inverse { (inst.ty.shape, t(a).shape) } else { (t(a).shape, inst.ty.shape) };
                    let (want_in, want_out) = if d.inverse { (Elem::Complex, Elem::Real) } else { (Elem::Real, Elem::Complex) };
                    match (time, freq) {
                        (Shape::Grid(tg), Shape::Grid(fg)) => {
                            inst.ty.shape == Shape::Grid(d.out)
                                && t(a).elem == want_in
                                && inst.ty.elem == want_out
                                && self.grids[fg.0 as usize].len == self.grids[tg.0 as usize].len / 2 + 1
                        }
                        _ => false,
                    }
                }
                Op::Tensor(op, g, a, b) => {
                    let lens = op.operand_lens();
                    let real_array =
                        |v: Value, len: usize| t(v).elem == Elem::Real && self.len_of(t(v).shape) == len && t(v).shape != Shape::Scalar;
                    inst.ty == Ty { elem: Elem::Real, shape: Shape::Grid(g) }
                        && self.len_of(inst.ty.shape) == op.out_len()
                        && real_array(a, lens[0])
                        && (op.arity() == 1 || real_array(b, lens[1]))
                }
                Op::Band(o, n, a) => match self.bands.get(n as usize) {
                    Some(band) => {
                        let (from, to) = (band.grid_on(o.sides().0), band.grid_on(o.sides().1));
                        let nodes_ok = band.nodes.len() == self.grid(band.coarse).len
                            && band.nodes.first() == Some(&0)
                            && band.nodes.last().map(|&l| l as usize + 1) == Some(self.grid(band.fine).len)
                            && band.nodes.windows(2).all(|w| w[0] < w[1]);
                        nodes_ok && t(a) == Ty { elem: Elem::Real, shape: Shape::Grid(from) } && inst.ty.shape == Shape::Grid(to)
                    }
                    None => false,
                },
                _ => true,
            };
            if !ok {
                return Err(format!("%{i} = {} has operands of mismatched types", self.fmt_op(&inst.op)));
            }
        }
        for r in self.roots() {
            if r.index() >= self.insts.len() {
                return Err(format!("result %{} is not defined", r.0));
            }
        }
        Ok(())
    }
}
