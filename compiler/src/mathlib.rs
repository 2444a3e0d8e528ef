//! Inline Cranelift IR for transcendental functions (`sin`, `cos`,
//! `sincos`, `exp`, `log`, `cbrt`, `pow`), so kernels need not call libm
//! once per element.
//!
//! Each function emits a fast path for the inputs it handles accurately and
//! a cold block that calls libm through a caller-supplied [`SlowPath`]
//! callback for everything else (NaN, ±inf, huge sin/cos arguments, exp
//! arguments that overflow or underflow, log of non-positive or subnormal
//! numbers, ...), so results are always correct. The two blocks join in a
//! merge block whose parameters are the results.
//!
//! # Algorithms
//! * sin/cos/sincos: `k = round(x·2/π)` by the 1.5·2^52 trick, Cody–Waite
//!   reduction with fdlibm's π/2 split (two 33-bit parts, so `k·C1` and
//!   `k·C2` are exact for |k| < 2^20, plus a 53-bit tail); in `Exact` the
//!   reduced argument is kept as a double-double (TwoSum) and fed to the
//!   fdlibm kernels `__kernel_sin`/`__kernel_cos`; `Fast`/`Fastest` use the
//!   rounded reduced argument and shorter polynomials. sin and cos of the reduced
//!   argument are both computed and the quadrant selects and signs them, so
//!   `sincos` costs one reduction. Inline domain |x| ≤ 1.6e6 (k < 2^20).
//! * exp: `k = round(x/ln2)`, `r = x − k·ln2` (fdlibm's hi/lo split),
//!   `Exact` uses fdlibm's rational form, `Fast`/`Fastest` a polynomial;
//!   scaled by building `2^k` from bits. Inline domain |x| < 708.
//! * log: `x = 2^k·m`, m ∈ [√½, √2), `s = f/(2+f)`, `log(1+f) = 2s + s·R(s²)`
//!   (musl/fdlibm formulation). Inline domain: positive normal finite x.
//! * cbrt: FreeBSD `s_cbrt.c` scheme: exponent/3 bit trick, a degree-4
//!   polynomial to ~23 bits, then (`Exact`) rounding to 21 bits plus one
//!   Halley step, (`Fast`) one Newton step, (`Fastest`) nothing. Works on
//!   |x|, the sign is copied back. Inline domain: normal finite x.
//! * pow: `Exact` f64 calls libm (an inline version would need a
//!   double-double log to stay within 2 ulp for large |y·log x|);
//!   `Fast`/`Fastest` (and f32 in every mode) compute `exp(y·log x)` for
//!   positive normal finite x, finite y and |y·log x| < 708, libm otherwise.
//!
//! sin, cos, sincos and exp also take f64x2 arguments (vectorised loops):
//! the same kernels run on both lanes, integer steps in i64x2, the quadrant
//! picked by lane masks; the fast path is taken when both lanes are in its
//! domain, otherwise the cold path calls libm lane by lane.
//!
//! f32 (`ty == F32`) promotes to f64, evaluates the f64 code (`Fast`
//! kernels for `Exact`, `Fastest` kernels otherwise) and demotes: scalar
//! f64 arithmetic costs the same as f32 on x86-64, f32 subnormals become
//! normal f64s, and the f64 exponent range covers every f32 result.
//!
//! `fma` is used only if the target ISA has it (see [`isa_has_fma`]);
//! otherwise Cranelift would turn it into a libcall, so the emitter falls
//! back to `fmul` + `fadd`. The range reductions never rely on FMA.
//!
//! # Coefficients
//! `Exact`: published fdlibm / FreeBSD msun values (`k_sin.c`, `k_cos.c`,
//! `e_exp.c`, `e_log.c`, `e_rem_pio2.c`, `s_cbrt.c`). `Fast`/`Fastest`:
//! near-minimax fits (Chebyshev interpolation with `mpmath.chebyfit`,
//! 60 digits) of the functions named above each coefficient table; the fitting script is
//! reproduced below (run with `mpmath` in a venv; `n` = number of coefficients).
//!
//! # Measured accuracy
//! Maximum error over the sweeps of `tests::accuracy_*` (≥ 1e5 random
//! points per domain plus edge cases: ±0, tiny, subnormal, huge, NaN, ±inf,
//! doubles nearest to multiples of π/2, 1e5 and 1e6 rad), against Rust
//! std (glibc libm) on x86-64 with FMA. f64 `Exact` in ulps of the libm
//! result, `Fast`/`Fastest` as relative error, f32 in f32 ulps (vs `sinf`
//! etc.). Measured with
//! `CARGO_TARGET_DIR=/work/target-math cargo test -p gwml-compiler mathlib -- --nocapture`.
//!
//! | function | f64 Exact (ulp) | f64 Exact, no FMA (ulp) | f64 Fast (rel) | f64 Fastest (rel) | f32 Exact (ulp) | f32 Fast (ulp) | f32 Fastest (ulp) |
//! |---|---|---|---|---|---|---|---|
//! | sincos | 1 | 1 | 1.7e-14 | 1.3e-08 | 1 | 1 | 1 |
//! | sin | 1 | 1 | 1.7e-14 | 1.3e-08 | 1 | 1 | 1 |
//! | cos | 1 | 1 | 1.7e-14 | 1.3e-08 | 1 | 1 | 1 |
//! | exp | 1 | 1 | 6.4e-14 | 9.5e-09 | 1 | 1 | 1 |
//! | log | 1 | 1 | 1.1e-13 | 2.7e-09 | 1 | 1 | 1 |
//! | cbrt | 1 | 1 | 6.8e-15 | 8.1e-08 | 0 | 2 | 2 |
//! | pow | 0 | 0 | 1.7e-13 | 9.5e-09 | 1 | 1 | 1 |
//!
//! (Max over all sweeps; pow `Exact` f64 is libm itself. Asserted bounds: f64 `Exact` 2 ulp,
//! `Fast` 1e-12, `Fastest` 1e-7 relative; f32 `Exact` 1 ulp, `Fast`/`Fastest` 2 ulp.)
//!
//! # Speed
//! ns/element, median (min) over 41 round-robin rounds of a JIT loop over
//! 8192 elements, `libm` = one imported libm call per element as `codegen`
//! does today. Machine: 2 shared cores under load average ≈ 7 from parallel
//! builds, so absolute numbers are inflated; compare within a row. Measured with
//! `CARGO_TARGET_DIR=/work/target-math cargo test --release -p gwml-compiler mathlib::tests::bench -- --ignored --nocapture`.
//!
//! | function | type | libm | Exact | Fast | Fastest |
//! |---|---|---|---|---|---|
//! | sincos x∈[0,1e5] | f64 | 33.81 (29.76) | 20.49 (19.64) | 12.02 (11.18) | 11.35 (10.47) |
//! | sincos x∈[0,1e5] | f32 | 13.93 (13.54) | 13.75 (13.46) | 14.92 (14.53) | 14.92 (14.58) |
//! | sin x∈[0,1e5] | f64 | 24.46 (23.73) | 18.33 (17.31) | 10.96 (10.58) | 9.94 (9.44) |
//! | sin x∈[0,1e5] | f32 | 17.29 (12.29) | 16.74 (11.27) | 14.67 (10.58) | 14.69 (10.61) |
//! | cos x∈[0,1e5] | f64 | 23.40 (22.70) | 17.79 (17.19) | 10.80 (10.05) | 10.07 (9.72) |
//! | cos x∈[0,1e5] | f32 | 17.10 (12.53) | 16.70 (15.54) | 15.05 (14.23) | 15.04 (12.13) |
//! | exp x∈[-50,50] | f64 | 10.86 (5.84) | 13.18 (7.58) | 10.18 (5.38) | 8.59 (4.28) |
//! | exp x∈[-50,50] | f32 | 4.76 (3.89) | 7.15 (6.57) | 5.95 (5.30) | 5.90 (5.31) |
//! | log x∈2^[-20,20] | f64 | 6.64 (6.13) | 7.69 (7.28) | 6.69 (6.26) | 6.18 (5.81) |
//! | log x∈2^[-20,20] | f32 | 11.87 (5.81) | 13.66 (7.87) | 12.38 (7.35) | 12.39 (7.47) |
//! | cbrt x∈±2^[-20,20] | f64 | 35.43 (24.07) | 12.03 (9.02) | 9.39 (7.01) | 6.68 (5.10) |
//! | cbrt x∈±2^[-20,20] | f32 | 7.99 (7.52) | 8.95 (8.71) | 6.93 (6.65) | 6.90 (6.64) |
//! | pow x∈2^[-10,10], y∈[-3,3] | f64 | 29.38 (20.75) | 29.34 (20.73) | 29.35 (18.72) | 25.93 (15.39) |
//! | pow x∈2^[-10,10], y∈[-3,3] | f32 | 16.77 (15.28) | 30.54 (30.12) | 28.34 (27.91) | 28.28 (27.84) |
//!
//! Inline code wins clearly for f64 sin/cos/sincos (1.3–3×) and cbrt (3–5×);
//! f64 exp/log/pow are at parity with glibc (whose table-driven exp/log/pow
//! are already fast; the inline log and `Exact` exp pay for a division).
//! glibc's f32 functions compute in double with tables and are as fast or
//! faster than the promoted inline code: for f32, inline `cbrt`/`sin`/`cos`
//! are at parity and `exp`/`log`/`pow` are slower, so callers should keep
//! libm for f32 exp/log/pow.
//!
//! # Fitting script
//! ```text
//! # Near-minimax (Chebyshev interpolation, mpmath.chebyfit) coefficients for gwml mathlib.
//! from mpmath import mp, mpf, sin, cos, exp, atanh, sqrt, log, pi, chebyfit
//! mp.dps = 60
//! def fit(name, f, a, b, n, scale):
//!     c, err = chebyfit(f, [mpf(a), mpf(b)], n, error=True)
//!     c = c[::-1]  # lowest degree first
//!     print(f"// {name}: {n} coeffs, |err| {float(err):.3e} -> result rel err <~ {float(err*scale):.3e}")
//!     print("[" + ", ".join(repr(float(x)) for x in c) + "]")
//! zs = (pi/4 + mpf('1e-3'))**2
//! for n in (3,4,5):
//!     fit("sin P(z): sin r = r + r z P(z)", lambda z: (sin(sqrt(z)) - sqrt(z))/(sqrt(z)*z), 0, zs, n, zs/0.9)
//! for n in (3,4,5):
//!     fit("cos Q(z): cos r = 1 - z/2 + z^2 Q(z)", lambda z: (cos(sqrt(z)) - 1 + z/2)/(z*z), 0, zs, n, zs*zs/0.7)
//! h = log(2)/2 + mpf('1e-3')
//! for n in (5,6,7,8,9):
//!     fit("exp E(r): e^r = 1 + r + r^2 E(r)", lambda r: (exp(r) - 1 - r)/(r*r) if r != 0 else mpf(1)/2, -h, h, n, h*h/0.7)
//! sm = (3 - 2*sqrt(2))**2 * 1.0001  # s = f/(2+f), |s| <= 3-2sqrt2
//! for n in (2,3,4,5):
//!     fit("log L(z): log(1+f) = 2s + s z L(z)", lambda z: (2*atanh(sqrt(z))/sqrt(z) - 2)/z, 0, sm, n, sm/2)
//! print("--- exp on shifted interval (no node at r=0)")
//! for n in (8,9):
//!     fit("exp E(r)", lambda r: (exp(r) - 1 - r)/(r*r), -h, h*mpf('1.0001'), n, h*h/0.7)
//! ```

