//! [`Ir`]: a FunctionBuilder with f64 (or f64x2) arithmetic shorthands, and the bitcast and select codegen shares.

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, Endianness, InstBuilder, MemFlagsData, Type, Value};
use cranelift_frontend::FunctionBuilder;

/// 1.5·2^52: adding it rounds a double of magnitude < 2^51 to an integer
/// held in the low significand bits.
const MAGIC: f64 = 6755399441055744.0;

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
pub(super) struct Ir<'a, 'f> {
    pub(super) b: &'a mut FunctionBuilder<'f>,
    pub(super) fma: bool,
    pub(super) vector: bool,
}

impl Ir<'_, '_> {
    pub(super) fn c(&mut self, v: f64) -> Value {
        let c = self.b.ins().f64const(v);
        if self.vector {
            self.b.ins().splat(types::F64X2, c)
        } else {
            c
        }
    }
    /// The integer `k` (i64, or i64x2 in every lane).
    pub(super) fn ic(&mut self, k: i64) -> Value {
        let c = self.b.ins().iconst(types::I64, k);
        if self.vector {
            self.b.ins().splat(types::I64X2, c)
        } else {
            c
        }
    }
    pub(super) fn iadd_c(&mut self, x: Value, k: i64) -> Value {
        let k = self.ic(k);
        self.b.ins().iadd(x, k)
    }
    pub(super) fn band_c(&mut self, x: Value, k: i64) -> Value {
        let k = self.ic(k);
        self.b.ins().band(x, k)
    }
    pub(super) fn shl(&mut self, x: Value, by: i64) -> Value {
        let by = self.b.ins().iconst(types::I32, by);
        self.b.ins().ishl(x, by)
    }
    /// `cond ? x : y` for a truth value from `fcmp` (a lane mask when vector).
    pub(super) fn select(&mut self, cond: Value, x: Value, y: Value) -> Value {
        select(self.b, cond, x, y)
    }
    /// `x` where bit 0 of the integer `n` is set, else `y`.
    pub(super) fn select_odd(&mut self, n: Value, x: Value, y: Value) -> Value {
        let odd = self.band_c(n, 1);
        if self.vector {
            let one = self.ic(1);
            let mask = self.b.ins().icmp(IntCC::Equal, odd, one);
            self.select(mask, x, y)
        } else {
            self.b.ins().select(odd, x, y)
        }
    }
    pub(super) fn add(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fadd(x, y)
    }
    pub(super) fn sub(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fsub(x, y)
    }
    pub(super) fn mul(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fmul(x, y)
    }
    pub(super) fn div(&mut self, x: Value, y: Value) -> Value {
        self.b.ins().fdiv(x, y)
    }
    pub(super) fn mulc(&mut self, x: Value, k: f64) -> Value {
        let k = self.c(k);
        self.mul(x, k)
    }
    /// `x·y + z`, fused if the ISA has FMA.
    pub(super) fn mla(&mut self, x: Value, y: Value, z: Value) -> Value {
        if self.fma {
            self.b.ins().fma(x, y, z)
        } else {
            let p = self.mul(x, y);
            self.add(p, z)
        }
    }
    /// `c[0] + x·(c[1] + x·(c[2] + …))`.
    pub(super) fn horner(&mut self, x: Value, cs: &[f64]) -> Value {
        let (last, rest) = cs.split_last().expect("non-empty coefficients");
        let mut acc = self.c(*last);
        for &k in rest.iter().rev() {
            let k = self.c(k);
            acc = self.mla(acc, x, k);
        }
        acc
    }
    pub(super) fn bits(&mut self, x: Value) -> Value {
        bitcast(self.b, if self.vector { types::I64X2 } else { types::I64 }, x)
    }
    pub(super) fn float(&mut self, i: Value) -> Value {
        bitcast(self.b, if self.vector { types::F64X2 } else { types::F64 }, i)
    }
    /// Rounds `x·scale` to the nearest integer: (as f64, as i64). |x·scale| < 2^51.
    pub(super) fn round_mul(&mut self, x: Value, scale: f64) -> (Value, Value) {
        let s = self.c(scale);
        let m = self.c(MAGIC);
        let t = self.mla(x, s, m);
        let kf = self.sub(t, m);
        let tb = self.bits(t);
        let ki = self.iadd_c(tb, -(MAGIC.to_bits() as i64));
        (kf, ki)
    }
    /// `x` with its sign flipped where bit 1 of the integer `n` is set.
    pub(super) fn flip_if_bit1(&mut self, x: Value, n: Value) -> Value {
        let bit = self.band_c(n, 2);
        let sign = self.shl(bit, 62);
        let xb = self.bits(x);
        let r = self.b.ins().bxor(xb, sign);
        self.float(r)
    }
    /// `x` is a positive normal finite double (false for NaN).
    pub(super) fn is_pos_normal(&mut self, x: Value) -> Value {
        let xb = self.bits(x);
        let d = self.b.ins().iadd_imm_s(xb, -(f64::MIN_POSITIVE.to_bits() as i64));
        let span = (f64::INFINITY.to_bits() - f64::MIN_POSITIVE.to_bits()) as i64;
        self.b.ins().icmp_imm_s(IntCC::UnsignedLessThan, d, span)
    }
    /// `|x| < bound` (false for NaN).
    pub(super) fn abs_lt(&mut self, x: Value, bound: f64) -> Value {
        let a = self.b.ins().fabs(x);
        let c = self.c(bound);
        self.b.ins().fcmp(FloatCC::LessThan, a, c)
    }
}
