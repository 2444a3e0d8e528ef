//! `gwml explain`'s physics: fit every candidate explanation of a trigger —
//! each glitch family of `std::glitch` and a TaylorF2 chirp — to the
//! whitened data around it, and rank them by Laplace evidence against
//! each other and against Gaussian noise alone.
//!
//! The scenes are `lab/models/glitch/explain.gw` (its header gives the
//! likelihood). For each family, [`Explainer::explain`]:
//! 1. tries a grid of starting shapes seeded from the trigger's loudest
//!    Q tile ([`Seed`]: time, frequency, Q), shapes found in the data by
//!    searches cheaper than the fit (`heterodyne.rs`, `fringes.rs`; a
//!    whistle's and a scratchy glitch's starts come from these alone) and,
//!    for a Koi Fish, from the Tomte fit's head and the blip fit's blip
//!    (`residual.rs`), taking each start's amplitude
//!    and phase from the data's projection on the template's two
//!    quadratures (two forward evaluations, no optimiser);
//! 2. refines the best starts ([`STARTS_REFINED`], a Tomte's six; for a
//!    Koi Fish also the best start from the blip fit, ranked apart) with
//!    L-BFGS inside the bounds (the phase is periodic and left unbounded;
//!    a whistle's first steps scaled by each param's curvature);
//! 3. takes the Fisher matrix at the best fit (the loss's Hessian,
//!    `runtime::fit::fit_run`, or where that is not positive definite the
//!    model's `JᵀJ` if the two agree: `fit.rs`), its 1σ errors, χ²/dof and
//!    the Laplace evidence (from the Hessian), with the phase's prior a
//!    full period around its estimate.
//!
//! A family whose templates stay at low frequencies runs all three at a
//! fraction of the data's rate, with the full window's likelihood
//! ([`Family::top`], `rates.rs`); a blip's and a Koi Fish's run the first
//! two at half the rate where every start sits below [`LOW_SEARCH_F0`],
//! then refine the best once more at the full rate
//! (`Family::low_search`).

mod campaign;
mod causes;
mod explanation;
mod fit;
mod fringes;
mod heterodyne;
mod rates;
mod report;
mod residual;
mod seeds;

pub use campaign::*;
pub use causes::*;
pub use explanation::*;
pub use fit::STARTS_REFINED;
use fit::START_MARGIN;
pub use fringes::*;
pub use heterodyne::*;
pub use rates::*;
pub use report::*;
pub use residual::*;
pub use seeds::*;

use fit::{fit_family, widen_to_profiles, Begin};
use gwml_compiler::ir::MathMode;
use gwml_compiler::Options;
use gwml_runtime::{Error, Model, Scene};
use gwml_strain::whitening::Whitened;
use std::time::Instant;

/// The scenes of the fits.
pub const EXPLAIN_SOURCE: &str = include_str!("../../models/glitch/explain.gw");

/// Fits within this `ln B` of the best are polished and have their
/// neighbouring modes tried.
const NEIGHBOUR_GATE: f64 = 10.0;

/// Fits within this `ln B` of noise alone are polished: whether they
/// beat noise is in doubt, and a polish can move them by more than
/// [`NEIGHBOUR_GATE`] (a blip beside the README's whistle had ln B −10.3
/// against noise before its polish, +3.3 after).
const NOISE_GATE: f64 = 20.0;

/// How many times a competing fit is redone from a better point of its
/// profile likelihood (`fit.rs`' `widen_to_profiles`); each redone fit's
/// profiles are taken again.
const PROFILE_JUMPS: usize = 2;

/// A starting point: `dt` and the shape params.
type Start = (f64, Vec<f64>);

/// Starting points found in the data: from the whitened window and its
/// sample rate (Hz).
type DataStarts = fn(&[f64], f64, &Seed) -> Vec<Start>;

/// Starts built on another family's fit: from that fit and the whitened
/// window at the full rate (and that rate).
type FitStarts = fn(&FamilyFit, &[f64], f64) -> Vec<Start>;

/// A free param of a fit scene: name, unit, bounds.
type FreeParam = (String, String, Option<(f64, f64)>);

/// A candidate explanation: one scene of `explain.gw`.
#[derive(Clone, Copy, Debug)]
pub struct Family {
    /// The scene's name (`blip`, `koi_fish`, ...).
    pub scene: &'static str,
    /// The Gravity Spy class it stands for (as `gwml scan` labels triggers).
    pub label: &'static str,
    /// The family this scene is a variant of (a blip with an echo is a
    /// blip): an explanation keeps the better-fitting variant only, and
    /// the cause is that family's. A variant is fitted only where the fit
    /// it builds on (`after`, if any) leaves something for it (gives
    /// starts), and the best fit so far is of one of `contests` (if any).
    pub variant_of: Option<&'static str>,
    /// The families a variant can take the verdict from (empty: any): it
    /// is fitted only where one of them leads (an echo does not turn a
    /// whistle's window into a blip's, and the fit costs a quarter of a
    /// trigger's time).
    contests: &'static [&'static str],
    /// Starting points for a seed: `dt` and the shape params (the scene's
    /// free params after `dt`, `snr` and `phi`).
    starts: fn(&Seed) -> Vec<Start>,
    /// More starting points found in the data (whitened window, its rate).
    data_starts: Option<DataStarts>,
    /// More starting points built on the fit of another family (its
    /// scene's name), which is fitted first.
    after: Option<(&'static str, FitStarts)>,
    /// Starting points built on another family's fit, ranked apart: their
    /// best is refined besides the family's best starts (one more L-BFGS
    /// run), so they cannot crowd those out.
    besides: Option<(&'static str, FitStarts)>,
    /// Other modes of the likelihood near a fit, given its `dt` and shape
    /// params: refined after the first fit, and kept if they fit better.
    neighbours: Option<fn(&Start) -> Vec<Start>>,
    /// How far inside its bounds (a fraction of the range) a start found in
    /// the data or a fit's neighbour puts each shape param
    /// (`fit::START_MARGIN` for the seeded grid).
    measured_margin: f64,
    /// Whether L-BFGS scales its first steps by each param's curvature at
    /// the start (`Settings::diagonal`): for params known to parts in 1e4
    /// of their range beside ones known to a percent (a whistle's vertex
    /// frequency and its width). On the other families it moved fits to
    /// worse optima (seed 1: Tomtes 100 → 96 % right, Koi Fish 88 → 83 %).
    scaled_steps: bool,
    /// How many of the best-matching starts L-BFGS refines.
    refined: usize,
    /// Params whose σ is widened to the profile likelihood's at ±3σ
    /// (`fit.rs`' `profile_sigma`) in the fits that compete for the
    /// verdict, in a pass of their own on the fit (`widen_to_profiles`).
    profiled: &'static [&'static str],
    /// The highest frequency (Hz) its whitened templates carry energy at
    /// within the bounds: the fit runs at the lowest rate whose Nyquist
    /// frequency is above it ([`factor_for`]).
    pub top: f64,
    /// Whether its search (starts ranked and refined) runs at the rate of
    /// [`SEARCH_TOP`] when every start's centre frequency, its first shape
    /// param, is at most [`LOW_SEARCH_F0`]; the best is then refined again
    /// and finished (Fisher matrix, evidence, model) at the family's rate.
    low_search: bool,
    /// A ridge its likelihood is known to follow, where a profile point
    /// also starts ([`Ridge`]).
    pub(super) ridge: Option<Ridge>,
}

