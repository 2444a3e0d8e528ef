//! Operations: what one instruction computes (elementwise, reductions,
//! transforms, tensor ops).

use super::types::*;

/// Unary operations.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnOp {
    /// `-x` (real or complex).
    Neg,
    /// Square root (real).
    Sqrt,
    /// Cube root (real, odd: defined for negative x).
    Cbrt,
    /// `e^x` (real or complex).
    Exp,
    /// Natural logarithm (real).
    Log,
    /// Sine.
    Sin,
    /// Cosine.
    Cos,
    /// Tangent.
    Tan,
    /// Hyperbolic tangent.
    Tanh,
    /// Absolute value; for a complex operand, the modulus (a real result).
    Abs,
    /// Sign: -1, 0 or 1.
    Sign,
    /// Real part of a complex value.
    Re,
    /// Imaginary part of a complex value.
    Im,
    /// Complex conjugate.
    Conj,
    /// `|z|^2` of a complex value (real result).
    Abs2,
    /// `e^{i x}` of a real x (complex result).
    Cis,
    /// A real value as a complex one with zero imaginary part.
    ToComplex,
}

/// Binary operations (operands of equal type unless noted).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinOp {
    /// Sum.
    Add,
    /// Difference.
    Sub,
    /// Product.
    Mul,
    /// Quotient.
    Div,
    /// `x^y` for real x, y.
    Pow,
    /// `atan2(y, x)`.
    Atan2,
    /// Smaller of two reals.
    Min,
    /// Larger of two reals.
    Max,
    /// `<` (bool result).
    Lt,
    /// `<=`
    Le,
    /// `>`
    Gt,
    /// `>=`
    Ge,
    /// `==`
    Eq,
    /// `!=`
    Ne,
    /// `re + i·im` from two reals (complex result).
    Complex,
}

/// Reductions of an array over its grid to a scalar.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Reduce {
    /// Sum of all elements (real or complex).
    Sum,
    /// Largest element (real).
    Max,
}

/// A discrete Fourier transform between a time grid of `n` samples and its
/// one-sided frequency grid of `n/2 + 1` bins. It runs as a library call
/// (realfft) between fused loops, never inside one.
///
/// With `w_k = 2` for bins strictly between DC and Nyquist and 1 at DC and
/// (even `n`) Nyquist when `doubled` is set, and `w_k = 1` otherwise:
/// - forward (`inverse == false`, real → complex):
///   `y_k = scale · w_k · Σ_j x_j e^{-2πi jk/n}`;
/// - inverse (complex → real): `x_j = scale · Σ_k w_k Re(Y_k e^{+2πi jk/n})`.
///
/// `rfft(x, f)` is the forward transform with `scale = dt`; `irfft(X, t)`
/// the inverse with `scale = df` and `doubled` (the Hermitian half
/// spectrum). The transpose of each (the adjoint) flips `inverse` and keeps
/// `doubled` and `scale`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Dft {
    /// Direction: false for time → frequency, true for frequency → time.
    pub inverse: bool,
    /// Whether the frequency side is weighted by `w_k` (see above).
    pub doubled: bool,
    /// Scale factor (bits of an f64).
    pub scale: u64,
    /// Grid of the result.
    pub out: GridId,
}

impl Dft {
    /// The scale factor.
    pub fn scale(&self) -> f64 {
        f64::from_bits(self.scale)
    }

    /// The weight `w_k` of frequency bin `k` for a transform of `n` samples.
    pub fn weight(&self, k: usize, n: usize) -> f64 {
        if !self.doubled || k == 0 || 2 * k == n {
            1.0
        } else {
            2.0
        }
    }
}

/// The row axis of a two-dimensional convolution or pooling window (the
/// column axis is the [`Conv`]'s or [`Pool`]'s own fields): positions,
/// taps (the window for pooling), stride, padding and dilation, with
/// `len_out = (len_in + 2·padding − dilation·(kernel−1) − 1) / stride + 1`.
/// One-dimensional layers have [`Axis::ONE`], one row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Axis {
    /// Input rows.
    pub len_in: u32,
    /// Output rows.
    pub len_out: u32,
    /// Kernel (or pooling window) rows.
    pub kernel: u32,
    /// Step between output rows.
    pub stride: u32,
    /// Zero rows added above and below.
    pub padding: u32,
    /// Step between kernel rows.
    pub dilation: u32,
}

