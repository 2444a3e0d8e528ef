//! The SSA IR: a flat list of instructions over scalars and arrays on named
//! grids. Every instruction defines one value (its index); operands always
//! refer to earlier instructions. Elementwise operands have equal element
//! kind and shape: the checker inserts explicit [`Op::Broadcast`] and
//! [`UnOp::ToComplex`] so that passes and backends never guess.

use std::fmt::{self, Write};

/// Element kind of a value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Elem {
    /// A real number.
    Real,
    /// A complex number.
    Complex,
    /// A truth value (from comparisons; consumed by `select`).
    Bool,
}

/// Index of a grid in [`Function::grids`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct GridId(pub u32);

/// Shape of a value: a scalar, or one element per point of a grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// One number.
    Scalar,
    /// One number per grid point.
    Grid(GridId),
}

/// Type of an IR value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Ty {
    /// Element kind.
    pub elem: Elem,
    /// Shape.
    pub shape: Shape,
}

impl Ty {
    /// A real scalar.
    pub const REAL: Ty = Ty { elem: Elem::Real, shape: Shape::Scalar };
    /// A complex scalar.
    pub const COMPLEX: Ty = Ty { elem: Elem::Complex, shape: Shape::Scalar };
    /// The same shape with another element kind.
    pub fn with_elem(self, elem: Elem) -> Ty {
        Ty { elem, shape: self.shape }
    }
}

/// An SSA value: the index of the instruction that defines it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Value(pub u32);

impl Value {
    /// As an index into [`Function::insts`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

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

/// Sizes of a one-dimensional convolution over `[channels × positions]`
/// arrays (row-major, as PyTorch's `conv1d` without a batch axis):
/// `y[o, t] = Σ_{c, j} w[o, c, j] · x[c, t·stride + j·dilation − padding]`,
/// where samples outside `0..len_in` are zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Conv {
    /// Input channels.
    pub c_in: u32,
    /// Output channels.
    pub c_out: u32,
    /// Input positions.
    pub len_in: u32,
    /// Output positions: `(len_in + 2·padding − dilation·(kernel−1) − 1) / stride + 1`.
    pub len_out: u32,
    /// Kernel taps.
    pub kernel: u32,
    /// Step between output positions.
    pub stride: u32,
    /// Zeros added on each side.
    pub padding: u32,
    /// Step between taps.
    pub dilation: u32,
}

/// Sizes of a pooling window over `[channels × positions]` arrays:
/// output `o` of channel `c` covers inputs `o·stride .. o·stride + window`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Pool {
    /// Channels (pooled independently).
    pub channels: u32,
    /// Input positions.
    pub len_in: u32,
    /// Output positions: `(len_in − window) / stride + 1`.
    pub len_out: u32,
    /// Window length.
    pub window: u32,
    /// Step between windows.
    pub stride: u32,
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
            TensorOp::Conv(c) => [u(c.c_in * c.len_in), u(c.c_out * c.c_in * c.kernel)],
            TensorOp::ConvBackData(c) => [u(c.c_out * c.len_out), u(c.c_out * c.c_in * c.kernel)],
            TensorOp::ConvBackWeight(c) => [u(c.c_out * c.len_out), u(c.c_in * c.len_in)],
            TensorOp::PoolPick(p) => [u(p.channels * p.len_in), u(p.channels * p.len_in)],
            TensorOp::PoolScatter(p) => [u(p.channels * p.len_in), u(p.channels * p.len_out)],
            TensorOp::PoolAvg(p) => [u(p.channels * p.len_in), 0],
            TensorOp::PoolAvgBack(p) => [u(p.channels * p.len_out), 0],
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
            TensorOp::Conv(c) => u(c.c_out * c.len_out),
            TensorOp::ConvBackData(c) => u(c.c_in * c.len_in),
            TensorOp::ConvBackWeight(c) => u(c.c_out * c.c_in * c.kernel),
            TensorOp::PoolPick(p) | TensorOp::PoolAvg(p) => u(p.channels * p.len_out),
            TensorOp::PoolScatter(p) | TensorOp::PoolAvgBack(p) => u(p.channels * p.len_in),
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
            Op::Unary(_, a) | Op::PowConst(a, _) | Op::Broadcast(a, _) | Op::Reduce(_, a) | Op::Dft(_, a) => {
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

/// A uniform grid: `len` points `start + i * step` (base units). Grids of
/// tensors (the layers of `learned` components) are index grids (start 0,
/// step 1) whose points are the row-major elements of an array of `dims`.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Name in the scene.
    pub name: String,
    /// First coordinate.
    pub start: f64,
    /// Spacing.
    pub step: f64,
    /// Number of points.
    pub len: usize,
    /// Unit of the coordinates, for display.
    pub unit: String,
    /// Tensor dimensions (product `len`); `[len]` for a physical grid.
    pub dims: Vec<usize>,
}

