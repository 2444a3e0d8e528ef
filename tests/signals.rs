//! Time-domain signals, transforms and filters of the standard library
//! (`std::burst`, `std::detector`'s time-series modules,
//! `std::taylorf2::tf2_strain_td`), each against an independent reference:
//! Fourier integrals by quadrature in this file, statistics of seeded noise,
//! and the Cauchy–Schwarz bound of the matched filter.

use gwml::{Model, Value};
use num_complex::Complex64 as C64;
use std::f64::consts::PI;

fn real_array(v: Result<&Value, gwml::Error>) -> Vec<f64> {
    match v {
        Ok(Value::RealArray(x)) => x.clone(),
        other => panic!("expected a real array, got {other:?}"),
    }
}

fn complex_array(v: Result<&Value, gwml::Error>) -> Vec<C64> {
    match v {
        Ok(Value::ComplexArray(x)) => x.clone(),
        other => panic!("expected a complex array, got {other:?}"),
    }
}

/// ∫ h(t) e^{-2πi f t} dt over [a, b] by composite Simpson with `n` (even) panels.
fn fourier_integral(h: impl Fn(f64) -> f64, f: f64, a: f64, b: f64, n: usize) -> C64 {
    let step = (b - a) / n as f64;
    let term = |t: f64| C64::from_polar(h(t), -2.0 * PI * f * t);
    let mut s = term(a) + term(b);
    for i in 1..n {
        s += term(a + i as f64 * step) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    s * step / 3.0
}

const FD_SOURCE: &str = "use std::burst::{sine_gaussian_fd, ringdown_fd}
scene fd {
    grid f = frequencies(from: 10 Hz, to: 400 Hz, step: 3.9 Hz)
    param f0: Hz = 120.0
    param q = 8.0
    param tau: s = 0.01
    param phi = 0.7
    output sg = sine_gaussian_fd(f, 0.3 s, f0, q, 2.0, phi)
    output rd = ringdown_fd(f, 0.3 s, f0, tau, 2.0, phi)
}";

#[test]
fn frequency_domain_bursts_are_the_fourier_integrals_of_the_time_domain_forms() {
    let model = Model::from_source("fd.gw", FD_SOURCE).unwrap();
    let scene = model.scene(None).unwrap();
    for (f0, q, tau, phi) in [(120.0, 8.0, 0.01, 0.7), (60.0, 3.0, 0.05, -1.2), (300.0, 20.0, 0.003, 0.0)] {
        let mut run = scene.bind();
        run.param("f0", f0).unwrap().param("q", q).unwrap().param("tau", tau).unwrap().param("phi", phi).unwrap();
        let out = run.forward().unwrap();
        let (sg, rd) = (complex_array(out.value("sg")), complex_array(out.value("rd")));
        let t0 = 0.3;
        let width = q / (2f64.sqrt() * PI * f0);
        let sg_t = |t: f64| 2.0 * (-((t - t0) / width).powi(2)).exp() * (2.0 * PI * f0 * (t - t0) + phi).cos();
        let rd_t = |t: f64| 2.0 * (-(t - t0) / tau).exp() * (2.0 * PI * f0 * (t - t0) + phi).cos();
        let peak_sg = sg.iter().map(|z| z.norm()).fold(0.0, f64::max);
        let peak_rd = rd.iter().map(|z| z.norm()).fold(0.0, f64::max);
        for (k, (got_sg, got_rd)) in sg.iter().zip(&rd).enumerate() {
            let f = 10.0 + 3.9 * k as f64;
            let want_sg = fourier_integral(sg_t, f, t0 - 12.0 * width, t0 + 12.0 * width, 40_000);
            let want_rd = fourier_integral(rd_t, f, t0, t0 + 60.0 * tau, 200_000);
            assert!((got_sg - want_sg).norm() <= 1e-9 * peak_sg, "sine-Gaussian at {f} Hz: {got_sg} vs {want_sg}");
            assert!((got_rd - want_rd).norm() <= 1e-9 * peak_rd, "ring-down at {f} Hz: {got_rd} vs {want_rd}");
        }
    }
}

const TD_SOURCE: &str = "use std::burst::{sine_gaussian, sine_gaussian_fd}
scene td {
    grid t = times(rate: 2048 Hz, duration: 1 s)
    grid f = spectrum(t)
    param f0: Hz = 150.0
    param q = 9.0
    output x = rfft(sine_gaussian(t, 0.4 s, f0, q, 1.0, 0.3), f)
    output y = sine_gaussian_fd(f, 0.4 s, f0, q, 1.0, 0.3)
    output back = irfft(sine_gaussian_fd(f, 0.4 s, f0, q, 1.0, 0.3), t)
    output direct = sine_gaussian(t, 0.4 s, f0, q, 1.0, 0.3)
}";

/// A well-sampled burst that decays inside the segment: the DFT of its
/// samples (rfft's dt normalisation) equals the continuous transform, and
/// irfft of the analytic spectrum gives back the samples.
#[test]
fn rfft_of_a_sampled_sine_gaussian_is_its_analytic_transform() {
    let model = Model::from_source("td.gw", TD_SOURCE).unwrap();
    let scene = model.scene(None).unwrap();
    for (f0, q) in [(150.0, 9.0), (40.0, 4.0), (700.0, 30.0)] {
        let mut run = scene.bind();
        run.param("f0", f0).unwrap().param("q", q).unwrap();
        let out = run.forward().unwrap();
        let (x, y) = (complex_array(out.value("x")), complex_array(out.value("y")));
        assert_eq!(x.len(), 1025);
        let peak = y.iter().map(|z| z.norm()).fold(0.0, f64::max);
        for (k, (a, b)) in x.iter().zip(&y).enumerate() {
            assert!((a - b).norm() <= 1e-10 * peak, "f0 = {f0}, bin {k}: {a} vs {b}");
        }
        let (back, direct) = (real_array(out.value("back")), real_array(out.value("direct")));
        for (a, b) in back.iter().zip(&direct) {
            assert!((a - b).abs() <= 1e-10, "irfft of the analytic spectrum: {a} vs {b}");
        }
    }
}

const WHITEN_SOURCE: &str = "use std::detector::{whiten, bandpass}
use std::psd::{psd_aligo_zerodet_highpower}
scene whitening {
    grid t = times(rate: 4096 Hz, duration: 4 s)
    grid f = spectrum(t)
    input n: complex[f] s
    let psd = psd_aligo_zerodet_highpower(max(f, 10 Hz))
    output psd_bins = psd
    let x = irfft(n, t)
    let w = whiten(x, psd, t, f, 20 Hz, 1024 Hz)
    output variance = mean(w * w)
    output band_variance = mean(bandpass(w, t, f, 100 Hz, 300 Hz) ^ 2)
}";

/// Seeded coloured noise from the aLIGO PSD, taken to the time domain with
/// irfft and whitened: unit variance per sample over the band, i.e. a
/// variance equal to the fraction of the spectrum kept.
#[test]
fn whitened_coloured_noise_is_white_with_unit_variance_in_band() {
    let model = Model::from_source("w.gw", WHITEN_SOURCE).unwrap();
    let scene = model.scene(None).unwrap();
    let zeros = vec![C64::new(0.0, 0.0); 8193];
    let psd = real_array(scene.bind().input_complex("n", &zeros).unwrap().forward().unwrap().value("psd_bins"));
    for seed in [1, 2, 3] {
        let noise = gwml_runtime::noise::colored_noise(&psd, 0.25, seed).unwrap();
        let out = scene.bind().input_complex("n", &noise).unwrap().forward().unwrap();
        let (v, vb) = (out.scalar("variance").unwrap(), out.scalar("band_variance").unwrap());
        // 20..1024 Hz of 0..2048 Hz; 100..300 Hz of it. About 4,000 and 800 independent bins.
        let (want, want_band) = ((1024.0 - 20.0) / 2048.0, 200.0 / 2048.0);
        assert!((v / want - 1.0).abs() < 0.05, "seed {seed}: whitened variance {v}, expected {want}");
        assert!((vb / want_band - 1.0).abs() < 0.12, "seed {seed}: band-passed variance {vb}, expected {want_band}");
    }
}

const SNR_SOURCE: &str = "use std::taylorf2::{tf2_strain_td}
use std::detector::{snr_series, sigma}
use std::psd::{psd_aligo_zerodet_highpower}
scene matched {
    grid t = times(rate: 2048 Hz, duration: 8 s)
    grid f = spectrum(t)
    param shift: s = 1.25
    let psd = psd_aligo_zerodet_highpower(max(f, 10 Hz))
    let h = tf2_strain_td(t, f, 20 Hz, 12 Msun, 0.7, 0.2, -0.1, 500 Mpc, 6 s, 0.4)
    let d = tf2_strain_td(t, f, 20 Hz, 12 Msun, 0.7, 0.2, -0.1, 500 Mpc, 6 s + shift, 1.9)
    output rho = snr_series(rfft(d, f), rfft(h, f), psd, t, f, 20 Hz, 1000 Hz)
    output optimal = sigma(rfft(h, f), psd, f, 20 Hz, 1000 Hz)
    output h_td = h
}";

/// Data = the template shifted in time and phase: the SNR series peaks at
/// the shift with the optimal SNR sqrt((h|h)) and stays below it elsewhere.
#[test]
fn matched_filter_peaks_at_the_injected_shift_with_the_optimal_snr() {
    let model = Model::from_source("snr.gw", SNR_SOURCE).unwrap();
    let scene = model.scene(None).unwrap();
    for shift in [1.25, -0.5, 0.0] {
        let out = scene.bind().param("shift", shift).unwrap().forward().unwrap();
        let rho = real_array(out.value("rho"));
        let optimal = out.scalar("optimal").unwrap();
        assert!(optimal > 10.0 && optimal < 200.0, "optimal SNR {optimal}");
        let (at, peak) = rho.iter().enumerate().fold((0, 0.0), |b, (i, r)| if *r > b.1 { (i, *r) } else { b });
        let want_at = ((shift * 2048.0) as i64).rem_euclid(rho.len() as i64) as usize;
        assert_eq!(at, want_at, "peak at sample {at}, injected at {want_at}");
        assert!((peak / optimal - 1.0).abs() < 1e-9, "peak {peak} vs optimal {optimal}");
        assert!(rho.iter().all(|r| r.is_finite() && *r <= optimal * (1.0 + 1e-9)));
        // The time-domain chirp ends at the merger: almost nothing after tc + 0.1 s.
        let h = real_array(out.value("h_td"));
        let loud = h.iter().map(|x| x.abs()).fold(0.0, f64::max);
        let after: f64 = h[(6.1 * 2048.0) as usize..(7.5 * 2048.0) as usize].iter().map(|x| x.abs()).fold(0.0, f64::max);
        assert!(after < 0.05 * loud, "after the merger {after} vs peak {loud}");
    }
}

/// Gradients flow through rfft, whitening and irfft: the derivative of a
/// whitened burst's energy w.r.t. its central frequency and quality factor
/// agrees with central finite differences of the kernel.
#[test]
fn gradient_through_whitening_matches_finite_differences() {
    let src = "use std::burst::{sine_gaussian}
use std::detector::{whiten}
use std::psd::{psd_aligo_zerodet_highpower}
scene g {
    grid t = times(rate: 1024 Hz, duration: 1 s)
    grid f = spectrum(t)
    param f0: Hz = 90.0
    param q = 6.0
    let x = sine_gaussian(t, 0.5 s, f0, q, 1e-21)
    let w = whiten(x, psd_aligo_zerodet_highpower(max(f, 10 Hz)), t, f, 20 Hz, 500 Hz)
    output energy = sum(w * w * (t / 1 s))
    grad energy wrt [f0, q]
}";
    let model = Model::from_source("g.gw", src).unwrap();
    let scene = model.scene(None).unwrap();
    let at = |f0: f64, q: f64| scene.bind().param("f0", f0).unwrap().param("q", q).unwrap().forward().unwrap().scalar("energy").unwrap();
    let out = scene.bind().value_and_grad().unwrap();
    let (gf, gq) = (out.grad("energy", "f0").unwrap(), out.grad("energy", "q").unwrap());
    let fd_f = (at(90.0 + 1e-4, 6.0) - at(90.0 - 1e-4, 6.0)) / 2e-4;
    let fd_q = (at(90.0, 6.0 + 1e-5) - at(90.0, 6.0 - 1e-5)) / 2e-5;
    assert!((gf - fd_f).abs() <= 1e-6 * fd_f.abs().max(gf.abs()), "d/df0 {gf} vs {fd_f}");
    assert!((gq - fd_q).abs() <= 1e-6 * fd_q.abs().max(gq.abs()), "d/dq {gq} vs {fd_q}");
}

/// `series_dot` of two spectra is Σ_j a_j b_j of their inverse transforms
/// (Parseval), computed independently here by irfft and a time-domain sum,
/// on even and odd lengths and with complex values at 0 Hz and at the last
/// bin (which irfft reads the real part of only at an even length's Nyquist
/// bin); and its gradient agrees with finite differences.
#[test]
fn series_dot_is_the_time_domain_sum_of_the_inverse_transforms() {
    let src = |samples: usize| {
        format!(
            "use std::detector::{{series_dot}}
scene dot {{
    knob rate = {samples} Hz
    grid t = times(rate: rate, duration: 1 s)
    grid f = spectrum(t)
    input a: complex[f] s
    input b: complex[f] s
    param k = 1.0
    let bk = b * k + a * (k * k)
    output spectral = series_dot(a, bk, t, f)
    output direct = sum(irfft(a, t) * irfft(bk, t))
    grad spectral wrt [k]
}}"
        )
    };
    for samples in [64usize, 65, 100, 101] {
        let model = Model::from_source("dot.gw", &src(samples)).unwrap();
        let scene = model.scene(None).unwrap();
        let bins = samples / 2 + 1;
        let wave =
            |seed: f64| (0..bins).map(|i| C64::new((seed * i as f64 + 0.3).sin(), (seed * 1.7 * i as f64 + 1.1).cos())).collect::<Vec<_>>();
        let (a, b) = (wave(0.37), wave(1.91));
        let at = |k: f64| {
            let mut run = scene.bind();
            run.input_complex("a", &a).unwrap().input_complex("b", &b).unwrap().param("k", k).unwrap();
            run.value_and_grad().unwrap()
        };
        let out = at(0.8);
        let (spectral, direct) = (out.scalar("spectral").unwrap(), out.scalar("direct").unwrap());
        assert!((spectral - direct).abs() <= 1e-12 * direct.abs().max(1.0), "{samples} samples: {spectral} vs {direct}");
        let h = 1e-5;
        let fd = (at(0.8 + h).scalar("spectral").unwrap() - at(0.8 - h).scalar("spectral").unwrap()) / (2.0 * h);
        let g = out.grad("spectral", "k").unwrap();
        assert!((g - fd).abs() <= 1e-7 * fd.abs().max(1.0), "{samples} samples: d/dk {g} vs {fd}");
    }
}
