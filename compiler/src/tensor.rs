//! The dense-tensor operations of [`TensorOp`] (the layers of `learned`
//! components) on row-major real arrays. Generated kernels call
//! [`gwml_tensor_f64`] / [`gwml_tensor_f32`] between fused loops; the
//! interpreter calls [`apply`]. Every transpose op is tested here against
//! the definition `⟨A x, y⟩ = ⟨x, Aᵀ y⟩`, which is what makes the adjoint
//! pass's rules correct.

use crate::ir::{Conv, Pool, TensorOp};
use num_traits::Float;
use std::cell::RefCell;

/// The element types of the kernels (f64 and f32), with their matrix
/// product and a per-thread scratch buffer for the convolutions' unfolded
/// input.
pub trait Scalar: Float + 'static {
    /// `c = a · b` (`beta` 0) or `c += a · b` (`beta` 1) for an `m × k`
    /// matrix `a` and a `k × n` matrix `b` at element `(i, j)` of
    /// `a[i * rsa + j * csa]` and `b[i * rsb + j * csb]`, and a row-major
    /// `m × n` matrix `c` with rows `rsc` apart. Panics when a matrix does
    /// not fit in its slice.
    #[allow(clippy::too_many_arguments)]
    fn gemm(dims: [usize; 3], a: &[Self], a_strides: [usize; 2], b: &[Self], b_strides: [usize; 2], beta: Self, c: &mut [Self], rsc: usize);

    /// Calls `f` with a buffer of `len` elements (contents unspecified),
    /// reused between calls on the same thread.
    fn with_scratch<R>(len: usize, f: impl FnOnce(&mut [Self]) -> R) -> R;

    /// [`TensorOp::PoolPick`] (`pick`) or [`TensorOp::PoolScatter`] of `p`
    /// in vector code, when this type and target have one for `p`'s shape;
    /// returns whether it did (if not, `out` is untouched). Same results as
    /// the scalar scan, element for element.
    fn max_pool_vector(pick: bool, p: Pool, a: &[Self], b: &[Self], out: &mut [Self]) -> bool;
}

/// The last element a strided matrix reads plus one, or 0 when empty.
fn extent(rows: usize, cols: usize, [rs, cs]: [usize; 2]) -> usize {
    if rows == 0 || cols == 0 {
        0
    } else {
        (rows - 1) * rs + (cols - 1) * cs + 1
    }
}

macro_rules! scalar {
    ($t:ty, $gemm:ident, $scratch:ident, $pool:path) => {
        thread_local! {
            static $scratch: RefCell<Vec<$t>> = const { RefCell::new(Vec::new()) };
        }

        impl Scalar for $t {
            fn gemm(
                [m, k, n]: [usize; 3],
                a: &[$t],
                [rsa, csa]: [usize; 2],
                b: &[$t],
                [rsb, csb]: [usize; 2],
                beta: $t,
                c: &mut [$t],
                rsc: usize,
            ) {
                assert!(extent(m, k, [rsa, csa]) <= a.len() && extent(k, n, [rsb, csb]) <= b.len());
                assert!(extent(m, n, [rsc, 1]) <= c.len() && (m <= 1 || rsc >= n));
                if m == 0 || n == 0 {
                    return;
                }
                if k == 0 {
                    if beta == 0.0 {
                        c.iter_mut().for_each(|x| *x = 0.0);
                    }
                    return;
                }
                let i = |x: usize| x as isize;
                // SAFETY: the asserts above keep every element of a, b and c
                // inside its slice, and c's rows (rsc >= n apart, unit
                // columns) do not alias; c is a unique borrow, so it
                // overlaps neither a nor b.
                unsafe {
                    matrixmultiply::$gemm(
                        m,
                        k,
                        n,
                        1.0,
                        a.as_ptr(),
                        i(rsa),
                        i(csa),
                        b.as_ptr(),
                        i(rsb),
                        i(csb),
                        beta,
                        c.as_mut_ptr(),
                        i(rsc),
                        1,
                    )
                }
            }

            fn with_scratch<R>(len: usize, f: impl FnOnce(&mut [$t]) -> R) -> R {
                $scratch.with(|s| {
                    let mut s = s.borrow_mut();
                    if s.len() < len {
                        s.resize(len, 0.0);
                    }
                    f(&mut s[..len])
                })
            }

            fn max_pool_vector(pick: bool, p: Pool, a: &[$t], b: &[$t], out: &mut [$t]) -> bool {
                $pool(pick, p, a, b, out)
            }
        }
    };
}

/// No vector max pooling (targets without SSE).
#[cfg(not(target_arch = "x86_64"))]
fn no_vector_pool<T>(_: bool, _: Pool, _: &[T], _: &[T], _: &mut [T]) -> bool {
    false
}

#[cfg(target_arch = "x86_64")]
scalar!(f64, dgemm, SCRATCH_F64, pool4::f64_windows_of_4);
#[cfg(target_arch = "x86_64")]
scalar!(f32, sgemm, SCRATCH_F32, pool4::f32_windows_of_4);
#[cfg(not(target_arch = "x86_64"))]
scalar!(f64, dgemm, SCRATCH_F64, no_vector_pool);
#[cfg(not(target_arch = "x86_64"))]
scalar!(f32, sgemm, SCRATCH_F32, no_vector_pool);

