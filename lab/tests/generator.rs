//! The glitch generator's realism, measured by the classifier two-sample
//! test: the test tells different shape sets apart and not two halves of
//! one, and the learned generator, trained on noisy examples of a shape no
//! `std::glitch` formula has (damped ringdowns), draws glitches the critic
//! can hardly tell from held-out ones.

use gwml_lab::generator::learned::{fit, LearnedOptions};
use gwml_lab::generator::realism::{two_sample_accuracy, TwoSampleOptions};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

const N: usize = 4096;
const FS: f64 = 4096.0;

/// Clean whitened shapes: `kind` 0 is a damped ringdown (a fast rise, then
/// exp(−t/τ) sin(2πft + φ), f log-uniform in 60–500 Hz, τ in 5–40 ms), 1 a
/// sine-Gaussian blip (f0 log-uniform in 30–250 Hz, Q in 2–6); at a time in
/// 0.3–0.7 s, unit norm.
fn shapes(kind: usize, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    (0..n)
        .map(|_| {
            let t0 = rng.random_range(0.3..0.7);
            let phi = rng.random_range(0.0..std::f64::consts::TAU);
            let row: Vec<f64> = if kind == 0 {
                let f = (rng.random_range(60f64.ln()..500f64.ln())).exp();
                let tau = rng.random_range(0.005..0.04);
                (0..N)
                    .map(|i| {
                        let t = i as f64 / FS - t0;
                        if t < 0.0 {
                            0.0
                        } else {
                            (1.0 - (-t / 0.001).exp()) * (-t / tau).exp() * (std::f64::consts::TAU * f * t + phi).sin()
                        }
                    })
                    .collect()
            } else {
                let f0 = (rng.random_range(30f64.ln()..250f64.ln())).exp();
                let q: f64 = rng.random_range(2.0..6.0);
                let tau = q / (std::f64::consts::TAU * f0);
                (0..N)
                    .map(|i| {
                        let t = i as f64 / FS - t0;
                        (-(t / tau).powi(2) / 2.0).exp() * (std::f64::consts::TAU * f0 * t + phi).sin()
                    })
                    .collect()
            };
            let norm = row.iter().map(|v| v * v).sum::<f64>().sqrt();
            row.into_iter().map(|v| v / norm).collect()
        })
        .collect()
}

/// `clean` at SNRs drawn from `snr` in fresh white noise.
fn noisy(clean: &[Vec<f64>], snr: (f64, f64), seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    clean
        .iter()
        .map(|s| {
            let a = rng.random_range(snr.0..snr.1);
            s.iter().map(|v| a * v + Distribution::<f64>::sample(&StandardNormal, &mut rng)).collect()
        })
        .collect()
}

fn options(snr: f64) -> TwoSampleOptions {
    TwoSampleOptions { snr, seed: 3, epochs: 40, threads: 2 }
}

#[test]
fn the_two_sample_test_tells_shapes_apart_and_not_one_set_from_itself() {
    let ringdowns = shapes(0, 200, 1);
    let blips = shapes(1, 100, 2);
    let same = two_sample_accuracy(&ringdowns[..100], &ringdowns[100..], &options(40.0)).unwrap();
    let different = two_sample_accuracy(&ringdowns[..100], &blips, &options(40.0)).unwrap();
    println!("two halves of one set: {same:.3}; ringdowns against blips: {different:.3}");
    assert!(same < 0.62, "two halves of one set: accuracy {same}");
    assert!(different > 0.85, "ringdowns against blips: accuracy {different}");
}

