//! The convolution and pooling layers of `learned` components (`conv1d`,
//! `conv2d`, `conv_transpose1d`, `upsample`, `max_pool`, `avg_pool` and
//! their 2-D forms): shapes checked, lowered to [`TensorOp::Conv`] and the
//! pooling ops. PyTorch's layout without a batch axis: `[channels,
//! positions]` in one dimension, `[channels, rows, columns]` in two. A
//! one-dimensional layer is the two-dimensional op with one row
//! ([`Axis::ONE`]), so both share every kernel and adjoint rule.

use super::layers::{channels, dims_of};
use super::{Checker, Tv};
use crate::front::diagnostics::Diagnostic;
use crate::front::source::Span;
use crate::front::units::Dim;
use crate::ir::builder::Builder;
use crate::ir::{Axis, Conv, GridId, Op, Pool, TensorOp, Value};

impl<'a> Checker<'a> {
    /// `conv1d(x, w, b)` (`rank` 1: x `[c_in, n]` or a time series, w
    /// `[c_out, c_in, k]`) and `conv2d(x, w, b)` (`rank` 2: x `[c_in, h, w]`
    /// or `[h, w]`, w `[c_out, c_in, kh, kw]`), with an optional bias
    /// `[c_out]`; stride, padding and dilation apply to every axis.
    pub(super) fn conv(
        &mut self,
        b: &mut Builder,
        x: (Tv, Span),
        w: (Tv, Span),
        bias: Option<(Tv, Span)>,
        (stride, padding, dilation): (u32, u32, u32),
        rank: usize,
    ) -> Option<Tv> {
        let layer = if rank == 1 { "conv1d" } else { "conv2d" };
        let (c_in, rows_in, len_in) = if rank == 1 {
            let (c, n) = channels(b, x.0);
            (c, 1, n)
        } else {
            self.image(b, x, layer)?
        };
        let wd = dims_of(b, w.0);
        if wd.len() != rank + 2 || wd[1] != c_in as usize {
            let mut want = vec![wd.first().copied().unwrap_or(1), c_in as usize];
            want.extend((0..rank).map(|i| wd.get(2 + i).copied().unwrap_or(1)));
            self.expect_dims(b, w, &want, "the weight", layer)?;
        }
        let c_out = wd[0] as u32;
        if let Some(bias) = bias {
            self.expect_dims(b, bias, &[c_out as usize], "the bias", layer)?;
        }
        let mut axis = |len: u32, kernel: u32, what: &str| {
            let axis = Axis::new(len, kernel, stride, padding, dilation);
            if axis.is_none() {
                let span = dilation as u64 * (kernel as u64).saturating_sub(1) + 1;
                let padded = len as u64 + 2 * padding as u64;
                self.error(
                    Diagnostic::error(w.1, format!("the kernel spans {span} {what} but the input has {padded} (with padding)"))
                        .with_help("use a shorter kernel, a smaller dilation or more padding"),
                );
            }
            axis
        };
        let (rows, cols) = if rank == 1 {
            (Axis::ONE, axis(len_in, wd[2] as u32, "samples")?)
        } else {
            (axis(rows_in, wd[2] as u32, "rows")?, axis(len_in, wd[3] as u32, "columns")?)
        };
        let conv = Conv { c_in, c_out, len_in, len_out: cols.len_out, kernel: cols.kernel, stride, padding, dilation, rows };
        let dims = if rank == 1 {
            vec![c_out as usize, cols.len_out as usize]
        } else {
            vec![c_out as usize, rows.len_out as usize, cols.len_out as usize]
        };
        let grid = Self::tensor_grid(b, &dims);
        let y = b.emit(Op::Tensor(TensorOp::Conv(conv), grid, x.0.v, w.0.v));
        Some(Tv { v: self.add_channel_bias(b, y, bias, (c_out, rows.len_out * cols.len_out), grid), dim: Dim::NONE })
    }

    /// `(channels, rows, columns)` of an image for a 2-D layer: `[c, h, w]`,
    /// or `[h, w]` as one channel; anything else is an error.
    fn image(&mut self, b: &Builder, (tv, span): (Tv, Span), layer: &str) -> Option<(u32, u32, u32)> {
        match dims_of(b, tv).as_slice() {
            [c, h, w] => Some((*c as u32, *h as u32, *w as u32)),
            [h, w] => Some((1, *h as u32, *w as u32)),
            d => {
                let shape = d.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(", ");
                self.error(
                    Diagnostic::error(
                        span,
                        format!("`{layer}` needs an image [channels, rows, columns] or [rows, columns], but this has shape [{shape}]"),
                    )
                    .with_label(format!("shape [{shape}]"))
                    .with_help("make one with `reshape(x, c, h, w)` or `reshape(x, h, w)`"),
                );
                None
            }
        }
    }

    /// `y + bias` with one bias per channel of `y` `[channels, positions]`.
    fn add_channel_bias(&self, b: &mut Builder, y: Value, bias: Option<(Tv, Span)>, (rows, cols): (u32, u32), grid: GridId) -> Value {
        match bias {
            Some(bias) => {
                let spread = b.emit(Op::Tensor(TensorOp::Spread { rows, cols }, grid, bias.0.v, bias.0.v));
                b.add(y, spread)
            }
            None => y,
        }
    }