// Published fdlibm/FreeBSD constants keep their printed digits, so they can be checked against the source.
#![allow(clippy::excessive_precision)]

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, Block, BlockArg, Endianness, InstBuilder, MemFlagsData, Type, Value};
use cranelift_codegen::isa::TargetIsa;
use cranelift_frontend::FunctionBuilder;

pub use crate::ir::MathMode;

/// Calls the libm function `name` (the f64 name: "sin", "cos", "sincos",
/// "exp", "log", "cbrt", "pow") on `args` of the emitter's type and returns
/// its results (two for "sincos": sin, cos). For `F32` the callback must call
/// the f32 variant ("sinf", ...), as `codegen`'s `call` does.
pub type SlowPath<'a> = dyn FnMut(&mut FunctionBuilder, &'static str, &[Value]) -> Vec<Value> + 'a;

/// Whether `isa` lowers `fma` to a hardware instruction (x86-64 `has_fma`,
/// always on aarch64/riscv64/s390x).
pub fn isa_has_fma(isa: &dyn TargetIsa) -> bool {
    match isa.name() {
        "x64" => isa.isa_flags().iter().any(|f| f.name == "has_fma" && f.as_bool() == Some(true)),
        "aarch64" | "riscv64" | "s390x" => true,
        _ => false,
    }
}

/// Emits inline transcendental functions into a [`FunctionBuilder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MathEmitter {
    /// Float type of arguments and results: `types::F64` or `types::F32`.
    pub ty: Type,
    /// Accuracy tier.
    pub mode: MathMode,
    /// Whether `fma` may be emitted (it must be a hardware instruction).
    pub fma: bool,
}

// ---------------------------------------------------------------- constants

/// 1.5·2^52: adding it rounds a double of magnitude < 2^51 to an integer
/// held in the low significand bits.
const MAGIC: f64 = 6755399441055744.0;
const FRAC_2_PI: f64 = std::f64::consts::FRAC_2_PI;
// π/2 split, fdlibm e_rem_pio2.c: pio2_1 (33 bits), pio2_2 (33 bits), pio2_2t.
const PIO2_1: f64 = 1.570_796_326_734_125_614_17e+00;
const PIO2_2: f64 = 6.077_100_506_303_965_976_60e-11;
const PIO2_2T: f64 = 2.022_266_248_795_950_631_54e-21;
/// Largest |x| reduced inline by sin/cos: k = round(x·2/π) stays below 2^20.
pub const SINCOS_MAX: f64 = 1.6e6;

// fdlibm k_sin.c S1..S6 and k_cos.c C1..C6.
const KSIN: [f64; 6] = [
    -1.666_666_666_666_663_243_48e-01,
    8.333_333_333_322_489_461_24e-03,
    -1.984_126_982_985_794_931_34e-04,
    2.755_731_370_707_006_767_89e-06,
    -2.505_076_025_340_686_341_95e-08,
    1.589_690_995_211_550_102_21e-10,
];
const KCOS: [f64; 6] = [
    4.166_666_666_666_660_190_37e-02,
    -1.388_888_888_887_410_957_49e-03,
    2.480_158_728_947_672_941_78e-05,
    -2.755_731_435_139_066_330_35e-07,
    2.087_572_321_298_174_827_90e-09,
    -1.135_964_755_778_819_482_65e-11,
];
// sin r = r + r·z·P(z), z = r², fit of (sin √z − √z)/(z√z) on [0, (π/4+1e-3)²].
const SIN_FAST: [f64; 5] =
    [-0.1666666666666385, 0.008333333331056203, -0.00019841266894627223, 2.7555984173088083e-06, -2.4805011207486557e-08];
const SIN_FASTEST: [f64; 3] = [-0.166666646469967, 0.00833274529736295, -0.00019587249321738546];
// cos r = 1 − z/2 + z²·Q(z), fit of (cos √z − 1 + z/2)/z² on [0, (π/4+1e-3)²].
const COS_FAST: [f64; 5] =
    [0.04166666666666465, -0.0013888888887260882, 2.4801585195001366e-05, -2.7556364863807e-07, 2.070015349613916e-09];
const COS_FASTEST: [f64; 3] = [0.04166666464415581, -0.0013888300056586712, 2.45472991724818e-05];

// fdlibm e_exp.c.
const LN2_HI: f64 = 6.931_471_803_691_238_164_90e-01;
const LN2_LO: f64 = 1.908_214_929_270_587_700_02e-10;
const INV_LN2: f64 = std::f64::consts::LOG2_E;
const KEXP: [f64; 5] = [
    1.666_666_666_666_660_190_37e-01,
    -2.777_777_777_701_559_338_42e-03,
    6.613_756_321_437_934_361_17e-05,
    -1.653_390_220_546_525_153_90e-06,
    4.138_136_797_057_238_460_39e-08,
];
/// Largest |x| handled inline by exp (results stay normal and finite).
pub const EXP_MAX: f64 = 708.0;
// e^r = 1 + r + r²·E(r), fit of (e^r − 1 − r)/r² on [−ln2/2 − 1e-3, ln2/2 + 1e-3].
const EXP_FAST: [f64; 8] = [
    0.4999999999995404,
    0.16666666666662067,
    0.041666666788390205,
    0.00833333334474622,
    0.0013888838522688892,
    0.0001984122336982278,
    2.4868260601356277e-05,
    2.7618303396436434e-06,
];
const EXP_FASTEST: [f64; 5] = [0.5, 0.16666575985420823, 0.041666553362644264, 0.00836334581098711, 0.0013926391896140632];

