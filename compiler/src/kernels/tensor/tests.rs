//! Tests of the tensor kernels: every transpose against ⟨A x, y⟩ = ⟨x, Aᵀ y⟩,
//! the fast paths against the plain scans.

use super::*;
use crate::ir::{Axis, Rows};

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
        let len_out = Axis::new(len_in, kernel, stride, padding, dilation).expect("a valid axis").len_out;
        out.push(Conv { c_in, c_out, len_in, len_out, kernel, stride, padding, dilation, rows: Axis::ONE });
    }
    // Two dimensions: square and oblong kernels, stride, padding and
    // dilation per axis, a kernel row that only meets padding, one column.
    for ((c_in, c_out), (rows, kh, sh, ph, dh), (len_in, kernel, stride, padding, dilation)) in [
        ((1, 2), (5, 3, 1, 1, 1), (6, 3, 1, 1, 1)),
        ((2, 3), (7, 2, 2, 0, 1), (9, 3, 2, 1, 2)),
        ((3, 2), (4, 3, 1, 2, 2), (5, 1, 1, 0, 1)),
        ((1, 1), (6, 1, 3, 0, 1), (1, 1, 1, 0, 1)),
        ((2, 4), (8, 4, 2, 3, 1), (8, 4, 2, 3, 1)),
    ] {
        let len_out = Axis::new(len_in, kernel, stride, padding, dilation).expect("a valid axis").len_out;
        let rows = Axis::new(rows, kh, sh, ph, dh).expect("a valid axis");
        out.push(Conv { c_in, c_out, len_in, len_out, kernel, stride, padding, dilation, rows });
    }
    out
}

fn pools() -> Vec<Pool> {
    let mut out = Vec::new();
    for (channels, (rows, kh, sh), (len_in, window, stride)) in [
        (2, (1, 1, 1), (9, 2, 2)),
        (3, (1, 1, 1), (10, 4, 3)),
        (2, (6, 2, 2), (7, 3, 2)),
        (1, (5, 3, 1), (4, 2, 1)),
        (3, (9, 4, 4), (8, 4, 4)),
    ] {
        let len_out = (len_in - window) / stride + 1;
        let rows = Axis::new(rows, kh, sh, 0, 1).expect("a valid axis");
        out.push(Pool { channels, len_in, len_out, window, stride, rows });
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

/// PyTorch's `conv1d` and `conv2d` (cross-correlation, zero padding), term
/// by term.
#[test]
fn convolution_matches_the_definition() {
    let u = |x: u32| x as usize;
    for c in convs() {
        let x = pseudo_random(c.input_len(), 3);
        let w = pseudo_random(c.weight_len(), 4);
        let y = run(TensorOp::Conv(c), &x, &w);
        let (hi, wi, ho, wo) = (u(c.rows.len_in), u(c.len_in), u(c.rows.len_out), u(c.len_out));
        for o in 0..u(c.c_out) {
            for r in 0..ho {
                for t in 0..wo {
                    let mut want = 0.0;
                    for ch in 0..u(c.c_in) {
                        for i in 0..u(c.rows.kernel) {
                            for j in 0..u(c.kernel) {
                                let row = (r * u(c.rows.stride) + i * u(c.rows.dilation)) as i64 - c.rows.padding as i64;
                                let col = (t * u(c.stride) + j * u(c.dilation)) as i64 - c.padding as i64;
                                if (0..hi as i64).contains(&row) && (0..wi as i64).contains(&col) {
                                    want += w[weight_index(c, o, ch, i, j)] * x[(ch * hi + row as usize) * wi + col as usize];
                                }
                            }
                        }
                    }
                    assert!((y[(o * ho + r) * wo + t] - want).abs() < 1e-14, "{c:?}");
                }
            }
        }
    }
}

/// Max and average pooling in two dimensions, window by window.
#[test]
fn pooling_matches_the_definition() {
    let u = |x: u32| x as usize;
    for p in pools() {
        let x = pseudo_random(p.input_len(), 23);
        let (max, avg) = (run(TensorOp::PoolPick(p), &x, &x), run(TensorOp::PoolAvg(p), &x, &[]));
        let (hi, wi, ho, wo) = (u(p.rows.len_in), u(p.len_in), u(p.rows.len_out), u(p.len_out));
        for ch in 0..u(p.channels) {
            for r in 0..ho {
                for o in 0..wo {
                    let window: Vec<f64> = (0..u(p.rows.kernel))
                        .flat_map(|i| (0..u(p.window)).map(move |j| (i, j)))
                        .map(|(i, j)| x[(ch * hi + r * u(p.rows.stride) + i) * wi + o * u(p.stride) + j])
                        .collect();
                    let at = (ch * ho + r) * wo + o;
                    assert_eq!(max[at], window.iter().cloned().fold(f64::NEG_INFINITY, f64::max), "{p:?}");
                    assert!((avg[at] - window.iter().sum::<f64>() / window.len() as f64).abs() < 1e-15, "{p:?}");
                }
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
        let x = pseudo_random(c.input_len(), 8);
        let w = pseudo_random(c.weight_len(), 9);
        let d = pseudo_random(c.output_len(), 10);
        let lhs = inner(&run(TensorOp::Conv(c), &x, &w), &d);
        close(lhs, inner(&x, &run(TensorOp::ConvBackData(c), &d, &w)));
        close(lhs, inner(&w, &run(TensorOp::ConvBackWeight(c), &d, &x)));
    }
    for p in pools() {
        let x = pseudo_random(p.input_len(), 11);
        let a = pseudo_random(p.input_len(), 12);
        let d = pseudo_random(p.output_len(), 13);
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
    let p = Pool { channels: 1, len_in: 4, len_out: 2, window: 2, stride: 2, rows: Axis::ONE };
    let x = [1.0, 1.0, -2.0, 3.0];
    assert_eq!(run(TensorOp::PoolPick(p), &x, &x), vec![1.0, 3.0]);
    assert_eq!(run(TensorOp::PoolScatter(p), &x, &[10.0, 20.0]), vec![10.0, 0.0, 0.0, 20.0]);
    // 2 × 2 windows of a 2 × 4 image: the first in row-major order wins.
    let p = Pool { rows: Axis::new(2, 2, 2, 0, 1).expect("a valid axis"), ..p };
    let x = [0.0, 5.0, 1.0, 2.0, 5.0, 5.0, 2.0, 1.0];
    assert_eq!(run(TensorOp::PoolPick(p), &x, &x), vec![5.0, 2.0]);
    assert_eq!(run(TensorOp::PoolScatter(p), &x, &[10.0, 20.0]), vec![0.0, 10.0, 0.0, 20.0, 0.0, 0.0, 0.0, 0.0]);
}

/// NaN never wins against a number, wherever it sits in the window.
#[test]
fn max_pooling_passes_over_nan() {
    let p = Pool { channels: 1, len_in: 9, len_out: 3, window: 3, stride: 3, rows: Axis::ONE };
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
        let p = Pool { channels, len_in, len_out, window: 4, stride: 4, rows: Axis::ONE };
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
                && a.iter().zip(b).all(|(p, q)| p.is_nan() && q.is_nan() || p.to_f64().map(f64::to_bits) == q.to_f64().map(f64::to_bits))
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
    let x = pseudo_random(c.input_len(), 16);
    let w = pseudo_random(c.weight_len(), 17);
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