/// Computes `op` on operands `a` and `b` (ignored for unary ops) into
/// `out`, which is overwritten. Slices must have the lengths
/// [`TensorOp::operand_lens`] and [`TensorOp::out_len`] give; shorter ones
/// are a caller bug and panic on indexing rather than read out of bounds.
pub fn apply<T: Scalar>(op: TensorOp, a: &[T], b: &[T], out: &mut [T]) {
    let u = |x: u32| x as usize;
    // Ops that accumulate into `out` or write part of it start from zeros;
    // the others write every element.
    if matches!(
        op,
        TensorOp::MatTVec { .. }
            | TensorOp::Outer { .. }
            | TensorOp::ConvBackData(_)
            | TensorOp::PoolScatter(_)
            | TensorOp::PoolAvg(_)
            | TensorOp::PoolAvgBack(_)
            | TensorOp::PlaceRows(_)
    ) {
        out.fill(T::zero());
    }
    match op {
        TensorOp::MatVec { m, k } => {
            let (m, k) = (u(m), u(k));
            for (r, o) in out[..m].iter_mut().enumerate() {
                *o = dot(&a[r * k..(r + 1) * k], &b[..k]);
            }
        }
        TensorOp::MatTVec { m, k } => {
            let (m, k) = (u(m), u(k));
            for r in 0..m {
                axpy(b[r], &a[r * k..(r + 1) * k], &mut out[..k]);
            }
        }
        TensorOp::Outer { m, k } => {
            let (m, k) = (u(m), u(k));
            for r in 0..m {
                axpy(a[r], &b[..k], &mut out[r * k..(r + 1) * k]);
            }
        }
        // The convolutions as matrix products with the unfolded input
        // `col` (`c_in · kernel` rows of `len_out`, see `unfold`): y = W col,
        // dW = dy colᵀ, and dx = fold(Wᵀ dy).
        // One input channel at stride 1: the unfolded input is a sliding
        // view of the zero-padded input (`padded_view`), read in place.
        TensorOp::Conv(c) if c.c_in == 1 && c.stride == 1 => {
            let (k, n, dil) = (u(c.kernel), u(c.len_out), u(c.dilation));
            padded_view(c, a, |xp| T::gemm([u(c.c_out), k, n], b, [k, 1], xp, [dil, 1], T::zero(), out, n));
        }
        TensorOp::ConvBackWeight(c) if c.c_in == 1 && c.stride == 1 => {
            let (k, n, dil) = (u(c.kernel), u(c.len_out), u(c.dilation));
            padded_view(c, b, |xp| T::gemm([u(c.c_out), n, k], a, [n, 1], xp, [1, dil], T::zero(), out, k));
        }
        TensorOp::Conv(c) => {
            let (rows, n) = (u(c.c_in * c.kernel), u(c.len_out));
            T::with_scratch(rows * n, |col| {
                unfold(c, a, col);
                T::gemm([u(c.c_out), rows, n], b, [rows, 1], col, [n, 1], T::zero(), out, n);
            });
        }
        TensorOp::ConvBackWeight(c) => {
            let (rows, n) = (u(c.c_in * c.kernel), u(c.len_out));
            T::with_scratch(rows * n, |col| {
                unfold(c, b, col);
                T::gemm([u(c.c_out), n, rows], a, [n, 1], col, [1, n], T::zero(), out, rows);
            });
        }
        TensorOp::ConvBackData(c) => {
            let (rows, n) = (u(c.c_in * c.kernel), u(c.len_out));
            T::with_scratch(rows * n, |col| {
                T::gemm([rows, u(c.c_out), n], b, [1, rows], a, [n, 1], T::zero(), col, n);
                fold_add(c, col, out);
            });
        }
        TensorOp::PoolPick(p) if T::max_pool_vector(true, p, a, b, out) => {}
        TensorOp::PoolScatter(p) if T::max_pool_vector(false, p, a, b, out) => {}
        TensorOp::PoolPick(p) => pool_argmax(p, a, |src, dst| out[dst] = b[src]),
        TensorOp::PoolScatter(p) => pool_argmax(p, a, |src, dst| out[src] = out[src] + b[dst]),
        TensorOp::PoolAvg(p) => {
            let inv = T::one() / T::from(p.window).unwrap_or_else(T::one);
            pool_windows(p, |src, dst| out[dst] = out[dst] + a[src] * inv);
        }
        TensorOp::PoolAvgBack(p) => {
            let inv = T::one() / T::from(p.window).unwrap_or_else(T::one);
            pool_windows(p, |src, dst| out[src] = out[src] + a[dst] * inv);
        }
        TensorOp::Spread { rows, cols } => {
            for (r, row) in out[..u(rows * cols)].chunks_mut(u(cols).max(1)).enumerate() {
                row.fill(a[r]);
            }
        }
        TensorOp::SumRows { rows, cols } => {
            for (r, o) in out[..u(rows)].iter_mut().enumerate() {
                *o = sum(&a[r * u(cols)..(r + 1) * u(cols)]);
            }
        }
        TensorOp::PlaceRows(r) => {
            let block = u(r.from * r.cols)..u((r.from + r.count) * r.cols);
            let n = block.len();
            out[block].copy_from_slice(&a[..n]);
        }
        TensorOp::TakeRows(r) => {
            let block = u(r.from * r.cols)..u((r.from + r.count) * r.cols);
            out[..block.len()].copy_from_slice(&a[block]);
        }
    }
}

/// Lanes of the partial sums in [`dot`] and [`sum`]: independent
/// accumulators the compiler keeps in vector registers (a sum in one
/// accumulator is a chain of dependent adds that cannot be vectorised).
const LANES: usize = 8;

