//! Benchmark of the standard workload W1 with `std::taylorf2`: TaylorF2
//! 3.5PN, m1 = 36, m2 = 29 Msun, non-spinning, 400 Mpc, 20..1024 Hz at
//! df = 1/8 Hz (8,033 bins), f64, one thread.
//!
//!     cargo bench --bench taylorf2
//!
//! Measures (medians over many calls, after warm-up), for the strain with
//! std::taylorf2's ISCO cut (scenes `w1_strain`, `w1_fit`) and, with the
//! suffix `_full`, without it (`w1_strain_full`, `w1_fit_full`):
//! - `gwml_forward_us`: the complex strain over the grid (one complex array
//!   output, copied out of the kernel as `Outputs` does);
//! - `gwml_loss_forward_us`: the likelihood 0.5 (d-h|d-h) alone (forward
//!   kernel);
//! - `gwml_value_and_grad_us`: that likelihood and its gradient w.r.t.
//!   (mc, q, tc, phic), one fused kernel call.
//!
//! The suffix `_banded` times the `_full` scenes multibanded
//! (`multiband: 1e-3`): the waveform's phase on a coarse subset of the
//! bins, `e^{iΨ}` by rotation between them; their errors against `_full`
//! (mismatch, loss, gradient) are printed as `gwml_banded_*` lines. The
//! suffix `_relbin` times the full-band likelihood by relative binning
//! (`w1_fit_relbin`, 100 bins, fiducial at the true system; its strain is
//! `w1_strain_full`'s): `gwml_relbin_*` lines give its loss and gradient
//! errors against `_full` and |Δ ln L|.
//!
//! The data `d` is the model at slightly different params, computed with the
//! strain scene first and bound as an input. The PSD is the toy curve of
//! `examples/taylorf2_fit.gw`, `1e-47 (y^-4 + 2 + 2 y^2)`, y = f / 150 Hz
//! (benches/peers/peers.py uses the same one). Above the Schwarzschild ISCO (67.6 Hz
//! for this system) the cut strain is zero: its kernels split their loop
//! there and evaluate the waveform on the 382 bins below it only (as
//! LALSimulation does with f_max = 0); the `_full` scenes evaluate it on
//! all 8,033 bins (as LALSimulation with f_max = 1024 Hz and ripplegw do).
//!
//! Lines starting with `gwml_` are machine-readable (`name value`), read by
//! `benches/peers/peers.py`.

use gwml::{Model, Value};
use gwml_lab::timing::median_us;
use std::hint::black_box;
use std::time::Instant;

/// Scenes `w1_strain`, `w1_fit` and their `_full` variants.
const SOURCE: &str = include_str!("w1.gw");

/// Params of the data (the true W1 system) and of the evaluation point.
const TRUTH: [(&str, f64); 4] = [("mc", 28.09555579546043), ("q", 0.8055555555555556), ("tc", 0.0), ("phic", 0.0)];
const POINT: [(&str, f64); 4] = [("mc", 28.1), ("q", 0.8), ("tc", 0.0005), ("phic", 0.1)];
const BINS: usize = 8033;

fn main() {
    let reps: usize = std::env::var("GWML_BENCH_REPS").ok().and_then(|s| s.parse().ok()).unwrap_or(400);
    println!("taylorf2 W1: 3.5PN, m1 = 36, m2 = 29 Msun, {BINS} bins (20..1024 Hz, df = 1/8 Hz), f64, one thread, median of {reps}");
    println!("gwml_reps {reps}");
    let mut results = Vec::new();
    let variants = [
        ("", "w1_strain", "cut at the ISCO"),
        ("_full", "w1_strain_full", "no cut, every bin"),
        ("_banded", "w1_strain_banded", "no cut, multibanded (2e-3 rad)"),
        ("_relbin", "w1_strain_full", "no cut, likelihood by relative binning (100 bins)"),
    ];
    for (suffix, strain, what) in variants {
        results.push(measure(reps, suffix, strain, what));
    }
    // The banded approximation against the exact full band.
    let (full, banded) = (&results[1], &results[2]);
    let psd: Vec<f64> = (0..BINS)
        .map(|k| {
            let y = (20.0 + 0.125 * k as f64) / 150.0;
            1e-47 * (y.powi(-4) + 2.0 + 2.0 * y * y)
        })
        .collect();
    let mismatch = gwml_lab::tradeoff::mismatch(&banded.h, &full.h, Some(&psd));
    let loss_error = ((banded.loss - full.loss) / full.loss).abs();
    let grad_error = banded.grads.iter().zip(&full.grads).map(|(b, f)| ((b - f) / f).abs()).fold(0.0, f64::max);
    println!("banded vs full: mismatch {mismatch:.2e}, loss rel. error {loss_error:.2e}, largest gradient rel. error {grad_error:.2e}");
    println!("gwml_banded_mismatch {mismatch:e}");
    println!("gwml_banded_loss_error {loss_error:e}");
    println!("gwml_banded_grad_error {grad_error:e}");
    let relbin = &results[3];
    let delta = (relbin.loss - full.loss).abs();
    let grad_error = relbin.grads.iter().zip(&full.grads).map(|(b, f)| ((b - f) / f).abs()).fold(0.0, f64::max);
    println!("relative binning vs full: |delta ln L| {delta:.2e}, largest gradient rel. error {grad_error:.2e}");
    println!("gwml_relbin_dlogl {delta:e}");
    println!("gwml_relbin_grad_error {grad_error:e}");
}

