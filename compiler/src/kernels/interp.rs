//! The reference interpreter: evaluates IR in f64 one instruction at a
//! time, with the semantics of [`crate::ir::eval`]. Slow and simple on purpose:
//! it is the oracle the JIT is tested against.

use crate::ir::eval;
use crate::ir::*;
use num_complex::Complex64 as C64;

/// Most elements (instructions × grid points) the compiler evaluates at
/// compile time (input defaults, grid folding): about 512 MiB of values.
pub const EVAL_BUDGET: usize = 1 << 25;

/// A value during interpretation: one element for scalars, `len` for arrays.
pub type Tensor = Vec<C64>;

/// Results of one interpretation.
#[derive(Clone, Debug)]
pub struct InterpResult {
    /// Every instruction's value.
    pub values: Vec<Tensor>,
}

impl InterpResult {
    /// The value of output `name` (at its true scale: times
    /// `2^exponent`, see [`Output::exponent`]).
    pub fn output(&self, func: &Function, name: &str) -> Option<Tensor> {
        let o = func.outputs.iter().find(|o| o.name == name)?;
        let k = 2f64.powi(o.exponent);
        Some(self.values[o.value.index()].iter().map(|z| z * k).collect())
    }
    /// The gradient d`output`/d`param` (per base unit of the param).
    pub fn grad(&self, func: &Function, output: &str, param: &str) -> Option<f64> {
        func.grads
            .iter()
            .find(|g| func.outputs[g.output].name == output && func.params[g.param].name == param)
            .and_then(|g| g.value)
            .map(|v| self.values[v.index()][0].re)
    }
}

/// Evaluates `func` with params (base units) and inputs (base units; one
/// `Tensor` each, real inputs with zero imaginary parts).
pub fn interpret(func: &Function, params: &[f64], inputs: &[Tensor]) -> InterpResult {
    interpret_only(func, params, inputs, &vec![true; func.insts.len()])
}

/// [`interpret`] for the instructions `wanted` marks (each of whose operands
/// must be wanted too); the others are left empty. The compiler folds
/// grid-only values this way without evaluating the rest of a scene.
pub fn interpret_only(func: &Function, params: &[f64], inputs: &[Tensor], wanted: &[bool]) -> InterpResult {
    interpret_streaming(func, params, inputs, wanted, |_, _| true)
}

/// [`interpret_only`] that hands each value to `visit(index, value)` as soon
/// as it is computed and keeps it in the result only if `visit` returns
/// true; the others are freed after their last wanted user. Memory then
/// follows the values alive at once, not the whole scene: on a 72 s chunk
/// at 4096 Hz every array is 4.7 MB, and fresh pages cost more than the
/// arithmetic.
pub fn interpret_streaming(
    func: &Function,
    params: &[f64],
    inputs: &[Tensor],
    wanted: &[bool],
    mut visit: impl FnMut(usize, &Tensor) -> bool,
) -> InterpResult {
    let mut last_use = vec![usize::MAX; func.insts.len()];
    for (i, inst) in func.insts.iter().enumerate().filter(|(i, _)| wanted[*i]) {
        for v in inst.op.operands() {
            last_use[v.index()] = i;
        }
    }
    let mut kept = vec![false; func.insts.len()];
    let mut values: Vec<Tensor> = Vec::with_capacity(func.insts.len());
    // Buffers of freed values, reused so large arrays do not take fresh pages.
    let mut spare: Vec<Tensor> = Vec::new();
    for (i, (inst, wanted)) in func.insts.iter().zip(wanted).enumerate() {
        if !wanted {
            values.push(Tensor::new());
            continue;
        }
        let mut t = spare.pop().unwrap_or_default();
        evaluate(func, inst, &values, (params, inputs), &mut t);
        kept[i] = visit(i, &t);
        values.push(t);
        for v in inst.op.operands().into_iter().chain([Value(i as u32)]) {
            let last = if v.index() == i { usize::MAX } else { i };
            if last_use[v.index()] == last && !kept[v.index()] && !values[v.index()].is_empty() {
                spare.push(std::mem::take(&mut values[v.index()]));
            }
        }
    }
    InterpResult { values }
}