/// Given a fit's params, the index of a profiled param and a new value
/// for it, the other params moved along a ridge of the family's
/// likelihood (`None` where it knows none for that param).
pub(super) type Ridge = fn(&[f64], usize, f64) -> Option<Vec<f64>>;

/// A heavy chirp's SNR lies near its ISCO frequency, which the total mass
/// `M = mc η^{-3/5}` (η = q/(1+q)²) sets: its fits trade mass ratio for
/// chirp mass at one `M` (seed 1: refitted from the injections' own
/// params, 99 of 100 ended no lower in loss than the fits, five of the
/// seven chirp masses outside 3σ at the injection's `M` to 1 % and `q`
/// at 0.97-1.0, where η is flat in q and the Fisher matrix loses the
/// ridge). A profile point of `mc` (param 3) or `mass_ratio` (param 4)
/// also starts at the same `M`.
fn chirp_ridge(x: &[f64], i: usize, v: f64) -> Option<Vec<f64>> {
    let eta = |q: f64| q / (1.0 + q).powi(2);
    let total = x[3] * eta(x[4]).powf(-0.6);
    let mut y = x.to_vec();
    match i {
        3 => {
            let e = (v / total).powf(5.0 / 3.0).min(0.25);
            y[4] = (1.0 - 2.0 * e - (1.0 - 4.0 * e).max(0.0).sqrt()) / (2.0 * e);
        }
        4 => y[3] = total * eta(v).powf(0.6),
        _ => return None,
    }
    y[i] = v;
    Some(y)
}

impl Family {
    /// The family this scene explains the data as (its own scene, or the
    /// one it is a variant of): what the ranking and the cause table name.
    pub fn base(&self) -> &'static str {
        self.variant_of.unwrap_or(self.scene)
    }
}

/// Starts a Tomte fit refines. A Tomte's rise, decay and Q trade along a
/// ridge, and from the two best-matching starts L-BFGS often climbed to
/// the bounds (asym 1, Q 5) ten units of loss short of the truth's, which
/// the blip fit (or a Koi Fish's head) then found instead. At an eighth of
/// the rate each refinement is cheap.
const TOMTE_STARTS_REFINED: usize = 6;

/// What a family is unless its entry in [`FAMILIES`] says otherwise: its
/// own family, seeded starts only, fitted at the full rate with
/// [`STARTS_REFINED`] refinements.
const PLAIN: Family = Family {
    scene: "",
    label: "",
    variant_of: None,
    contests: &[],
    starts: no_starts,
    data_starts: None,
    after: None,
    besides: None,
    neighbours: None,
    measured_margin: START_MARGIN,
    scaled_steps: false,
    refined: STARTS_REFINED,
    profiled: &[],
    top: f64::INFINITY,
    low_search: false,
    ridge: None,
};

/// The Nyquist frequency (Hz) a search at a lower rate keeps at least
/// (`Family::low_search`).
pub const SEARCH_TOP: f64 = 1000.0;

/// The highest centre frequency (Hz) of a search at the rate of
/// [`SEARCH_TOP`]. Whitened by the O3 ASD (`lab/data/o3_asd.csv`), a burst
/// at 300 Hz keeps at most 0.55 % of its energy above 1024 Hz over Q ≥ 1,
/// asym 0.4-3 and drift ±0.5 (the worst corner, Q 1), 0.08 % at 200 Hz
/// (`scripts/burst_energy_above.py`): a mode found below is the same mode
/// at the full rate, where the fit refines it again.
pub const LOW_SEARCH_F0: f64 = 300.0;