/// What one variant computed at the evaluation point.
struct Measured {
    h: Vec<num_complex::Complex64>,
    loss: f64,
    grads: Vec<f64>,
}

/// Compiles scenes `strain` and `w1_fit{suffix}`, times them and
/// prints the results, the machine-readable lines with `suffix`.
fn measure(reps: usize, suffix: &str, strain: &str, what: &str) -> Measured {
    let t0 = Instant::now();
    let model = Model::from_source("taylorf2_w1.gw", SOURCE).unwrap_or_else(|e| panic!("{e}"));
    let strain = model.scene(Some(strain)).unwrap_or_else(|e| panic!("{e}"));
    let fit = model.scene(Some(&format!("w1_fit{suffix}"))).unwrap_or_else(|e| panic!("{e}"));
    let compile_ms = t0.elapsed().as_secs_f64() * 1e3;

    // Data: the model at the true params, through the runtime.
    let mut srun = strain.bind();
    for (n, v) in TRUTH {
        srun.param(n, v).unwrap();
    }
    let data = match srun.forward().unwrap().value("h").unwrap() {
        Value::ComplexArray(h) => h.clone(),
        other => panic!("strain output is not a complex array: {other:?}"),
    };
    assert_eq!(data.len(), BINS, "W1 grid has 8,033 bins");

    let mut frun = fit.bind();
    frun.input_complex("d", &data).unwrap();
    for (n, v) in POINT {
        frun.param(n, v).unwrap();
        srun.param(n, v).unwrap();
    }
    let out = frun.value_and_grad().unwrap();
    let loss = out.scalar("loss").unwrap();
    let grads: Vec<f64> = POINT.iter().map(|(n, _)| out.grad("loss", n).unwrap()).collect();
    let h = match srun.forward().unwrap().value("h").unwrap() {
        Value::ComplexArray(h) => h.clone(),
        _ => unreachable!(),
    };
    let nonzero = h.iter().filter(|z| z.norm() > 0.0).count();

    let fwd = median_us(reps, || {
        black_box(srun.forward().unwrap());
    });
    let loss_fwd = median_us(reps, || {
        black_box(frun.forward().unwrap());
    });
    let vg = median_us(reps, || {
        black_box(frun.value_and_grad().unwrap());
    });

    println!("W1, {what}: nonzero strain bins {nonzero}; h[0] = {:.6e}", h[0]);
    println!("  at mc = {}, q = {}, tc = {}, phic = {}:", POINT[0].1, POINT[1].1, POINT[2].1, POINT[3].1);
    println!("  loss {loss:.10e}; dL/dmc {:.6e}, dL/dq {:.6e}, dL/dtc {:.6e}, dL/dphic {:.6e}", grads[0], grads[1], grads[2], grads[3]);
    println!("  {:<36} {:>9.1} ms", "compile (both scenes)", compile_ms);
    println!("  {:<36} {:>9.1} µs", "gwml forward (complex strain)", fwd);
    println!("  {:<36} {:>9.1} µs", "gwml forward (likelihood only)", loss_fwd);
    println!("  {:<36} {:>9.1} µs", "gwml value_and_grad (4 params)", vg);
    println!("  value_and_grad / likelihood forward: {:.2}x", vg / loss_fwd);
    println!("gwml_compile{suffix}_ms {compile_ms:.3}");
    println!("gwml_forward{suffix}_us {fwd:.3}");
    println!("gwml_loss_forward{suffix}_us {loss_fwd:.3}");
    println!("gwml_value_and_grad{suffix}_us {vg:.3}");
    println!("gwml_loss{suffix} {loss:.17e}");
    for ((n, _), g) in POINT.iter().zip(&grads) {
        println!("gwml_grad_{n}{suffix} {g:.17e}");
    }
    Measured { h, loss, grads }
}