/// Working precision of generated code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Precision {
    /// 64-bit floats everywhere.
    #[default]
    F64,
    /// 32-bit floats for arithmetic; reductions accumulate in f64; values
    /// far outside f32's range are stored scaled by powers of two
    /// (`passes::rescale`).
    F32,
    /// f32, rescaled as [`Precision::F32`] is, except two kinds of values,
    /// which are computed (and kept, in tables, scratch arrays and outputs)
    /// in f64: phases, i.e. every value that flows through elementwise
    /// arithmetic alone into the argument of a sine, cosine, tangent, `cis`
    /// or complex exponential, and that function itself; and values still
    /// outside f32's comfortable range after rescaling, i.e. whose largest
    /// magnitude, when the scene is evaluated at its default params and
    /// inputs, is below 2^-96 or above 2^96 (f32's normal range less 2^30
    /// of headroom; the result of `exp(100)`, say), and what is computed
    /// directly from those. Reductions accumulate in f64. Inputs, and what
    /// transforms and tensor ops read and write, stay f32. See
    /// [`Function::wide_values`].
    Mixed,
}

impl Precision {
    /// The element type of inputs, outputs and library-call buffers.
    pub fn storage(self) -> Precision {
        match self {
            Precision::F64 => Precision::F64,
            Precision::F32 | Precision::Mixed => Precision::F32,
        }
    }
}

impl fmt::Display for Precision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Precision::F64 => "f64",
            Precision::F32 => "f32",
            Precision::Mixed => "mixed",
        })
    }
}

/// How generated code computes transcendental functions (the scene's
/// `math` knob); see `mathlib` for the measured errors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MathMode {
    /// Within 2 ulp of glibc libm (f64); f32 within 1 ulp of glibc's f32 functions.
    #[default]
    Exact,
    /// About 1e-12 relative error (cheaper polynomials, no extra-precision tails).
    Fast,
    /// About 1e-7 relative error (f32 work and users who want speed).
    Fastest,
}

impl fmt::Display for MathMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MathMode::Exact => "exact",
            MathMode::Fast => "fast",
            MathMode::Fastest => "fastest",
        })
    }
}

/// A scalar parameter of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamInfo {
    /// Name.
    pub name: String,
    /// Default value in the declared unit.
    pub default: Option<f64>,
    /// Bounds in the declared unit.
    pub bounds: Option<(f64, f64)>,
    /// Base units per declared unit (values are multiplied by it on the way in).
    pub scale: f64,
    /// Declared unit, for display.
    pub unit: String,
}

/// Run-time data of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct InputInfo {
    /// Name.
    pub name: String,
    /// Type (element kind and shape).
    pub ty: Ty,
    /// Base units per declared unit.
    pub scale: f64,
    /// Declared unit, for display.
    pub unit: String,
    /// Data used when none is bound (base units), from the input's default.
    pub default: Option<Vec<num_complex::Complex64>>,
    /// What the input is for.
    pub role: InputRole,
}