/// `Σ x_i y_i` over the common length, in [`LANES`] interleaved partial
/// sums added pairwise at the end (a fixed order: deterministic).
fn dot<T: Float>(x: &[T], y: &[T]) -> T {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut acc = [T::zero(); LANES];
    let (xc, yc) = (x.chunks_exact(LANES), y.chunks_exact(LANES));
    let tail = xc.remainder().iter().zip(yc.remainder()).fold(T::zero(), |s, (a, b)| s + *a * *b);
    for (a, b) in xc.zip(yc) {
        for l in 0..LANES {
            acc[l] = acc[l] + a[l] * b[l];
        }
    }
    reduce_lanes(acc) + tail
}

/// `Σ x_i`, in the same lanes as [`dot`].
fn sum<T: Float>(x: &[T]) -> T {
    let mut acc = [T::zero(); LANES];
    let xc = x.chunks_exact(LANES);
    let tail = xc.remainder().iter().fold(T::zero(), |s, a| s + *a);
    for a in xc {
        for l in 0..LANES {
            acc[l] = acc[l] + a[l];
        }
    }
    reduce_lanes(acc) + tail
}

fn reduce_lanes<T: Float>(acc: [T; LANES]) -> T {
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7]))
}

fn axpy<T: Float>(alpha: T, x: &[T], y: &mut [T]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi = *yi + alpha * *xi;
    }
}

/// Index of weight `(o, c, j)` in the row-major `c_out × c_in × kernel` array.
#[cfg(test)]
fn weight_index(c: Conv, o: usize, ch: usize, j: usize) -> usize {
    (o * c.c_in as usize + ch) * c.kernel as usize + j
}

/// The terms of a convolution sum for one tap `(o, c, j)` whose input
/// sample lies inside the array (padding contributes zeros): output
/// positions `t0..t1` read input samples `start + (t - t0) * stride`.
#[derive(Clone, Copy, Debug)]
struct Run {
    t0: usize,
    t1: usize,
    start: usize,
    stride: usize,
}

/// Unfolds (im2col) input `x` (`c_in × len_in`) into `col`, row
/// `c · kernel + j` of which holds, for every output position `t`, the
/// input sample tap `j` of channel `c` multiplies there (0 in the padding).
fn unfold<T: Float>(c: Conv, x: &[T], col: &mut [T]) {
    let (k, n, len_in) = (c.kernel as usize, c.len_out as usize, c.len_in as usize);
    for ch in 0..c.c_in as usize {
        for j in 0..k {
            let row = &mut col[(ch * k + j) * n..][..n];
            let Some(r) = tap_run(c, j) else {
                row.fill(T::zero());
                continue;
            };
            row[..r.t0].fill(T::zero());
            row[r.t1..].fill(T::zero());
            let src = &x[ch * len_in..][r.start..];
            if r.stride == 1 {
                row[r.t0..r.t1].copy_from_slice(&src[..r.t1 - r.t0]);
            } else {
                for (d, s) in row[r.t0..r.t1].iter_mut().zip(src.iter().step_by(r.stride)) {
                    *d = *s;
                }
            }
        }
    }
}

/// Calls `f` with the one-channel input `x` zero-padded by `c.padding` on
/// the left and cut or padded on the right to the `len_out + (kernel − 1) ·
/// dilation` samples a stride-1 convolution reads: as a `kernel × len_out`
/// matrix with strides `[dilation, 1]` it is [`unfold`]'s `col` (row `j`,
/// column `t` holds `x[t + j · dilation − padding]`), without writing it out.
fn padded_view<T: Scalar, R>(c: Conv, x: &[T], f: impl FnOnce(&[T]) -> R) -> R {
    let (pad, len_in) = (c.padding as usize, c.len_in as usize);
    let len = c.len_out as usize + (c.kernel as usize - 1) * c.dilation as usize;
    T::with_scratch(len, |xp| {
        xp.fill(T::zero());
        let copied = len_in.min(len.saturating_sub(pad));
        if copied > 0 {
            xp[pad..pad + copied].copy_from_slice(&x[..copied]);
        }
        f(xp)
    })
}

/// The transpose of [`unfold`]: adds every element of `col` to the input
/// sample it was read from.
fn fold_add<T: Float>(c: Conv, col: &[T], out: &mut [T]) {
    let (k, n, len_in) = (c.kernel as usize, c.len_out as usize, c.len_in as usize);
    for ch in 0..c.c_in as usize {
        for j in 0..k {
            let Some(r) = tap_run(c, j) else { continue };
            let src = &col[(ch * k + j) * n..][r.t0..r.t1];
            let dst = &mut out[ch * len_in..][r.start..];
            if r.stride == 1 {
                axpy(T::one(), src, &mut dst[..src.len()]);
            } else {
                for (d, s) in dst.iter_mut().step_by(r.stride).zip(src) {
                    *d = *d + *s;
                }
            }
        }
    }
}

/// The [`Run`] of kernel tap `j`, or `None` when it only meets padding.
fn tap_run(c: Conv, j: usize) -> Option<Run> {
    let stride = (c.stride as usize).max(1);
    let s = stride as i64;
    // Output t reads input position t * stride + off.
    let off = j as i64 * c.dilation as i64 - c.padding as i64;
    let t0 = if off >= 0 { 0 } else { (-off + s - 1) / s };
    let last = c.len_in as i64 - 1 - off;
    let t1 = if last < 0 { 0 } else { (last / s + 1).min(c.len_out as i64) };
    (t0 < t1).then(|| Run { t0: t0 as usize, t1: t1 as usize, start: (t0 * s + off) as usize, stride })
}

