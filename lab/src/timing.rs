//! Wall-clock medians, because the machine is noisy: used by `gwml
//! tradeoff` and the benchmarks.

use std::time::Instant;

/// Median wall time of `f` in microseconds over `reps` calls (at least
/// one), after a tenth as many warm-up calls.
pub fn median_us(reps: usize, mut f: impl FnMut()) -> f64 {
    let reps = reps.max(1);
    for _ in 0..reps / 10 + 1 {
        f();
    }
    let mut t: Vec<f64> = (0..reps)
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[reps / 2]
}
