//! Relative binning (the scene's `relative_binning: BINS` setting;
//! Zackay, Dai & Venumadhav 2018, arXiv:1806.08792; Cornish 2010,
//! arXiv:1007.4820, "heterodyning"). A likelihood sums, over every
//! frequency of a grid, an expression at most quadratic in one waveform
//! `h` and its conjugate, with coefficients the params do not change (the
//! data, the PSD): `(d − h | d − h) = 4 df Σ |d − h|² / S`. With the
//! fiducial waveform `h0` (`h` at the fiducial params: scalar inputs
//! `fiducial.NAME`, one per param, defaulting to the param's default, so
//! a caller sets the fiducial from a search by binding them), the ratio
//! `r = h / h0` is taken quadratic on each bin, through its first node
//! (`t = 0`), its midpoint (`t_m`) and its last node (`t = 1`), with the
//! Lagrange basis `L_u(t)`, so that
//!
//! ```text
//! Σ_k a_k h_k = Σ_j Σ_u S_uj r_uj,        S_uj = Σ_{k in bin j} a_k h0_k L_u(t_k),
//! Σ_k q_k |h_k|² = Σ_j Σ_{u≤v} Q_uvj (2 −δ_uv) Re(r_uj conj r_vj),
//!                                         Q_uvj = Σ_{k in bin j} q_k |h0_k|² L_u(t_k) L_v(t_k),
//! ```
//!
//! and likewise for `conj(h)`, where `t_k` is the position of point `k` in
//! its bin. `S` and `Q` are the *summary data*: they depend on the data
//! and the fiducial, not on the params, so the per-call work is the
//! waveform at the `2 BINS + 1` nodes and midpoints and `O(BINS)`
//! arithmetic (the summary data and `1/h0` at the nodes are computed from
//! inputs alone: the runtime computes them once per bound data or
//! fiducial, `passes::stage`). The rewrite runs before the adjoint, so
//! `grad` is the exact gradient of the approximation.
//!
//! The nodes are equally spaced in the bound on how far any post-Newtonian
//! phase can drift from the fiducial's,
//! `ψ(f) = 2π Σ_γ sign(γ) (f / f_*)^γ` over `γ = −5/3, −4/3, …, 5/3`
//! (`f_*` the lowest frequency for `γ < 0`, the highest otherwise), as
//! jimgw's `HeterodynedTransientLikelihoodFD` places its bins, snapped to
//! grid points.
//!
//! A sum is rewritten when, descending from it through `+ − ×`, `/` by
//! param-free values, `re`, `im`, `conj`, `abs2`, `tocomplex` and `select`
//! on param-free conditions, every param-dependent leaf is one complex
//! array `h` on the sum's grid that multibanding could clone onto the
//! nodes (elementwise in the grid's coordinates and scalars), of degree
//! at most one in `h` and in `conj(h)`, and `h0` at the params' defaults
//! is finite and nonzero at every point. Anything else is left exact.

use super::multiband::{clone_onto, Cone};
use super::precision::defaults;
use super::prune;
use crate::ir::builder::Builder;
use crate::ir::*;
use crate::kernels::interp;
use num_complex::Complex64 as C64;
use std::collections::HashMap;

/// Most nodes the expansion of one sum visits before giving up.
const EXPANSION_BUDGET: usize = 20_000;

