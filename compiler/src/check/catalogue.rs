//! The builtin and constant catalogue: names every expression can use,
//! with their values (constants) or one-line descriptions (builtins).

use crate::front::units::{self, Dim, Ratio};

/// A physical constant available by name in every expression.
pub struct Constant {
    /// Name in source.
    pub name: &'static str,
    /// Value in base units.
    pub value: f64,
    /// Dimension.
    pub dim: Dim,
    /// What it is, with its source.
    pub doc: &'static str,
}

const S_PER_MSUN: Dim = Dim([Ratio::int(1), Ratio::int(-1), Ratio::ZERO]);
const M_PER_MSUN: Dim = Dim([Ratio::ZERO, Ratio::int(-1), Ratio::int(1)]);
const M_PER_S: Dim = Dim([Ratio::int(-1), Ratio::ZERO, Ratio::int(1)]);

/// Named constants (values as in LALConstants.h, LALSuite).
pub const CONSTANTS: &[Constant] = &[
    Constant { name: "pi", value: std::f64::consts::PI, dim: Dim::NONE, doc: "π" },
    Constant { name: "MTSUN", value: 4.925_490_947_641_267e-6, dim: S_PER_MSUN, doc: "solar mass in seconds, G Msun / c^3 (LAL_MTSUN_SI)" },
    Constant { name: "MRSUN", value: 1.476_625_038_050_124_7e3, dim: M_PER_MSUN, doc: "solar mass in metres, G Msun / c^2 (LAL_MRSUN_SI)" },
    Constant { name: "C", value: 299_792_458.0, dim: M_PER_S, doc: "speed of light in m/s (LAL_C_SI)" },
    Constant { name: "MPC_M", value: units::MPC_IN_M, dim: Dim::LENGTH, doc: "one megaparsec in metres (LAL_PC_SI × 1e6)" },
    Constant { name: "MPC_S", value: units::MPC_IN_M / 299_792_458.0, dim: Dim::TIME, doc: "one megaparsec in light-seconds (Mpc / c)" },
];

/// Names callable as builtins, with a one-line description (used by
/// diagnostics and the REPL's completion).
pub const BUILTINS: &[(&str, &str)] = &[
    ("sqrt", "sqrt(x): square root"),
    ("cbrt", "cbrt(x): cube root"),
    ("exp", "exp(x): exponential of a dimensionless real or complex x"),
    ("log", "log(x): natural logarithm of a dimensionless x"),
    ("sin", "sin(x): sine of a dimensionless x"),
    ("cos", "cos(x): cosine of a dimensionless x"),
    ("tan", "tan(x): tangent of a dimensionless x"),
    ("tanh", "tanh(x): hyperbolic tangent of a dimensionless x"),
    ("atan2", "atan2(y, x): angle of the point (x, y), y and x in the same unit"),
    ("abs", "abs(x): absolute value, or modulus of a complex x"),
    ("min", "min(a, b): elementwise minimum, or min(x): minimum over the grid"),
    ("max", "max(a, b): elementwise maximum, or max(x): maximum over the grid"),
    ("clamp", "clamp(x, lo, hi): x limited to lo..hi"),
    ("re", "re(z): real part"),
    ("im", "im(z): imaginary part"),
    ("conj", "conj(z): complex conjugate"),
    ("abs2", "abs2(z): squared modulus |z|^2"),
    ("cis", "cis(theta): e^(i theta) for a dimensionless real theta"),
    ("complex", "complex(re, im): a complex number from two reals of the same unit"),
    ("select", "select(cond, a, b): a where cond holds, else b"),
    ("masked_div", "masked_div(a, s): a / s where s is positive and finite, 0 elsewhere (in values and gradients), e.g. dividing by a PSD that is 0, inf or NaN outside its band"),
    ("sum", "sum(x): sum over the grid of x"),
    ("mean", "mean(x): mean over the grid of x"),
    ("rfft", "rfft(x, f): Fourier transform dt·Σ x_j e^(-2πi f t_j) of a real x over a time grid onto its spectrum grid f"),
    ("irfft", "irfft(X, t): inverse of rfft: df·Σ over the Hermitian spectrum X, a real array over the time grid t"),
    ("spacing", "spacing(g): the step between points of grid g (dt of a time grid, df of a frequency grid)"),
    ("dense", "dense(x, w, b): w·x + b for a weight w of shape [m, k], any array x of k elements and an optional bias b [m]"),
    (
        "conv1d",
        "conv1d(x, w, b, stride: 1, padding: 0, dilation: 1): convolution of x [c_in, n] (or a time series) with w [c_out, c_in, k], optional bias b [c_out]",
    ),
    (
        "conv_transpose1d",
        "conv_transpose1d(x, w, b, stride: 1, padding: 0, output_padding: 0, dilation: 1): the transpose of conv1d in its input, PyTorch's layout: x [c_in, n], w [c_in, c_out, k], output [c_out, (n-1)·stride - 2·padding + dilation·(k-1) + output_padding + 1]",
    ),
    (
        "conv2d",
        "conv2d(x, w, b, stride: 1, padding: 0, dilation: 1): convolution of an image x [c_in, h, w] (or [h, w]) with w [c_out, c_in, kh, kw], optional bias b [c_out], PyTorch's layout; stride, padding and dilation apply to both axes",
    ),
    ("upsample", "upsample(x, factor): each position of x [channels, n] repeated factor times, [channels, n·factor]"),
    ("randn", "randn(n) or randn(g): standard normal noise, n values or one per point of grid g; zeros unless training or sampling draws it"),
    ("reshape", "reshape(x, g), reshape(x, c, n) or reshape(x, c, h, w): the values of x in order as an array over grid g, or as a tensor [c, n] or [c, h, w]"),
    ("slice", "slice(x, from, count): channels from..from+count of x [channels, n] (elements of a 1-D x), the inverse of stack"),
    ("max_pool", "max_pool(x, window, stride: window): the largest value of each window of x [channels, n]"),
    ("avg_pool", "avg_pool(x, window, stride: window): the mean of each window of x [channels, n]"),
    ("max_pool2d", "max_pool2d(x, window, stride: window): the largest value of each window × window square of an image x [channels, h, w]"),
    ("avg_pool2d", "avg_pool2d(x, window, stride: window): the mean of each window × window square of an image x [channels, h, w]"),
    ("global_avg_pool", "global_avg_pool(x): the mean over positions of x [channels, n], one value per channel"),
    ("stack", "stack(a, b, ...): the channels of a, b, ... one after the other, one array [channels, n] (every argument has n positions)"),
    ("dropout", "dropout(x, rate): x with each value zeroed with probability rate and the rest scaled by 1/(1 - rate) while training; x itself otherwise"),
    ("index", "index(n): a grid of n points 0, 1, ..., n-1, e.g. classes (in `grid` declarations)"),
    ("frequencies", "frequencies(from:, to:, step:): a frequency grid (in `grid` declarations)"),
    ("spectrum", "spectrum(t): the grid of rfft bins of time grid t, 0 Hz to the Nyquist frequency (in `grid` declarations)"),
    ("times", "times(rate:, duration:): a time grid (in `grid` declarations)"),
];
