//! The population of the glitch benchmark: how each class's shape params,
//! loudness and position are drawn, and what the noise carries besides
//! Gaussian noise. Sources for the numbers (see `../shared/FACTS.md`):
//! Gravity Spy's class descriptions (Zevin et al. 2017, Class. Quantum
//! Grav. 34 064003), the O3 classes and their medians (Glanz et al. 2024;
//! the public O3a metadata): peak frequencies Blip 160–200 Hz, Koi Fish
//! 110–160 Hz, Whistle 700–1100 Hz, Scratchy ~100–150 Hz, Tomte 40–47 Hz,
//! Scattered Light arches ~27–30 Hz; durations Blip ~0.25 s (Omicron's,
//! which overstates a 10–30 ms core), Koi Fish ~1.7 s, Whistle 0.3–0.6 s,
//! Scratchy ~1.5 s, Tomte 0.7–1 s, Scattered Light ~2.6 s; SNR medians Blip
//! ~23, Koi Fish 140–195, Whistle 10–30, Scratchy 9–25, Tomte 16–21,
//! Scattered Light 16–29.
//!
//! What the draws deliberately do not give away: every class is placed at
//! the same distribution of energy centres ([`GlitchOptions::position`]),
//! and the SNR ranges overlap (a Blip reaches SNR 100, a Koi Fish goes down
//! to 12), so loudness is a cue for Koi Fish, as it is in real data, and
//! not a label.
//!
//! [`GlitchOptions::position`]: super::GlitchOptions::position

use rand::Rng;
use std::f64::consts::{PI, TAU};

/// Class indices (positions in [`super::GLITCH_CLASSES`]).
pub(crate) const BLIP: usize = 1;
pub(crate) const KOI_FISH: usize = 2;
pub(crate) const WHISTLE: usize = 3;
pub(crate) const SCRATCHY: usize = 4;
pub(crate) const CHIRP: usize = 5;
pub(crate) const TOMTE: usize = 6;
pub(crate) const SCATTERED_LIGHT: usize = 7;

/// A draw log-uniform on `lo..=hi`.
fn log_uniform<R: Rng>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    (rng.random_range(lo.ln()..=hi.ln())).exp()
}

/// The optimal-SNR range of each class (drawn log-uniformly, so the median
/// is the geometric mean): Blip 6.5–100 (median 25), Koi Fish 12–400
/// (69; real ones are louder, 5 % of the H1/L1 Koi Fish fits in
/// `lab/data/real_glitch_fits.csv` are below 25, but a scan meets quiet
/// ones and must name them; a floor of 8 took real Blips at SNR 8–12 as
/// Koi Fish, `scripts/blip_realism.py`), Whistle and Scattered Light 6.5–60 (20), Scratchy and Chirp
/// 6.5–40 (16), Tomte 6.5–50 (18). Gravity Spy triggers start at an
/// Omicron SNR of 7.5; the floor sits below it because a trigger's SNR
/// scatters around the optimal one, and above the weak transients of the
/// None class (SNR ≤ 5). A Koi Fish with a real fit's shape keeps the
/// fit's SNR within this range (`real_fits.rs`).
pub fn snr_range(class: usize) -> (f64, f64) {
    match class {
        BLIP => (6.5, 100.0),
        KOI_FISH => (12.0, 400.0),
        WHISTLE | SCATTERED_LIGHT => (6.5, 60.0),
        TOMTE => (6.5, 50.0),
        _ => (6.5, 40.0),
    }
}

/// Draws the optimal SNR of a signal of `class`: from `fixed` (uniform)
/// when given, else log-uniform on the class's [`snr_range`].
pub fn draw_snr<R: Rng>(rng: &mut R, class: usize, fixed: Option<(f64, f64)>) -> f64 {
    match fixed {
        Some((lo, hi)) => rng.random_range(lo..=hi),
        None => {
            let (lo, hi) = snr_range(class);
            log_uniform(rng, lo, hi)
        }
    }
}

