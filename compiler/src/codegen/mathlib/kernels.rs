//! The f64 (and f64x2) kernels of sin/cos, exp, log and cbrt, with their fdlibm/FreeBSD and fitted coefficients.

// Published fdlibm/FreeBSD constants keep their printed digits, so they can be checked against the source.
#![allow(clippy::excessive_precision)]

use super::arith::Ir;
use crate::ir::MathMode;
use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, InstBuilder, Value};

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
/// Below this, e^x rounds to +0 (it is under half the least subnormal,
/// 2^-1075, for x < −1075·ln 2 = −745.1332…), as libm returns: exp gives
/// 0 inline there, so the far tails of a Gaussian envelope, e^(−u²) with
/// u in the tens, take no libm call.
pub const EXP_ZERO: f64 = -745.2;
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
pub(super) fn sincos_kernel(e: &mut Ir, x: Value, mode: MathMode) -> (Value, Value) {
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
pub(super) fn exp_kernel(e: &mut Ir, x: Value, mode: MathMode) -> Value {
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
pub(super) fn log_kernel(e: &mut Ir, x: Value, mode: MathMode) -> Value {
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
pub(super) fn cbrt_kernel(e: &mut Ir, x: Value, mode: MathMode) -> Value {
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