impl Axis {
    /// The row axis of a one-dimensional layer: one row in, one row out.
    pub const ONE: Axis = Axis { len_in: 1, len_out: 1, kernel: 1, stride: 1, padding: 0, dilation: 1 };

    /// An axis of `len_in` positions read by `kernel` taps `dilation`
    /// apart at steps of `stride` with `padding` zeros on each side, or
    /// `None` when the kernel spans more than the padded input.
    pub fn new(len_in: u32, kernel: u32, stride: u32, padding: u32, dilation: u32) -> Option<Axis> {
        let span = dilation as u64 * (kernel as u64).checked_sub(1)? + 1;
        let padded = len_in as u64 + 2 * padding as u64;
        let len_out = u32::try_from(padded.checked_sub(span)? / (stride as u64).max(1) + 1).ok()?;
        Some(Axis { len_in, len_out, kernel, stride, padding, dilation })
    }
}

/// Sizes of a convolution over `[channels × rows × columns]` arrays
/// (row-major, as PyTorch's `conv2d` without a batch axis; `conv1d` has
/// one row, [`Axis::ONE`]):
/// `y[o, r, t] = Σ_{c, i, j} w[o, c, i, j] · x[c, r·rows.stride + i·rows.dilation − rows.padding, t·stride + j·dilation − padding]`,
/// where samples outside the input are zero. The unnamed fields are the
/// column axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Conv {
    /// Input channels.
    pub c_in: u32,
    /// Output channels.
    pub c_out: u32,
    /// Input positions (columns).
    pub len_in: u32,
    /// Output positions: `(len_in + 2·padding − dilation·(kernel−1) − 1) / stride + 1`.
    pub len_out: u32,
    /// Kernel taps (columns).
    pub kernel: u32,
    /// Step between output positions.
    pub stride: u32,
    /// Zeros added on each side.
    pub padding: u32,
    /// Step between taps.
    pub dilation: u32,
    /// The row axis ([`Axis::ONE`] for `conv1d`).
    pub rows: Axis,
}

impl Conv {
    /// Elements of the input: `c_in · rows · columns`.
    pub fn input_len(&self) -> usize {
        [self.c_in, self.rows.len_in, self.len_in].iter().map(|x| *x as usize).product()
    }

    /// Elements of the output: `c_out · rows · columns`.
    pub fn output_len(&self) -> usize {
        [self.c_out, self.rows.len_out, self.len_out].iter().map(|x| *x as usize).product()
    }

    /// Taps of one kernel: `kernel rows · kernel columns`.
    pub fn taps(&self) -> usize {
        self.rows.kernel as usize * self.kernel as usize
    }

    /// Elements of the weight: `c_out · c_in · taps`.
    pub fn weight_len(&self) -> usize {
        self.c_out as usize * self.c_in as usize * self.taps()
    }
}

/// Sizes of a pooling window over `[channels × rows × columns]` arrays
/// (one row for one-dimensional pooling): output `(r, o)` of channel `c`
/// covers rows `r·rows.stride .. + rows.kernel` and columns
/// `o·stride .. o·stride + window`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Pool {
    /// Channels (pooled independently).
    pub channels: u32,
    /// Input positions (columns).
    pub len_in: u32,
    /// Output positions: `(len_in − window) / stride + 1`.
    pub len_out: u32,
    /// Window length (columns).
    pub window: u32,
    /// Step between windows.
    pub stride: u32,
    /// The row axis: [`Axis::ONE`] in one dimension; no padding, dilation 1.
    pub rows: Axis,
}

impl Pool {
    /// Elements of the input.
    pub fn input_len(&self) -> usize {
        [self.channels, self.rows.len_in, self.len_in].iter().map(|x| *x as usize).product()
    }

    /// Elements of the output.
    pub fn output_len(&self) -> usize {
        [self.channels, self.rows.len_out, self.len_out].iter().map(|x| *x as usize).product()
    }

    /// Elements of one window: `rows · columns`.
    pub fn window_len(&self) -> usize {
        self.rows.kernel as usize * self.window as usize
    }
}

/// A block of rows of a `[rows × cols]` array: rows `from .. from + count`
/// (one argument of `stack`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rows {
    /// Rows of the whole array.
    pub rows: u32,
    /// Columns (positions) of every row.
    pub cols: u32,
    /// First row of the block.
    pub from: u32,
    /// Rows in the block.
    pub count: u32,
}