/// Calls `f(src, dst)` for every input element `src` of every window `dst`.
fn pool_windows(p: Pool, mut f: impl FnMut(usize, usize)) {
    let u = |x: u32| x as usize;
    for ch in 0..u(p.channels) {
        for o in 0..u(p.len_out) {
            for w in 0..u(p.window) {
                f(ch * u(p.len_in) + o * u(p.stride) + w, ch * u(p.len_out) + o);
            }
        }
    }
}

/// Calls `f(src, dst)` once per window `dst` with `src` the position of the
/// first largest element of `x` in it (NaN never wins against a number; in
/// a window of NaNs only, the last).
fn pool_argmax<T: Float>(p: Pool, x: &[T], mut f: impl FnMut(usize, usize)) {
    let u = |x: u32| x as usize;
    for ch in 0..u(p.channels) {
        for o in 0..u(p.len_out) {
            let start = ch * u(p.len_in) + o * u(p.stride);
            let window = &x[start..start + u(p.window)];
            f(start + window_argmax(window), ch * u(p.len_out) + o);
        }
    }
}

/// The position of the first largest number in `window` (NaN never wins
/// against a number; with no number above -inf, [`window_argmax_slow`]
/// decides). The fast loop is a strict `>` from -inf, which compiles to
/// conditional moves: it picks the first of tied maxima and never a NaN.
fn window_argmax<T: Float>(window: &[T]) -> usize {
    let (mut best, mut top) = (usize::MAX, T::neg_infinity());
    for (w, &v) in window.iter().enumerate() {
        let take = v > top;
        best = if take { w } else { best };
        top = if take { v } else { top };
    }
    if best == usize::MAX {
        window_argmax_slow(window)
    } else {
        best
    }
}

/// [`window_argmax`] for windows of NaN and -inf only: the first -inf if
/// there is one, else the last NaN.
fn window_argmax_slow<T: Float>(window: &[T]) -> usize {
    let (mut best, mut top) = (0, window[0]);
    for (w, v) in window.iter().enumerate().skip(1) {
        if *v > top || top.is_nan() {
            (best, top) = (w, *v);
        }
    }
    best
}

/// Max pooling over non-overlapping windows of 4 in SSE (x86-64's
/// baseline), f32 and f64: a block of windows is loaded and transposed, so
/// each register holds one position of several windows, then the scan of
/// [`window_argmax_slow`] (`v > top || top is NaN`) runs as lane masks, so
/// no branch depends on the data. A profile of the glitch CNN put its
/// pooling at a quarter of f32 inference with the scalar scan.
#[cfg(target_arch = "x86_64")]
mod pool4 {
    use super::{window_argmax, Pool};
    use num_traits::Float;
    use std::arch::x86_64::*;

    /// An SSE register of `LANES` values of `T` and the operations the
    /// blocked scan needs. A block is `LANES` windows of 4: four registers.
    trait Lanes: Copy {
        type T: Float;
        const LANES: usize;
        /// The first `LANES` values of `x`.
        fn load(x: &[Self::T]) -> Self;
        /// Into the first `LANES` values of `x`.
        fn store(self, x: &mut [Self::T]);
        fn splat(v: f64) -> Self;
        fn and(self, o: Self) -> Self;
        fn or(self, o: Self) -> Self;
        /// `!self & o`.
        fn and_not(self, o: Self) -> Self;
        fn add(self, o: Self) -> Self;
        fn gt(self, o: Self) -> Self;
        fn unordered(self, o: Self) -> Self;
        fn eq(self, o: Self) -> Self;
        /// `self > o ? self : o` per lane (SSE's max: `o` when either is
        /// NaN or both are zeros).
        fn max(self, o: Self) -> Self;
        /// Whether any lane of a mask is set.
        fn any(self) -> bool;
        /// A block's four registers in memory order to the four positions
        /// (register `w` holds position `w` of every window in the block).
        fn to_columns(rows: [Self; 4]) -> [Self; 4];
        /// The inverse of [`Lanes::to_columns`].
        fn to_rows(columns: [Self; 4]) -> [Self; 4];
    }

    /// Implements [`Lanes`] for register type `$v` of `$n` values of `$t`
    /// with the named SSE/SSE2 intrinsics and transposes.
    macro_rules! lanes {
        ($v:ty, $t:ty, $n:expr, $load:ident, $store:ident, $set1:ident, $movemask:ident, $columns:ident, $rows:ident,
         $($op:ident: $intrinsic:ident),*) => {
            // SAFETY (every method): SSE and SSE2 are part of x86-64's
            // baseline, and `load`/`store` touch the first `$n` elements of
            // a slice checked to hold them.
            impl Lanes for $v {
                type T = $t;
                const LANES: usize = $n;
                fn load(x: &[$t]) -> Self {
                    unsafe { $load(x[..$n].as_ptr()) }
                }
                fn store(self, x: &mut [$t]) {
                    unsafe { $store(x[..$n].as_mut_ptr(), self) }
                }
                fn splat(v: f64) -> Self {
                    unsafe { $set1(v as $t) }
                }
                $(fn $op(self, o: Self) -> Self {
                    unsafe { $intrinsic(self, o) }
                })*
                fn any(self) -> bool {
                    unsafe { $movemask(self) != 0 }
                }
                fn to_columns(rows: [Self; 4]) -> [Self; 4] {
                    $columns(rows)
                }
                fn to_rows(columns: [Self; 4]) -> [Self; 4] {
                    $rows(columns)
                }
            }
        };
    }