// fdlibm e_log.c Lg1..Lg7.
const KLOG: [f64; 7] = [
    6.666_666_666_666_735_130e-01,
    3.999_999_999_940_941_908e-01,
    2.857_142_874_366_239_149e-01,
    2.222_219_843_214_978_396e-01,
    1.818_357_216_161_805_012e-01,
    1.531_383_769_920_937_332e-01,
    1.479_819_860_511_658_591e-01,
];
// log(1+f) = 2s + s·z·L(z), z = s², fit of (2 atanh(√z)/√z − 2)/z on [0, (3−2√2)²].
const LOG_FAST: [f64; 5] = [0.6666666666737545, 0.39999998796848674, 0.2857175463573276, 0.22191394493175057, 0.19362776836747533];
const LOG_FASTEST: [f64; 3] = [0.6666668504515603, 0.39988778282162807, 0.2958005304318844];

// FreeBSD s_cbrt.c: B1 and the polynomial P0..P4 for the first ~23 bits.
const CBRT_B1: i64 = 715_094_163;
const KCBRT: [f64; 5] = [
    1.875_951_824_271_770_096_43,
    -1.884_979_795_433_771_698_75,
    1.621_429_720_105_354_466_140,
    -0.758_397_934_778_766_047_437,
    0.145_996_192_886_612_446_982,
];

// ---------------------------------------------------------------- IR helpers

/// `x` reinterpreted as `ty` (same size); vector bitcasts state their lane
/// order (little-endian), as Cranelift requires.
pub(crate) fn bitcast(b: &mut FunctionBuilder, ty: Type, x: Value) -> Value {
    let flags = if ty.is_vector() { MemFlagsData::new().with_endianness(Endianness::Little) } else { MemFlagsData::new() };
    b.ins().bitcast(ty, flags, x)
}

/// `c ? x : y` for a truth value `c` from `fcmp`/`icmp`: a scalar select,
/// or for vectors a bitwise select on the lane mask `c`.
pub(crate) fn select(b: &mut FunctionBuilder, c: Value, x: Value, y: Value) -> Value {
    let ty = b.func.dfg.value_type(x);
    if ty.is_vector() {
        let mask = bitcast(b, ty, c);
        b.ins().bitselect(mask, x, y)
    } else {
        b.ins().select(c, x, y)
    }
}

/// A FunctionBuilder plus the FMA decision, with small arithmetic helpers
/// (all f64, or f64x2 when `vector`: constants are splatted and integer
/// work is done in i64x2 lanes).
struct Ir<'a, 'f> {
    b: &'a mut FunctionBuilder<'f>,
    fma: bool,
    vector: bool,
}

impl Ir<'_, '_> {
    fn c(&mut self, v: f64) -> Value {
        let c = self.b.ins().f64const(v);
        if self.vector {
            self.b.ins().splat(types::F64X2, c)
        } else {
            c
        }
    }
    /// The integer `k` (i64, or i64x2 in every lane).
    fn ic(&mut self, k: i64) -> Value {
        let c = self.b.ins().iconst(types::I64, k);
        if self.vector {
            self.b.ins().splat(types::I64X2, c)
        } else {
            c
        }
    }
    fn iadd_c(&mut self, x: Value, k: i64) -> Value {
        let k = self.ic(k);
        self.b.ins().iadd(x, k)
    }
    fn band_c(&mut self, x: Value, k: i64) -> Value {
        let k = self.ic(k);
        self.b.ins().band(x, k)
    }
    fn shl(&mut self, x: Value, by: i64) -> Value {
        let by = self.b.ins().iconst(types::I32, by);
        self.b.ins().ishl(x, by)
    }
    /// `cond ? x : y` for a truth value from `fcmp` (a lane mask when vector).
    fn select(&mut self, cond: Value, x: Value, y: Value) -> Value {
        select(self.b, cond, x, y)
    }
    /// `x` where bit 0 of the integer `n` is set, else `y`.
    fn select_odd(&mut self, n: Value, x: Value, y: Value) -> Value {
        let odd = self.band_c(n, 1);
        if self.vector {
            let one = self.ic(1);
            let mask = self.b.ins().icmp(IntCC::Equal, odd, one);
            self.select(mask, x, y)
        } else {
            self.b.ins().select(odd, x, y)
        }
    }
    fn add(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fadd(x, y)
    }
    fn sub(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fsub(x, y)
    }
    fn mul(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fmul(x, y)
    }
    fn div(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fdiv(x, y)
    }
    fn mulc(&mut self, x: Value, k: f64) -> Value {
        let k = self.c(k);
        self.mul(x, k)
    }
    /// `x·y + z`, fused if the ISA has FMA.
    fn mla(&mut self, x: Value, y: Value, z: Value) -> Value {
        if self.fma {
            self.b.ins().fma(x, y, z)
        } else {
            let p = self.mul(x, y);
            self.add(p, z)
        }
    }
    /// `c[0] + x·(c[1] + x·(c[2] + …))`.
    fn horner(&mut self, x: Value, cs: &[f64]) -> Value {
        let (last, rest) = cs.split_last().expect("non-empty coefficients");
        let mut acc = self.c(*last);
        for &k in rest.iter().rev() {
            let k = self.c(k);
            acc = self.mla(acc, x, k);
        }
        acc
    }
    fn bits(&mut self, x: Value) -> Value {
        bitcast(self.b, if self.vector { types::I64X2 } else { types::I64 }, x)
    }
    fn float(&mut self, i: Value) -> Value {
        bitcast(self.b, if self.vector { types::F64X2 } else { types::F64 }, i)
    }
    /// Rounds `x·scale` to the nearest integer: (as f64, as i64). |x·scale| < 2^51.
    fn round_mul(&mut self, x: Value, scale: f64) -> (Value, Value) {
        let s = self.c(scale);
        let m = self.c(MAGIC);
        let t = self.mla(x, s, m);
        let kf = self.sub(t, m);
        let tb = self.bits(t);
        let ki = self.iadd_c(tb, -(MAGIC.to_bits() as i64));
        (kf, ki)
    }
    /// `x` with its sign flipped where bit 1 of the integer `n` is set.
    fn flip_if_bit1(&mut self, x: Value, n: Value) -> Value {
        let bit = self.band_c(n, 2);
        let sign = self.shl(bit, 62);
        let xb = self.bits(x);
        let r = self.b.ins().bxor(xb, sign);
        self.float(r)
    }
    /// `x` is a positive normal finite double (false for NaN).
    fn is_pos_normal(&mut self, x: Value) -> Value {
        let xb = self.bits(x);
        let d = self.b.ins().iadd_imm_s(xb, -(f64::MIN_POSITIVE.to_bits() as i64));
        let span = (f64::INFINITY.to_bits() - f64::MIN_POSITIVE.to_bits()) as i64;
        self.b.ins().icmp_imm_s(IntCC::UnsignedLessThan, d, span)
    }
    /// `|x| < bound` (false for NaN).
    fn abs_lt(&mut self, x: Value, bound: f64) -> Value {
        let a = self.b.ins().fabs(x);
        let c = self.c(bound);
        self.b.ins().fcmp(FloatCC::LessThan, a, c)
    }
}

// ---------------------------------------------------------------- f64 kernels

/// sin and cos of the reduced argument `hi + lo` (|hi| ≲ π/4).
fn sincos_reduced(e: &mut Ir, hi: Value, lo: Option<Value>, mode: MathMode) -> (Value, Value) {
    let z = e.mul(hi, hi);
    match (mode, lo) {
        (MathMode::Exact, Some(y)) => {
            // fdlibm __kernel_sin(x, y, 1).
            let w = e.mul(z, z);
            let r0 = e.horner(z, &KSIN[1..4]);
            let r1 = e.horner(z, &KSIN[4..6]);
            let zw = e.mul(z, w);
            let r = e.mla(zw, r1, r0);
            let v = e.mul(z, hi);
            let half_y = e.mulc(y, 0.5);
            let vr = e.mul(v, r);
            let t = e.sub(half_y, vr);
            let t = e.mul(z, t);
            let t = e.sub(t, y);
            let vs1 = e.mulc(v, KSIN[0]);
            let t = e.sub(t, vs1);
            let s = e.sub(hi, t);
            // fdlibm __kernel_cos(x, y).
            let c0 = e.horner(z, &KCOS[0..3]);
            let c0 = e.mul(z, c0);
            let c1 = e.horner(z, &KCOS[3..6]);
            let ww = e.mul(w, w);
            let r = e.mla(ww, c1, c0);
            let hz = e.mulc(z, 0.5);
            let one = e.c(1.0);
            let w1 = e.sub(one, hz);
            let t = e.sub(one, w1);
            let t = e.sub(t, hz);
            let xy = e.mul(hi, y);
            let zr = e.mul(z, r);
            let u = e.sub(zr, xy);
            let t = e.add(t, u);
            let c = e.add(w1, t);
            (s, c)
        }
        _ => {
            let (ps, pc): (&[f64], &[f64]) = match mode {
                MathMode::Fastest => (&SIN_FASTEST, &COS_FASTEST),
                _ => (&SIN_FAST, &COS_FAST),
            };
            let p = e.horner(z, ps);
            let rz = e.mul(hi, z);
            let s = e.mla(rz, p, hi);
            let q = e.horner(z, pc);
            let zz = e.mul(z, z);
            let hz = e.mulc(z, -0.5);
            let one = e.c(1.0);
            let base = e.add(one, hz);
            let c = e.mla(zz, q, base);
            (s, c)
        }
    }
}