/// A dense-tensor operation on row-major real arrays: the layers of
/// `learned` components. Like [`Dft`] it runs as a library call between
/// fused loops (see `tensor`). The forward layers are `MatVec`, `Conv`,
/// `PoolPick` (max pooling is `PoolPick(x, x)`), `PoolAvg` and `Spread`;
/// every other variant is the transpose of one of them in one operand, so
/// the adjoint of each op is again a `TensorOp` (see `passes::adjoint`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TensorOp {
    /// `(W[m×k], x[k]) → y[m] = W·x`.
    MatVec { m: u32, k: u32 },
    /// `(W[m×k], y[m]) → x[k] = Wᵀ·y`.
    MatTVec { m: u32, k: u32 },
    /// `(y[m], x[k]) → W[m×k] = y ⊗ x`.
    Outer { m: u32, k: u32 },
    /// `(x, w) → y`, see [`Conv`].
    Conv(Conv),
    /// `(ȳ, w) → x̄`: the transpose of `Conv` in `x`.
    ConvBackData(Conv),
    /// `(ȳ, x) → w̄`: the transpose of `Conv` in `w`.
    ConvBackWeight(Conv),
    /// `(x, a) → y`: in each window, the element of `a` where `x` is
    /// largest (the first such on ties).
    PoolPick(Pool),
    /// `(x, ȳ) → ā`: the transpose of `PoolPick` in `a` (each `ȳ` goes to
    /// the position `PoolPick` took it from).
    PoolScatter(Pool),
    /// `(x) → y`: the mean of each window.
    PoolAvg(Pool),
    /// `(ȳ) → x̄`: the transpose of `PoolAvg`.
    PoolAvgBack(Pool),
    /// `(b[rows]) → y[rows×cols]`, `y[r, c] = b[r]` (a bias per channel).
    Spread { rows: u32, cols: u32 },
    /// `(y[rows×cols]) → b[rows]`, the sum of each row: the transpose of `Spread`.
    SumRows { rows: u32, cols: u32 },
    /// `(x[count×cols]) → y[rows×cols]`: `x` as the block [`Rows`] of `y`,
    /// zeros elsewhere.
    PlaceRows(Rows),
    /// `(y[rows×cols]) → x[count×cols]`: the block [`Rows`] of `y`, the
    /// transpose of `PlaceRows`.
    TakeRows(Rows),
}

impl TensorOp {
    /// Number of operands (1 or 2).
    pub fn arity(&self) -> usize {
        match self {
            TensorOp::PoolAvg(_)
            | TensorOp::PoolAvgBack(_)
            | TensorOp::Spread { .. }
            | TensorOp::SumRows { .. }
            | TensorOp::PlaceRows(_)
            | TensorOp::TakeRows(_) => 1,
            _ => 2,
        }
    }

    /// Element counts of the operands (the second is 0 for unary ops).
    pub fn operand_lens(&self) -> [usize; 2] {
        let u = |x: u32| x as usize;
        match *self {
            TensorOp::MatVec { m, k } => [u(m * k), u(k)],
            TensorOp::MatTVec { m, k } => [u(m * k), u(m)],
            TensorOp::Outer { m, k } => [u(m), u(k)],
            TensorOp::Conv(c) => [c.input_len(), c.weight_len()],
            TensorOp::ConvBackData(c) => [c.output_len(), c.weight_len()],
            TensorOp::ConvBackWeight(c) => [c.output_len(), c.input_len()],
            TensorOp::PoolPick(p) => [p.input_len(), p.input_len()],
            TensorOp::PoolScatter(p) => [p.input_len(), p.output_len()],
            TensorOp::PoolAvg(p) => [p.input_len(), 0],
            TensorOp::PoolAvgBack(p) => [p.output_len(), 0],
            TensorOp::Spread { rows, .. } => [u(rows), 0],
            TensorOp::SumRows { rows, cols } => [u(rows * cols), 0],
            TensorOp::PlaceRows(r) => [u(r.count * r.cols), 0],
            TensorOp::TakeRows(r) => [u(r.rows * r.cols), 0],
        }
    }