    /// f32: four windows, one per register; a 4 × 4 transpose, its own inverse.
    fn transpose_ps([r0, r1, r2, r3]: [__m128; 4]) -> [__m128; 4] {
        // SAFETY: SSE is part of x86-64's baseline.
        unsafe {
            let (lo01, lo23) = (_mm_unpacklo_ps(r0, r1), _mm_unpacklo_ps(r2, r3));
            let (hi01, hi23) = (_mm_unpackhi_ps(r0, r1), _mm_unpackhi_ps(r2, r3));
            [_mm_movelh_ps(lo01, lo23), _mm_movehl_ps(lo23, lo01), _mm_movelh_ps(hi01, hi23), _mm_movehl_ps(hi23, hi01)]
        }
    }

    /// f64: two windows a, b in memory order [a0 a1], [a2 a3], [b0 b1],
    /// [b2 b3] to [a0 b0], [a1 b1], [a2 b2], [a3 b3].
    fn columns_pd([a01, a23, b01, b23]: [__m128d; 4]) -> [__m128d; 4] {
        // SAFETY: SSE2 is part of x86-64's baseline.
        unsafe { [_mm_unpacklo_pd(a01, b01), _mm_unpackhi_pd(a01, b01), _mm_unpacklo_pd(a23, b23), _mm_unpackhi_pd(a23, b23)] }
    }

    /// The inverse of [`columns_pd`].
    fn rows_pd([c0, c1, c2, c3]: [__m128d; 4]) -> [__m128d; 4] {
        // SAFETY: SSE2 is part of x86-64's baseline.
        unsafe { [_mm_unpacklo_pd(c0, c1), _mm_unpacklo_pd(c2, c3), _mm_unpackhi_pd(c0, c1), _mm_unpackhi_pd(c2, c3)] }
    }

    #[rustfmt::skip]
    lanes!(__m128, f32, 4, _mm_loadu_ps, _mm_storeu_ps, _mm_set1_ps, _mm_movemask_ps, transpose_ps, transpose_ps,
           and: _mm_and_ps, or: _mm_or_ps, and_not: _mm_andnot_ps, add: _mm_add_ps,
           gt: _mm_cmpgt_ps, unordered: _mm_cmpunord_ps, eq: _mm_cmpeq_ps, max: _mm_max_ps);
    #[rustfmt::skip]
    lanes!(__m128d, f64, 2, _mm_loadu_pd, _mm_storeu_pd, _mm_set1_pd, _mm_movemask_pd, columns_pd, rows_pd,
           and: _mm_and_pd, or: _mm_or_pd, and_not: _mm_andnot_pd, add: _mm_add_pd,
           gt: _mm_cmpgt_pd, unordered: _mm_cmpunord_pd, eq: _mm_cmpeq_pd, max: _mm_max_pd);

    /// The block of `4 · LANES` values at the start of `x`, as columns.
    #[inline(always)]
    fn block<V: Lanes>(x: &[V::T]) -> [V; 4] {
        // Written out: `[0, 1, 2, 3].map(..)` was left as a call to
        // `array::try_map` (3 % of the glitch CNN's f32 inference).
        let n = V::LANES;
        V::to_columns([V::load(x), V::load(&x[n..]), V::load(&x[2 * n..]), V::load(&x[3 * n..])])
    }

    /// Per lane (window), the mask of the position its scan ends on.
    #[inline(always)]
    fn winners<V: Lanes>(c: [V; 4]) -> [V; 4] {
        let select = |m: V, x: V, y: V| m.and(x).or(m.and_not(y));
        let (mut top, mut best) = (c[0], V::splat(0.0));
        for (w, &v) in c.iter().enumerate().skip(1) {
            let take = v.gt(top).or(top.unordered(top));
            top = select(take, v, top);
            best = select(take, V::splat(w as f64), best);
        }
        [best.eq(V::splat(0.0)), best.eq(V::splat(1.0)), best.eq(V::splat(2.0)), best.eq(V::splat(3.0))]
    }

    /// Per lane (window), its maximum by a strict `>` scan from −inf: the
    /// value [`winners`] picks (ties keep the first, NaN never wins),
    /// except that a window of NaN and −inf only gives −inf.
    #[inline(always)]
    fn maxima<V: Lanes>(c: [V; 4]) -> V {
        c.iter().fold(V::splat(f64::NEG_INFINITY), |top, &v| v.max(top))
    }