    /// `conv_transpose1d(x, w, b)`: the transpose of `conv1d` in its input,
    /// with PyTorch's layout: x `[c_in, n]`, w `[c_in, c_out, k]`, output
    /// `[c_out, (n − 1)·stride − 2·padding + dilation·(k − 1) + output_padding + 1]`.
    /// Lowers to `ConvBackData` of the convolution it transposes.
    pub(super) fn conv_transpose1d(
        &mut self,
        b: &mut Builder,
        x: (Tv, Span),
        w: (Tv, Span),
        bias: Option<(Tv, Span)>,
        (stride, padding, output_padding, dilation): (u32, u32, u32, u32),
        at: Span,
    ) -> Option<Tv> {
        let (c_in, len_in) = channels(b, x.0);
        let wd = dims_of(b, w.0);
        if wd.len() != 3 || wd[0] != c_in as usize {
            let c_out = wd.get(1).copied().unwrap_or(1);
            let k = wd.get(2).copied().unwrap_or(1);
            self.expect_dims(b, w, &[c_in as usize, c_out, k], "the weight", "conv_transpose1d")?;
        }
        let (c_out, kernel) = (wd[1] as u32, wd[2] as u32);
        if let Some(bias) = bias {
            self.expect_dims(b, bias, &[c_out as usize], "the bias", "conv_transpose1d")?;
        }
        if output_padding >= stride.max(dilation) {
            self.error(
                Diagnostic::error(at, format!("`output_padding` ({output_padding}) must be smaller than the stride or the dilation"))
                    .with_help("it only picks among the output lengths a strided convolution maps to the same input length"),
            );
            return None;
        }
        let full = (len_in as i64 - 1) * stride as i64 + dilation as i64 * (kernel as i64 - 1) + output_padding as i64 + 1;
        let len_out = full - 2 * padding as i64;
        if !(1..1 << 31).contains(&len_out) {
            self.error(
                Diagnostic::error(at, format!("the output would have {len_out} positions: the padding ({padding}) is too large"))
                    .with_help("use less padding, a longer kernel or a larger stride"),
            );
            return None;
        }
        let len_out = len_out as u32;
        // The convolution this op transposes maps `len_out` positions of
        // `c_out` channels to the `len_in` positions of `x`'s `c_in`.
        let conv = Conv { c_in: c_out, c_out: c_in, len_in: len_out, len_out: len_in, kernel, stride, padding, dilation, rows: Axis::ONE };
        let grid = Self::tensor_grid(b, &[c_out as usize, len_out as usize]);
        let y = b.emit(Op::Tensor(TensorOp::ConvBackData(conv), grid, x.0.v, w.0.v));
        Some(Tv { v: self.add_channel_bias(b, y, bias, (c_out, len_out), grid), dim: Dim::NONE })
    }

    /// `upsample(x, factor)`: each position of x `[c, n]` repeated `factor`
    /// times, `[c, n·factor]` (nearest neighbour); the transpose of a mean
    /// over windows of `factor`, times `factor`.
    pub(super) fn upsample(&mut self, b: &mut Builder, x: (Tv, Span), factor: u32) -> Option<Tv> {
        let (channels, n) = channels(b, x.0);
        let Some(len) = n.checked_mul(factor).filter(|l| *l < 1 << 31) else {
            self.error(Diagnostic::error(x.1, format!("upsampling {n} positions by {factor} is too long")));
            return None;
        };
        let p = Pool { channels, len_in: len, len_out: n, window: factor, stride: factor, rows: Axis::ONE };
        let grid = Self::tensor_grid(b, &[channels as usize, len as usize]);
        let spread = b.emit(Op::Tensor(TensorOp::PoolAvgBack(p), grid, x.0.v, x.0.v));
        Some(Tv { v: b.scale(spread, factor as f64), dim: Dim::NONE })
    }

    /// `max_pool`/`avg_pool` (`rank` 1, windows along positions of x
    /// `[c, n]`) and `max_pool2d`/`avg_pool2d` (`rank` 2, square windows of
    /// an image `[c, h, w]`), at `stride`.
    pub(super) fn pool(&mut self, b: &mut Builder, x: (Tv, Span), (window, stride): (u32, u32), max: bool, rank: usize) -> Option<Tv> {
        let (channels, rows_in, len_in) = if rank == 1 {
            let (c, n) = channels(b, x.0);
            (c, 1, n)
        } else {
            self.image(b, x, if max { "max_pool2d" } else { "avg_pool2d" })?
        };
        let (shortest, what) = if rank == 2 && rows_in < len_in { (rows_in, "rows") } else { (len_in, "positions") };
        if window > shortest {
            self.error(
                Diagnostic::error(x.1, format!("the pooling window ({window}) is longer than the input ({shortest} {what})"))
                    .with_help("use a smaller window"),
            );
            return None;
        }
        let rows = if rank == 1 { Axis::ONE } else { Axis::new(rows_in, window, stride, 0, 1)? };
        let len_out = (len_in - window) / stride + 1;
        let p = Pool { channels, len_in, len_out, window, stride, rows };
        let dims = if rank == 1 {
            vec![channels as usize, len_out as usize]
        } else {
            vec![channels as usize, rows.len_out as usize, len_out as usize]
        };
        let grid = Self::tensor_grid(b, &dims);
        let op = if max { TensorOp::PoolPick(p) } else { TensorOp::PoolAvg(p) };
        Some(Tv { v: b.emit(Op::Tensor(op, grid, x.0.v, x.0.v)), dim: Dim::NONE })
    }
}