impl InputInfo {
    /// Whether it is a weight tensor (trainable).
    pub fn is_weight(&self) -> bool {
        self.role == InputRole::Weight
    }
}

/// What a scene input is for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum InputRole {
    /// Data the caller binds (or its default).
    Data,
    /// A weight tensor of a `learned` component (initialised in `default`),
    /// which `grad ... wrt` may name.
    Weight,
    /// The mask of a `dropout(x, rate)`: all ones by default (evaluation);
    /// a trainer binds a fresh mask per example, each element 0 with
    /// probability `rate` and 1/(1 − rate) otherwise.
    DropoutMask(f64),
}

/// A real array over a grid computed at compile time.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// The grid it lives on.
    pub grid: GridId,
    /// One value per grid point.
    pub data: Vec<f64>,
}

/// A named result of the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    /// Name.
    pub name: String,
    /// The value.
    pub value: Value,
    /// Unit (base units), for display.
    pub unit: String,
    /// The kernel returns the value times `2^-exponent` (0 unless
    /// `passes::rescale` scaled it; readers multiply by `2^exponent`).
    pub exponent: i32,
}

/// A gradient the scene computes: d output / d param.
#[derive(Clone, Debug, PartialEq)]
pub struct GradOutput {
    /// Index into [`Function::outputs`].
    pub output: usize,
    /// Index into [`Function::params`].
    pub param: usize,
    /// The value (per base unit of the param); `None` until the adjoint pass runs.
    pub value: Option<Value>,
}

/// A gradient with respect to a trainable input (a weight tensor):
/// an array of the input's shape.
#[derive(Clone, Debug, PartialEq)]
pub struct InputGrad {
    /// Index into [`Function::outputs`].
    pub output: usize,
    /// Index into [`Function::inputs`].
    pub input: usize,
    /// The value; `None` until the adjoint pass runs.
    pub value: Option<Value>,
}

/// The value a scene `knob` was compiled with (its own or a `--knob`
/// override), in base units; printed by `--emit ir`.
#[derive(Clone, Debug, PartialEq)]
pub struct KnobValue {
    /// The knob's name.
    pub name: String,
    /// Its value in base units.
    pub value: f64,
    /// The unit of the value (`1` when dimensionless).
    pub unit: String,
}

/// A scene lowered to IR: everything one compiled kernel computes.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Function {
    /// Scene name.
    pub name: String,
    /// The scene's knobs, in declaration order, with the values compiled in.
    pub knobs: Vec<KnobValue>,
    /// Grids.
    pub grids: Vec<Grid>,
    /// Parameters.
    pub params: Vec<ParamInfo>,
    /// Inputs.
    pub inputs: Vec<InputInfo>,
    /// Instructions; value `%i` is defined by `insts[i]`.
    pub insts: Vec<Inst>,
    /// Requested outputs.
    pub outputs: Vec<Output>,
    /// Requested gradients with respect to params.
    pub grads: Vec<GradOutput>,
    /// Requested gradients with respect to trainable inputs.
    pub input_grads: Vec<InputGrad>,
    /// Grid-only arrays folded at compile time (see `passes::specialise`).
    pub tables: Vec<Table>,
    /// Working precision.
    pub precision: Precision,
    /// Accuracy of transcendental functions.
    pub math: MathMode,
}

impl Function {
    /// Keeps the outputs `keep` accepts, and the gradients of those (a
    /// later prune drops what only the others needed).
    pub fn retain_outputs(&mut self, keep: impl Fn(&Output) -> bool) {
        // Each output's index among the kept ones, `None` if dropped.
        let mut kept = 0;
        let new_index: Vec<Option<usize>> = self
            .outputs
            .iter()
            .map(|o| {
                keep(o).then(|| {
                    kept += 1;
                    kept - 1
                })
            })
            .collect();
        let mut old = new_index.iter();
        self.outputs.retain(|_| old.next().is_some_and(Option::is_some));
        self.grads.retain_mut(|g| new_index[g.output].map(|n| g.output = n).is_some());
        self.input_grads.retain_mut(|g| new_index[g.output].map(|n| g.output = n).is_some());
    }