/// Every candidate, in the order of `explain.gw`.
pub const FAMILIES: [Family; 9] = [
    Family { scene: "blip", label: "Blip", starts: blip_starts, profiled: &["f0", "q"], low_search: true, ..PLAIN },
    Family {
        scene: "koi_fish",
        label: "Koi Fish",
        starts: koi_fish_starts,
        after: Some(("tomte", koi_fish_from_head)),
        besides: Some(("blip", koi_fish_from_blip)),
        profiled: &["f0", "q"],
        low_search: true,
        ..PLAIN
    },
    Family {
        scene: "blip_echo",
        label: "Blip",
        variant_of: Some("blip"),
        contests: &["blip", "koi_fish", "tomte"],
        starts: blip_echo_starts,
        after: Some(("blip", blip_echo_from_blip)),
        profiled: &["f0", "q"],
        ..PLAIN
    },
    Family {
        scene: "whistle",
        label: "Whistle",
        data_starts: Some(whistle_data_starts),
        neighbours: Some(whistle_neighbours),
        scaled_steps: true,
        profiled: &["f_turn"],
        ..PLAIN
    },
    // A carrier of at most 600 Hz swung by at most 40 %, and the arches'
    // sidelines a few rates (≤ 40 Hz) beyond: below 1000 Hz.
    Family {
        scene: "scratchy",
        label: "Scratchy",
        data_starts: Some(scratchy_data_starts),
        neighbours: Some(scratchy_neighbours),
        top: 1000.0,
        ..PLAIN
    },
    // f0 ≤ 60 Hz at Q ≥ 1.2: the envelope's spectrum has a 1/e half-width
    // of √2 f0 / Q ≤ 71 Hz, so at 400 Hz it is down by e^-23.
    Family { scene: "tomte", label: "Tomte", starts: tomte_starts, refined: TOMTE_STARTS_REFINED, top: 400.0, ..PLAIN },
    // The third harmonic of fringes of at most 100 Hz.
    Family {
        scene: "scattered_light",
        label: "Scattered Light",
        starts: scattered_light_starts,
        data_starts: Some(scattered_light_data_starts),
        neighbours: Some(scattered_light_neighbours),
        measured_margin: SCATTERED_LIGHT_MEASURED_MARGIN,
        top: 400.0,
        ..PLAIN
    },
    // The inspiral ends at its ISCO: 191 Hz for the lightest binary of the bounds.
    Family {
        scene: "chirp",
        label: "Chirp",
        starts: chirp_starts,
        top: 400.0,
        profiled: &["mc", "mass_ratio"],
        ridge: Some(chirp_ridge),
        ..PLAIN
    },
    // Through merger and ringdown: PhenomA's cut is at 908 Hz for the
    // lightest binary of the bounds. Fitted on every window, as the chirp is.
    Family {
        scene: "chirp_imr",
        label: "Chirp",
        variant_of: Some("chirp"),
        starts: chirp_imr_starts,
        top: 1000.0,
        profiled: &["mc", "mass_ratio"],
        ..PLAIN
    },
];

/// Every combination of one value per axis, each at time offset `dt`.
fn grid(dt: f64, axes: &[&[f64]]) -> Vec<Start> {
    let shapes = axes.iter().fold(vec![Vec::new()], |acc: Vec<Vec<f64>>, axis| {
        acc.iter().flat_map(|g| axis.iter().map(move |v| [g.as_slice(), &[*v]].concat())).collect()
    });
    shapes.into_iter().map(|s| (dt, s)).collect()
}

/// `v` scaled by each factor.
fn scaled<const N: usize>(v: f64, factors: [f64; N]) -> [f64; N] {
    factors.map(|f| f * v)
}

// Symmetric, without drift.
fn blip_starts(s: &Seed) -> Vec<Start> {
    grid(s.dt, &[&scaled(s.frequency, [0.8, 1.0, 1.25]), &[2.5, 4.5, s.q.clamp(1.5, 12.0)], &[1.0], &[0.0]])
}

// The blip's starts with an echo at its frequency, 15 ms later (the fit
// of the blip finds better ones: `blip_echo_from_blip`).
fn blip_echo_starts(s: &Seed) -> Vec<Start> {
    blip_starts(s).into_iter().map(|(dt, x)| (dt, [x.as_slice(), &[0.3, 0.0, 0.015, 1.0]].concat())).collect()
}

// Seeded from the blip when the loudest tile is above [`HIGH_BAND`];
// else the loudest tile is the head (loud before whitening: 0.5-4 times
// the blip in the glitch benchmark), and the blip is the loudest pixel
// above that band, `lead` after the head.
fn koi_fish_starts(s: &Seed) -> Vec<Start> {
    let shape = |f0: &[f64], f_head: &[f64], lead: f64| grid(0.0, &[f0, &[1.5, 3.0], f_head, &[0.5, 2.0], &[lead], &[3.0], &[2.0], &[0.0]]);
    let at = |dt: f64, starts: Vec<Start>| starts.into_iter().map(move |(_, x)| (dt, x));
    match s.high {
        None => at(s.dt, shape(&scaled(s.frequency, [0.8, 1.0, 1.25]), &[20.0, 30.0, 45.0], 0.02)).collect(),
        Some((dt, f)) => {
            let lead = (dt - s.dt).clamp(0.005, 0.06);
            let heads = scaled(s.frequency, [0.9, 1.1]);
            at(dt, shape(&scaled(f, [0.8, 1.0, 1.25]), &heads, lead)).collect()
        }
    }
}

/// Times (s) around the loudest tile's that a Tomte's starts are tried
/// at: a slow decay puts the tile late, and a start a quarter cycle off
/// (6 ms at 40 Hz) climbs to the wrong ridge.
const TOMTE_START_OFFSETS: [f64; 5] = [-0.008, -0.004, 0.0, 0.004, 0.008];

// Tomtes sit below 60 Hz: starts there even when the loudest tile is
// higher (a low burst's whitened energy can peak above its f0).
fn tomte_starts(s: &Seed) -> Vec<Start> {
    let shapes = [&scaled(s.frequency.clamp(25.0, 55.0), [0.7, 0.85, 1.0, 1.2])[..], &[1.5, 2.5, 4.0], &[1.0, 2.0]];
    TOMTE_START_OFFSETS.iter().flat_map(|o| grid(s.dt + o, &shapes)).collect()
}

// The loudest tile sits near an arch's top (its highest fringe frequency,
// where the whitened fringes are strongest); the surface's period sets the
// arch's width and needs a grid: a template a few percent off in
// f_fringe / f_motion loses the fringes' phase.
fn scattered_light_starts(s: &Seed) -> Vec<Start> {
    let f = s.frequency.clamp(15.0, 100.0);
    grid(s.dt, &[&scaled(f, [0.8, 0.9, 1.0, 1.1, 1.25]), &[0.15, 0.25, 0.4, 0.6, 1.0, 1.6, 2.5], &[0.2], &[2.0]])
}

/// How many of the fringe search's arch shapes become starts (each with
/// a few bounces and durations).
const SCATTERED_LIGHT_DATA_STARTS: usize = 4;

// The arches' fringe frequency, surface motion and time, from tracks in
// the data's spectrogram refined by a coherent fringe search (`fringes.rs`).
fn scattered_light_data_starts(d: &[f64], fs: f64, _: &Seed) -> Vec<Start> {
    scattered_light_starts_from_data(d, fs, SCATTERED_LIGHT_DATA_STARTS)
}