/// sin x and cos x for |x| ≤ [`SINCOS_MAX`].
fn sincos_kernel(e: &mut Ir, x: Value, mode: MathMode) -> (Value, Value) {
    let (kf, n) = e.round_mul(x, FRAC_2_PI);
    // k·PIO2_1 is exact (33-bit constant, |k| < 2^20) and so is x − k·PIO2_1.
    let kc1 = e.mulc(kf, PIO2_1);
    let a = e.sub(x, kc1);
    let (hi, lo) = match mode {
        MathMode::Exact => {
            // a − k·PIO2_2 (exact product) as a double-double via TwoSum, then − k·PIO2_2T.
            let b = e.mulc(kf, PIO2_2);
            let s = e.sub(a, b);
            let bb = e.sub(s, a);
            let sb = e.sub(s, bb);
            let ea = e.sub(a, sb);
            let eb = e.add(b, bb);
            let err = e.sub(ea, eb);
            let kc3 = e.mulc(kf, PIO2_2T);
            let lo = e.sub(err, kc3);
            let hi = e.add(s, lo);
            let d = e.sub(hi, s);
            let lo = e.sub(lo, d);
            (hi, Some(lo))
        }
        // A two-part π/2 (PIO2_1 + PIO2_1T) loses ~k·3.5e-27 absolute, 2e-6
        // relative next to multiples of π/2 near 1e6 rad: keep three parts.
        MathMode::Fast | MathMode::Fastest => {
            let b = e.mulc(kf, PIO2_2);
            let r = e.sub(a, b);
            let kc3 = e.mulc(kf, PIO2_2T);
            (e.sub(r, kc3), None)
        }
    };
    let (s, c) = sincos_reduced(e, hi, lo, mode);
    // The reduction and polynomials turn −0 into +0; sin(±0) = ±0.
    let zero = e.c(0.0);
    let is0 = e.b.ins().fcmp(FloatCC::Equal, x, zero);
    let s = e.select(is0, x, s);
    // Quadrant n mod 4: 0 → (s, c), 1 → (c, −s), 2 → (−s, −c), 3 → (−c, s).
    let sr = e.select_odd(n, c, s);
    let cr = e.select_odd(n, s, c);
    let sr = e.flip_if_bit1(sr, n);
    let n1 = e.iadd_c(n, 1);
    let cr = e.flip_if_bit1(cr, n1);
    (sr, cr)
}

/// e^x for |x| < [`EXP_MAX`].
fn exp_kernel(e: &mut Ir, x: Value, mode: MathMode) -> Value {
    let (kf, k) = e.round_mul(x, INV_LN2);
    let khi = e.mulc(kf, LN2_HI);
    let hi = e.sub(x, khi);
    let lo = e.mulc(kf, LN2_LO);
    let r = e.sub(hi, lo);
    let y = match mode {
        MathMode::Exact => {
            // fdlibm: c = r − r²·P(r²); e^r = 1 − ((lo − r·c/(2 − c)) − hi).
            let t = e.mul(r, r);
            let p = e.horner(t, &KEXP);
            let tp = e.mul(t, p);
            let c = e.sub(r, tp);
            let rc = e.mul(r, c);
            let two = e.c(2.0);
            let d = e.sub(two, c);
            let q = e.div(rc, d);
            let u = e.sub(lo, q);
            let u = e.sub(u, hi);
            let one = e.c(1.0);
            e.sub(one, u)
        }
        _ => {
            let p = e.horner(r, if mode == MathMode::Fast { &EXP_FAST } else { &EXP_FASTEST });
            let rr = e.mul(r, r);
            let q = e.mla(rr, p, r);
            let one = e.c(1.0);
            e.add(one, q)
        }
    };
    let bias = e.iadd_c(k, 1023);
    let sb = e.shl(bias, 52);
    let scale = e.float(sb);
    e.mul(y, scale)
}

/// ln x for positive normal finite x.
fn log_kernel(e: &mut Ir, x: Value, mode: MathMode) -> Value {
    // musl/fdlibm: x = 2^k·m with m ∈ [0x3fe6a09e…, ·2), f = m − 1.
    const LO: i64 = 0x3fe6_a09e_0000_0000;
    let xb = e.bits(x);
    let u = e.b.ins().iadd_imm_s(xb, 0x3ff0_0000_0000_0000 - LO);
    let ke = e.b.ins().ushr_imm_s(u, 52);
    let k = e.b.ins().iadd_imm_s(ke, -0x3ff);
    let mant = e.b.ins().band_imm_s(u, 0x000f_ffff_ffff_ffff);
    let mb = e.b.ins().iadd_imm_s(mant, LO);
    let m = e.float(mb);
    let one = e.c(1.0);
    let f = e.sub(m, one);
    let dk = e.b.ins().fcvt_from_sint(types::F64, k);
    let ff = e.mul(f, f);
    let hfsq = e.mulc(ff, 0.5);
    let two = e.c(2.0);
    let d = e.add(two, f);
    let s = e.div(f, d);
    let z = e.mul(s, s);
    let r = match mode {
        MathMode::Exact => {
            let w = e.mul(z, z);
            let t1 = e.horner(w, &[KLOG[1], KLOG[3], KLOG[5]]);
            let t1 = e.mul(w, t1);
            let t2 = e.horner(w, &[KLOG[0], KLOG[2], KLOG[4], KLOG[6]]);
            let t2 = e.mul(z, t2);
            e.add(t2, t1)
        }
        MathMode::Fast => {
            let l = e.horner(z, &LOG_FAST);
            e.mul(z, l)
        }
        MathMode::Fastest => {
            let l = e.horner(z, &LOG_FASTEST);
            e.mul(z, l)
        }
    };
    // s·(hfsq + R) + k·ln2_lo − hfsq + f + k·ln2_hi
    let hr = e.add(hfsq, r);
    let kl = e.mulc(dk, LN2_LO);
    let t = e.mla(s, hr, kl);
    let t = e.sub(t, hfsq);
    let t = e.add(t, f);
    let kh = e.mulc(dk, LN2_HI);
    e.add(t, kh)
}

/// ∛x for normal finite x.
fn cbrt_kernel(e: &mut Ir, x: Value, mode: MathMode) -> Value {
    let ax = e.b.ins().fabs(x);
    // t ≈ ∛|x| to ~5 bits: high word / 3 + B1 (floor(n/3) = n·0xAAAAAAAB >> 33 for n < 2^32).
    let xb = e.bits(ax);
    let hx = e.b.ins().ushr_imm_s(xb, 32);
    let q = e.b.ins().imul_imm_s(hx, 0xAAAA_AAAB);
    let q = e.b.ins().ushr_imm_s(q, 33);
    let th = e.b.ins().iadd_imm_s(q, CBRT_B1);
    let tb = e.b.ins().ishl_imm_s(th, 32);
    let t = e.float(tb);
    // r = t³/|x|; t ·= P(r) to ~23 bits.
    let tt = e.mul(t, t);
    let tx = e.div(t, ax);
    let r = e.mul(tt, tx);
    let p0 = e.horner(r, &KCBRT[0..3]);
    let p1 = e.horner(r, &KCBRT[3..5]);
    let rr = e.mul(r, r);
    let rrr = e.mul(rr, r);
    let p = e.mla(rrr, p1, p0);
    let mut t = e.mul(t, p);
    match mode {
        MathMode::Exact => {
            // Round to 21 bits (away from zero), then one Halley step (error < 0.667 ulp).
            let tb = e.bits(t);
            let tb = e.b.ins().iadd_imm_s(tb, 0x8000_0000);
            let tb = e.b.ins().band_imm_s(tb, 0xffff_ffff_c000_0000_u64 as i64);
            t = e.float(tb);
            let s = e.mul(t, t);
            let r = e.div(ax, s);
            let w = e.add(t, t);
            let num = e.sub(r, t);
            let den = e.add(w, r);
            let r = e.div(num, den);
            t = e.mla(t, r, t);
        }
        MathMode::Fast => {
            // Newton: t += (|x|/t² − t)/3.
            let s = e.mul(t, t);
            let r = e.div(ax, s);
            let d = e.sub(r, t);
            let third = e.c(1.0 / 3.0);
            t = e.mla(d, third, t);
        }
        MathMode::Fastest => {}
    }
    e.b.ins().fcopysign(t, x)
}

// ---------------------------------------------------------------- emitter