/// Draws the shape params of a signal of `class`: every param of the
/// signal scene (`lab/models/glitch/synth.gw`), the class's own drawn and
/// the others at their neutral values, so one bound run can draw any class.
/// Times: glitches centred at `t0` = 0.5 s, the chirp merging at
/// `tc` 0.8–0.95 s; callers move them (see `super::glitches`).
///
/// - Blip: a burst at f0 70–350 Hz (log-uniform; 98 % of the real H1/L1
///   Blip fits peak above 72 Hz, lower ones are Gravity Spy's
///   Blip_Low_Frequency), Q 1.2–6, envelope
///   asymmetry 0.5–2.5 (decay over rise), frequency drift ±0.3 per τ, and in
///   30 % of draws an echo of 20–70 % amplitude 5–30 ms away at 0.6–1.6
///   times the frequency.
/// - Koi Fish: a broadband burst (f0 90–220 Hz, Q 1–2.5) with a head at
///   15–45 Hz (Q 2–6, 0.5–4 times the amplitude before whitening, 5–40 ms
///   before) decaying 1–4 times slower than it rises: the fish's head and
///   long low-frequency tail. Draws whose head outshines the body once
///   whitened, or cannot be seen, are redrawn
///   ([`super::glitch::KOI_FISH_BODY_SHARE`], `draw_signal_shape`).
/// - Whistle: the sweep's turning frequency 450–1400 Hz; the ends
///   150–700 Hz above it (a V, 70 %) or below (an inverted V); in 40 % a
///   quartic term making a W; half-width 0.08–0.3 s; every draw stays in
///   120–1900 Hz where its envelope is above 1/10.
/// - Scratchy: carrier 60–350 Hz, 12–25 arches per second wobbling the
///   frequency by up to 25 %, envelope 1/e half-width 0.4–1.25 s.
/// - Chirp: TaylorF2 from 30 Hz, chirp mass 18–40 Msun, mass ratio 0.3–1.
/// - Tomte: a burst at 25–45 Hz, Q 1.5–4, decaying 1–3 times slower than
///   it rises. Whitened, its peak is 1–6 Hz above f0 (higher at low Q):
///   27–50 Hz, as the real H1/L1 Tomte fits' whitened peaks are (5–95 %:
///   33–44 Hz; 98 % below 51 Hz). Up to 55 Hz, one formula Tomte in six
///   peaked above 51 Hz, among the low Blips of a generator trained on
///   real L1 Blips (gengli), which the classifier then called Tomte.
/// - Scattered Light: arches peaking at a fringe frequency of 22–70 Hz,
///   surface motion at 0.15–2 Hz (one arch every 0.25–3.3 s), second and
///   third harmonics at 0–50 % and its square, envelope half-width 0.75–2 s.
///
/// Every signal has a random phase.
pub fn draw_shape<R: Rng>(rng: &mut R, class: usize) -> Vec<(&'static str, f64)> {
    let mut p: Vec<(&'static str, f64)> = vec![
        ("t0", 0.5),
        ("f0", 150.0),
        ("q", 3.0),
        ("asym", 1.0),
        ("drift", 0.0),
        ("echo", 0.0),
        ("echo_lag", 0.01),
        ("echo_ratio", 1.0),
        ("f_head", 30.0),
        ("q_head", 3.0),
        ("head", 0.2),
        ("lead", 0.02),
        ("f_min", 600.0),
        ("f_max", 1000.0),
        ("wiggle", 0.0),
        ("half", 0.2),
        ("rate", 18.0),
        ("duration", 0.6),
        ("wobble", 0.0),
        ("f_fringe", 40.0),
        ("f_motion", 0.5),
        ("bounce", 0.3),
        ("mc", 25.0),
        ("mass_ratio", 0.8),
        ("tc", 0.9),
        ("phi", rng.random_range(0.0..TAU)),
    ];
    let mut set = |name: &str, value: f64| {
        if let Some(slot) = p.iter_mut().find(|(n, _)| *n == name) {
            slot.1 = value;
        }
    };
    match class {
        BLIP => {
            set("f0", log_uniform(rng, 70.0, 350.0));
            set("q", log_uniform(rng, 1.2, 6.0));
            set("asym", log_uniform(rng, 0.5, 2.5));
            set("drift", rng.random_range(-0.3..=0.3));
            if rng.random_bool(0.3) {
                set("echo", rng.random_range(0.2..=0.7));
                let lag = rng.random_range(0.005..=0.03);
                set("echo_lag", if rng.random_bool(0.5) { lag } else { -lag });
                set("echo_ratio", log_uniform(rng, 0.6, 1.6));
            }
        }
        KOI_FISH => {
            set("f0", log_uniform(rng, 90.0, 220.0));
            set("q", log_uniform(rng, 1.0, 2.5));
            set("drift", rng.random_range(-0.2..=0.2));
            set("f_head", log_uniform(rng, 15.0, 45.0));
            set("q_head", rng.random_range(2.0..=6.0));
            set("head", log_uniform(rng, 0.5, 4.0));
            set("lead", rng.random_range(0.005..=0.04));
            set("asym", log_uniform(rng, 1.0, 4.0));
        }
        WHISTLE => {
            let (turn, ends, wiggle, half) = loop {
                let turn = log_uniform(rng, 450.0, 1400.0);
                let ends = rng.random_range(150.0..=700.0) * if rng.random_bool(0.7) { 1.0 } else { -1.0 };
                let wiggle = if rng.random_bool(0.4) { rng.random_range(-600.0..=600.0) } else { 0.0 };
                // Where the envelope e^{-u²} is above 1/10, |u| ≤ 1.52.
                let in_band = (0..=20).all(|i| {
                    let u: f64 = 1.52 * i as f64 / 20.0;
                    let f = turn + ends * u * u + wiggle * u.powi(4);
                    (120.0..=1900.0).contains(&f)
                });
                if in_band {
                    break (turn, ends, wiggle, rng.random_range(0.08..=0.3));
                }
            };
            set("f_min", turn);
            set("f_max", turn + ends);
            set("wiggle", wiggle);
            set("half", half);
        }
        SCRATCHY => {
            set("f0", log_uniform(rng, 60.0, 350.0));
            set("rate", rng.random_range(12.0..=25.0));
            set("duration", rng.random_range(0.8..=2.5));
            set("wobble", rng.random_range(0.0..=0.25));
        }
        CHIRP => {
            set("mc", rng.random_range(18.0..=40.0));
            set("mass_ratio", rng.random_range(0.3..=1.0));
            set("tc", rng.random_range(0.8..=0.95));
        }
        TOMTE => {
            set("f0", log_uniform(rng, 25.0, 45.0));
            set("q", log_uniform(rng, 1.5, 4.0));
            set("asym", log_uniform(rng, 1.0, 3.0));
        }
        SCATTERED_LIGHT => {
            set("f_fringe", log_uniform(rng, 22.0, 70.0));
            set("f_motion", log_uniform(rng, 0.15, 2.0));
            set("bounce", rng.random_range(0.0..=0.5));
            set("duration", rng.random_range(1.5..=4.0));
        }
        _ => {}
    }
    p
}