/// A twentieth of the range moved every slow surface's start (f_motion
/// 0.1-0.245 Hz, a fifth of the campaign's log-uniform 0.15-2 Hz) to
/// 0.245 Hz, lobes away; a two-hundredth keeps them where the fringe
/// search put them. (For scratchy glitches it took seed 6's carriers
/// within 3σ from 97 to 82 of 100, cause not traced: they keep a twentieth.)
const SCATTERED_LIGHT_MEASURED_MARGIN: f64 = 0.005;

/// Relative steps in `f_motion`, either way, from a scattered-light fit
/// to its neighbours.
const SCATTERED_LIGHT_MOTION_STEPS: [f64; 6] = [0.01, 0.02, 0.03, 0.05, 0.08, 0.12];

// The arches' phase, (f_fringe / f_motion) sin(2π f_motion τ), puts the
// likelihood in lobes a few Fisher σ wide in `f_motion` (`fringes.rs`),
// and the fringe search's pick among them is made on unwhitened data
// under a fixed envelope. Seed 6's campaign had 17 of 100 surface speeds
// outside 3σ, 0.8-43 % from the truth; refitted from the truth, 13 of the
// 15 named Scattered Light fitted better (by 0.8-128 units of loss).
// Other speeds 1-12 % either way, the fringes at the arch's top kept:
// L-BFGS from each lands in a nearby lobe, and the modes found widen σ
// (seed 6: 83 -> 90 of 100 within 3σ).
fn scattered_light_neighbours((dt, shape): &Start) -> Vec<Start> {
    let &[f_fringe, f_motion, bounce, duration] = shape.as_slice() else { return Vec::new() };
    let steps = SCATTERED_LIGHT_MOTION_STEPS.iter().flat_map(|r| [1.0 - r, 1.0 + r]);
    steps.map(|s| (*dt, vec![f_fringe, f_motion * s, bounce, duration])).collect()
}

/// How many of the heterodyne search's whistle shapes become starts.
const WHISTLE_DATA_STARTS: usize = 12;

// The best whistle shapes of a dense grid of spans and widths, each with
// the vertex frequency that best matches the data (`heterodyne.rs`): any
// grid of starts the fits can afford is too coarse to land in a long
// sweep's narrow lobe.
fn whistle_data_starts(d: &[f64], fs: f64, s: &Seed) -> Vec<Start> {
    whistle_starts_from_data(d, fs, s, WHISTLE_DATA_STARTS)
}

/// A whistle's vertex frequency a cycle slip away, in cycles over its
/// half-width: the slip is `WHISTLE_SLIP_CYCLES / half` Hz.
const WHISTLE_SLIP_CYCLES: f64 = 0.15;

// The vertex frequency trades with the arms' shape (span, width and
// wiggle) along a curved valley, and noise breaks it into modes about
// 0.15 / half Hz apart (4-5 of its Fisher σ at SNR 15), each with its own
// wiggle: in white noise at SNR 15, 3 of 40 fits sat a mode off the
// truth's, 3.5-4.7 σ away. Vertices a slip either way, with the fit's
// wiggle or none.
fn whistle_neighbours((dt, shape): &Start) -> Vec<Start> {
    let &[f_turn, span, half, wiggle] = shape.as_slice() else { return Vec::new() };
    let slip = WHISTLE_SLIP_CYCLES / half;
    let wiggles = if wiggle == 0.0 { vec![0.0] } else { vec![wiggle, 0.0] };
    [-slip, slip].iter().flat_map(|s| wiggles.iter().map(move |w| (*dt, vec![f_turn + s, span, half, *w]))).collect()
}

// Whistles and scratchy glitches start from their data searches alone
// (`data_starts`): on 100 injections of each (seed 1) and 30 of every
// class (seed 4), grids of starts around the loudest tile (184 for a
// whistle, 108 for a scratchy glitch) changed no verdict, and ranking
// them took 0.14 s of a trigger's 1.19 s (median).
fn no_starts(_: &Seed) -> Vec<Start> {
    Vec::new()
}

/// How many of the heterodyne search's scratchy shapes become starts.
const SCRATCHY_DATA_STARTS: usize = 12;

// Carrier, rate, swing and arch phase from the comb of lines a train of
// arches makes in the data's spectrum (`heterodyne.rs`).
fn scratchy_data_starts(d: &[f64], fs: f64, s: &Seed) -> Vec<Start> {
    scratchy_starts_from_data(d, fs, s, SCRATCHY_DATA_STARTS)
}

/// How many comb lines away from a scratchy fit's carrier the fit is tried again.
const SCRATCHY_HOPS: [f64; 2] = [-1.0, 1.0];

// A train of arches is a comb of lines `rate` apart (`heterodyne.rs`); a
// carrier a line off, with another swing, matches nearly as well, and
// once there L-BFGS stays (seed 1: 32 of 100 carriers were one to three
// lines off, 26 of them one). Carriers a line away, with the same swing
// in hertz (`wobble · f0`) or the same `wobble`.
fn scratchy_neighbours((dt, shape): &Start) -> Vec<Start> {
    let &[f0, rate, duration, wobble] = shape.as_slice() else { return Vec::new() };
    let carriers = SCRATCHY_HOPS.iter().map(|k| f0 + k * rate).filter(|f| *f > 0.0);
    carriers.flat_map(|f| [wobble * f0 / f, wobble].map(|w| (*dt, vec![f, rate, duration, w]))).collect()
}

// The loudest tile usually sits just before the merger. A chirp stays in phase
// over its second in band only with the chirp mass within several
// percent, so the grid is dense: 9 % steps over the bounds (the chirp's
// scene runs at a quarter of the rate: 160 starts cost ~40 ms). On seed
// 2's campaign this took Chirps from 78 to 89 % right.
fn chirp_starts(s: &Seed) -> Vec<Start> {
    let masses = chirp_masses();
    let near_tile = [-0.01, 0.0, 0.01, 0.025, 0.05].iter().flat_map(|o| grid(s.dt + o, &[&masses, &[0.4, 0.8]]));
    // A light chirp's loudest tile can be its early inspiral, 0.1-0.3 s
    // before the merger (seed 1: all three light Chirps lost had it there):
    // each mass also starts at the merger its track puts after the tile,
    // at a few fractions of that time (the tile's frequency is coarse).
    let on_track = masses.iter().flat_map(|&mc| {
        let tau = time_to_merger(s.frequency, mc);
        CHIRP_TRACK_FRACTIONS.iter().flat_map(move |k| grid(s.dt + k * tau, &[&[mc], &[0.4, 0.8]]))
    });
    near_tile.chain(on_track.filter(|(dt, _)| dt.abs() < 0.3)).collect()
}