    /// Element count of the result.
    pub fn out_len(&self) -> usize {
        let u = |x: u32| x as usize;
        match *self {
            TensorOp::MatVec { m, .. } => u(m),
            TensorOp::MatTVec { k, .. } => u(k),
            TensorOp::Outer { m, k } => u(m * k),
            TensorOp::Conv(c) => c.output_len(),
            TensorOp::ConvBackData(c) => c.input_len(),
            TensorOp::ConvBackWeight(c) => c.weight_len(),
            TensorOp::PoolPick(p) | TensorOp::PoolAvg(p) => p.output_len(),
            TensorOp::PoolScatter(p) | TensorOp::PoolAvgBack(p) => p.input_len(),
            TensorOp::Spread { rows, cols } => u(rows * cols),
            TensorOp::SumRows { rows, .. } => u(rows),
            TensorOp::PlaceRows(r) => u(r.rows * r.cols),
            TensorOp::TakeRows(r) => u(r.count * r.cols),
        }
    }

    /// The name in IR dumps.
    pub fn name(&self) -> &'static str {
        match self {
            TensorOp::MatVec { .. } => "matvec",
            TensorOp::MatTVec { .. } => "matvec_t",
            TensorOp::Outer { .. } => "outer",
            TensorOp::Conv(_) => "conv",
            TensorOp::ConvBackData(_) => "conv_back_data",
            TensorOp::ConvBackWeight(_) => "conv_back_weight",
            TensorOp::PoolPick(_) => "pool_pick",
            TensorOp::PoolScatter(_) => "pool_scatter",
            TensorOp::PoolAvg(_) => "pool_avg",
            TensorOp::PoolAvgBack(_) => "pool_avg_back",
            TensorOp::Spread { .. } => "spread",
            TensorOp::SumRows { .. } => "sum_rows",
            TensorOp::PlaceRows(_) => "place_rows",
            TensorOp::TakeRows(_) => "take_rows",
        }
    }
}

/// An operation between a grid and a coarse subset of its points, a
/// [`Banding`](super::Banding) (multibanding, see `passes::multiband`).
/// With nodes `i_0 = 0 < i_1 < … < i_m = n − 1` of the fine grid and
/// `L(x)[k] = (1 − t) x_j + t x_{j+1}`, `t = (k − i_j)/(i_{j+1} − i_j)` for
/// `i_j ≤ k ≤ i_{j+1}`, the linear interpolation of coarse values `x`.
/// Like [`Dft`] each runs as a library call between fused loops.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BandOp {
    /// Real `x` on the coarse grid → complex `e^{i L(x)}` on the fine grid,
    /// computed by rotation: one exact `e^{i x_j}` per node and one complex
    /// multiply per fine point.
    Cis,
    /// Real `x` on the coarse grid → real `L(x)` on the fine grid.
    Interp,
    /// Real `y` on the fine grid → real `Lᵀ y` on the coarse grid: the
    /// transpose of [`BandOp::Interp`] (the adjoint of both others).
    InterpT,
    /// Real `y` on the fine grid → real sums over each node's band on the
    /// coarse grid: `s_j = Σ y_k` over `i_j ≤ k < i_{j+1}`, and the last
    /// node's is the last point (relative binning's summary data, see
    /// `passes::relbin`).
    BinSum,
    /// Real `x` on the coarse grid → real `y_k = x_j` on the fine points of
    /// node `j`'s band: the transpose of [`BandOp::BinSum`].
    BinSpread,
    /// Real `x` on the coarse grid → `y_j = x_{j+1}`, 0 at the last node.
    Next,
    /// Real `x` on the coarse grid → `y_j = x_{j−1}`, 0 at the first node:
    /// the transpose of [`BandOp::Next`].
    Prev,
}

/// Which grid of a [`Banding`](super::Banding) a band op's value lives on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BandSide {
    /// The fine grid.
    Fine,
    /// The coarse grid of the nodes.
    Coarse,
}