    /// Type of `v`.
    pub fn ty(&self, v: Value) -> Ty {
        self.insts[v.index()].ty
    }

    /// Whether array `v` is the same at every grid point: a broadcast
    /// scalar, or elementwise arithmetic on such (as `passes::rescale`
    /// writes a scaled scalar), looking at most `depth` ops deep.
    pub fn is_uniform(&self, v: Value, depth: u32) -> bool {
        match self.insts[v.index()].op {
            Op::Broadcast(..) => true,
            op @ (Op::Unary(..) | Op::Binary(..) | Op::PowConst(..)) if depth > 0 => {
                op.operands().iter().all(|&a| self.is_uniform(a, depth - 1))
            }
            _ => false,
        }
    }

    /// Whether the truth value `c` is an *interval condition*: an order
    /// comparison of a grid's coordinates with a uniform value
    /// ([`Function::is_uniform`]: a broadcast scalar), such as
    /// the ISCO cut `f <= f_isco`. Coordinates `start + i·step` are
    /// monotone in `i`, so such a condition holds on a prefix or a suffix
    /// of the grid. Returns the grid and whether the points where `c`
    /// holds come first.
    pub fn interval_condition(&self, c: Value) -> Option<(GridId, bool)> {
        let Op::Binary(op, x, y) = self.insts[c.index()].op else { return None };
        let below = match op {
            BinOp::Lt | BinOp::Le => true,
            BinOp::Gt | BinOp::Ge => false,
            _ => return None,
        };
        let is_scalar = |v: Value| self.is_uniform(v, 4);
        let (grid, coord_left) = match (self.insts[x.index()].op, self.insts[y.index()].op) {
            (Op::GridCoord(g), _) if is_scalar(y) => (g, true),
            (_, Op::GridCoord(g)) if is_scalar(x) => (g, false),
            _ => return None,
        };
        // `coord < s` holds first on an increasing grid; `s < coord` last.
        let increasing = self.grids[grid.0 as usize].step >= 0.0;
        Some((grid, below == coord_left && increasing || below != coord_left && !increasing))
    }

    /// The number of elements a value of shape `s` holds.
    pub fn len_of(&self, s: Shape) -> usize {
        match s {
            Shape::Scalar => 1,
            Shape::Grid(g) => self.grids[g.0 as usize].len,
        }
    }

    /// Per instruction, whether [`Precision::Mixed`] computes it in f64 (a
    /// phase, the periodic function of one, or a value out of f32's
    /// comfortable range at the defaults); all false in the other
    /// precisions.
    pub fn wide_values(&self) -> Vec<bool> {
        let mut wide = vec![false; self.insts.len()];
        if self.precision != Precision::Mixed {
            return wide;
        }
        if let Some(magnitudes) = self.default_magnitudes() {
            let (lo, hi) = (2f64.powi(-96), 2f64.powi(96));
            let out_of_range: Vec<bool> = magnitudes
                .iter()
                .enumerate()
                .map(|(i, m)| self.insts[i].ty.elem != Elem::Bool && *m > 0.0 && (*m < lo || *m > hi))
                .collect();
            // A value computed from one out of range is computed in f64 too
            // (its operands would not survive conversion to f32).
            for (i, inst) in self.insts.iter().enumerate() {
                wide[i] = out_of_range[i] || inst.op.operands().iter().any(|a| out_of_range[a.index()]);
            }
        }
        // Operands precede their users, so one backward sweep closes the set.
        for i in (0..self.insts.len()).rev() {
            let op = self.insts[i].op;
            let phase = match op {
                Op::Unary(UnOp::Sin | UnOp::Cos | UnOp::Tan | UnOp::Cis, a) => Some(a),
                Op::Unary(UnOp::Exp, a) if self.ty(a).elem == Elem::Complex => Some(a),
                _ => None,
            };
            if let Some(a) = phase {
                wide[i] = true;
                wide[a.index()] = true;
            }
            let elementwise = !matches!(op, Op::Reduce(..) | Op::Dft(..) | Op::Tensor(..));
            if wide[i] && elementwise {
                for a in op.operands() {
                    wide[a.index()] = true;
                }
            }
        }
        wide
    }