// The loudest tile is the merger's, the peak of the strain (`dt`): within
// 30 ms of it, in 10 ms steps (a start 5 ms off still matches well enough
// to rank; with the chirp's steps, up to 25 ms apart, the GWOSC GW150914
// fit took a 17 Msun mode, SNR 10.7 of 18.6). The masses and ratios of
// the chirp's grid.
fn chirp_imr_starts(s: &Seed) -> Vec<Start> {
    let masses = chirp_masses();
    (-3..=3).flat_map(|k| grid(s.dt + 0.01 * k as f64, &[&masses, &[0.4, 0.8]])).filter(|(dt, _)| dt.abs() < 0.3).collect()
}

/// The chirp masses (M☉) chirp starts are tried at: 9 % steps over the
/// scenes' bounds, 10.5-39.9.
fn chirp_masses() -> Vec<f64> {
    (0..16).map(|k| 10.5 * 1.093f64.powi(k)).collect()
}

/// Fractions of the leading-order time to merger from the tile at which
/// chirp starts are tried.
const CHIRP_TRACK_FRACTIONS: [f64; 3] = [0.6, 0.8, 1.0];

/// Seconds from gravitational-wave frequency `f` (Hz) to merger for chirp
/// mass `mc` (M☉), at leading (Newtonian) order: (5/256) (π f)^(−8/3)
/// (G Mc / c³)^(−5/3), the quadrupole formula's inspiral (Peters 1964).
fn time_to_merger(f: f64, mc: f64) -> f64 {
    // The language's `MTSUN`, G M☉ / c³ in seconds.
    let mtsun = gwml_compiler::check::CONSTANTS.iter().find(|c| c.name == "MTSUN").map_or(f64::NAN, |c| c.value);
    5.0 / 256.0 * (std::f64::consts::PI * f).powf(-8.0 / 3.0) * (mc * mtsun).powf(-5.0 / 3.0)
}

/// What the fits are compiled for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ExplainOptions {
    /// Sample rate of the whitened data (Hz).
    pub sample_rate: f64,
    /// Seconds of data fitted, centred on the trigger.
    pub window: f64,
    /// The band the data were whitened over (Hz); the models are whitened over it too.
    pub band: (f64, f64),
}

/// The stretch of whitened data a trigger's fits see.
#[derive(Clone, Debug, PartialEq)]
pub struct Window {
    /// GPS time of the window's centre sample (where `dt = 0`).
    pub gps_centre: f64,
    /// GPS time of its first sample.
    pub gps_start: f64,
    /// Index of its first sample in the whitened stretch it was cut from.
    pub offset: usize,
    /// Samples per second.
    pub sample_rate: f64,
    /// The whitened samples.
    pub d: Vec<f64>,
    /// The PSD the data were whitened by, on the window's `len / 2 + 1` bins.
    pub psd: Vec<f64>,
}

/// Seconds at each end of whitened data that a window may not reach (the
/// whitening's taper and filter edges).
pub const EDGE_SECONDS: f64 = 2.0;

/// Cuts `samples` whitened samples centred on `gps` out of `w`, or says
/// why it cannot (too near an end of the data, or longer than it).
pub fn window_at(w: &Whitened, gps: f64, samples: usize) -> Result<Window, String> {
    let fs = w.sample_rate;
    let (usable_start, usable_end) = (w.gps_start + EDGE_SECONDS, w.gps_start + w.w.len() as f64 / fs - EDGE_SECONDS);
    let seconds = samples as f64 / fs;
    let first = ((gps - w.gps_start) * fs).round() as i64 - (samples / 2) as i64;
    let gps_start = w.gps_start + first as f64 / fs;
    if seconds > usable_end - usable_start || first < 0 || gps_start < usable_start || gps_start + seconds > usable_end {
        return Err(format!(
            "a {seconds} s window around GPS {gps} needs GPS {:.3}..{:.3}, but the whitened data are usable over GPS {usable_start:.3}..{usable_end:.3} \
             only (the time is too near an end of the data, or the window too long)",
            gps - seconds / 2.0,
            gps + seconds / 2.0,
        ));
    }
    let offset = first as usize;
    Ok(Window {
        gps_centre: gps_start + (samples / 2) as f64 / fs,
        gps_start,
        offset,
        sample_rate: fs,
        d: w.w[offset..offset + samples].to_vec(),
        psd: w.psd.resample(fs / samples as f64, samples / 2 + 1),
    })
}

/// Explains the trigger at `gps` in whitened data `w` (whitened over the
/// band the explainer was compiled for): its window, seed and fits.
pub fn explain_at(explainer: &Explainer, w: &Whitened, gps: f64, band: (f64, f64)) -> Result<(Window, Seed, Explanation), String> {
    let win = window_at(w, gps, explainer.samples())?;
    let seed = seed_of(&win, w.sample_rate, band)?;
    let explanation = explainer.explain(&win.d, &win.psd, &seed).map_err(|e| e.render(false))?;
    Ok((win, seed, explanation))
}

/// The fit scenes, compiled once for a window and reused for every trigger.
pub struct Explainer {
    /// Each family's scenes and the divisor of the rate it runs at.
    scenes: Vec<(Family, FamilyScenes, usize)>,
    samples: usize,
    sample_rate: f64,
}

/// One family's scene, compiled twice from `explain.gw`.
pub(super) struct FamilyScenes {
    /// `loss` and `overlap` alone, what the fits evaluate: without the
    /// `model` series they take no inverse transform.
    pub(super) fit: Scene,
    /// Every output: `model`, the fitted shape, for the report and the
    /// Gauss–Newton Fisher matrix.
    pub(super) shape: Scene,
    /// `fit` at a lower rate and its divisor, for a family whose search
    /// may run there ([`Family::low_search`]).
    pub(super) search: Option<(Scene, usize)>,
}

