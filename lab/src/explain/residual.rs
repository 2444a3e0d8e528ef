//! Starts built on another family's fit: a Koi Fish is a long,
//! low-frequency head — a Tomte's shape, which the Tomte fit has already
//! found — and a blip 5–60 ms after it. Where the head outshines the blip
//! in the data, starts seeded from the loudest pixels land on the head and
//! the Koi Fish fit drops its blip (the head's amplitude runs to its bound),
//! so the window goes to the Tomte. Here the blip is looked for in what the
//! Tomte fit leaves: the whitened residual's best sine-Gaussian matches
//! (not whitened again: above 60 Hz the whitened PSD is nearly flat over a
//! blip's band) over the lead's range of times.

use super::{FamilyFit, Start};
use std::f64::consts::{PI, TAU};

/// The Koi Fish's blip follows its head by this much (s): the scene's
/// bounds on `lead`.
const LEAD: (f64, f64) = (0.005, 0.06);
/// Blip frequencies (Hz) and Qs searched: the scene's bounds, 12 % apart.
const BLIP_F0: (f64, f64) = (60.0, 300.0);
const BLIP_F0_RATIO: f64 = 1.12;
const BLIP_Q: [f64; 3] = [1.2, 2.0, 3.5];
/// Blips kept, and head-to-blip amplitude ratios tried with each.
const BLIPS: usize = 3;
const HEADS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

/// Koi Fish starts from the Tomte fit `head` to the whitened window `d` (at
/// `fs` Hz): the head's time, frequency, Q and tail from the fit, and the
/// [`BLIPS`] best sine-Gaussians in the residual `d − head.model` within
/// the lead's range after it, each with a few head amplitudes. As
/// `(dt, [f0, q, f_head, head, lead, q_head, tail, drift])`.
pub fn koi_fish_from_head(head: &FamilyFit, d: &[f64], fs: f64) -> Vec<Start> {
    let value = |name: &str| head.param(name).map(|p| p.value);
    let (Some(dt_head), Some(f_head), Some(q_head), Some(tail)) = (value("dt"), value("f0"), value("q"), value("asym")) else {
        return Vec::new();
    };
    if head.model.len() != d.len() {
        return Vec::new();
    }
    let residual: Vec<f64> = d.iter().zip(&head.model).map(|(d, m)| d - m).collect();
    let blips = loudest_blips(&residual, fs, (dt_head + LEAD.0, dt_head + LEAD.1), BLIPS);
    blips.into_iter().flat_map(|(dt, f0, q)| HEADS.map(|ratio| (dt, vec![f0, q, f_head, ratio, dt - dt_head, q_head, tail, 0.0]))).collect()
}

/// The `keep` best sine-Gaussian matches to `x` (at `fs` Hz) centred
/// within `times` (s from the window's centre), at most one per
/// frequency and Q: `(dt, f0, q)`, best first.
fn loudest_blips(x: &[f64], fs: f64, times: (f64, f64), keep: usize) -> Vec<(f64, f64, f64)> {
    let centre = 0.5 * x.len() as f64 / fs;
    let first = ((centre + times.0) * fs).round().max(0.0) as usize;
    let last = (((centre + times.1) * fs).round() as usize).min(x.len().saturating_sub(1));
    let mut found: Vec<(f64, f64, f64, f64)> = Vec::new();
    let f0s = std::iter::successors(Some(BLIP_F0.0), |f| Some(f * BLIP_F0_RATIO)).take_while(|f| *f <= BLIP_F0.1);
    for f0 in f0s {
        for q in BLIP_Q {
            // The envelope's 1/e half-width (std::burst's sg_tau); three of them each side.
            let tau = q / (2f64.sqrt() * PI * f0);
            let reach = (3.0 * tau * fs).ceil() as i64;
            let template: Vec<(f64, f64, f64)> = (-reach..=reach)
                .map(|k| {
                    let s = k as f64 / fs;
                    let (sin, cos) = (TAU * f0 * s).sin_cos();
                    ((-(s / tau).powi(2)).exp(), cos, sin)
                })
                .collect();
            let norm: f64 = template.iter().map(|(w, ..)| 0.5 * w * w).sum::<f64>().sqrt();
            let mut best = (0.0, 0);
            for i in first..=last {
                let (mut re, mut im) = (0.0, 0.0);
                for (j, (w, cos, sin)) in template.iter().enumerate() {
                    let k = i as i64 + j as i64 - reach;
                    if let Some(v) = usize::try_from(k).ok().and_then(|k| x.get(k)) {
                        re += v * w * cos;
                        im += v * w * sin;
                    }
                }
                let m = re.hypot(im) / norm;
                if m > best.0 {
                    best = (m, i);
                }
            }
            found.push((best.0, best.1 as f64 / fs - centre, f0, q));
        }
    }
    found.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut kept: Vec<(f64, f64, f64)> = Vec::with_capacity(keep);
    for (_, dt, f0, q) in found {
        if kept.len() == keep {
            break;
        }
        // Neighbours in frequency and time are the same blip.
        if kept.iter().all(|k| (f0 / k.1).ln().abs() > 0.2 || (dt - k.0).abs() > 0.005) {
            kept.push((dt, f0, q));
        }
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::super::test_support::at_snr_in_white_noise;
    use super::*;

    #[test]
    fn a_blip_under_a_louder_head_is_found_in_the_residual() {
        // Unit white noise at 4096 Hz with a blip at 150 Hz, Q 1.8, 23 ms
        // after the window's centre + 0.05 s, SNR 15; the head is taken as
        // already subtracted. The best match sits on the blip.
        let (n, fs) = (8192, 4096.0);
        let (t_blip, f0, q) = (1.0 + 0.05 + 0.023, 150.0, 1.8);
        let tau = q / (2f64.sqrt() * PI * f0);
        let blip: Vec<f64> = (0..n)
            .map(|k| {
                let s = k as f64 / fs - t_blip;
                (-(s / tau).powi(2)).exp() * (TAU * f0 * s + 0.3).cos()
            })
            .collect();
        let x = at_snr_in_white_noise(&blip, 15.0, 11);
        let blips = loudest_blips(&x, fs, (0.05 + LEAD.0, 0.05 + LEAD.1), 3);
        assert_eq!(blips.len(), 3);
        let (dt, f, _) = blips[0];
        assert!((dt - 0.073).abs() < 0.002, "time {dt}: {blips:?}");
        assert!((f / f0 - 1.0).abs() < 0.15, "frequency {f}: {blips:?}");
    }
}