/// Applies the scene's relative binning setting (nothing when it is off).
pub fn relbin(func: &Function) -> Function {
    let RelativeBinning::Bins(bins) = func.relative_binning else { return func.clone() };
    let found = candidates(func);
    if found.is_empty() || func.params.iter().any(|p| p.default.is_none()) {
        return func.clone();
    }
    let longest = func.grids.iter().map(|g| g.len).max().unwrap_or(1);
    if func.insts.len().saturating_mul(longest) > interp::EVAL_BUDGET {
        return func.clone();
    }
    // The fiducial waveforms.
    let mut wanted = vec![false; func.insts.len()];
    let mut stack: Vec<usize> = found.iter().map(|(_, c)| c.h.index()).collect();
    while let Some(i) = stack.pop() {
        if !std::mem::replace(&mut wanted[i], true) {
            stack.extend(func.insts[i].op.operands().iter().map(|v| v.index()));
        }
    }
    let (params, inputs) = defaults(func);
    let values = interp::interpret_only(func, &params, &inputs, &wanted).values;
    let usable = |h: Value| values[h.index()].iter().all(|z| z.re.is_finite() && z.im.is_finite() && z.norm_sqr() > 0.0);
    let found: Vec<(usize, Candidate)> = found.into_iter().filter(|(_, c)| usable(c.h)).collect();
    if found.is_empty() {
        return func.clone();
    }

    let mut header = func.clone();
    header.insts.clear();
    // The fiducial: one scalar input `fiducial.NAME` per param, at the
    // param's default unless bound.
    let first_fiducial = header.inputs.len();
    for p in &func.params {
        header.inputs.push(InputInfo {
            name: format!("fiducial.{}", p.name),
            ty: Ty { elem: Elem::Real, shape: Shape::Scalar },
            scale: p.scale,
            unit: p.unit.clone(),
            default: p.default.map(|d| vec![C64::new(d * p.scale, 0.0)]),
            role: InputRole::Data,
        });
    }
    let varies = param_dependent(func);
    let mut b = Builder::new(header, true);
    let mut banding_of: HashMap<GridId, u32> = HashMap::new();
    for (_, c) in &found {
        if banding_of.contains_key(&c.grid) {
            continue;
        }
        let fine = b.func.grid(c.grid).clone();
        let coords: Vec<f64> = (0..fine.len).map(|k| fine.start + k as f64 * fine.step).collect();
        let (nodes, error) = bin_nodes(&coords, bins);
        b.func.grids.push(Grid::index(format!("{}_bins", fine.name), nodes.len()));
        let coarse = GridId(b.func.grids.len() as u32 - 1);
        let mids = midpoints(&nodes);
        b.func.bands.push(Banding { fine: c.grid, coarse, nodes, error, purpose: BandPurpose::RelativeBinning });
        banding_of.insert(c.grid, b.func.bands.len() as u32 - 1);
        b.func.bands.push(Banding { fine: c.grid, coarse, nodes: mids, error, purpose: BandPurpose::Midpoints });
    }
    let rewrite: HashMap<usize, &Candidate> = found.iter().map(|(i, c)| (*i, c)).collect();
    let mut map: Vec<Value> = Vec::with_capacity(func.insts.len());
    let mut coarse: HashMap<(usize, u32), Value> = HashMap::new();
    let mut fiducial: HashMap<(usize, Option<u32>), Value> = HashMap::new();
    for (i, inst) in func.insts.iter().enumerate() {
        let v = match rewrite.get(&i) {
            Some(c) => {
                let n = banding_of[&c.grid];
                let mut e = Emitter {
                    func,
                    b: &mut b,
                    map: &map,
                    coarse: &mut coarse,
                    varies: &varies,
                    fiducial: &mut fiducial,
                    first_fiducial,
                    n,
                    grid: c.grid,
                };
                let total = e.summary_sum(c);
                if inst.ty.elem == Elem::Real {
                    b.unary(UnOp::Re, total)
                } else {
                    total
                }
            }
            None => b.emit(inst.op.map_operands(|v| map[v.index()])),
        };
        map.push(v);
    }
    let mut out = b.func;
    out.remap_roots(|v| map[v.index()]);
    prune(&out)
}

/// A sum of the form the module doc describes.
struct Candidate {
    /// The waveform.
    h: Value,
    /// Its grid (the sum's).
    grid: GridId,
    /// The sum's operand as a polynomial in `h` and `conj(h)`.
    poly: Poly,
}

/// Per instruction, whether its value depends on a param.
pub(super) fn param_dependent(func: &Function) -> Vec<bool> {
    let mut varies = vec![false; func.insts.len()];
    for (i, inst) in func.insts.iter().enumerate() {
        varies[i] = matches!(inst.op, Op::Param(_)) || inst.op.operands().iter().any(|a| varies[a.index()]);
    }
    varies
}

