//! The discrete Fourier transforms of [`Dft`], computed with realfft
//! (rustfft's real-input transforms). Generated kernels call
//! [`gwml_dft_f64`] / [`gwml_dft_f32`] between fused loops; the interpreter
//! calls [`apply`] directly. [`crate::kernels::interp::naive_dft`] is the independent
//! O(n²) definition they are tested against.

use crate::ir::Dft;
use realfft::num_complex::Complex;
use realfft::{ComplexToReal, FftNum, RealFftPlanner, RealToComplex};
use std::sync::Arc;

/// One transform of `n` samples, planned once: what a kernel's call site
/// points at.
pub struct DftPlan<T: FftNum> {
    dft: Dft,
    n: usize,
    forward: Arc<dyn RealToComplex<T>>,
    inverse: Arc<dyn ComplexToReal<T>>,
}

impl<T: FftNum> DftPlan<T> {
    /// Plans `dft` over `n` time samples (`n ≥ 1`).
    pub fn new(dft: Dft, n: usize) -> Self {
        let mut planner = RealFftPlanner::<T>::new();
        let n = n.max(1);
        DftPlan { dft, n, forward: planner.plan_fft_forward(n), inverse: planner.plan_fft_inverse(n) }
    }

    /// Floats of the working memory [`DftPlan::run`] needs.
    pub fn work_floats(&self) -> usize {
        let bins = self.n / 2 + 1;
        let scratch = if self.dft.inverse { self.inverse.get_scratch_len() } else { self.forward.get_scratch_len() };
        (2 * bins).max(self.n) + 2 * scratch
    }

    /// Floats read from the input (`n` reals, or `n/2 + 1` interleaved complex bins).
    pub fn input_floats(&self) -> usize {
        if self.dft.inverse {
            2 * (self.n / 2 + 1)
        } else {
            self.n
        }
    }

    /// Floats written to the output.
    pub fn output_floats(&self) -> usize {
        if self.dft.inverse {
            self.n
        } else {
            2 * (self.n / 2 + 1)
        }
    }

    /// Transforms `input` into `output`, using `work` (at least
    /// [`DftPlan::work_floats`]) as scratch. Never panics on the lengths
    /// [`DftPlan::input_floats`] and [`DftPlan::output_floats`] promise.
    pub fn run(&self, input: &[T], output: &mut [T], work: &mut [T]) {
        let n = self.n;
        let bins = n / 2 + 1;
        let scale = T::from_f64(self.dft.scale()).unwrap_or_else(T::zero);
        let weight = |k: usize| T::from_f64(self.dft.weight(k, n)).unwrap_or_else(T::zero);
        let half = T::from_f64(0.5).unwrap_or_else(T::zero);
        let split = (2 * bins).max(n);
        let (head, scratch) = work.split_at_mut(split);
        let scratch = as_complex(scratch);
        if self.dft.inverse {
            // realfft's inverse sums the Hermitian extension: x_j = Z_0 +
            // 2 Σ Re(Z_k e^{iθ}) + Z_{n/2}(-1)^j. Halving the inner bins gives
            // Σ_k Re(u_k e^{iθ}) with u_k = scale · w_k · Y_k.
            let z = &mut as_complex(head)[..bins];
            let y = as_complex_ref(&input[..2 * bins]);
            for (k, (zk, yk)) in z.iter_mut().zip(y).enumerate() {
                let inner = k != 0 && 2 * k != n;
                let u = *yk * (scale * weight(k));
                *zk = if inner { u * half } else { Complex::new(u.re, T::zero()) };
            }
            let _ = self.inverse.process_with_scratch(z, &mut output[..n], scratch);
        } else {
            let x = &mut head[..n];
            x.copy_from_slice(&input[..n]);
            let y = &mut as_complex(output)[..bins];
            let _ = self.forward.process_with_scratch(x, y, scratch);
            for (k, yk) in y.iter_mut().enumerate() {
                *yk = *yk * (scale * weight(k));
            }
        }
    }
}

fn as_complex<T>(x: &mut [T]) -> &mut [Complex<T>] {
    // SAFETY: Complex<T> is repr(C) { re: T, im: T }: two consecutive Ts with T's alignment.
    unsafe { std::slice::from_raw_parts_mut(x.as_mut_ptr().cast::<Complex<T>>(), x.len() / 2) }
}

fn as_complex_ref<T>(x: &[T]) -> &[Complex<T>] {
    // SAFETY: as in `as_complex`.
    unsafe { std::slice::from_raw_parts(x.as_ptr().cast::<Complex<T>>(), x.len() / 2) }
}

