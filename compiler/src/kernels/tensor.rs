//! The dense-tensor operations of [`TensorOp`] (the layers of `learned`
//! components) on row-major real arrays. Generated kernels call
//! [`gwml_tensor_f64`] / [`gwml_tensor_f32`] between fused loops; the
//! interpreter calls [`apply`]. Every transpose op is tested here against
//! the definition `⟨A x, y⟩ = ⟨x, Aᵀ y⟩`, which is what makes the adjoint
//! pass's rules correct.

use crate::ir::{Axis, Conv, Pool, TensorOp};
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
        // `col` (`c_in · taps` rows of one value per output position, see
        // `unfold`): y = W col, dW = dy colᵀ, and dx = fold(Wᵀ dy).
        // One row and one input channel at stride 1: the unfolded input is
        // a sliding view of the zero-padded input (`padded_view`), read in
        // place.
        TensorOp::Conv(c) if c.c_in == 1 && c.stride == 1 && c.rows == Axis::ONE => {
            let (k, n, dil) = (u(c.kernel), u(c.len_out), u(c.dilation));
            padded_view(c, a, |xp| T::gemm([u(c.c_out), k, n], b, [k, 1], xp, [dil, 1], T::zero(), out, n));
        }
        TensorOp::ConvBackWeight(c) if c.c_in == 1 && c.stride == 1 && c.rows == Axis::ONE => {
            let (k, n, dil) = (u(c.kernel), u(c.len_out), u(c.dilation));
            padded_view(c, b, |xp| T::gemm([u(c.c_out), n, k], a, [n, 1], xp, [1, dil], T::zero(), out, k));
        }
        TensorOp::Conv(c) => {
            let (rows, n) = (u(c.c_in) * c.taps(), u(c.rows.len_out) * u(c.len_out));
            T::with_scratch(rows * n, |col| {
                unfold(c, a, col);
                T::gemm([u(c.c_out), rows, n], b, [rows, 1], col, [n, 1], T::zero(), out, n);
            });
        }
        TensorOp::ConvBackWeight(c) => {
            let (rows, n) = (u(c.c_in) * c.taps(), u(c.rows.len_out) * u(c.len_out));
            T::with_scratch(rows * n, |col| {
                unfold(c, b, col);
                T::gemm([u(c.c_out), n, rows], a, [n, 1], col, [1, n], T::zero(), out, rows);
            });
        }
        TensorOp::ConvBackData(c) => {
            let (rows, n) = (u(c.c_in) * c.taps(), u(c.rows.len_out) * u(c.len_out));
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
            let inv = T::one() / T::from(p.window_len()).unwrap_or_else(T::one);
            pool_windows(p, |src, dst| out[dst] = out[dst] + a[src] * inv);
        }
        TensorOp::PoolAvgBack(p) => {
            let inv = T::one() / T::from(p.window_len()).unwrap_or_else(T::one);
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

/// Index of weight `(o, c, i, j)` in the row-major `c_out × c_in × rows × kernel` array.
#[cfg(test)]
fn weight_index(c: Conv, o: usize, ch: usize, i: usize, j: usize) -> usize {
    ((o * c.c_in as usize + ch) * c.rows.kernel as usize + i) * c.kernel as usize + j
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

/// Unfolds (im2col) input `x` (`c_in × rows × len_in`) into `col`: row
/// `(c · kernel rows + i) · kernel + j` of which holds, for every output
/// position `(r, t)` in row-major order, the input sample tap `(i, j)` of
/// channel `c` multiplies there (0 in the padding).
fn unfold<T: Float>(c: Conv, x: &[T], col: &mut [T]) {
    let (kh, kw) = (c.rows.kernel as usize, c.kernel as usize);
    let (wi, wo) = (c.len_in as usize, c.len_out as usize);
    let n = c.rows.len_out as usize * wo;
    for ch in 0..c.c_in as usize {
        for i in 0..kh {
            for j in 0..kw {
                let row = &mut col[((ch * kh + i) * kw + j) * n..][..n];
                let run = tap_run(c, j);
                for (r, seg) in row.chunks_exact_mut(wo).enumerate() {
                    let (Some(run), Some(y)) = (run, input_row(c, r, i)) else {
                        seg.fill(T::zero());
                        continue;
                    };
                    seg[..run.t0].fill(T::zero());
                    seg[run.t1..].fill(T::zero());
                    let src = &x[(ch * c.rows.len_in as usize + y) * wi..][run.start..];
                    if run.stride == 1 {
                        seg[run.t0..run.t1].copy_from_slice(&src[..run.t1 - run.t0]);
                    } else {
                        for (d, s) in seg[run.t0..run.t1].iter_mut().zip(src.iter().step_by(run.stride)) {
                            *d = *s;
                        }
                    }
                }
            }
        }
    }
}

/// The input row kernel row `i` reads for output row `r`, or `None` in the
/// padding.
fn input_row(c: Conv, r: usize, i: usize) -> Option<usize> {
    let a = c.rows;
    let y = (r * a.stride as usize + i * a.dilation as usize).checked_sub(a.padding as usize)?;
    (y < a.len_in as usize).then_some(y)
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
    let (kh, kw) = (c.rows.kernel as usize, c.kernel as usize);
    let (wi, wo) = (c.len_in as usize, c.len_out as usize);
    let n = c.rows.len_out as usize * wo;
    for ch in 0..c.c_in as usize {
        for i in 0..kh {
            for j in 0..kw {
                let Some(run) = tap_run(c, j) else { continue };
                let row = &col[((ch * kh + i) * kw + j) * n..][..n];
                for (r, seg) in row.chunks_exact(wo).enumerate() {
                    let Some(y) = input_row(c, r, i) else { continue };
                    let src = &seg[run.t0..run.t1];
                    let dst = &mut out[(ch * c.rows.len_in as usize + y) * wi..][run.start..];
                    if run.stride == 1 {
                        axpy(T::one(), src, &mut dst[..src.len()]);
                    } else {
                        for (d, s) in dst.iter_mut().step_by(run.stride).zip(src) {
                            *d = *d + *s;
                        }
                    }
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
    let (wi, wo, ho) = (u(p.len_in), u(p.len_out), u(p.rows.len_out));
    for ch in 0..u(p.channels) {
        for r in 0..ho {
            let top = (ch * u(p.rows.len_in) + r * u(p.rows.stride)) * wi;
            for o in 0..wo {
                let dst = (ch * ho + r) * wo + o;
                for i in 0..u(p.rows.kernel) {
                    for w in 0..u(p.window) {
                        f(top + i * wi + o * u(p.stride) + w, dst);
                    }
                }
            }
        }
    }
}

/// Calls `f(src, dst)` once per window `dst` with `src` the position of the
/// first largest element of `x` in it, in row-major order (NaN never wins
/// against a number; in a window of NaNs only, the last).
fn pool_argmax<T: Float>(p: Pool, x: &[T], mut f: impl FnMut(usize, usize)) {
    let u = |x: u32| x as usize;
    let (wi, wo, ho, win) = (u(p.len_in), u(p.len_out), u(p.rows.len_out), u(p.window));
    let mut gathered = Vec::with_capacity(p.window_len());
    for ch in 0..u(p.channels) {
        for r in 0..ho {
            let top = (ch * u(p.rows.len_in) + r * u(p.rows.stride)) * wi;
            for o in 0..wo {
                let (start, dst) = (top + o * u(p.stride), (ch * ho + r) * wo + o);
                if p.rows.kernel == 1 {
                    f(start + window_argmax(&x[start..start + win]), dst);
                } else {
                    // A window of several rows is not contiguous: scan a copy.
                    gathered.clear();
                    for i in 0..u(p.rows.kernel) {
                        gathered.extend_from_slice(&x[start + i * wi..][..win]);
                    }
                    let k = window_argmax(&gathered);
                    f(start + (k / win) * wi + k % win, dst);
                }
            }
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
    use super::{window_argmax, Axis, Pool};
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
        if p.window != 4 || p.stride != 4 || p.rows != Axis::ONE {
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
mod tests;