/// Every sum of `func` that can be rewritten, by instruction index.
fn candidates(func: &Function) -> Vec<(usize, Candidate)> {
    let varies = param_dependent(func);
    let mut cone = Cone::new(func);
    let mut found = Vec::new();
    for (i, inst) in func.insts.iter().enumerate() {
        let Op::Reduce(Reduce::Sum, x) = inst.op else { continue };
        let Shape::Grid(g) = func.ty(x).shape else { continue };
        let grid = func.grid(g);
        if !varies[x.index()] || grid.dims.len() != 1 || grid.start <= 0.0 || grid.step <= 0.0 || grid.len < 3 {
            continue;
        }
        let mut ex = Expander { func, varies: &varies, grid: g, h: None, visits: 0 };
        let Some(poly) = ex.expand(x) else { continue };
        let Some(h) = ex.h else { continue };
        if poly.terms[1..].iter().all(Option::is_none) || !cone.clonable(h, g) {
            continue;
        }
        found.push((i, Candidate { h, grid: g, poly }));
    }
    found
}

/// A coefficient that does not depend on the params, kept symbolic until
/// it is emitted (complex, on the sum's grid, when emitted).
#[derive(Clone, Debug)]
enum Coef {
    /// A param-free value of the source function (scalar or array).
    Of(Value),
    /// A complex constant.
    Const(C64),
    Conj(Box<Coef>),
    Neg(Box<Coef>),
    Add(Box<Coef>, Box<Coef>),
    Mul(Box<Coef>, Box<Coef>),
    Div(Box<Coef>, Box<Coef>),
    /// `select(condition, a, b)` on a param-free condition.
    Select(Value, Box<Coef>, Box<Coef>),
}

/// `Σ_m c_m · m` over the monomials `1, h, conj(h), h·conj(h)` (index
/// `a + 2b` for `h^a conj(h)^b`).
#[derive(Clone, Debug, Default)]
struct Poly {
    terms: [Option<Coef>; 4],
}

impl Poly {
    fn monomial(k: usize, c: Coef) -> Poly {
        let mut p = Poly::default();
        p.terms[k] = Some(c);
        p
    }

    fn map(self, f: impl Fn(Coef) -> Coef) -> Poly {
        Poly { terms: self.terms.map(|t| t.map(&f)) }
    }

    fn add(self, other: Poly) -> Poly {
        let mut terms = self.terms;
        for (t, o) in terms.iter_mut().zip(other.terms) {
            *t = match (t.take(), o) {
                (Some(a), Some(b)) => Some(Coef::Add(Box::new(a), Box::new(b))),
                (a, b) => a.or(b),
            };
        }
        Poly { terms }
    }

    fn neg(self) -> Poly {
        self.map(|c| Coef::Neg(Box::new(c)))
    }

    /// The conjugate: `h` and `conj(h)` swap.
    fn conj(self) -> Poly {
        let [c0, c1, c2, c3] = self.terms.map(|t| t.map(|c| Coef::Conj(Box::new(c))));
        Poly { terms: [c0, c2, c1, c3] }
    }

    /// The product, or `None` when it has `h²` or `conj(h)²`.
    fn mul(&self, other: &Poly) -> Option<Poly> {
        let mut out = Poly::default();
        for (i, a) in self.terms.iter().enumerate() {
            for (j, b) in other.terms.iter().enumerate() {
                let (Some(a), Some(b)) = (a, b) else { continue };
                if i & j != 0 {
                    return None;
                }
                out = out.add(Poly::monomial(i | j, Coef::Mul(Box::new(a.clone()), Box::new(b.clone()))));
            }
        }
        Some(out)
    }

    fn scale(self, z: C64) -> Poly {
        self.map(|c| Coef::Mul(Box::new(Coef::Const(z)), Box::new(c)))
    }
}