/// What real whitened strain carries besides Gaussian noise, drawn per row
/// unless the noise is ideal: a smooth misestimate of the PSD the data are
/// whitened with (`tilt`, `curve`: the noise PSD is the model's times
/// exp(tilt l + curve l²), l = ln(f / 200 Hz); sd 0.1 and 0.05, so ±10–20 %
/// over the band, as a PSD estimated from 128 s of drifting data misses
/// it), and residual lines: the 60 Hz mains and two harmonics and the first
/// violin modes near 500 Hz, each a sinusoid of whitened amplitude up to
/// 0.05 (a bin up to ~3.5 times the noise's power in 1 s), as lines left
/// by whitening with a PSD from neighbouring data.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct NoiseExtras {
    /// PSD tilt and curvature in ln(f / 200 Hz).
    pub tilt: f64,
    pub curve: f64,
    /// Residual lines: frequency (Hz), amplitude and phase.
    pub lines: Vec<(f64, f64, f64)>,
}

impl NoiseExtras {
    /// Draws the extras of one row.
    pub fn draw<R: Rng>(rng: &mut R) -> NoiseExtras {
        let normal = |rng: &mut R| {
            // Box–Muller, to keep one generator stream.
            let (u, v): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random_range(0.0..1.0));
            (-2.0 * u.ln()).sqrt() * (TAU * v).cos()
        };
        let tilt = 0.1 * normal(rng);
        let curve = 0.05 * normal(rng);
        let violin = rng.random_range(495.0..=515.0);
        let lines = [60.0, 120.0, 180.0, violin]
            .iter()
            .map(|f| (f + rng.random_range(-0.1..=0.1), rng.random_range(0.0..=0.05), rng.random_range(0.0..TAU)))
            .collect();
        NoiseExtras { tilt, curve, lines }
    }

    /// Adds the residual lines to a whitened row sampled at `rate` Hz.
    pub fn add_lines(&self, row: &mut [f64], rate: f64) {
        for (f, a, phase) in &self.lines {
            for (i, x) in row.iter_mut().enumerate() {
                *x += a * (2.0 * PI * f * i as f64 / rate + phase).cos();
            }
        }
    }
}