impl BandOp {
    /// The name in IR dumps.
    pub fn name(&self) -> &'static str {
        match self {
            BandOp::Cis => "band_cis",
            BandOp::Interp => "band_interp",
            BandOp::InterpT => "band_interp_t",
            BandOp::BinSum => "band_sum",
            BandOp::BinSpread => "band_spread",
            BandOp::Next => "band_next",
            BandOp::Prev => "band_prev",
        }
    }

    /// The grids of the operand and of the result.
    pub fn sides(&self) -> (BandSide, BandSide) {
        match self {
            BandOp::Cis | BandOp::Interp | BandOp::BinSpread => (BandSide::Coarse, BandSide::Fine),
            BandOp::InterpT | BandOp::BinSum => (BandSide::Fine, BandSide::Coarse),
            BandOp::Next | BandOp::Prev => (BandSide::Coarse, BandSide::Coarse),
        }
    }

    /// The transpose of a linear op (every op but `Cis`).
    pub fn transpose(&self) -> BandOp {
        match self {
            BandOp::Interp => BandOp::InterpT,
            BandOp::InterpT => BandOp::Interp,
            BandOp::BinSum => BandOp::BinSpread,
            BandOp::BinSpread => BandOp::BinSum,
            BandOp::Next => BandOp::Prev,
            BandOp::Prev => BandOp::Next,
            BandOp::Cis => BandOp::Cis,
        }
    }
}

/// An instruction's operation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Op {
    /// A real constant (stored as bits so ops can be hashed).
    Const(u64),
    /// A complex constant (bits of re, im).
    ConstComplex(u64, u64),
    /// Parameter number n (a real scalar, in base units).
    Param(u32),
    /// Input number n.
    Input(u32),
    /// The coordinates of a grid: `start + i * step`.
    GridCoord(GridId),
    /// Precomputed real array number n of [`Function::tables`]: a value
    /// that depends only on a grid, folded once per scene.
    Table(u32),
    /// Unary operation.
    Unary(UnOp, Value),
    /// Binary operation.
    Binary(BinOp, Value, Value),
    /// `x^c` for a constant c (bits).
    PowConst(Value, u64),
    /// Elementwise choice: `if c then a else b`.
    Select(Value, Value, Value),
    /// A scalar repeated over a grid.
    Broadcast(Value, GridId),
    /// A reduction over the operand's grid.
    Reduce(Reduce, Value),
    /// A discrete Fourier transform of an array onto [`Dft::out`].
    Dft(Dft, Value),
    /// A tensor operation whose result lives on the grid; unary ops repeat
    /// their operand in the second slot (see [`Op::operands`]).
    Tensor(TensorOp, GridId, Value, Value),
    /// A [`BandOp`] over banding number n of [`Function::bands`](super::Function::bands).
    Band(BandOp, u32, Value),
}

impl Op {
    /// A real constant.
    pub fn constant(x: f64) -> Op {
        Op::Const(x.to_bits())
    }

    /// The operands, in order.
    pub fn operands(&self) -> Vec<Value> {
        match *self {
            Op::Const(_) | Op::ConstComplex(..) | Op::Param(_) | Op::Input(_) | Op::GridCoord(_) | Op::Table(_) => vec![],
            Op::Unary(_, a) | Op::PowConst(a, _) | Op::Broadcast(a, _) | Op::Reduce(_, a) | Op::Dft(_, a) | Op::Band(_, _, a) => {
                vec![a]
            }
            Op::Binary(_, a, b) => vec![a, b],
            Op::Tensor(t, _, a, _) if t.arity() == 1 => vec![a],
            Op::Tensor(_, _, a, b) => vec![a, b],
            Op::Select(c, a, b) => vec![c, a, b],
        }
    }

    /// The same op with each operand replaced by `f(operand)`.
    pub fn map_operands(&self, mut f: impl FnMut(Value) -> Value) -> Op {
        match *self {
            Op::Unary(u, a) => Op::Unary(u, f(a)),
            Op::PowConst(a, c) => Op::PowConst(f(a), c),
            Op::Broadcast(a, g) => Op::Broadcast(f(a), g),
            Op::Reduce(r, a) => Op::Reduce(r, f(a)),
            Op::Dft(d, a) => Op::Dft(d, f(a)),
            Op::Band(o, n, a) => Op::Band(o, n, f(a)),
            Op::Binary(b, x, y) => Op::Binary(b, f(x), f(y)),
            Op::Select(c, x, y) => Op::Select(f(c), f(x), f(y)),
            Op::Tensor(t, g, x, _) if t.arity() == 1 => {
                let x = f(x);
                Op::Tensor(t, g, x, x)
            }
            Op::Tensor(t, g, x, y) => Op::Tensor(t, g, f(x), f(y)),
            other => other,
        }
    }
}

/// One instruction: an operation and the type of the value it defines.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Inst {
    /// What it computes.
    pub op: Op,
    /// Type of the result.
    pub ty: Ty,
}