/// Writes the value of one instruction into `out` (whose capacity is
/// reused), its operands' values in `values`.
fn evaluate(func: &Function, inst: &Inst, values: &[Tensor], (params, inputs): (&[f64], &[Tensor]), out: &mut Tensor) {
    let len = func.len_of(inst.ty.shape);
    let get = |v: Value, i: usize| -> C64 {
        let t: &Tensor = &values[v.index()];
        if t.len() == 1 {
            t[0]
        } else {
            t[i]
        }
    };
    let elem_of = |v: Value| func.ty(v).elem;
    let real = |x: f64| C64::new(x, 0.0);
    out.clear();
    match inst.op {
        Op::Const(b) => out.push(real(f64::from_bits(b))),
        Op::ConstComplex(r, i) => out.push(C64::new(f64::from_bits(r), f64::from_bits(i))),
        Op::Param(p) => out.push(real(params[p as usize])),
        Op::Input(i) => out.extend_from_slice(&inputs[i as usize]),
        Op::Table(t) => out.extend(func.tables[t as usize].data.iter().map(|x| real(*x))),
        Op::GridCoord(g) => {
            let gr = &func.grids[g.0 as usize];
            out.extend((0..gr.len).map(|i| real(gr.start + i as f64 * gr.step)));
        }
        Op::Unary(u, a) => out.extend((0..len).map(|i| eval::unary(u, get(a, i), elem_of(a)))),
        Op::Binary(op, x, y) => out.extend((0..len).map(|i| eval::binary(op, get(x, i), get(y, i), elem_of(x)))),
        Op::PowConst(a, c) => out.extend((0..len).map(|i| real(eval::pow_const(get(a, i).re, f64::from_bits(c))))),
        Op::Select(c, x, y) => out.extend((0..len).map(|i| if get(c, i).re != 0.0 { get(x, i) } else { get(y, i) })),
        Op::Broadcast(a, _) => out.resize(len, get(a, 0)),
        Op::Reduce(Reduce::Sum, a) => {
            // Compensated so the oracle is accurate.
            let xs = &values[a.index()];
            out.push(C64::new(compensated_sum(xs.iter().map(|x| x.re)), compensated_sum(xs.iter().map(|x| x.im))));
        }
        Op::Reduce(Reduce::Max, a) => out.push(real(values[a.index()].iter().map(|x| x.re).fold(f64::NEG_INFINITY, f64::max))),
        Op::Dft(d, a) => {
            let n = if d.inverse { len } else { values[a.index()].len() };
            *out = crate::kernels::dft::apply(d, n, &values[a.index()]);
        }
        Op::Band(op, n, a) => *out = crate::kernels::band::apply(op, &func.bands[n as usize].nodes, &values[a.index()]),
        Op::Tensor(t, _, a, b) => {
            let re = |v: Value| values[v.index()].iter().map(|z| z.re).collect::<Vec<f64>>();
            let mut flat = vec![0.0; t.out_len()];
            crate::kernels::tensor::apply(t, &re(a), &re(b), &mut flat);
            out.extend(flat.into_iter().map(real));
        }
    }
}

/// The transform of [`Dft`] by its definition, in O(n²) with compensated
/// sums and exactly reduced angles: independent of the FFT the kernels call.
pub fn naive_dft(d: Dft, x: &[C64], n: usize) -> Tensor {
    let bins = n / 2 + 1;
    let twiddle = |j: usize, k: usize| {
        // e^{-2πi jk/n} with jk reduced mod n first, so the angle is exact-ish for large n.
        let r = ((j as u128 * k as u128) % n as u128) as f64;
        C64::from_polar(1.0, -2.0 * std::f64::consts::PI * r / n as f64)
    };
    let s = d.scale();
    if d.inverse {
        (0..n)
            .map(|j| {
                let terms = (0..bins).map(|k| d.weight(k, n) * (x[k] * twiddle(j, k).conj()).re);
                C64::new(s * compensated_sum(terms), 0.0)
            })
            .collect()
    } else {
        (0..bins)
            .map(|k| {
                let re = compensated_sum((0..n).map(|j| (x[j] * twiddle(j, k)).re));
                let im = compensated_sum((0..n).map(|j| (x[j] * twiddle(j, k)).im));
                C64::new(re, im) * (s * d.weight(k, n))
            })
            .collect()
    }
}

/// Neumaier's compensated sum.
fn compensated_sum(xs: impl Iterator<Item = f64>) -> f64 {
    let (mut s, mut c) = (0.0f64, 0.0f64);
    for x in xs {
        let t = s + x;
        c += if s.abs() >= x.abs() { (s - t) + x } else { (x - t) + s };
        s = t;
    }
    s + c
}