impl MathEmitter {
    /// An emitter for `ty` (F64 or F32) in `mode`, using FMA if `isa` has it.
    pub fn new(isa: &dyn TargetIsa, ty: Type, mode: MathMode) -> MathEmitter {
        assert!(ty == types::F64 || ty == types::F32, "mathlib supports F64 and F32, not {ty}");
        MathEmitter { ty, mode, fma: isa_has_fma(isa) }
    }

    fn f32(&self) -> bool {
        self.ty == types::F32
    }

    /// The f64 kernel tier used for this emitter's type and mode.
    fn tier(&self) -> MathMode {
        match (self.f32(), self.mode) {
            (false, m) => m,
            (true, MathMode::Exact) => MathMode::Fast,
            (true, _) => MathMode::Fastest,
        }
    }

    fn widen(&self, b: &mut FunctionBuilder, x: Value) -> Value {
        if self.f32() {
            b.ins().fpromote(types::F64, x)
        } else {
            x
        }
    }

    fn narrow(&self, b: &mut FunctionBuilder, x: Value) -> Value {
        if self.f32() {
            b.ins().fdemote(types::F32, x)
        } else {
            x
        }
    }

    /// Emits `if ok(wide args) { fast(wide args) } else { slow(name, args) }`
    /// and returns the merged results (of type `self.ty`; two for "sincos").
    fn guarded(
        &self,
        b: &mut FunctionBuilder,
        args: &[Value],
        name: &'static str,
        slow: &mut SlowPath,
        ok: impl FnOnce(&mut Ir, &[Value]) -> Value,
        fast: impl FnOnce(&mut Ir, &[Value]) -> Vec<Value>,
    ) -> Vec<Value> {
        // f64x2 arguments: the fast path runs on both lanes when both are in
        // its domain, the slow path calls libm lane by lane.
        let arg_ty = b.func.dfg.value_type(args[0]);
        let vector = arg_ty.is_vector();
        assert!(!vector || arg_ty == types::F64X2, "vector math is f64x2 only, not {arg_ty}");
        let wide: Vec<Value> = args.iter().map(|&a| self.widen(b, a)).collect();
        let cond = ok(&mut Ir { b, fma: self.fma, vector }, &wide);
        let cond = if vector { b.ins().vall_true(cond) } else { cond };
        let fast_blk = b.create_block();
        let slow_blk = b.create_block();
        let merge = b.create_block();
        let nret = if name == "sincos" { 2 } else { 1 };
        for _ in 0..nret {
            b.append_block_param(merge, if vector { arg_ty } else { self.ty });
        }
        b.ins().brif(cond, fast_blk, &[], slow_blk, &[]);
        b.seal_block(fast_blk);
        b.seal_block(slow_blk);
        b.switch_to_block(fast_blk);
        let res = fast(&mut Ir { b, fma: self.fma, vector }, &wide);
        let res: Vec<BlockArg> = res.into_iter().map(|v| BlockArg::Value(self.narrow(b, v))).collect();
        b.ins().jump(merge, &res);
        self.emit_slow(b, slow_blk, merge, name, args, slow);
        b.seal_block(merge);
        b.switch_to_block(merge);
        b.block_params(merge).to_vec()
    }

    fn emit_slow(&self, b: &mut FunctionBuilder, blk: Block, merge: Block, name: &'static str, args: &[Value], slow: &mut SlowPath) {
        b.switch_to_block(blk);
        b.set_cold_block(blk);
        let ty = b.func.dfg.value_type(args[0]);
        let r = if ty.is_vector() {
            let mut out: Vec<Value> = Vec::new();
            for lane in 0..ty.lane_count() as u8 {
                let xs: Vec<Value> = args.iter().map(|&a| b.ins().extractlane(a, lane)).collect();
                let r = slow(b, name, &xs);
                if out.is_empty() {
                    out = vec![args[0]; r.len()];
                }
                for (o, v) in out.iter_mut().zip(r) {
                    *o = b.ins().insertlane(*o, v, lane);
                }
            }
            out
        } else {
            slow(b, name, args)
        };
        let r: Vec<BlockArg> = r.into_iter().map(BlockArg::Value).collect();
        b.ins().jump(merge, &r);
    }

    /// (sin x, cos x) with one shared range reduction.
    pub fn sincos(&self, b: &mut FunctionBuilder, x: Value, slow: &mut SlowPath) -> (Value, Value) {
        let tier = self.tier();
        let r = self.guarded(
            b,
            &[x],
            "sincos",
            slow,
            |e, a| {
                let ax = e.b.ins().fabs(a[0]);
                let m = e.c(SINCOS_MAX);
                e.b.ins().fcmp(FloatCC::LessThanOrEqual, ax, m)
            },
            |e, a| {
                let (s, c) = sincos_kernel(e, a[0], tier);
                vec![s, c]
            },
        );
        (r[0], r[1])
    }

    fn sin_or_cos(&self, b: &mut FunctionBuilder, x: Value, slow: &mut SlowPath, cos: bool) -> Value {
        let tier = self.tier();
        self.guarded(
            b,
            &[x],
            if cos { "cos" } else { "sin" },
            slow,
            |e, a| {
                let ax = e.b.ins().fabs(a[0]);
                let m = e.c(SINCOS_MAX);
                e.b.ins().fcmp(FloatCC::LessThanOrEqual, ax, m)
            },
            |e, a| {
                let (s, c) = sincos_kernel(e, a[0], tier);
                vec![if cos { c } else { s }]
            },
        )[0]
    }

    /// sin x.
    pub fn sin(&self, b: &mut FunctionBuilder, x: Value, slow: &mut SlowPath) -> Value {
        self.sin_or_cos(b, x, slow, false)
    }

    /// cos x.
    pub fn cos(&self, b: &mut FunctionBuilder, x: Value, slow: &mut SlowPath) -> Value {
        self.sin_or_cos(b, x, slow, true)
    }

    /// e^x (libm for |x| ≥ 708, NaN and ±inf).
    pub fn exp(&self, b: &mut FunctionBuilder, x: Value, slow: &mut SlowPath) -> Value {
        let tier = self.tier();
        self.guarded(b, &[x], "exp", slow, |e, a| e.abs_lt(a[0], EXP_MAX), |e, a| vec![exp_kernel(e, a[0], tier)])[0]
    }

    /// ln x (libm for x ≤ 0, subnormal f64, +inf and NaN).
    pub fn log(&self, b: &mut FunctionBuilder, x: Value, slow: &mut SlowPath) -> Value {
        let tier = self.tier();
        self.guarded(b, &[x], "log", slow, |e, a| e.is_pos_normal(a[0]), |e, a| vec![log_kernel(e, a[0], tier)])[0]
    }

    /// ∛x for all reals (libm for ±0, subnormal f64, ±inf and NaN).
    pub fn cbrt(&self, b: &mut FunctionBuilder, x: Value, slow: &mut SlowPath) -> Value {
        let tier = self.tier();
        self.guarded(
            b,
            &[x],
            "cbrt",
            slow,
            |e, a| {
                let ax = e.b.ins().fabs(a[0]);
                e.is_pos_normal(ax)
            },
            |e, a| vec![cbrt_kernel(e, a[0], tier)],
        )[0]
    }