/// Expands a sum's operand into a [`Poly`] in one waveform `h`.
struct Expander<'a> {
    func: &'a Function,
    varies: &'a [bool],
    grid: GridId,
    h: Option<Value>,
    visits: usize,
}

impl Expander<'_> {
    fn expand(&mut self, v: Value) -> Option<Poly> {
        self.visits += 1;
        if self.visits > EXPANSION_BUDGET {
            return None;
        }
        if !self.varies[v.index()] {
            return Some(Poly::monomial(0, Coef::Of(v)));
        }
        if self.h == Some(v) {
            return Some(Poly::monomial(1, Coef::Const(C64::new(1.0, 0.0))));
        }
        let before = self.h;
        match self.structural(v) {
            Some(p) => Some(p),
            None => {
                // Not a polynomial in one waveform below here: `v` itself
                // may be the waveform.
                self.h = before;
                self.leaf(v)
            }
        }
    }

    fn leaf(&mut self, v: Value) -> Option<Poly> {
        let ty = self.func.ty(v);
        if self.h.is_some() || ty != (Ty { elem: Elem::Complex, shape: Shape::Grid(self.grid) }) || self.visits > EXPANSION_BUDGET {
            return None;
        }
        self.h = Some(v);
        Some(Poly::monomial(1, Coef::Const(C64::new(1.0, 0.0))))
    }

    fn structural(&mut self, v: Value) -> Option<Poly> {
        let half = C64::new(0.5, 0.0);
        match self.func.insts[v.index()].op {
            Op::Unary(UnOp::Neg, a) => Some(self.expand(a)?.neg()),
            Op::Unary(UnOp::ToComplex, a) => self.expand(a),
            Op::Unary(UnOp::Conj, a) => Some(self.expand(a)?.conj()),
            Op::Unary(UnOp::Re, a) => {
                let p = self.expand(a)?;
                Some(p.clone().add(p.conj()).scale(half))
            }
            Op::Unary(UnOp::Im, a) => {
                let p = self.expand(a)?;
                Some(p.clone().add(p.conj().neg()).scale(C64::new(0.0, -0.5)))
            }
            Op::Unary(UnOp::Abs2, a) => {
                let p = self.expand(a)?;
                p.mul(&p.clone().conj())
            }
            Op::Binary(op @ (BinOp::Add | BinOp::Sub), x, y) => {
                let p = self.expand(x)?;
                let q = self.expand(y)?;
                Some(if op == BinOp::Add { p.add(q) } else { p.add(q.neg()) })
            }
            Op::Binary(BinOp::Mul, x, y) => {
                let p = self.expand(x)?;
                let q = self.expand(y)?;
                p.mul(&q)
            }
            Op::Binary(BinOp::Div, x, y) if !self.varies[y.index()] => {
                Some(self.expand(x)?.map(|c| Coef::Div(Box::new(c), Box::new(Coef::Of(y)))))
            }
            Op::Select(c, x, y) if !self.varies[c.index()] => {
                let p = self.expand(x)?;
                let q = self.expand(y)?;
                let zero = || Coef::Const(C64::new(0.0, 0.0));
                let mut out = Poly::default();
                for (k, (a, b)) in p.terms.into_iter().zip(q.terms).enumerate() {
                    if a.is_some() || b.is_some() {
                        let sel = Coef::Select(c, Box::new(a.unwrap_or_else(zero)), Box::new(b.unwrap_or_else(zero)));
                        out.terms[k] = Some(sel);
                    }
                }
                Some(out)
            }
            _ => None,
        }
    }
}

/// Emits one rewritten sum into the new function.
struct Emitter<'a, 'b> {
    func: &'a Function,
    b: &'b mut Builder,
    map: &'b [Value],
    coarse: &'b mut HashMap<(usize, u32), Value>,
    /// Per source instruction, whether it depends on a param.
    varies: &'b [bool],
    /// Values recomputed at the fiducial, by source value and banding.
    fiducial: &'b mut HashMap<(usize, Option<u32>), Value>,
    /// The input `fiducial.NAME` of param 0 (the others follow).
    first_fiducial: usize,
    /// The banding.
    n: u32,
    /// The fine grid.
    grid: GridId,
}

