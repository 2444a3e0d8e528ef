//! Benchmark of `examples/chirp_fit.gw` (8,033 frequency bins): the JIT's
//! forward and fused forward+gradient calls against the same computation
//! hand-written in Rust, and the heap the gradient call allocates.
//!
//!     cargo bench --bench chirp_fit
//!
//! Prints medians over many repetitions (the machine is noisy: compare ratios).

#[path = "../tests/common/chirp_reference.rs"]
mod reference;

use gwml_lab::timing::median_us;
use std::alloc::{GlobalAlloc, Layout, System};
use std::hint::black_box;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Counts live heap bytes and their peak.
struct Counting;
static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let live = LIVE.fetch_add(l.size(), Ordering::Relaxed) + l.size();
        PEAK.fetch_max(live, Ordering::Relaxed);
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        LIVE.fetch_sub(l.size(), Ordering::Relaxed);
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// The same loss and gradient with what the grid fixes precomputed, as gwml
/// does after specialisation: the fair baseline for code quality.
struct Tabled {
    amp: Vec<f64>,
    w: Vec<f64>,
    f53: Vec<f64>,
    twopif: Vec<f64>,
}

impl Tabled {
    fn new() -> Tabled {
        let f = |k| reference::freq(k);
        let n = reference::N;
        Tabled {
            amp: (0..n).map(|k| 0.01 * (f(k) / 100.0).powf(-7.0 / 6.0)).collect(),
            w: (0..n).map(|k| 1.0 / reference::psd(f(k))).collect(),
            f53: (0..n).map(|k| f(k).powf(-5.0 / 3.0)).collect(),
            twopif: (0..n).map(|k| 2.0 * std::f64::consts::PI * f(k)).collect(),
        }
    }

    fn loss_and_grad(&self, data: &[f64], mc: f64, tc: f64, phic: f64, grad: bool) -> (f64, [f64; 3]) {
        let pi = std::f64::consts::PI;
        let mcs = pi * mc * reference::MTSUN;
        let (c53, c83) = (mcs.powf(-5.0 / 3.0) * 3.0 / 128.0, 3.0 / 128.0 * (-5.0 / 3.0) * mcs.powf(-5.0 / 3.0) / mc);
        let (mut s, mut g) = (0.0, [0.0; 3]);
        for k in 0..reference::N {
            let psi = self.twopif[k] * tc - phic - pi / 4.0 + c53 * self.f53[k];
            let (sn, cs) = psi.sin_cos();
            let (hr, hi) = (self.amp[k] * cs, -self.amp[k] * sn);
            let (rr, ri) = (data[2 * k] - hr, data[2 * k + 1] - hi);
            s += (rr * rr + ri * ri) * self.w[k];
            if grad {
                let q = (rr * hi - ri * hr) * self.w[k];
                g[0] += q * c83 * self.f53[k];
                g[1] += q * self.twopif[k];
                g[2] -= q;
            }
        }
        let c = -4.0 * reference::DF;
        (0.5 * 4.0 * reference::DF * s, [c * g[0], c * g[1], c * g[2]])
    }
}

fn main() {
    let reps = 400;
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/chirp_fit.gw");
    let model = gwml::compile_file(path).expect("example compiles");
    let scene = model.scene(None).expect("scene compiles");
    let mut run = scene.bind();
    run.param("mc", 29.0).unwrap().param("tc", 0.001).unwrap().param("phic", 0.2).unwrap();
    run.value_and_grad().unwrap();
    let data = reference::default_data();

    let jit_fwd = median_us(reps, || {
        black_box(run.forward().unwrap());
    });
    let jit_grad = median_us(reps, || {
        black_box(run.value_and_grad().unwrap());
    });
    let rust_fwd = median_us(reps, || {
        black_box(reference::loss(black_box(&data), 29.0, 0.001, 0.2));
    });
    let rust_grad = median_us(reps, || {
        black_box(reference::loss_and_grad(black_box(&data), 29.0, 0.001, 0.2));
    });

    let tabled = Tabled::new();
    let tab_fwd = median_us(reps, || {
        black_box(tabled.loss_and_grad(black_box(&data), 29.0, 0.001, 0.2, false));
    });
    let tab_grad = median_us(reps, || {
        black_box(tabled.loss_and_grad(black_box(&data), 29.0, 0.001, 0.2, true));
    });
    let (tl, tg) = tabled.loss_and_grad(&data, 29.0, 0.001, 0.2, true);

    // Heap during one forward+gradient call, above what was live before it.
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let out = run.value_and_grad().unwrap();
    let peak_extra = PEAK.load(Ordering::Relaxed) - before;
    drop(out);

    let (loss, grad) = reference::loss_and_grad(&data, 29.0, 0.001, 0.2);
    let out = run.value_and_grad().unwrap();
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    println!("chirp_fit, {} bins, f64, one thread, median of {reps}", reference::N);
    println!(
        "  agreement with hand-written Rust: loss {:.1e}, dL/dmc {:.1e}",
        rel(out.scalar("loss").unwrap(), loss),
        rel(out.grad("loss", "mc").unwrap(), grad[0])
    );
    println!("  {:<34} {:>9.1} µs", "gwml forward", jit_fwd);
    println!("  {:<34} {:>9.1} µs", "gwml forward+gradient (fused)", jit_grad);
    println!("  {:<34} {:>9.1} µs", "hand-written Rust forward", rust_fwd);
    println!("  {:<34} {:>9.1} µs", "hand-written Rust forward+gradient", rust_grad);
    println!("  {:<34} {:>9.1} µs", "hand-written Rust, tables, forward", tab_fwd);
    println!("  {:<34} {:>9.1} µs", "hand-written Rust, tables, fwd+grad", tab_grad);
    println!("  tabled Rust agrees: loss {:.1e}, dL/dmc {:.1e}", rel(tl, loss), rel(tg[0], grad[0]));
    println!("  forward+gradient / forward (gwml):  {:.2}x  (target <= 2.5x)", jit_grad / jit_fwd);
    println!("  gwml forward / Rust forward:        {:.2}x  (target <= 1.5x)", jit_fwd / rust_fwd);
    println!("  gwml fwd+grad / Rust fwd+grad:      {:.2}x", jit_grad / rust_grad);
    println!("  gwml forward / tabled Rust forward: {:.2}x", jit_fwd / tab_fwd);
    println!("  gwml fwd+grad / tabled Rust:        {:.2}x", jit_grad / tab_grad);
    println!("  heap allocated during one forward+gradient call: {peak_extra} bytes (one bin of data is 16 bytes; {} bins)", reference::N);
}
