//! The IR's text form (`--emit ir|adjoint`).

use super::*;
use std::fmt::{self, Write};

impl Function {
    pub(super) fn fmt_op(&self, op: &Op) -> String {
        let g = |g: GridId| self.grids.get(g.0 as usize).map(|g| g.name.clone()).unwrap_or("?".into());
        match *op {
            Op::Const(b) => format!("const {:?}", f64::from_bits(b)),
            Op::ConstComplex(r, i) => {
                format!("const {:?}{:+?}i", f64::from_bits(r), f64::from_bits(i))
            }
            Op::Param(p) => format!("param {}", self.params.get(p as usize).map(|p| p.name.as_str()).unwrap_or("?")),
            Op::Input(p) => format!("input {}", self.inputs.get(p as usize).map(|p| p.name.as_str()).unwrap_or("?")),
            Op::GridCoord(gr) => format!("grid {}", g(gr)),
            Op::Table(t) => format!("table {t}"),
            Op::Unary(u, a) => format!("{} %{}", format!("{u:?}").to_lowercase(), a.0),
            Op::Binary(b, x, y) => {
                format!("{} %{}, %{}", format!("{b:?}").to_lowercase(), x.0, y.0)
            }
            Op::PowConst(a, c) => format!("powc %{}, {:?}", a.0, f64::from_bits(c)),
            Op::Select(c, a, b) => format!("select %{}, %{}, %{}", c.0, a.0, b.0),
            Op::Broadcast(a, gr) => format!("broadcast %{} to {}", a.0, g(gr)),
            Op::Reduce(r, a) => format!("{} %{}", format!("{r:?}").to_lowercase(), a.0),
            Op::Dft(d, a) => format!(
                "{}{} %{} to {}, scale {:?}",
                if d.inverse { "idft" } else { "dft" },
                if d.doubled { " doubled" } else { "" },
                a.0,
                g(d.out),
                d.scale()
            ),
            Op::Band(o, n, a) => format!("{} %{} (bands {n})", o.name(), a.0),
            Op::Tensor(t, _, a, b) => {
                let sizes = match t {
                    TensorOp::MatVec { m, k } | TensorOp::MatTVec { m, k } | TensorOp::Outer { m, k } => format!("{m}x{k}"),
                    TensorOp::Conv(c) | TensorOp::ConvBackData(c) | TensorOp::ConvBackWeight(c) if c.rows == Axis::ONE => format!(
                        "{}x{} -> {}x{}, kernel {}, stride {}, padding {}, dilation {}",
                        c.c_in, c.len_in, c.c_out, c.len_out, c.kernel, c.stride, c.padding, c.dilation
                    ),
                    TensorOp::Conv(c) | TensorOp::ConvBackData(c) | TensorOp::ConvBackWeight(c) => {
                        let r = c.rows;
                        format!(
                            "{}x{}x{} -> {}x{}x{}, kernel {}x{}, stride {}x{}, padding {}x{}, dilation {}x{}",
                            c.c_in,
                            r.len_in,
                            c.len_in,
                            c.c_out,
                            r.len_out,
                            c.len_out,
                            r.kernel,
                            c.kernel,
                            r.stride,
                            c.stride,
                            r.padding,
                            c.padding,
                            r.dilation,
                            c.dilation
                        )
                    }
                    TensorOp::PoolPick(p) | TensorOp::PoolScatter(p) | TensorOp::PoolAvg(p) | TensorOp::PoolAvgBack(p)
                        if p.rows == Axis::ONE =>
                    {
                        format!("{}x{} -> {}x{}, window {}, stride {}", p.channels, p.len_in, p.channels, p.len_out, p.window, p.stride)
                    }
                    TensorOp::PoolPick(p) | TensorOp::PoolScatter(p) | TensorOp::PoolAvg(p) | TensorOp::PoolAvgBack(p) => {
                        let r = p.rows;
                        format!(
                            "{}x{}x{} -> {}x{}x{}, window {}x{}, stride {}x{}",
                            p.channels, r.len_in, p.len_in, p.channels, r.len_out, p.len_out, r.kernel, p.window, r.stride, p.stride
                        )
                    }
                    TensorOp::Spread { rows, cols } | TensorOp::SumRows { rows, cols } => format!("{rows}x{cols}"),
                    TensorOp::PlaceRows(r) | TensorOp::TakeRows(r) => {
                        format!("rows {}..{} of {}x{}", r.from, r.from + r.count, r.rows, r.cols)
                    }
                };
                if t.arity() == 1 {
                    format!("{} %{} ({sizes})", t.name(), a.0)
                } else {
                    format!("{} %{}, %{} ({sizes})", t.name(), a.0, b.0)
                }
            }
        }
    }