/// The outputs a fit evaluates (see [`FamilyScenes::fit`]).
const FIT_OUTPUTS: [&str; 2] = ["loss", "overlap"];

impl Explainer {
    /// Checks `explain.gw` and compiles each family's scene for `o`.
    pub fn new(o: &ExplainOptions) -> Result<Explainer, Error> {
        let samples = (o.window * o.sample_rate).round() as usize;
        if !(o.window > 0.0 && samples >= 64 && o.band.0 >= 0.0 && o.band.1 > o.band.0) {
            return Err(Error::Bind(format!(
                "cannot fit a {} s window at {} Hz over {}..{} Hz: the window needs at least 64 samples and the band must be increasing",
                o.window, o.sample_rate, o.band.0, o.band.1
            )));
        }
        let model = Model::from_source("lab/models/glitch/explain.gw", EXPLAIN_SOURCE)?;
        let compile_at = |family: &Family, factor: usize, outputs: Option<Vec<String>>| {
            let rate = o.sample_rate / factor as f64;
            let knobs = [
                ("sample_rate", format!("{rate:?} Hz")),
                ("window", format!("{:?} s", samples as f64 / o.sample_rate)),
                ("f_low", format!("{:?} Hz", o.band.0)),
                ("f_high", format!("{:?} Hz", o.band.1.min(0.5 * rate))),
            ];
            // Inline exp, sin and cos to 1.1e-13: in unit-variance whitened
            // noise that is 1e-10 σ at SNR 1000, and the fits take 0.75 s a
            // trigger instead of 1.07 s with libm's (README, "Fast math").
            let options = Options {
                math: Some(MathMode::Fast),
                knobs: knobs.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(),
                outputs,
                ..Options::default()
            };
            model.scene_with(Some(family.scene), options)
        };
        let fit_outputs = || Some(FIT_OUTPUTS.map(String::from).to_vec());
        let compile = |family: &Family| {
            let factor = factor_for(o.sample_rate, samples, family.top);
            let low = factor_for(o.sample_rate, samples, SEARCH_TOP.min(family.top));
            let search = match family.low_search && low > factor {
                true => Some((compile_at(family, low, fit_outputs())?, low)),
                false => None,
            };
            let scenes = FamilyScenes { fit: compile_at(family, factor, fit_outputs())?, shape: compile_at(family, factor, None)?, search };
            Ok((*family, scenes, factor))
        };
        let scenes = FAMILIES.iter().map(compile).collect::<Result<_, Error>>()?;
        Ok(Explainer { scenes, samples, sample_rate: o.sample_rate })
    }

    /// Samples of the window the scenes take.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Fits every family to the whitened window `d` (centred on the
    /// trigger) whose PSD on the window's `samples / 2 + 1` bins is `psd`.
    pub fn explain(&self, d: &[f64], psd: &[f64], seed: &Seed) -> Result<Explanation, Error> {
        if d.len() != self.samples {
            return Err(Error::Bind(format!("the window has {} samples, the fits were compiled for {}", d.len(), self.samples)));
        }
        if let Some(i) = d.iter().position(|v| !v.is_finite()) {
            return Err(Error::Bind(format!("the whitened window has a non-finite sample at index {i}")));
        }
        let mut rates: Vec<Decimated> = Vec::new();
        let searched = self.scenes.iter().filter_map(|(_, s, _)| s.search.as_ref().map(|(_, factor)| *factor));
        for factor in self.scenes.iter().map(|(_, _, factor)| *factor).chain(searched) {
            if rates.iter().all(|r| r.factor != factor) {
                rates.push(decimate(d, psd, factor));
            }
        }
        // The window at `1 / factor` of the rate, and that rate.
        let at = |factor: usize| {
            let window = rates.iter().find(|r| r.factor == factor).expect("every factor decimated");
            (window, self.sample_rate / factor as f64)
        };
        let mut fits: Vec<FamilyFit> = Vec::with_capacity(self.scenes.len());
        // Families that build on another's fit go after the others.
        for building in [false, true] {
            let builds = |f: &Family| f.after.is_some() || f.besides.is_some();
            for (family, scene, factor) in self.scenes.iter().filter(|(f, ..)| builds(f) == building) {
                let clock = Instant::now();
                let built = |on: Option<(&'static str, FitStarts)>| {
                    on.and_then(|(base, starts)| {
                        let fit = fits.iter().find(|f| f.family.scene == base)?;
                        Some(starts(fit, d, self.sample_rate))
                    })
                    .unwrap_or_default()
                };
                let more = built(family.after);
                let leader = fits.iter().max_by(|a, b| a.ln_z().total_cmp(&b.ln_z())).map(|f| f.family.base());
                let nothing_left = family.after.is_some() && more.is_empty();
                let not_contested = !family.contests.is_empty() && !leader.is_some_and(|l| family.contests.contains(&l));
                if family.variant_of.is_some() && (nothing_left || not_contested) {
                    continue;
                }
                let window = at(*factor);
                let low = scene.search.as_ref().map(|(_, factor)| at(*factor));
                let begin = Begin::Search { seed, more, besides: built(family.besides), low };
                let mut fit = fit_family(family, scene, window, begin)?;
                fit.seconds = clock.elapsed().as_secs_f64();
                fits.push(fit);
            }
        }
        fits.sort_by(|a, b| b.ln_z().total_cmp(&a.ln_z()));
        // One fit per family: its better-fitting variant.
        let mut kept: Vec<&str> = Vec::new();
        let (fits, worse_variants): (Vec<FamilyFit>, Vec<FamilyFit>) = fits.into_iter().partition(|f| {
            let fresh = !kept.contains(&f.family.base());
            kept.push(f.family.base());
            fresh
        });
        let mut fits = fits;
        // The neighbouring modes and profiled σ of the fits that compete
        // for the verdict (only there do their params matter enough to pay
        // for them), and a polish for those and for the fits whose ln B
        // against noise alone is within [`NOISE_GATE`].
        let best = fits.first().map_or(f64::NEG_INFINITY, FamilyFit::ln_z);
        let noise_loss = 0.5 * d.iter().map(|v| v * v).sum::<f64>();
        let contends = |f: &FamilyFit| f.ln_z() >= best - NEIGHBOUR_GATE;
        let near_noise = |f: &FamilyFit| (f.ln_z() + noise_loss).abs() <= NOISE_GATE;
        let refined = |f: &Family| f.neighbours.is_some() || !f.profiled.is_empty();
        let comes_back = |f: &FamilyFit| (contends(f) && (refined(&f.family) || !f.polished)) || (near_noise(f) && !f.polished);
        for fit in fits.iter_mut().filter(|f| comes_back(f)) {
            let contender = contends(fit);
            let clock = Instant::now();
            let (family, scene, factor) = self.scenes.iter().find(|(f, ..)| f.scene == fit.family.scene).expect("a compiled family");
            let window = at(*factor);
            let seconds = fit.seconds;
            // Refitted from its params: polished, and its neighbours tried.
            if !fit.polished || (contender && family.neighbours.is_some()) {
                let x = fit.params.iter().map(|p| p.value).collect();
                let begin = if contender { Begin::Neighbours(x) } else { Begin::Params(x) };
                let hopped = fit_family(family, scene, window, begin)?;
                let evaluations = fit.evaluations + hopped.evaluations;
                *fit = FamilyFit { evaluations, ..hopped };
            }
            // A profile point that fits better is a better mode along the
            // valley the profile follows: the fit is redone from there.
            let mut jumps = 0;
            while let Some(x) = if contender { widen_to_profiles(&scene.fit, window.0, fit)? } else { None } {
                if jumps == PROFILE_JUMPS {
                    break;
                }
                jumps += 1;
                let jumped = fit_family(family, scene, window, Begin::Neighbours(x))?;
                let evaluations = fit.evaluations + jumped.evaluations;
                *fit = FamilyFit { evaluations, ..jumped };
            }
            fit.seconds = seconds + clock.elapsed().as_secs_f64();
        }
        fits.sort_by(|a, b| b.ln_z().total_cmp(&a.ln_z()));
        Ok(Explanation { fits, worse_variants, noise_loss, samples: d.len() })
    }
}