impl Emitter<'_, '_> {
    fn fine(&self) -> Ty {
        Ty { elem: Elem::Complex, shape: Shape::Grid(self.grid) }
    }

    /// A real table on `grid`.
    fn table(&mut self, grid: GridId, data: Vec<f64>) -> Value {
        self.b.func.tables.push(Table { grid, data });
        self.b.emit(Op::Table(self.b.func.tables.len() as u32 - 1))
    }

    /// Source value `x` at the fiducial params (the `fiducial.NAME`
    /// inputs): on its own grid, or on the nodes of banding `onto`.
    fn at_fiducial(&mut self, x: Value, onto: Option<(u32, &Banding)>) -> Value {
        let scalar = self.func.ty(x).shape == Shape::Scalar;
        if !self.varies[x.index()] {
            return match onto {
                Some(band) if !scalar => clone_onto(self.func, self.b, self.map, self.coarse, x, band),
                _ => self.map[x.index()],
            };
        }
        let key = (x.index(), if scalar { None } else { onto.map(|o| o.0) });
        if let Some(&v) = self.fiducial.get(&key) {
            return v;
        }
        let v = match self.func.insts[x.index()].op {
            Op::Param(p) => self.b.emit(Op::Input((self.first_fiducial + p as usize) as u32)),
            Op::Broadcast(s, g) => {
                let s = self.at_fiducial(s, None);
                self.b.emit(Op::Broadcast(s, onto.map_or(g, |o| o.1.coarse)))
            }
            op => {
                let operands: Vec<(Value, Value)> = op.operands().into_iter().map(|a| (a, self.at_fiducial(a, onto))).collect();
                let mapped = op.map_operands(|a| operands.iter().find(|(o, _)| *o == a).expect("an operand").1);
                self.b.emit(mapped)
            }
        };
        self.fiducial.insert(key, v);
        v
    }

    /// `c` on the fine grid, complex.
    fn coef(&mut self, c: &Coef) -> Value {
        match c {
            Coef::Of(v) => {
                let mut x = self.map[v.index()];
                if self.b.ty(x).elem == Elem::Real {
                    x = self.b.unary(UnOp::ToComplex, x);
                }
                if self.b.ty(x).shape == Shape::Scalar {
                    x = self.b.emit(Op::Broadcast(x, self.grid));
                }
                x
            }
            Coef::Const(z) => self.b.constant(*z, self.fine()),
            Coef::Conj(a) => {
                let a = self.coef(a);
                self.b.unary(UnOp::Conj, a)
            }
            Coef::Neg(a) => {
                let a = self.coef(a);
                self.b.unary(UnOp::Neg, a)
            }
            Coef::Add(a, b) | Coef::Mul(a, b) | Coef::Div(a, b) => {
                let (x, y) = (self.coef(a), self.coef(b));
                let op = match c {
                    Coef::Add(..) => BinOp::Add,
                    Coef::Mul(..) => BinOp::Mul,
                    _ => BinOp::Div,
                };
                self.b.binary(op, x, y)
            }
            Coef::Select(cond, a, b) => {
                let mut cond = self.map[cond.index()];
                if self.b.ty(cond).shape == Shape::Scalar {
                    cond = self.b.emit(Op::Broadcast(cond, self.grid));
                }
                let (x, y) = (self.coef(a), self.coef(b));
                self.b.emit(Op::Select(cond, x, y))
            }
        }
    }

    /// `Σ_{k in bin j} z_k` on the nodes, for complex `z`.
    fn bin_sum(&mut self, z: Value) -> Value {
        let re = self.b.unary(UnOp::Re, z);
        let im = self.b.unary(UnOp::Im, z);
        let re = self.b.emit(Op::Band(BandOp::BinSum, self.n, re));
        let im = self.b.emit(Op::Band(BandOp::BinSum, self.n, im));
        self.b.binary(BinOp::Complex, re, im)
    }