    /// [`super::Scalar::max_pool_vector`] for windows of 4 at stride 4.
    #[inline(always)]
    fn windows_of_4<V: Lanes>(pick: bool, p: Pool, a: &[V::T], b: &[V::T], out: &mut [V::T]) -> bool {
        if p.window != 4 || p.stride != 4 {
            return false;
        }
        let (len_in, len_out) = (p.len_in as usize, p.len_out as usize);
        let (n, span) = (V::LANES, 4 * V::LANES);
        let blocks = len_out / n;
        // Picking a window's maximum from itself (max pooling's forward)
        // needs no positions.
        let own = pick && std::ptr::eq(a, b);
        for ch in 0..p.channels as usize {
            let xa = &a[ch * len_in..][..len_out * 4];
            if own {
                let o = &mut out[ch * len_out..][..len_out];
                for k in 0..blocks {
                    let top = maxima(block::<V>(&xa[span * k..]));
                    if top.eq(V::splat(f64::NEG_INFINITY)).any() {
                        // A window of NaN and −inf only: the scan decides.
                        for i in n * k..n * (k + 1) {
                            o[i] = xa[4 * i + window_argmax(&xa[4 * i..4 * i + 4])];
                        }
                    } else {
                        top.store(&mut o[n * k..]);
                    }
                }
                for i in blocks * n..len_out {
                    o[i] = xa[4 * i + window_argmax(&xa[4 * i..4 * i + 4])];
                }
            } else if pick {
                let xb = &b[ch * len_in..][..len_out * 4];
                let o = &mut out[ch * len_out..][..len_out];
                for k in 0..blocks {
                    let (m, vb) = (winners(block::<V>(&xa[span * k..])), block::<V>(&xb[span * k..]));
                    let mut v = m[0].and(vb[0]);
                    for w in 1..4 {
                        v = v.or(m[w].and(vb[w]));
                    }
                    v.store(&mut o[n * k..]);
                }
                for i in blocks * n..len_out {
                    o[i] = xb[4 * i + window_argmax(&xa[4 * i..4 * i + 4])];
                }
            } else {
                let g = &b[ch * len_out..][..len_out];
                let xo = &mut out[ch * len_in..][..len_out * 4];
                for k in 0..blocks {
                    let gv = V::load(&g[n * k..]);
                    let [m0, m1, m2, m3] = winners(block::<V>(&xa[span * k..]));
                    let rows = V::to_rows([m0.and(gv), m1.and(gv), m2.and(gv), m3.and(gv)]);
                    for (i, r) in rows.into_iter().enumerate() {
                        let dst = &mut xo[span * k + n * i..];
                        V::load(dst).add(r).store(dst);
                    }
                }
                for i in blocks * n..len_out {
                    let src = 4 * i + window_argmax(&xa[4 * i..4 * i + 4]);
                    xo[src] = xo[src] + g[i];
                }
            }
        }
        true
    }

    /// f32 windows of 4: four windows a step.
    pub fn f32_windows_of_4(pick: bool, p: Pool, a: &[f32], b: &[f32], out: &mut [f32]) -> bool {
        windows_of_4::<__m128>(pick, p, a, b, out)
    }

    /// f64 windows of 4: two windows a step.
    pub fn f64_windows_of_4(pick: bool, p: Pool, a: &[f64], b: &[f64], out: &mut [f64]) -> bool {
        windows_of_4::<__m128d>(pick, p, a, b, out)
    }
}

macro_rules! entry_point {
    ($name:ident, $t:ty) => {
        /// Entry point generated kernels call for one tensor op.
        ///
        /// # Safety
        /// `op` must point to a valid [`TensorOp`]; `a`, `b` and `out` to at
        /// least [`TensorOp::operand_lens`] / [`TensorOp::out_len`] elements
        /// (`b` may equal `a` for unary ops); `out` must not overlap them.
        pub unsafe extern "C" fn $name(op: *const TensorOp, a: *const $t, b: *const $t, out: *mut $t) {
            // SAFETY: guaranteed by the caller (the code generator sizes every buffer from the op).
            unsafe {
                let op = *op;
                let [la, lb] = op.operand_lens();
                let a = std::slice::from_raw_parts(a, la);
                let b = if op.arity() == 2 { std::slice::from_raw_parts(b, lb) } else { &[] };
                let out = std::slice::from_raw_parts_mut(out, op.out_len());
                apply(op, a, b, out);
            }
        }
    };
}