    /// x^y: `exp(y·log x)` inline for positive normal finite x, finite y and
    /// |y·log x| < 708; libm otherwise, and always for f64 in `Exact` mode.
    pub fn pow(&self, b: &mut FunctionBuilder, x: Value, y: Value, slow: &mut SlowPath) -> Value {
        if !self.f32() && self.mode == MathMode::Exact {
            return slow(b, "pow", &[x, y])[0];
        }
        let tier = self.tier();
        let (xw, yw) = (self.widen(b, x), self.widen(b, y));
        let slow_blk = b.create_block();
        let log_blk = b.create_block();
        let exp_blk = b.create_block();
        let merge = b.create_block();
        b.append_block_param(merge, self.ty);
        let ok = {
            let mut e = Ir { b, fma: self.fma, vector: false };
            let xok = e.is_pos_normal(xw);
            let yok = e.abs_lt(yw, f64::INFINITY);
            e.b.ins().band(xok, yok)
        };
        b.ins().brif(ok, log_blk, &[], slow_blk, &[]);
        b.seal_block(log_blk);
        b.switch_to_block(log_blk);
        let (t, tok) = {
            let mut e = Ir { b, fma: self.fma, vector: false };
            // log(x) errors are multiplied by y: use the next better log.
            // (f32 only needs |error of y·log x| ≲ 1e-8, which the Fast log gives.)
            let ltier = if tier == MathMode::Fast && !self.f32() { MathMode::Exact } else { MathMode::Fast };
            let l = log_kernel(&mut e, xw, ltier);
            let t = e.mul(yw, l);
            let tok = e.abs_lt(t, EXP_MAX);
            (t, tok)
        };
        b.ins().brif(tok, exp_blk, &[], slow_blk, &[]);
        b.seal_block(exp_blk);
        b.seal_block(slow_blk);
        b.switch_to_block(exp_blk);
        let r = exp_kernel(&mut Ir { b, fma: self.fma, vector: false }, t, tier);
        let r = self.narrow(b, r);
        b.ins().jump(merge, &[BlockArg::Value(r)]);
        self.emit_slow(b, slow_blk, merge, "pow", &[x, y], slow);
        b.seal_block(merge);
        b.switch_to_block(merge);
        b.block_params(merge)[0]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cranelift_codegen::ir::{AbiParam, FuncRef, Signature, StackSlot, StackSlotData, StackSlotKind};
    use cranelift_codegen::settings::{self, Configurable};
    use cranelift_frontend::FunctionBuilderContext;
    use cranelift_jit::{JITBuilder, JITModule};
    use cranelift_module::{default_libcall_names, Linkage, Module};
    use std::collections::HashMap;

    mod libm {
        unsafe extern "C" {
            pub fn sincos(x: f64, s: *mut f64, c: *mut f64);
            pub fn sincosf(x: f32, s: *mut f32, c: *mut f32);
        }
    }

    fn symbols() -> Vec<(&'static str, *const u8)> {
        vec![
            ("sin", f64::sin as fn(f64) -> f64 as *const u8),
            ("cos", f64::cos as fn(f64) -> f64 as *const u8),
            ("exp", f64::exp as fn(f64) -> f64 as *const u8),
            ("log", f64::ln as fn(f64) -> f64 as *const u8),
            ("cbrt", f64::cbrt as fn(f64) -> f64 as *const u8),
            ("pow", f64::powf as fn(f64, f64) -> f64 as *const u8),
            ("sincos", libm::sincos as *const u8),
            ("sinf", f32::sin as fn(f32) -> f32 as *const u8),
            ("cosf", f32::cos as fn(f32) -> f32 as *const u8),
            ("expf", f32::exp as fn(f32) -> f32 as *const u8),
            ("logf", f32::ln as fn(f32) -> f32 as *const u8),
            ("cbrtf", f32::cbrt as fn(f32) -> f32 as *const u8),
            ("powf", f32::powf as fn(f32, f32) -> f32 as *const u8),
            ("sincosf", libm::sincosf as *const u8),
        ]
    }

    /// The function a test kernel evaluates.
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub(super) enum Func {
        Sin,
        Cos,
        SinCos,
        Exp,
        Log,
        Cbrt,
        Pow,
    }

    /// Inline code in a mode, or a libm call per element (as codegen does today).
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub(super) enum Imp {
        Inline(MathMode),
        Libm,
    }

    type LoopFn = unsafe extern "C" fn(*const u8, *const u8, *mut u8, *mut u8, i64);

    /// A JIT loop `for i in 0..n { out0[i], out1[i] = f(a[i], b[i]) }`.
    pub(super) struct Kernel {
        module: Option<JITModule>,
        entry: LoopFn,
    }

    impl Drop for Kernel {
        fn drop(&mut self) {
            if let Some(m) = self.module.take() {
                // SAFETY: no pointer into the module's code survives the kernel.
                unsafe { m.free_memory() };
            }
        }
    }

    impl Kernel {
        /// Runs the kernel over `a` (and `b` for pow) into `o0` (and `o1` for sincos).
        pub(super) fn run<T: Copy>(&self, a: &[T], b: &[T], o0: &mut [T], o1: &mut [T]) {
            assert!(b.len() >= a.len() && o0.len() >= a.len() && o1.len() >= a.len());
            // SAFETY: every buffer holds at least `a.len()` elements of the kernel's type.
            unsafe { (self.entry)(a.as_ptr().cast(), b.as_ptr().cast(), o0.as_mut_ptr().cast(), o1.as_mut_ptr().cast(), a.len() as i64) }
        }
    }

    /// JIT-compiles a loop evaluating `func` with `imp` on elements of type `ty`.
    pub(super) fn build(func: Func, ty: Type, imp: Imp, fma: Option<bool>) -> Kernel {
        let mut flags = settings::builder();
        flags.set("opt_level", "speed").unwrap();
        let isa = cranelift_native::builder().unwrap().finish(settings::Flags::new(flags)).unwrap();
        let mut em = MathEmitter::new(&*isa, ty, if let Imp::Inline(m) = imp { m } else { MathMode::Exact });
        if let Some(f) = fma {
            em.fma = f;
        }
        let mut jb = JITBuilder::with_isa(isa, default_libcall_names());
        for (name, ptr) in symbols() {
            jb.symbol(name, ptr);
        }
        let mut module = JITModule::new(jb);
        let ptr = module.target_config().pointer_type();
        let call_conv = module.isa().default_call_conv();
        let mut ctx = module.make_context();
        for _ in 0..4 {
            ctx.func.signature.params.push(AbiParam::new(ptr));
        }
        ctx.func.signature.params.push(AbiParam::new(types::I64));
        let id = module.declare_function("k", Linkage::Export, &ctx.func.signature).unwrap();
        let mut fbc = FunctionBuilderContext::new();
        {
            let mut b = FunctionBuilder::new(&mut ctx.func, &mut fbc);
            let entry = b.create_block();
            b.append_block_params_for_function_params(entry);
            b.switch_to_block(entry);
            let p = b.block_params(entry).to_vec();
            let header = b.create_block();
            let body = b.create_block();
            let exit = b.create_block();
            b.append_block_param(header, types::I64);
            let zero = b.ins().iconst(types::I64, 0);
            b.ins().jump(header, &[BlockArg::Value(zero)]);
            b.switch_to_block(header);
            let i = b.block_params(header)[0];
            let more = b.ins().icmp(IntCC::SignedLessThan, i, p[4]);
            b.ins().brif(more, body, &[], exit, &[]);
            b.seal_block(body);
            b.switch_to_block(body);
            let off = b.ins().imul_imm_s(i, ty.bytes() as i64);
            let flags = MemFlagsData::trusted();
            let addr = |b: &mut FunctionBuilder, k: usize| b.ins().iadd(p[k], off);
            let pa = addr(&mut b, 0);
            let x = b.ins().load(ty, flags, pa, 0);
            let pb = addr(&mut b, 1);
            let y = b.ins().load(ty, flags, pb, 0);
            let f32 = ty == types::F32;
            let mut imports: HashMap<String, FuncRef> = HashMap::new();
            let mut slot: Option<StackSlot> = None;
            let mut slow = |b: &mut FunctionBuilder, name: &'static str, args: &[Value]| -> Vec<Value> {
                let full = if f32 { format!("{name}f") } else { name.to_string() };
                let fref = *imports.entry(full.clone()).or_insert_with(|| {
                    let mut sig = Signature::new(call_conv);
                    for _ in 0..if name == "pow" { 2 } else { 1 } {
                        sig.params.push(AbiParam::new(ty));
                    }
                    if name == "sincos" {
                        sig.params.push(AbiParam::new(ptr));
                        sig.params.push(AbiParam::new(ptr));
                    } else {
                        sig.returns.push(AbiParam::new(ty));
                    }
                    let id = module.declare_function(&full, Linkage::Import, &sig).unwrap();
                    module.declare_func_in_func(id, b.func)
                });
                if name == "sincos" {
                    let s = *slot.get_or_insert_with(|| b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 3)));
                    let size = ty.bytes() as i32;
                    let ps = b.ins().stack_addr(ptr, s, 0);
                    let pc = b.ins().stack_addr(ptr, s, size);
                    b.ins().call(fref, &[args[0], ps, pc]);
                    vec![b.ins().stack_load(ptr, ty, s, 0), b.ins().stack_load(ptr, ty, s, size)]
                } else {
                    let c = b.ins().call(fref, args);
                    b.inst_results(c).to_vec()
                }
            };
            let out: Vec<Value> = match (imp, func) {
                (Imp::Libm, Func::SinCos) => slow(&mut b, "sincos", &[x]),
                (Imp::Libm, Func::Pow) => slow(&mut b, "pow", &[x, y]),
                (Imp::Libm, f) => {
                    let name = match f {
                        Func::Sin => "sin",
                        Func::Cos => "cos",
                        Func::Exp => "exp",
                        Func::Log => "log",
                        _ => "cbrt",
                    };
                    slow(&mut b, name, &[x])
                }
                (Imp::Inline(_), Func::Sin) => vec![em.sin(&mut b, x, &mut slow)],
                (Imp::Inline(_), Func::Cos) => vec![em.cos(&mut b, x, &mut slow)],
                (Imp::Inline(_), Func::SinCos) => {
                    let (s, c) = em.sincos(&mut b, x, &mut slow);
                    vec![s, c]
                }
                (Imp::Inline(_), Func::Exp) => vec![em.exp(&mut b, x, &mut slow)],
                (Imp::Inline(_), Func::Log) => vec![em.log(&mut b, x, &mut slow)],
                (Imp::Inline(_), Func::Cbrt) => vec![em.cbrt(&mut b, x, &mut slow)],
                (Imp::Inline(_), Func::Pow) => vec![em.pow(&mut b, x, y, &mut slow)],
            };
            for (k, v) in out.into_iter().enumerate() {
                let po = addr(&mut b, 2 + k);
                b.ins().store(flags, v, po, 0);
            }
            let next = b.ins().iadd_imm_s(i, 1);
            b.ins().jump(header, &[BlockArg::Value(next)]);
            b.seal_block(header);
            b.seal_block(exit);
            b.switch_to_block(exit);
            b.ins().return_(&[]);
            b.seal_all_blocks();
            b.finalize(module.target_config());
        }
        let disasm = std::env::var("MATHLIB_DISASM").is_ok_and(|v| v == format!("{func:?}"));
        ctx.set_disasm(disasm);
        module.define_function(id, &mut ctx).unwrap_or_else(|e| panic!("{e:?}\n{}", ctx.func.display()));
        if disasm {
            println!("{func:?} {ty} {imp:?}:\n{}", ctx.compiled_code().and_then(|c| c.vcode.clone()).unwrap_or_default());
        }
        module.clear_context(&mut ctx);
        module.finalize_definitions().unwrap();
        let code = module.get_finalized_function(id);
        // SAFETY: `code` is the finalized function with the signature declared above.
        let entry = unsafe { std::mem::transmute::<*const u8, LoopFn>(code) };
        Kernel { module: Some(module), entry }
    }

    /// SplitMix64.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }
        fn unif(&mut self, a: f64, b: f64) -> f64 {
            a + (b - a) * ((self.next() >> 11) as f64 / (1u64 << 53) as f64)
        }
        /// ±2^u·m with u uniform in [lo, hi), m uniform in [1, 2).
        fn logspace(&mut self, lo: f64, hi: f64, signed: bool) -> f64 {
            let v = self.unif(lo, hi).exp2() * self.unif(1.0, 2.0);
            if signed && self.next() & 1 == 1 {
                -v
            } else {
                v
            }
        }
    }

    const N: usize = 100_000;

    /// Special values every sweep includes.
    fn specials() -> Vec<f64> {
        let mut v = vec![0.0, -0.0, 1e-300, -1e-300, 5e-324, -5e-324, 1e-310, f64::MIN_POSITIVE, 1.0, -1.0, 2.0, 0.5, 1e300, -1e300];
        v.extend([f64::MAX, -f64::MAX, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e-20, -1e-20, 1e5, -1e5, 1e6, -1e6]);
        v
    }

    /// Named sweeps of (x, y) inputs for `f`.
    pub(super) fn domains(f: Func) -> Vec<(&'static str, Vec<f64>, Vec<f64>)> {
        let mut rng = Rng(0x5eed_0000 + f as u64);
        let mut d: Vec<(&'static str, Vec<f64>, Vec<f64>)> = Vec::new();
        let uni = |name, a: f64, b: f64, rng: &mut Rng| (name, (0..N).map(|_| rng.unif(a, b)).collect::<Vec<_>>(), vec![0.0; N]);
        match f {
            Func::Sin | Func::Cos | Func::SinCos => {
                d.push(uni("[-4,4]", -4.0, 4.0, &mut rng));
                d.push(uni("[-1e5,1e5]", -1e5, 1e5, &mut rng));
                d.push(uni("[-2e6,2e6]", -2e6, 2e6, &mut rng));
                // Doubles nearest to multiples of π/2 (and their neighbours), k up to 1e6.
                let mut v = specials();
                for j in 0..N / 4 {
                    let k = if j < 2000 { j as f64 } else { (rng.next() % 1_000_000) as f64 };
                    let x = k * std::f64::consts::FRAC_PI_2;
                    let b = x.to_bits();
                    v.extend([x, f64::from_bits(b + 1), f64::from_bits(b.saturating_sub(1)), -x]);
                }
                d.push(("k·π/2 ± ulp, specials", v, vec![0.0; N + 100]));
            }
            Func::Exp => {
                d.push(uni("[-1,1]", -1.0, 1.0, &mut rng));
                d.push(uni("[-746,710]", -746.0, 710.0, &mut rng));
                let mut v = specials();
                v.extend([708.0, -708.0, 707.999, 709.78, 709.79, -745.13, -745.14, 1e-17, -1e-17]);
                v.extend((0..N).map(|_| rng.logspace(-60.0, 10.0, true)));
                d.push(("±2^[-60,10], specials", v, vec![0.0; N + 100]));
            }
            Func::Log | Func::Cbrt => {
                let signed = f == Func::Cbrt;
                d.push(uni("[0.5,2]", 0.5, 2.0, &mut rng));
                let v: Vec<f64> = (0..N).map(|_| rng.logspace(-1074.0, 1024.0, signed)).collect();
                d.push(("±2^[-1074,1024]", v, vec![0.0; N]));
                let mut v = specials();
                v.extend((0..N).map(|_| 1.0 + rng.unif(-1e-6, 1e-6)));
                v.extend([-8.0, 27.0, 1e-308, 3e-308, 1.0 - f64::EPSILON / 2.0, 1.0 + f64::EPSILON]);
                d.push(("1±1e-6, specials", v, vec![0.0; N + 100]));
            }
            Func::Pow => {
                let x: Vec<f64> = (0..N).map(|_| rng.logspace(-10.0, 10.0, false)).collect();
                let y: Vec<f64> = (0..N).map(|_| rng.unif(-20.0, 20.0)).collect();
                d.push(("x∈2^[-10,10], y∈[-20,20]", x, y));
                let x: Vec<f64> = (0..N).map(|_| rng.unif(0.9, 1.1)).collect();
                let y: Vec<f64> = (0..N).map(|_| rng.unif(-5000.0, 5000.0)).collect();
                d.push(("x∈[0.9,1.1], y∈[-5e3,5e3]", x, y));
                let s = specials();
                let ys = [
                    0.0,
                    -0.0,
                    1.0,
                    -1.0,
                    2.0,
                    3.0,
                    -3.0,
                    0.5,
                    1.5,
                    1e10,
                    -1e10,
                    400.0,
                    -400.0,
                    f64::NAN,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                ];
                let (mut x, mut y) = (Vec::new(), Vec::new());
                for &a in &s {
                    for &b in &ys {
                        x.push(a);
                        y.push(b);
                    }
                }
                for _ in 0..N {
                    x.push(rng.logspace(-1074.0, 1024.0, true));
                    y.push(rng.unif(-3.0, 3.0));
                }
                d.push(("specials, x∈±2^[-1074,1024]", x, y));
            }
        }
        d
    }

    fn reference(f: Func, x: f64, y: f64) -> (f64, f64) {
        match f {
            Func::Sin => (x.sin(), 0.0),
            Func::Cos => (x.cos(), 0.0),
            Func::SinCos => (x.sin(), x.cos()),
            Func::Exp => (x.exp(), 0.0),
            Func::Log => (x.ln(), 0.0),
            Func::Cbrt => (x.cbrt(), 0.0),
            Func::Pow => (x.powf(y), 0.0),
        }
    }

    fn reference32(f: Func, x: f32, y: f32) -> (f32, f32) {
        match f {
            Func::Sin => (x.sin(), 0.0),
            Func::Cos => (x.cos(), 0.0),
            Func::SinCos => (x.sin(), x.cos()),
            Func::Exp => (x.exp(), 0.0),
            Func::Log => (x.ln(), 0.0),
            Func::Cbrt => (x.cbrt(), 0.0),
            Func::Pow => (x.powf(y), 0.0),
        }
    }

    /// Error of `y` against `r`: in units of `ulp` if given, else relative. NaN/inf/zero-sign mismatches are infinite.
    fn err(y: f64, r: f64, ulp: Option<f64>) -> f64 {
        if y.is_nan() && r.is_nan() {
            return 0.0;
        }
        if y == r {
            return if y == 0.0 && y.is_sign_negative() != r.is_sign_negative() { f64::INFINITY } else { 0.0 };
        }
        if !y.is_finite() || !r.is_finite() {
            return f64::INFINITY;
        }
        match ulp {
            Some(u) => (y - r).abs() / u,
            None => (y - r).abs() / r.abs().max(f64::MIN_POSITIVE),
        }
    }

    fn ulp64(r: f64) -> f64 {
        let a = r.abs();
        f64::from_bits(a.to_bits() + 1) - a
    }

    fn ulp32(r: f32) -> f64 {
        let a = r.abs();
        (f32::from_bits(a.to_bits() + 1) - a) as f64
    }

    /// Max error of `imp` on each domain of `f` (f64: ulps for Exact, relative otherwise; f32: f32 ulps).
    pub(super) fn max_errors(f: Func, ty: Type, imp: Imp, fma: Option<bool>) -> Vec<(&'static str, f64, f64)> {
        let k = build(f, ty, imp, fma);
        let ulps = ty == types::F32 || imp == Imp::Inline(MathMode::Exact);
        let mut out = Vec::new();
        for (name, xs, ys) in domains(f) {
            let n = xs.len();
            let (mut worst, mut at) = (0.0f64, f64::NAN);
            if ty == types::F64 {
                let (mut o0, mut o1) = (vec![0.0f64; n], vec![0.0f64; n]);
                k.run(&xs, &ys, &mut o0, &mut o1);
                for i in 0..n {
                    let (r0, r1) = reference(f, xs[i], ys[i]);
                    let mut e = err(o0[i], r0, ulps.then(|| ulp64(r0)));
                    if f == Func::SinCos {
                        e = e.max(err(o1[i], r1, ulps.then(|| ulp64(r1))));
                    }
                    if e > worst || e.is_nan() {
                        (worst, at) = (e, xs[i]);
                    }
                }
            } else {
                let xs: Vec<f32> = xs.iter().map(|&v| v as f32).collect();
                let ys: Vec<f32> = ys.iter().map(|&v| v as f32).collect();
                let (mut o0, mut o1) = (vec![0.0f32; n], vec![0.0f32; n]);
                k.run(&xs, &ys, &mut o0, &mut o1);
                for i in 0..n {
                    let (r0, r1) = reference32(f, xs[i], ys[i]);
                    let mut e = err(o0[i] as f64, r0 as f64, Some(ulp32(r0)));
                    if f == Func::SinCos {
                        e = e.max(err(o1[i] as f64, r1 as f64, Some(ulp32(r1))));
                    }
                    if e > worst || e.is_nan() {
                        (worst, at) = (e, xs[i] as f64);
                    }
                }
            }
            out.push((name, worst, at));
        }
        out
    }

    /// Documented bounds: f64 Exact in ulps, f64 Fast/Fastest relative, f32 in f32 ulps.
    fn bound(ty: Type, mode: MathMode) -> f64 {
        match (ty == types::F32, mode) {
            (false, MathMode::Exact) => 2.0,
            (false, MathMode::Fast) => 1e-12,
            (false, MathMode::Fastest) => 1e-7,
            (true, MathMode::Exact) => 1.0,
            (true, _) => 2.0,
        }
    }

    fn check(f: Func) {
        let mut failures = Vec::new();
        for ty in [types::F64, types::F32] {
            for mode in [MathMode::Exact, MathMode::Fast, MathMode::Fastest] {
                let fmas: &[Option<bool>] = if ty == types::F64 && mode == MathMode::Exact { &[None, Some(false)] } else { &[None] };
                for &fma in fmas {
                    for (dom, e, at) in max_errors(f, ty, Imp::Inline(mode), fma) {
                        let unit = if ty == types::F32 || mode == MathMode::Exact { "ulp" } else { "rel" };
                        let nofma = if fma == Some(false) { " (no FMA)" } else { "" };
                        println!("| {f:?} | {ty} | {mode:?}{nofma} | {dom} | {e:.3e} {unit} | x={at:e} |");
                        if !(e <= bound(ty, mode)) {
                            failures.push(format!("{f:?} {ty} {mode:?}{nofma} on {dom}: {e:e} {unit} at x={at:e}"));
                        }
                    }
                }
            }
        }
        assert!(failures.is_empty(), "errors above bound:\n{}", failures.join("\n"));
    }

    #[test]
    fn accuracy_sincos() {
        check(Func::SinCos);
    }

    #[test]
    fn accuracy_sin() {
        check(Func::Sin);
    }

    #[test]
    fn accuracy_cos() {
        check(Func::Cos);
    }

    #[test]
    fn accuracy_exp() {
        check(Func::Exp);
    }

    #[test]
    fn accuracy_log() {
        check(Func::Log);
    }

    #[test]
    fn accuracy_cbrt() {
        check(Func::Cbrt);
    }

    #[test]
    fn accuracy_pow() {
        check(Func::Pow);
    }

    /// FMA is used exactly when the CPU has it (cranelift_native enables `has_fma`).
    #[test]
    fn fma_detection() {
        let isa = cranelift_native::builder().unwrap().finish(settings::Flags::new(settings::builder())).unwrap();
        #[cfg(target_arch = "x86_64")]
        assert_eq!(isa_has_fma(&*isa), std::is_x86_feature_detected!("fma"));
        println!("isa {} has_fma = {}", isa.name(), isa_has_fma(&*isa));
    }

    /// The error measure is not vacuous: libm's sin vs a 1-ulp-perturbed copy is caught.
    #[test]
    fn error_measure_detects_mistakes() {
        let r = 0.7f64.sin();
        assert_eq!(err(f64::from_bits(r.to_bits() + 3), r, Some(ulp64(r))), 3.0);
        assert!(err(-0.0, 0.0, None).is_infinite());
        assert!(err(f64::NAN, 1.0, None).is_infinite());
        assert!(err(1.0 + 1e-6, 1.0, None) > 1e-7);
    }

    /// ns/element of a JIT loop over 8192 elements, inline modes vs a libm call per element.
    /// Run: `CARGO_TARGET_DIR=/work/target-math cargo test --release -p gwml-compiler mathlib::tests::bench -- --ignored --nocapture`
    #[test]
    #[ignore]
    fn bench() {
        const LEN: usize = 8192;
        let mut rng = Rng(42);
        let funcs = [
            (Func::SinCos, "sincos x∈[0,1e5]"),
            (Func::Sin, "sin x∈[0,1e5]"),
            (Func::Cos, "cos x∈[0,1e5]"),
            (Func::Exp, "exp x∈[-50,50]"),
            (Func::Log, "log x∈2^[-20,20]"),
            (Func::Cbrt, "cbrt x∈±2^[-20,20]"),
            (Func::Pow, "pow x∈2^[-10,10], y∈[-3,3]"),
        ];
        println!("ns/element, median (min) of 41 rounds of 5 × {LEN} elements");
        println!("| function | type | libm | Exact | Fast | Fastest |");
        println!("|---|---|---|---|---|---|");
        for (f, label) in funcs {
            let xs: Vec<f64> = (0..LEN)
                .map(|_| match f {
                    Func::Sin | Func::Cos | Func::SinCos => rng.unif(0.0, 1e5),
                    Func::Exp => rng.unif(-50.0, 50.0),
                    Func::Log => rng.logspace(-20.0, 20.0, false),
                    Func::Cbrt => rng.logspace(-20.0, 20.0, true),
                    Func::Pow => rng.logspace(-10.0, 10.0, false),
                })
                .collect();
            let ys: Vec<f64> = (0..LEN).map(|_| rng.unif(-3.0, 3.0)).collect();
            for ty in [types::F64, types::F32] {
                let imps = [Imp::Libm, Imp::Inline(MathMode::Exact), Imp::Inline(MathMode::Fast), Imp::Inline(MathMode::Fastest)];
                let kernels: Vec<Kernel> = imps.iter().map(|&imp| build(f, ty, imp, None)).collect();
                let (x32, y32): (Vec<f32>, Vec<f32>) = (xs.iter().map(|&v| v as f32).collect(), ys.iter().map(|&v| v as f32).collect());
                let (mut o0, mut o1) = (vec![0.0f64; LEN], vec![0.0f64; LEN]);
                let (mut p0, mut p1) = (vec![0.0f32; LEN], vec![0.0f32; LEN]);
                // Round-robin over the implementations so machine noise hits all of them alike.
                let mut samples = vec![Vec::new(); imps.len()];
                for _ in 0..41 {
                    for (k, s) in kernels.iter().zip(samples.iter_mut()) {
                        let t = std::time::Instant::now();
                        for _ in 0..5 {
                            if ty == types::F64 {
                                k.run(&xs, &ys, &mut o0, &mut o1);
                            } else {
                                k.run(&x32, &y32, &mut p0, &mut p1);
                            }
                        }
                        s.push(t.elapsed().as_secs_f64() / (5 * LEN) as f64 * 1e9);
                    }
                }
                let mut row = format!("| {label} | {ty} |");
                for s in &mut samples {
                    s.sort_by(f64::total_cmp);
                    row += &format!(" {:.2} ({:.2}) |", s[s.len() / 2], s[0]);
                }
                println!("{row}");
            }
        }
    }
}