/// Applies `dft` for `n` time samples to `input` (f64; real samples, or
/// complex bins as `Complex64`), returning complex values (real results
/// with zero imaginary parts): the interpreter's entry point.
pub fn apply(dft: Dft, n: usize, input: &[num_complex::Complex64]) -> Vec<num_complex::Complex64> {
    let plan = DftPlan::<f64>::new(dft, n);
    let flat: Vec<f64> = if dft.inverse { input.iter().flat_map(|z| [z.re, z.im]).collect() } else { input.iter().map(|z| z.re).collect() };
    let mut out = vec![0.0; plan.output_floats()];
    let mut work = vec![0.0; plan.work_floats()];
    plan.run(&flat, &mut out, &mut work);
    if dft.inverse {
        out.into_iter().map(|x| num_complex::Complex64::new(x, 0.0)).collect()
    } else {
        out.chunks_exact(2).map(|c| num_complex::Complex64::new(c[0], c[1])).collect()
    }
}

macro_rules! entry_point {
    ($name:ident, $t:ty) => {
        /// The symbol generated kernels call for one transform.
        ///
        /// # Safety
        /// `plan` points at a live [`DftPlan`]; `input`, `output` and `work`
        /// hold at least its input, output and work floats, and do not overlap.
        pub unsafe extern "C" fn $name(plan: *const DftPlan<$t>, input: *const $t, output: *mut $t, work: *mut $t) {
            // SAFETY: guaranteed by the caller (the code generator sizes every buffer from the plan).
            unsafe {
                let plan = &*plan;
                let input = std::slice::from_raw_parts(input, plan.input_floats());
                let output = std::slice::from_raw_parts_mut(output, plan.output_floats());
                let work = std::slice::from_raw_parts_mut(work, plan.work_floats());
                plan.run(input, output, work);
            }
        }
    };
}

entry_point!(gwml_dft_f64, f64);
entry_point!(gwml_dft_f32, f32);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ir::GridId;
    use crate::kernels::interp::naive_dft;
    use num_complex::Complex64 as C64;

    fn pseudo_random(n: usize, seed: u64) -> Vec<f64> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            })
            .collect()
    }

    #[test]
    fn every_kind_matches_the_definition_for_odd_even_and_tiny_lengths() {
        for n in [1usize, 2, 3, 4, 5, 8, 15, 16, 27, 100, 257] {
            for inverse in [false, true] {
                for doubled in [false, true] {
                    let d = Dft { inverse, doubled, scale: 0.37f64.to_bits(), out: GridId(0) };
                    let bins = n / 2 + 1;
                    let r = pseudo_random(2 * n + 2, n as u64);
                    let input: Vec<C64> = if inverse {
                        (0..bins).map(|k| C64::new(r[2 * k], r[2 * k + 1])).collect()
                    } else {
                        r[..n].iter().map(|x| C64::new(*x, 0.0)).collect()
                    };
                    let fast = apply(d, n, &input);
                    let slow = naive_dft(d, &input, n);
                    assert_eq!(fast.len(), slow.len());
                    for (a, b) in fast.iter().zip(&slow) {
                        assert!((a - b).norm() < 1e-13 * (n as f64), "n={n} inverse={inverse} doubled={doubled}: {a} vs {b}");
                    }
                }
            }
        }
    }

    #[test]
    fn rfft_then_irfft_is_the_identity() {
        let n = 64;
        let dt = 1.0 / 64.0;
        let df = 1.0 / (n as f64 * dt);
        let x: Vec<C64> = pseudo_random(n, 7).into_iter().map(|v| C64::new(v, 0.0)).collect();
        let fwd = Dft { inverse: false, doubled: false, scale: dt.to_bits(), out: GridId(1) };
        let inv = Dft { inverse: true, doubled: true, scale: df.to_bits(), out: GridId(0) };
        let back = apply(inv, n, &apply(fwd, n, &x));
        for (a, b) in back.iter().zip(&x) {
            assert!((a - b).norm() < 1e-14, "{a} vs {b}");
        }
    }

    #[test]
    fn f32_entry_point_agrees_with_f64() {
        let n = 48;
        let d = Dft { inverse: false, doubled: true, scale: 0.5f64.to_bits(), out: GridId(0) };
        let x = pseudo_random(n, 3);
        let plan64 = DftPlan::<f64>::new(d, n);
        let plan32 = DftPlan::<f32>::new(d, n);
        let (mut o64, mut w64) = (vec![0.0f64; plan64.output_floats()], vec![0.0f64; plan64.work_floats()]);
        let x32: Vec<f32> = x.iter().map(|v| *v as f32).collect();
        let (mut o32, mut w32) = (vec![0.0f32; plan32.output_floats()], vec![0.0f32; plan32.work_floats()]);
        // SAFETY: buffers sized from the plans.
        unsafe {
            gwml_dft_f64(&plan64, x.as_ptr(), o64.as_mut_ptr(), w64.as_mut_ptr());
            gwml_dft_f32(&plan32, x32.as_ptr(), o32.as_mut_ptr(), w32.as_mut_ptr());
        }
        for (a, b) in o64.iter().zip(&o32) {
            assert!((a - *b as f64).abs() < 1e-5, "{a} vs {b}");
        }
    }
}