/// What the start searches' tests share.
#[cfg(test)]
mod test_support;

#[cfg(test)]
mod tests {
    use super::*;

    /// A scratchy fit's neighbours sit a comb line either side of its
    /// carrier, with its swing in hertz or its `wobble`, and nothing else moved.
    #[test]
    fn scratchy_neighbours_are_a_comb_line_either_side() {
        let near = scratchy_neighbours(&(0.03, vec![180.0, 17.0, 1.2, 0.1]));
        let expected = [[163.0, 0.1 * 180.0 / 163.0], [163.0, 0.1], [197.0, 0.1 * 180.0 / 197.0], [197.0, 0.1]];
        assert_eq!(near.len(), expected.len());
        for ((dt, shape), [f0, wobble]) in near.iter().zip(expected) {
            assert_eq!((*dt, shape[1], shape[2]), (0.03, 17.0, 1.2));
            assert!((shape[0] - f0).abs() < 1e-12 && (shape[3] - wobble).abs() < 1e-12, "{shape:?}");
        }
        // A carrier a line below zero is not one.
        assert_eq!(scratchy_neighbours(&(0.0, vec![10.0, 17.0, 1.2, 0.1])).len(), 2);
    }

    /// A whistle fit's neighbours sit a cycle slip (0.15 / half Hz) either
    /// side of its vertex, with its wiggle and with none, the span, width
    /// and time unmoved; a V's (no wiggle) are two.
    #[test]
    fn whistle_neighbours_are_a_cycle_slip_either_side() {
        let near = whistle_neighbours(&(0.01, vec![700.0, 300.0, 0.25, 40.0]));
        let expected = [[699.4, 40.0], [699.4, 0.0], [700.6, 40.0], [700.6, 0.0]];
        assert_eq!(near.len(), expected.len());
        for ((dt, shape), [f_turn, wiggle]) in near.iter().zip(expected) {
            assert_eq!((*dt, shape[1], shape[2]), (0.01, 300.0, 0.25));
            assert!((shape[0] - f_turn).abs() < 1e-9 && shape[3] == wiggle, "{shape:?}");
        }
        let v = whistle_neighbours(&(0.0, vec![700.0, 300.0, 0.1, 0.0]));
        assert_eq!(v.len(), 2);
        assert!((v[0].1[0] - 698.5).abs() < 1e-9 && (v[1].1[0] - 701.5).abs() < 1e-9, "{v:?}");
    }

    /// A scattered-light fit's neighbours change the surface's speed by
    /// 1-12 % either way and nothing else.
    #[test]
    fn scattered_light_neighbours_step_the_surface_speed_alone() {
        let near = scattered_light_neighbours(&(-0.02, vec![40.0, 0.25, 0.2, 2.5]));
        assert_eq!(near.len(), 2 * SCATTERED_LIGHT_MOTION_STEPS.len());
        for ((dt, shape), r) in near.iter().zip(SCATTERED_LIGHT_MOTION_STEPS.iter().flat_map(|r| [-r, *r])) {
            assert_eq!((*dt, shape[0], shape[2], shape[3]), (-0.02, 40.0, 0.2, 2.5));
            assert!((shape[1] - 0.25 * (1.0 + r)).abs() < 1e-15, "{shape:?}");
        }
        assert!(scattered_light_neighbours(&(0.0, vec![40.0, 0.25])).is_empty());
    }