    /// The largest finite magnitude of each instruction's value (0 when all
    /// are zero or not finite) with the params and inputs at their defaults
    /// (an input without one at zero, a param without one at 1), by the
    /// reference interpreter; `None` when that would exceed
    /// [`crate::interp::EVAL_BUDGET`].
    pub fn default_magnitudes(&self) -> Option<Vec<f64>> {
        let longest = self.grids.iter().map(|g| g.len).max().unwrap_or(1);
        if self.insts.len().saturating_mul(longest) > crate::interp::EVAL_BUDGET {
            return None;
        }
        let params: Vec<f64> = self.params.iter().map(|p| p.default.map_or(1.0, |d| d * p.scale)).collect();
        let inputs: Vec<crate::interp::Tensor> = self
            .inputs
            .iter()
            .map(|i| i.default.clone().unwrap_or_else(|| vec![num_complex::Complex64::new(0.0, 0.0); self.len_of(i.ty.shape)]))
            .collect();
        let values = crate::interp::interpret(self, &params, &inputs).values;
        Some(values.iter().map(|t| t.iter().flat_map(|z| [z.re.abs(), z.im.abs()]).filter(|x| x.is_finite()).fold(0.0, f64::max)).collect())
    }

    /// All values the function returns (outputs, then computed gradients).
    pub fn roots(&self) -> Vec<Value> {
        self.outputs
            .iter()
            .map(|o| o.value)
            .chain(self.grads.iter().filter_map(|g| g.value))
            .chain(self.input_grads.iter().filter_map(|g| g.value))
            .collect()
    }

    /// Whether the scene asks for any gradient (of params or of weights).
    pub fn has_gradients(&self) -> bool {
        !self.grads.is_empty() || !self.input_grads.is_empty()
    }

    /// Renames every root (outputs and computed gradients) through `map`,
    /// after a pass renumbered the instructions.
    pub fn remap_roots(&mut self, map: impl Fn(Value) -> Value) {
        for o in &mut self.outputs {
            o.value = map(o.value);
        }
        for g in &mut self.grads {
            g.value = g.value.map(&map);
        }
        for g in &mut self.input_grads {
            g.value = g.value.map(&map);
        }
    }

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

    fn fmt_op(&self, op: &Op) -> String {
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
            Op::Tensor(t, _, a, b) => {
                let sizes = match t {
                    TensorOp::MatVec { m, k } | TensorOp::MatTVec { m, k } | TensorOp::Outer { m, k } => format!("{m}x{k}"),
                    TensorOp::Conv(c) | TensorOp::ConvBackData(c) | TensorOp::ConvBackWeight(c) => format!(
                        "{}x{} -> {}x{}, kernel {}, stride {}, padding {}, dilation {}",
                        c.c_in, c.len_in, c.c_out, c.len_out, c.kernel, c.stride, c.padding, c.dilation
                    ),
                    TensorOp::PoolPick(p) | TensorOp::PoolScatter(p) | TensorOp::PoolAvg(p) | TensorOp::PoolAvgBack(p) => {
                        format!("{}x{} -> {}x{}, window {}, stride {}", p.channels, p.len_in, p.channels, p.len_out, p.window, p.stride)
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

impl fmt::Display for Function {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
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
        let wide = self.wide_values();
        for (i, inst) in self.insts.iter().enumerate() {
            // In mixed precision, the values computed in f64 are marked.
            let mark = if wide[i] { " f64" } else { "" };
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
