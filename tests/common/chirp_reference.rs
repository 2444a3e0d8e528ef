//! `examples/chirp_fit.gw` written by hand in plain Rust, with its gradient
//! derived by hand: the independent reference for end-to-end tests and the
//! baseline the benchmark compares the JIT against.

#![allow(dead_code)]

use std::f64::consts::PI;

/// LAL_MTSUN_SI: solar mass in seconds.
pub const MTSUN: f64 = 4.925_490_947_641_267e-6;
/// Grid of the example: 20..=1024 Hz in steps of 0.125 Hz.
pub const F_MIN: f64 = 20.0;
/// Bin width.
pub const DF: f64 = 0.125;
/// Number of bins.
pub const N: usize = 8033;

/// Frequency of bin `k`.
pub fn freq(k: usize) -> f64 {
    F_MIN + k as f64 * DF
}

/// SPA phase Ψ(f) and its derivative with respect to mc.
fn phase(f: f64, mc: f64, tc: f64, phic: f64) -> (f64, f64) {
    let x = PI * mc * MTSUN * f;
    let psi = 2.0 * PI * f * tc - phic - PI / 4.0 + 3.0 / 128.0 * x.powf(-5.0 / 3.0);
    let dpsi_dmc = 3.0 / 128.0 * (-5.0 / 3.0) * x.powf(-8.0 / 3.0) * PI * MTSUN * f;
    (psi, dpsi_dmc)
}

/// The chirp h(f) = A (f/100)^(-7/6) e^{-iΨ} as (re, im), with its mc-derivative of Ψ.
pub fn chirp(f: f64, mc: f64, tc: f64, phic: f64) -> (f64, f64, f64) {
    let amp = 0.01 * (f / 100.0).powf(-7.0 / 6.0);
    let (psi, dpsi) = phase(f, mc, tc, phic);
    let (s, c) = psi.sin_cos();
    (amp * c, -amp * s, dpsi)
}

/// The toy PSD of the example.
pub fn psd(f: f64) -> f64 {
    let y = f / 150.0;
    1e-4 * (y.powi(-4) + 2.0 + 2.0 * y * y)
}

/// The example's default data (the chirp at mc = 30, tc = 0.002, phic = 0.3), interleaved re/im.
pub fn default_data() -> Vec<f64> {
    (0..N)
        .flat_map(|k| {
            let (re, im, _) = chirp(freq(k), 30.0, 0.002, 0.3);
            [re, im]
        })
        .collect()
}

/// Loss 0.5 (d-h|d-h) of the example.
pub fn loss(data: &[f64], mc: f64, tc: f64, phic: f64) -> f64 {
    let mut s = 0.0;
    for k in 0..N {
        let f = freq(k);
        let (hr, hi, _) = chirp(f, mc, tc, phic);
        let (rr, ri) = (data[2 * k] - hr, data[2 * k + 1] - hi);
        s += (rr * rr + ri * ri) / psd(f);
    }
    0.5 * 4.0 * DF * s
}

/// Loss and its gradient with respect to (mc, tc, phic), derived by hand:
/// ∂L/∂θ = -4 df Σ Re(conj(d-h) ∂h/∂θ) / S with ∂h/∂θ = -i h ∂Ψ/∂θ.
pub fn loss_and_grad(data: &[f64], mc: f64, tc: f64, phic: f64) -> (f64, [f64; 3]) {
    let (mut s, mut g) = (0.0, [0.0; 3]);
    for k in 0..N {
        let f = freq(k);
        let (hr, hi, dpsi_dmc) = chirp(f, mc, tc, phic);
        let w = 1.0 / psd(f);
        let (rr, ri) = (data[2 * k] - hr, data[2 * k + 1] - hi);
        s += (rr * rr + ri * ri) * w;
        // Re(conj(r) · (-i h)) = rr·hi - ri·hr
        let q = (rr * hi - ri * hr) * w;
        g[0] += q * dpsi_dmc;
        g[1] += q * 2.0 * PI * f;
        g[2] -= q;
    }
    let c = -4.0 * DF;
    (0.5 * 4.0 * DF * s, [c * g[0], c * g[1], c * g[2]])
}