    /// The summary of coefficient `c` weighted by the fine table `w`.
    fn summary(&mut self, c: Value, w: Value) -> Value {
        let w = self.b.unary(UnOp::ToComplex, w);
        let cw = self.b.mul(c, w);
        self.bin_sum(cw)
    }

    /// The rewritten sum (complex).
    fn summary_sum(&mut self, c: &Candidate) -> Value {
        let band = self.b.func.bands[self.n as usize].clone();
        let mids = self.b.func.bands[self.n as usize + 1].clone();
        let (fine, nodes) = (self.grid, band.coarse);
        let len = self.b.func.grid(fine).len;
        // The quadratic Lagrange basis on each bin (nodes at t = 0, the
        // midpoint's t_m and 1), at every fine point.
        let mut basis = [vec![0.0; len], vec![0.0; len], vec![0.0; len]];
        basis[0][len - 1] = 1.0;
        for (j, w) in band.nodes.windows(2).enumerate() {
            let (a, b, m) = (w[0] as usize, w[1] as usize, mids.nodes[j] as usize);
            for k in a..b {
                let weights = lagrange((k - a) as f64 / (b - a) as f64, (m - a) as f64 / (b - a) as f64);
                for (l, w) in basis.iter_mut().zip(weights) {
                    l[k] = w;
                }
            }
        }
        let h0_fine = self.at_fiducial(c.h, None);
        let h0_conj = self.b.unary(UnOp::Conj, h0_fine);
        // The waveform's ratio to the fiducial at each bin's first node,
        // its midpoint and its last node (the next bin's first).
        let ratio = |e: &mut Self, n: u32, at: &Banding| {
            let h0 = e.at_fiducial(c.h, Some((n, at)));
            let one = e.b.constant(C64::new(1.0, 0.0), Ty { elem: Elem::Complex, shape: Shape::Grid(nodes) });
            let inverse = e.b.binary(BinOp::Div, one, h0);
            let h = clone_onto(e.func, e.b, e.map, e.coarse, c.h, (n, at));
            e.b.mul(h, inverse)
        };
        let r = ratio(self, self.n, &band);
        let r_mid = ratio(self, self.n + 1, &Banding { coarse: nodes, ..mids });
        let next = |e: &mut Self, part: UnOp| {
            let x = e.b.unary(part, r);
            e.b.emit(Op::Band(BandOp::Next, e.n, x))
        };
        let (next_re, next_im) = (next(self, UnOp::Re), next(self, UnOp::Im));
        let r_next = self.b.binary(BinOp::Complex, next_re, next_im);
        let at = [r, r_mid, r_next];

        let mut terms: Vec<Value> = Vec::new();
        let mut weights: Vec<Value> = Vec::new();
        for (k, h0_factor, conj) in [(1, h0_fine, false), (2, h0_conj, true)] {
            let Some(coef) = &c.poly.terms[k] else { continue };
            let coef = self.coef(coef);
            let a = self.b.mul(coef, h0_factor);
            if weights.is_empty() {
                weights = basis.iter().map(|l| self.table(fine, l.clone())).collect();
            }
            for (&w, r) in weights.iter().zip(at) {
                let s = self.summary(a, w);
                let x = if conj { self.b.unary(UnOp::Conj, r) } else { r };
                terms.push(self.b.mul(s, x));
            }
        }
        if let Some(coef) = &c.poly.terms[3] {
            let coef = self.coef(coef);
            let h0_abs2 = self.b.mul(h0_fine, h0_conj);
            let q = self.b.mul(coef, h0_abs2);
            for u in 0..3 {
                for v in u..3 {
                    let w = self.table(fine, basis[u].iter().zip(&basis[v]).map(|(x, y)| x * y).collect());
                    let s = self.summary(q, w);
                    // Both orders of an off-diagonal pair: r_u conj(r_v) + conj(r_u) r_v = 2 Re(r_u conj(r_v)).
                    let rv = self.b.unary(UnOp::Conj, at[v]);
                    let product = self.b.mul(at[u], rv);
                    let mut x = self.b.unary(UnOp::Re, product);
                    if u != v {
                        x = self.b.add(x, x);
                    }
                    let x = self.b.unary(UnOp::ToComplex, x);
                    terms.push(self.b.mul(s, x));
                }
            }
        }
        let per_node = terms.into_iter().reduce(|a, b| self.b.add(a, b)).expect("a term in h");
        let mut total = self.b.emit(Op::Reduce(Reduce::Sum, per_node));
        if let Some(k) = &c.poly.terms[0] {
            let k = self.coef(k);
            let constant = self.b.emit(Op::Reduce(Reduce::Sum, k));
            total = self.b.add(total, constant);
        }
        total
    }
}