entry_point!(gwml_tensor_f64, f64);
entry_point!(gwml_tensor_f32, f32);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ir::Rows;

    fn pseudo_random(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
            })
            .collect()
    }

    fn run(op: TensorOp, a: &[f64], b: &[f64]) -> Vec<f64> {
        let mut out = vec![f64::NAN; op.out_len()];
        apply(op, a, b, &mut out);
        out
    }

    fn inner(x: &[f64], y: &[f64]) -> f64 {
        assert_eq!(x.len(), y.len());
        x.iter().zip(y).map(|(a, b)| a * b).sum()
    }

    fn convs() -> Vec<Conv> {
        let mut out = Vec::new();
        for (c_in, c_out, len_in, kernel, stride, padding, dilation) in [
            (1, 1, 5, 1, 1, 0, 1),
            (2, 3, 11, 3, 1, 1, 1),
            (3, 2, 17, 4, 2, 3, 2),
            (1, 4, 9, 9, 3, 4, 1),
            (2, 2, 8, 3, 4, 0, 3),
            // One channel at stride 1 (read through `padded_view`): padding
            // and dilation, padding wider than the input, no padding.
            (1, 3, 12, 4, 1, 2, 2),
            (1, 2, 3, 5, 1, 4, 1),
            (1, 2, 10, 3, 1, 0, 1),
        ] {
            let span = dilation * (kernel - 1) + 1;
            let len_out = (len_in + 2 * padding - span) / stride + 1;
            out.push(Conv { c_in, c_out, len_in, len_out, kernel, stride, padding, dilation });
        }
        out
    }

    #[test]
    fn matvec_and_outer_match_the_definition() {
        let (m, k) = (3usize, 4usize);
        let w = pseudo_random(m * k, 1);
        let x = pseudo_random(k, 2);
        let y = run(TensorOp::MatVec { m: 3, k: 4 }, &w, &x);
        for r in 0..m {
            let want: f64 = (0..k).map(|c| w[r * k + c] * x[c]).sum();
            assert!((y[r] - want).abs() < 1e-15);
        }
        let outer = run(TensorOp::Outer { m: 3, k: 4 }, &y, &x);
        assert_eq!(outer[2 * k + 1], y[2] * x[1]);
    }

    #[test]
    fn convolution_matches_the_definition() {
        for c in convs() {
            let x = pseudo_random((c.c_in * c.len_in) as usize, 3);
            let w = pseudo_random((c.c_out * c.c_in * c.kernel) as usize, 4);
            let y = run(TensorOp::Conv(c), &x, &w);
            for o in 0..c.c_out as usize {
                for t in 0..c.len_out as usize {
                    let mut want = 0.0;
                    for ch in 0..c.c_in as usize {
                        for j in 0..c.kernel as usize {
                            let pos = (t * c.stride as usize + j * c.dilation as usize) as i64 - c.padding as i64;
                            if (0..c.len_in as i64).contains(&pos) {
                                want += w[weight_index(c, o, ch, j)] * x[ch * c.len_in as usize + pos as usize];
                            }
                        }
                    }
                    assert!((y[o * c.len_out as usize + t] - want).abs() < 1e-14, "{c:?}");
                }
            }
        }
    }

    /// ⟨A x, y⟩ = ⟨x, Aᵀ y⟩ for every op and its transpose(s).
    #[test]
    fn transposes_satisfy_the_adjoint_identity() {
        let close = |l: f64, r: f64| assert!((l - r).abs() <= 1e-12 * (1.0 + l.abs()), "{l} vs {r}");
        let (m, k) = (5u32, 7u32);
        let w = pseudo_random((m * k) as usize, 5);
        let x = pseudo_random(k as usize, 6);
        let y = pseudo_random(m as usize, 7);
        // In x: MatVec vs MatTVec; in W: MatVec vs Outer.
        close(inner(&run(TensorOp::MatVec { m, k }, &w, &x), &y), inner(&x, &run(TensorOp::MatTVec { m, k }, &w, &y)));
        close(inner(&run(TensorOp::MatVec { m, k }, &w, &x), &y), inner(&w, &run(TensorOp::Outer { m, k }, &y, &x)));
        for c in convs() {
            let x = pseudo_random((c.c_in * c.len_in) as usize, 8);
            let w = pseudo_random((c.c_out * c.c_in * c.kernel) as usize, 9);
            let d = pseudo_random((c.c_out * c.len_out) as usize, 10);
            let lhs = inner(&run(TensorOp::Conv(c), &x, &w), &d);
            close(lhs, inner(&x, &run(TensorOp::ConvBackData(c), &d, &w)));
            close(lhs, inner(&w, &run(TensorOp::ConvBackWeight(c), &d, &x)));
        }
        for p in [
            Pool { channels: 2, len_in: 9, len_out: 4, window: 2, stride: 2 },
            Pool { channels: 3, len_in: 10, len_out: 3, window: 4, stride: 3 },
        ] {
            let x = pseudo_random((p.channels * p.len_in) as usize, 11);
            let a = pseudo_random((p.channels * p.len_in) as usize, 12);
            let d = pseudo_random((p.channels * p.len_out) as usize, 13);
            close(inner(&run(TensorOp::PoolPick(p), &x, &a), &d), inner(&a, &run(TensorOp::PoolScatter(p), &x, &d)));
            close(inner(&run(TensorOp::PoolAvg(p), &a, &[]), &d), inner(&a, &run(TensorOp::PoolAvgBack(p), &d, &[])));
        }
        let (rows, cols) = (3u32, 4u32);
        let b = pseudo_random(rows as usize, 14);
        let z = pseudo_random((rows * cols) as usize, 15);
        close(inner(&run(TensorOp::Spread { rows, cols }, &b, &[]), &z), inner(&b, &run(TensorOp::SumRows { rows, cols }, &z, &[])));
        for from in 0..rows {
            let r = Rows { rows, cols, from, count: rows - from };
            let part = pseudo_random(((rows - from) * cols) as usize, 16);
            close(inner(&run(TensorOp::PlaceRows(r), &part, &[]), &z), inner(&part, &run(TensorOp::TakeRows(r), &z, &[])));
        }
    }

    #[test]
    fn max_pooling_takes_the_first_of_tied_maxima() {
        let p = Pool { channels: 1, len_in: 4, len_out: 2, window: 2, stride: 2 };
        let x = [1.0, 1.0, -2.0, 3.0];
        assert_eq!(run(TensorOp::PoolPick(p), &x, &x), vec![1.0, 3.0]);
        assert_eq!(run(TensorOp::PoolScatter(p), &x, &[10.0, 20.0]), vec![10.0, 0.0, 0.0, 20.0]);
    }

    /// NaN never wins against a number, wherever it sits in the window.
    #[test]
    fn max_pooling_passes_over_nan() {
        let p = Pool { channels: 1, len_in: 9, len_out: 3, window: 3, stride: 3 };
        let x = [f64::NAN, -1.0, -3.0, 2.0, f64::NAN, 5.0, 4.0, 4.0, f64::NAN];
        assert_eq!(run(TensorOp::PoolPick(p), &x, &x), vec![-1.0, 5.0, 4.0]);
        let positions = run(TensorOp::PoolScatter(p), &x, &[1.0, 2.0, 3.0]);
        assert_eq!(positions, vec![0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 3.0, 0.0, 0.0]);
    }

    /// The fast argmax agrees with the plain first-largest-number scan on
    /// windows of numbers, NaN and ±inf in every arrangement of 4.
    #[test]
    fn window_argmax_matches_the_plain_scan() {
        let values = [f64::NAN, f64::NEG_INFINITY, -1.0, 0.0, 2.0, f64::INFINITY];
        let n = values.len();
        for code in 0..n.pow(4) {
            let w: Vec<f64> = (0..4).map(|i| values[code / n.pow(i) % n]).collect();
            assert_eq!(window_argmax(&w), window_argmax_slow(&w), "{w:?}");
        }
        assert_eq!(window_argmax(&[f64::NAN, f64::NAN, f64::NAN]), 2, "NaNs only: the last");
        assert_eq!(window_argmax(&[f64::NAN, f64::NEG_INFINITY, f64::NEG_INFINITY]), 1, "the first -inf");
    }

    /// Max pooling over windows of 4 in `T` (vector code on x86-64) picks
    /// and scatters exactly as the window-by-window scan, with NaN, ±inf,
    /// ±0 and ties, in full blocks, in the tail and with input left over
    /// after the last window; so do the maxima of a pick from the input
    /// itself (the forward's own path), windows of NaN and −inf only
    /// included.
    fn windows_of_4_match_the_scan<T: Scalar>() {
        let special = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.5, 0.5, -0.0, 0.0];
        let t = |v: f64| T::from(v).unwrap_or_else(T::nan);
        for (channels, len_in) in [(3u32, 4 * 4 * 9 + 3), (2, 4 * 13), (1, 7), (2, 16), (2, 4 * 3 + 1)] {
            let len_out = len_in / 4;
            let p = Pool { channels, len_in, len_out, window: 4, stride: 4 };
            let mut x: Vec<T> = pseudo_random((channels * len_in) as usize, 21).into_iter().map(t).collect();
            for (i, v) in x.iter_mut().enumerate() {
                if i % 5 == 3 || i % 7 == 0 {
                    *v = t(special[i % special.len()]);
                }
            }
            let g: Vec<T> = pseudo_random((channels * len_out) as usize, 22).into_iter().map(t).collect();
            let y: Vec<T> = x.iter().enumerate().map(|(i, v)| g[i % g.len()] + *v).collect();
            let (mut pick, mut scatter) = (vec![T::zero(); (channels * len_out) as usize], vec![T::zero(); (channels * len_in) as usize]);
            pool_argmax(p, &x, |src, dst| pick[dst] = y[src]);
            pool_argmax(p, &x, |src, dst| scatter[src] = scatter[src] + g[dst]);
            let mut own = vec![T::zero(); pick.len()];
            pool_argmax(p, &x, |src, dst| own[dst] = x[src]);
            // Windows of NaN and −inf only, and zero ties, in the first block.
            let mut edge = x.clone();
            let windows = [
                [f64::NAN; 4],
                [f64::NEG_INFINITY, f64::NAN, f64::NEG_INFINITY, f64::NAN],
                [-0.0, 0.0, -0.0, 0.0],
                [0.0, -0.0, f64::NAN, -0.0],
            ];
            for (w, values) in windows.iter().enumerate().take(len_out as usize) {
                for (j, v) in values.iter().enumerate() {
                    edge[4 * w + j] = t(*v);
                }
            }
            let mut own_edge = vec![T::zero(); pick.len()];
            pool_argmax(p, &edge, |src, dst| own_edge[dst] = edge[src]);
            let (mut got_pick, mut got_scatter) = (vec![T::one(); pick.len()], vec![T::one(); scatter.len()]);
            let (mut got_own, mut got_own_edge) = (vec![T::one(); pick.len()], vec![T::one(); pick.len()]);
            apply(TensorOp::PoolPick(p), &x, &x, &mut got_own);
            apply(TensorOp::PoolPick(p), &edge, &edge, &mut got_own_edge);
            apply(TensorOp::PoolPick(p), &x, &y, &mut got_pick);
            apply(TensorOp::PoolScatter(p), &x, &g, &mut got_scatter);
            let same = |a: &[T], b: &[T]| {
                a.len() == b.len()
                    && a.iter()
                        .zip(b)
                        .all(|(p, q)| p.is_nan() && q.is_nan() || p.to_f64().map(f64::to_bits) == q.to_f64().map(f64::to_bits))
            };
            assert!(same(&got_pick, &pick), "pick, {channels} × {len_in}");
            assert!(same(&got_own, &own), "maxima, {channels} × {len_in}");
            assert!(same(&got_own_edge, &own_edge), "maxima of NaN, -inf and zeros, {channels} × {len_in}");
            assert!(same(&got_scatter, &scatter), "scatter, {channels} × {len_in}");
        }
    }

    #[test]
    fn f32_windows_of_4_match_the_scan() {
        windows_of_4_match_the_scan::<f32>();
    }

    #[test]
    fn f64_windows_of_4_match_the_scan() {
        windows_of_4_match_the_scan::<f64>();
    }

    #[test]
    fn f32_entry_point_matches_f64() {
        let c = convs()[2];
        let x = pseudo_random((c.c_in * c.len_in) as usize, 16);
        let w = pseudo_random((c.c_out * c.c_in * c.kernel) as usize, 17);
        let op = TensorOp::Conv(c);
        let (x32, w32): (Vec<f32>, Vec<f32>) = (x.iter().map(|v| *v as f32).collect(), w.iter().map(|v| *v as f32).collect());
        let mut o64 = vec![0.0f64; op.out_len()];
        let mut o32 = vec![0.0f32; op.out_len()];
        // SAFETY: every buffer has the op's lengths.
        unsafe {
            gwml_tensor_f64(&op, x.as_ptr(), w.as_ptr(), o64.as_mut_ptr());
            gwml_tensor_f32(&op, x32.as_ptr(), w32.as_ptr(), o32.as_mut_ptr());
        }
        for (a, b) in o64.iter().zip(&o32) {
            assert!((a - *b as f64).abs() < 1e-5, "{a} vs {b}");
        }
    }
}