    /// Formats a type as `real`, `complex[f]`.
    pub fn fmt_ty(&self, ty: Ty) -> String {
        let e = match ty.elem {
            Elem::Real => "real",
            Elem::Complex => "complex",
            Elem::Bool => "bool",
        };
        match ty.shape {
            Shape::Scalar => e.to_string(),
            Shape::Grid(g) => format!("{e}[{}]", self.grids.get(g.0 as usize).map(|g| g.name.as_str()).unwrap_or("?")),
        }
    }
}

/// A function's text with some values marked `f64`: in mixed precision,
/// those computed in f64 (`passes::precision::wide_values`).
pub struct Marked<'a> {
    func: &'a Function,
    wide: &'a [bool],
}

impl Function {
    /// The text form with the values `wide` flags marked `f64`.
    pub fn marked<'a>(&'a self, wide: &'a [bool]) -> Marked<'a> {
        Marked { func: self, wide }
    }

    fn write_text(&self, f: &mut fmt::Formatter<'_>, wide: &[bool]) -> fmt::Result {
        let mut s = String::new();
        let _ = writeln!(s, "scene {} (precision {}, math {})", self.name, self.precision, self.math);
        for k in &self.knobs {
            let _ = writeln!(s, "  knob {} = {:?} [{}]", k.name, k.value, k.unit);
        }
        for g in &self.grids {
            let _ = writeln!(s, "  grid {}: {} points, {:?} + i*{:?} [{}]", g.name, g.len, g.start, g.step, g.unit);
        }
        for p in &self.params {
            let _ = writeln!(s, "  param {} [{}] scale {:?}", p.name, p.unit, p.scale);
        }
        for i in &self.inputs {
            let _ = writeln!(s, "  input {}: {} [{}]", i.name, self.fmt_ty(i.ty), i.unit);
        }
        for (k, t) in self.tables.iter().enumerate() {
            let (lo, hi) = t.data.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(*x), b.max(*x)));
            let _ = writeln!(s, "  table {k}: real[{}], {} values in [{lo:e}, {hi:e}]", self.grids[t.grid.0 as usize].name, t.data.len());
        }
        for (k, b) in self.bands.iter().enumerate() {
            let fine = &self.grids[b.fine.0 as usize];
            let widest = b.nodes.windows(2).map(|w| w[1] - w[0]).max().unwrap_or(0);
            let coord = |i: u32| fine.start + i as f64 * fine.step;
            let nodes: Vec<String> = if b.nodes.len() <= 12 {
                b.nodes.iter().map(|&i| format!("{:?}", coord(i))).collect()
            } else {
                let head = b.nodes[..6].iter().map(|&i| format!("{:?}", coord(i)));
                head.chain(["…".to_string()]).chain(b.nodes[b.nodes.len() - 3..].iter().map(|&i| format!("{:?}", coord(i)))).collect()
            };
            let what = match b.purpose {
                BandPurpose::Multiband => format!("widest band {widest} points, phase error {:.1e} rad at the defaults", b.error),
                BandPurpose::RelativeBinning => {
                    format!("relative binning, widest bin {widest} points, phase bound {:.2} rad per bin", b.error)
                }
                BandPurpose::Midpoints => "the bins' midpoints".to_string(),
            };
            let _ = writeln!(
                s,
                "  bands {k}: {} of the {} points of {} ({what}) [{}]: {}",
                b.nodes.len(),
                fine.len,
                fine.name,
                fine.unit,
                nodes.join(", ")
            );
        }
        for (i, inst) in self.insts.iter().enumerate() {
            // In mixed precision, the values computed in f64 are marked.
            let mark = if wide.get(i).copied().unwrap_or(false) { " f64" } else { "" };
            let _ = writeln!(s, "  %{i}: {}{mark} = {}", self.fmt_ty(inst.ty), self.fmt_op(&inst.op));
        }
        for o in &self.outputs {
            let scaled = if o.exponent == 0 { String::new() } else { format!(" × 2^{}", o.exponent) };
            let _ = writeln!(s, "  output {} = %{}{scaled} [{}]", o.name, o.value.0, o.unit);
        }
        for g in &self.grads {
            let v = g.value.map(|v| format!("%{}", v.0)).unwrap_or("(not computed)".into());
            let _ = writeln!(s, "  grad d{}/d{} = {v}", self.outputs[g.output].name, self.params[g.param].name);
        }
        for g in &self.input_grads {
            let v = g.value.map(|v| format!("%{}", v.0)).unwrap_or("(not computed)".into());
            let _ = writeln!(s, "  grad d{}/d{} = {v}", self.outputs[g.output].name, self.inputs[g.input].name);
        }
        f.write_str(&s)
    }
}

impl fmt::Display for Function {
    /// The text form, without marks (printing analyses nothing).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.write_text(f, &[])
    }
}

impl fmt::Display for Marked<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.func.write_text(f, self.wide)
    }
}