    /// A blip and a Koi Fish whose starts sit below [`LOW_SEARCH_F0`] are
    /// searched at half the rate. On blips the blip fit ends where the
    /// full-rate search ends (loss to 0.05, params to a quarter of their σ;
    /// the drift, in a flat valley, moves by a tenth), and the Koi Fish fit
    /// no worse (it has other modes: at 180 Hz the half-rate path found
    /// one 0.3 lower).
    #[test]
    fn a_search_at_half_the_rate_ends_where_the_full_rate_search_does() {
        use super::test_support::at_snr_in_white_noise;
        let (fs, n) = (4096.0, 8192);
        let o = ExplainOptions { sample_rate: fs, window: 2.0, band: (20.0, 2000.0) };
        let low = Explainer::new(&o).unwrap();
        let mut full = Explainer::new(&o).unwrap();
        for (family, scenes, factor) in &mut full.scenes {
            assert_eq!(scenes.search.as_ref().map(|(_, f)| *f), family.low_search.then_some(2 * *factor), "{}", family.scene);
            scenes.search = None;
        }
        // Blips at 120 and 180 Hz (Q 3 and 1.5, the second's decay half its rise).
        for (seed, f0, q, asym) in [(1, 120.0, 3.0, 1.0), (2, 180.0, 1.5, 0.5)] {
            let tau = q / (std::f64::consts::SQRT_2 * std::f64::consts::PI * f0);
            let h: Vec<f64> = (0..n)
                .map(|k| {
                    let dt = k as f64 / fs - 1.01;
                    let u = dt / if dt < 0.0 { tau } else { asym * tau };
                    (-u * u).exp() * (std::f64::consts::TAU * f0 * dt + 0.7).cos()
                })
                .collect();
            let d = at_snr_in_white_noise(&h, 25.0, seed);
            let psd = vec![1.0; n / 2 + 1];
            let win = Window { gps_centre: 1.0, gps_start: 0.0, offset: 0, sample_rate: fs, d: d.clone(), psd: psd.clone() };
            let start = seed_of(&win, fs, o.band).unwrap();
            let fit = |e: &Explainer, scene: &str| {
                let x = e.explain(&d, &psd, &start).unwrap();
                x.fits.into_iter().chain(x.worse_variants).find(|f| f.family.scene == scene).unwrap()
            };
            for scene in ["blip", "koi_fish"] {
                let (a, b) = (fit(&low, scene), fit(&full, scene));
                let worse = a.score.loss - b.score.loss;
                let (low_loss, full_loss) = (a.score.loss, b.score.loss);
                assert!(worse < 0.05, "{scene} at {f0} Hz: loss {low_loss} searched low, {full_loss} at full rate");
                if scene == "blip" {
                    assert!(worse > -0.05, "blip at {f0} Hz: loss {low_loss} searched low, {full_loss} at full rate");
                    for (p, q) in a.params.iter().zip(&b.params).filter(|(p, _)| p.name != "phi") {
                        let sigma = q.sigma.expect("a blip at SNR 25 has σ");
                        assert!(
                            (p.value - q.value).abs() < 0.25 * sigma,
                            "{} at {f0} Hz: {} against {} ± {sigma}",
                            p.name,
                            p.value,
                            q.value
                        );
                    }
                }
            }
        }
    }

    /// A 1.4 + 1.4 M☉ binary spends ~17 minutes above 10 Hz at leading
    /// order (1002.4 s from the closed form in double precision, Python).
    #[test]
    fn the_time_to_merger_is_the_quadrupole_inspirals() {
        let mc = (1.4f64 * 1.4).powf(0.6) / 2.8f64.powf(0.2);
        assert!((time_to_merger(10.0, mc) - 1002.4078).abs() < 1e-3, "{}", time_to_merger(10.0, mc));
        // τ ∝ f^(−8/3) Mc^(−5/3).
        let ratio = time_to_merger(34.0, 21.0) / time_to_merger(68.0, 42.0);
        assert!((ratio - 2f64.powf(8.0 / 3.0 + 5.0 / 3.0)).abs() < 1e-9 * ratio);
    }

    /// A chirp whose loudest tile is its early inspiral, 0.25 s before the
    /// merger at 34 Hz, has starts near the merger for masses around its own.
    #[test]
    fn chirp_starts_reach_the_merger_after_an_early_tile() {
        let seed = Seed { dt: -0.25, frequency: 34.0, q: 5.7, arches: None, high: None, whistle: Vec::new() };
        let starts = chirp_starts(&seed);
        let near = starts.iter().filter(|(dt, x)| dt.abs() < 0.05 && (18.0..24.0).contains(&x[0])).count();
        assert!(near >= 2, "{} starts within 50 ms of the merger at 18-24 Msun", near);
        assert!(starts.iter().all(|(dt, _)| dt.abs() < 0.3), "a start outside the dt bounds");
    }

    /// A profile point on the chirp's ridge keeps the fit's total mass:
    /// seed 1's fit at mc 27.75, q 0.998 is on the ridge through the
    /// injection (25.63, 0.48); past equal masses q stays at 1.
    #[test]
    fn a_chirp_profile_point_keeps_the_total_mass() {
        let total = |mc: f64, q: f64| mc * (q / (1.0 + q).powi(2)).powf(-0.6);
        let fit = [0.002, 20.0, 1.0, 27.75, 0.998];
        let y = chirp_ridge(&fit, 3, 25.63).unwrap();
        assert_eq!((y[0], y[1], y[2], y[3]), (0.002, 20.0, 1.0, 25.63), "only mc and q move");
        assert!((total(y[3], y[4]) - total(27.75, 0.998)).abs() < 1e-9 * total(27.75, 0.998));
        assert!((y[4] - 0.48).abs() < 0.01, "q {}", y[4]);
        for (mc, q, to) in [(30.0, 0.5, 27.0), (12.0, 0.3, 11.0), (35.0, 0.8, 35.2)] {
            let y = chirp_ridge(&[0.0, 10.0, 0.0, mc, q], 3, to).unwrap();
            assert!((total(y[3], y[4]) - total(mc, q)).abs() < 1e-9 * total(mc, q), "{mc} {q} -> {to}: q {}", y[4]);
            let z = chirp_ridge(&[0.0, 10.0, 0.0, mc, q], 4, 0.9 * q).unwrap();
            assert!((total(z[3], z[4]) - total(mc, q)).abs() < 1e-9 * total(mc, q));
        }
        // A chirp mass above the ridge's equal-mass end: q at 1.
        assert_eq!(chirp_ridge(&fit, 3, 29.0).unwrap()[4], 1.0);
        assert!(chirp_ridge(&fit, 0, 0.01).is_none(), "no ridge in dt");
    }
}