/// The quadratic Lagrange basis through `t = 0`, `t_m` and `1` at `t`
/// (linear when the bin has no point inside, `t_m = 0`).
fn lagrange(t: f64, tm: f64) -> [f64; 3] {
    if tm <= 0.0 || tm >= 1.0 {
        return [1.0 - t, 0.0, t];
    }
    [(t - tm) * (t - 1.0) / tm, t * (t - 1.0) / (tm * (tm - 1.0)), t * (t - tm) / (1.0 - tm)]
}

/// The midpoint of each bin between `nodes` (a fine index, the bin's
/// first point when it has none inside), and the last point for the last node.
fn midpoints(nodes: &[u32]) -> Vec<u32> {
    let mut mids: Vec<u32> = nodes.windows(2).map(|w| w[0] + (w[1] - w[0]) / 2).collect();
    mids.extend(nodes.last());
    mids
}

/// Nodes for `bins` bins of a grid with increasing positive coordinates
/// `f`, equally spaced in the phase bound `ψ` of the module doc (snapped
/// to grid points, so neighbours may merge), and the bound per bin in radians.
pub fn bin_nodes(f: &[f64], bins: u32) -> (Vec<u32>, f64) {
    let (f_lo, f_hi) = (f[0], f[f.len() - 1]);
    let psi = |x: f64| {
        let mut s = 0.0;
        for k in [-5, -4, -3, -2, -1, 1, 2, 3, 4, 5] {
            let gamma = k as f64 / 3.0;
            let star = if gamma < 0.0 { f_lo } else { f_hi };
            s += gamma.signum() * (x / star).powf(gamma);
        }
        2.0 * std::f64::consts::PI * s
    };
    let phase: Vec<f64> = f.iter().map(|&x| psi(x)).collect();
    let (p0, p1) = (phase[0], phase[phase.len() - 1]);
    let step = (p1 - p0) / bins as f64;
    let mut nodes = vec![0u32];
    for j in 1..bins {
        let target = p0 + j as f64 * step;
        // The first point at or past the target, or the one before if nearer.
        let k = phase.partition_point(|&p| p < target).min(f.len() - 1);
        let k = if k > 0 && (target - phase[k - 1]) < (phase[k] - target) { k - 1 } else { k };
        if k as u32 > *nodes.last().expect("a node") && k < f.len() - 1 {
            nodes.push(k as u32);
        }
    }
    nodes.push(f.len() as u32 - 1);
    (nodes, step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_are_equal_in_the_phase_bound_and_cover_the_grid() {
        let f: Vec<f64> = (0..8033).map(|k| 20.0 + 0.125 * k as f64).collect();
        let (nodes, bound) = bin_nodes(&f, 100);
        assert_eq!(nodes.len(), 101, "{nodes:?}");
        assert_eq!((nodes[0], *nodes.last().unwrap()), (0, 8032));
        assert!(nodes.windows(2).all(|w| w[0] < w[1]));
        // Narrow bins at low frequency where f^(-5/3) moves fast, wide at the top.
        assert!(nodes[1] - nodes[0] < 10 && nodes[100] - nodes[99] > 100, "{nodes:?}");
        assert!(bound > 0.1 && bound < 10.0, "{bound}");
        // More bins than points: every point a node.
        let (all, _) = bin_nodes(&f[..50], 1000);
        assert_eq!(all, (0..50).collect::<Vec<u32>>());
    }
}