/// The learned generator on ringdowns, a shape no `std::glitch` formula
/// has (150 epochs on 350 examples at SNR 15–30). Its training loss
/// explains 87 % of the examples' signal energy (the time-domain decoder
/// before it: about half), and at SNR 20 the critic tells its draws from
/// held-out ringdowns at 0.72 (before: 0.83) where it tells blips from them
/// at 0.94. Issue #30's target is 0.60 at SNR 40, measured with
/// `scripts/generator_realism.sh` (`results/generator/realism/`); this
/// test's draw of the set is harder (0.79–0.80 at SNR 40 where the
/// script's sets, drawn from the same distribution, give 0.54–0.56; why is
/// not known) and it holds the ground gained.
#[test]
fn the_learned_generator_learns_ringdowns() {
    let clean = shapes(0, 500, 5);
    let (train, held_out) = clean.split_at(350);
    let examples = noisy(train, (15.0, 30.0), 6);
    let (g, reports) = fit(&examples, &vec![1; examples.len()], LearnedOptions { epochs: 150, seed: 1, threads: 2 }, |_| {}).unwrap();
    // The loss of decoding every example as silence: ½‖x‖² plus no KL.
    let silent = examples.iter().map(|x| 0.5 * x.iter().map(|v| v * v).sum::<f64>()).sum::<f64>() / examples.len() as f64;
    let noise_only = 0.5 * N as f64;
    let last = reports.last().unwrap().train_loss;
    let band = g.classes[0].band;
    println!("final loss {last:.1}; silence {silent:.1}; noise alone {noise_only:.1}; band {band:?}");
    assert!(last < silent - 0.75 * (silent - noise_only), "the decoder explains signal energy: loss {last}, silence {silent}");
    assert!(band.1 < 1000.0, "the ringdowns (60–500 Hz) set the band: {band:?}");
    let draws = g.sample(150, 2, None).unwrap().rows;
    let blips = shapes(1, 150, 7);
    let learned = two_sample_accuracy(&draws, held_out, &options(20.0)).unwrap();
    let wrong_shape = two_sample_accuracy(&blips, held_out, &options(20.0)).unwrap();
    let learned_40 = two_sample_accuracy(&draws, held_out, &options(40.0)).unwrap();
    println!("SNR 20: learned draws against held-out ringdowns {learned:.3}; blips against them {wrong_shape:.3}; SNR 40: learned {learned_40:.3}");
    assert!(learned < 0.78 && learned < wrong_shape - 0.1, "draws {learned} vs blips {wrong_shape}");
}

/// One conditional generator fitted to two classes at once, ringdowns
/// (label 9, a class the library does not have) and sine-Gaussian blips
/// (label 1), draws each class more like its own held-out examples than
/// the other class's draws are: the class input steers the decoder.
#[test]
fn the_conditional_generator_draws_each_class_like_its_examples() {
    let (ringdowns, blips) = (shapes(0, 300, 11), shapes(1, 300, 12));
    let examples: Vec<Vec<f64>> =
        noisy(&ringdowns[..200], (15.0, 30.0), 13).into_iter().chain(noisy(&blips[..200], (15.0, 30.0), 14)).collect();
    let labels: Vec<usize> = [9; 200].into_iter().chain([1; 200]).collect();
    let (g, _) = fit(&examples, &labels, LearnedOptions { epochs: 150, seed: 1, threads: 2 }, |_| {}).unwrap();
    assert_eq!(g.class_labels(), vec![1, 9]);
    let drawn_ringdowns = g.sample(100, 3, Some(9)).unwrap();
    let drawn_blips = g.sample(100, 4, Some(1)).unwrap();
    assert!(drawn_ringdowns.labels.iter().all(|l| *l == 9) && drawn_blips.labels.iter().all(|l| *l == 1));
    let o = options(20.0);
    let critic = |draws: &[Vec<f64>], held_out: &[Vec<f64>]| two_sample_accuracy(draws, held_out, &o).unwrap();
    let (r_r, b_r) = (critic(&drawn_ringdowns.rows, &ringdowns[200..]), critic(&drawn_blips.rows, &ringdowns[200..]));
    let (b_b, r_b) = (critic(&drawn_blips.rows, &blips[200..]), critic(&drawn_ringdowns.rows, &blips[200..]));
    println!("SNR 20, against held-out ringdowns: ringdown draws {r_r:.3}, blip draws {b_r:.3}; against held-out blips: blip draws {b_b:.3}, ringdown draws {r_b:.3}");
    assert!(r_r < b_r - 0.08, "ringdown draws {r_r} are no more like ringdowns than blip draws {b_r}");
    assert!(b_b < r_b - 0.08, "blip draws {b_b} are no more like blips than ringdown draws {r_b}");
    // Without a class, draws come in proportion to the training examples.
    let mixed = g.sample(200, 5, None).unwrap();
    let ones = mixed.labels.iter().filter(|l| **l == 1).count();
    assert!((70..=130).contains(&ones), "{ones} of 200 draws are blips");
    assert!(g.sample(1, 6, Some(3)).is_err(), "a class it was not fitted to is an error");
}
