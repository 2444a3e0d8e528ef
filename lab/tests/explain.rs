//! `gwml explain`'s fits on injections into simulated coloured strain: the
//! right family wins, the shape params come back within their Fisher
//! errors, and Gaussian noise alone is explained as noise. (The full
//! campaign, 100 per family, is `gwml experiment explain`; README.)

use gwml_lab::explain::*;
use gwml_lab::strain::{simulate, Injection, NoiseCurve, StrainOptions, SAMPLE_RATE};
use gwml_lab::synth::GLITCH_CLASSES;
use gwml_strain::psd::{Welch, WelchOptions};
use gwml_strain::whitening::{whiten_series, whiten_with, WhitenOptions, Whitened, Whitener};

#[test]
fn each_family_is_told_apart_and_its_params_recovered() {
    let o = CampaignOptions { per_class: 4, classes: (1..GLITCH_CLASSES.len()).collect(), snr: Some((15.0, 30.0)), window: 2.0, seed: 3 };
    let outcomes = run_campaign(&o, |_| {}).unwrap();
    assert_eq!(outcomes.len(), 28);
    // A blip below 80 Hz (they start at 70 Hz) may be called a Tomte
    // (25-45 Hz), and that is the prior's verdict.
    let f0 = |o: &Outcome| o.injection.params.iter().find(|p| p.0 == "f0").map_or(f64::NAN, |p| p.1);
    let overlap = |o: &Outcome| o.verdict() == "Tomte" && GLITCH_CLASSES[o.injection.class] == "Blip" && f0(o) < 80.0;
    let right = outcomes.iter().filter(|o| o.right() || overlap(o)).count();
    let verdicts: Vec<(&str, &str, f64)> = outcomes.iter().map(|o| (GLITCH_CLASSES[o.injection.class], o.verdict(), f0(o))).collect();
    // The campaign (README) wins Blip 94-98 %, Koi Fish 96-98 %,
    // Whistle 94-100 %, Scratchy 100 %, Chirp 97-98 %,
    // Tomte 100 %, Scattered Light 95-99 %: ~26 of these 28 on average.
    assert!(right >= 23, "{right} of 28 explained by the injected family: {verdicts:?}");
    for (label, n, right, params) in summarise(&outcomes) {
        let overlapping = outcomes.iter().filter(|o| GLITCH_CLASSES[o.injection.class] == label && overlap(o)).count();
        // Whistles, Koi Fish and Blips are won less often (the campaign,
        // README): a long sweep's search can miss, a Koi Fish whose head
        // is below the band looks like a blip, and a blip with an echo
        // like a Koi Fish (3-5 % of Blips).
        let misses = if ["Whistle", "Koi Fish", "Blip"].contains(&label) { 2 } else { 1 };
        assert!(right + overlapping + misses >= n, "{label}: {right} of {n} right: {verdicts:?}");
        for (name, with_sigma, within, median) in params {
            // The targets: f0 within 10 % and Q within 30 % in the
            // median, and within 3σ. A scratchy glitch's carrier and arch
            // rate come from the comb of lines it makes (heterodyne.rs):
            // within 0.1-0.2 % in the campaign's median; 7 % before.
            if label == "Blip" && name == "f0" {
                assert!(median < 0.1, "{label} {name}: median relative error {median}");
                assert!(within + 1 >= with_sigma, "{label} {name}: {within} of {with_sigma} within 3σ");
            }
            // The chirp's ISCO cut is smoothed over a bin, so its loss is
            // smooth and every fit has Fisher errors (with the hard cut the
            // fits stopped on a bin edge: 70 of 100 had none, seed 1).
            if label == "Chirp" && name == "mc" {
                assert!(with_sigma >= right, "{label} {name}: {with_sigma} of {right} with a σ");
            }
            if label == "Scratchy" && (name == "f0" || name == "rate") {
                assert!(median < 0.02, "{label} {name}: median relative error {median}");
            }
            // A carrier a comb line off, a mode of its own, is tried from
            // the fit (`scratchy_neighbours`), and σ covers both modes when
            // both are known: 68 -> 97 % within 3σ on the campaign's seed 1.
            if label == "Scratchy" && name == "f0" {
                assert_eq!(within, with_sigma, "{label} {name}: {within} of {with_sigma} within 3σ");
            }
            // Scattered light's fringe frequency and surface speed come
            // from the fringe search (fringes.rs): 0.1 % in the campaign's
            // median, with a tail in the speed (one arch in the window
            // pins it only by its curvature).
            if label == "Scattered Light" && name == "f_fringe" {
                assert!(median < 0.02, "{label} {name}: median relative error {median}");
            }
            if label == "Scattered Light" && name == "f_motion" {
                assert!(median < 0.05, "{label} {name}: median relative error {median}");
            }
        }
    }
    // The fits that contend for the verdict (within 10 in ln B of the
    // best, 20 of noise alone) are polished; the far ones keep their
    // refined minimum, and those are most fits (what the saving is:
    // 1.18 -> 1.11 s a trigger).
    let (mut far, mut unpolished) = (0, 0);
    for o in &outcomes {
        let best = o.explanation.fits[0].ln_z();
        for f in &o.explanation.fits {
            let is_far = f.ln_z() < best - 10.0 && o.explanation.ln_bayes_vs_noise(f).abs() > 20.0;
            assert!(f.polished || is_far, "{}: an unpolished contender ({} against {best})", f.family.scene, f.ln_z());
            far += usize::from(is_far);
            unpolished += usize::from(!f.polished);
        }
    }
    assert!(2 * unpolished > far, "{unpolished} of {far} far fits unpolished");
    // Every fit is finite and its evidence well defined.
    for o in &outcomes {
        for f in &o.explanation.fits {
            assert!(f.ln_z().is_finite() && f.chi2_dof.is_finite(), "{}: {:?}", f.family.scene, f.score);
        }
    }
}

#[test]
fn w_and_m_shaped_whistles_are_fitted_with_their_wiggle() {
    // 40 % of the benchmark's whistles bend their arms (`wiggle`, up to
    // ±600 Hz). Without it in the fit, the vertex frequency came back
    // within 3σ for 62 of 93 whistles on the campaign's seed 1; with it
    // (heterodyne.rs' W and M search, fit.rs' JᵀJ Fisher matrix), 86 of 100.
    let whistle = GLITCH_CLASSES.iter().position(|c| *c == "Whistle").unwrap();
    let o = CampaignOptions { per_class: 8, classes: vec![whistle], snr: Some((20.0, 30.0)), window: 2.0, seed: 5 };
    let outcomes = run_campaign(&o, |_| {}).unwrap();
    let truth = |o: &Outcome, name: &str| o.injection.params.iter().find(|p| p.0 == name).map_or(f64::NAN, |p| p.1);
    let bent: Vec<&Outcome> = outcomes.iter().filter(|o| truth(o, "wiggle").abs() > 100.0).collect();
    assert!(bent.len() >= 2, "{} of 8 whistles bent", bent.len());
    // Each a Whistle, its vertex frequency, span, width and wiggle all
    // within 4σ and all but two of them within 3σ (without the wiggle,
    // bent whistles' vertices were 5-15σ off).
    let mut pulls = Vec::new();
    for o in &bent {
        assert_eq!(o.verdict(), "Whistle");
        for (name, value, sigma, t) in o.recovered() {
            let sigma = sigma.unwrap_or_else(|| panic!("{name}: no σ"));
            pulls.push((name, (value - t) / sigma, truth(o, "wiggle")));
        }
    }
    assert_eq!(pulls.len(), 4 * bent.len());
    assert!(pulls.iter().all(|p| p.1.abs() < 4.0), "pulls (param, pull, wiggle): {pulls:?}");
    assert!(pulls.iter().filter(|p| p.1.abs() > 3.0).count() <= 2, "pulls (param, pull, wiggle): {pulls:?}");
}

#[test]
fn gaussian_noise_alone_is_explained_as_noise() {
    let strain = StrainOptions {
        duration: 64.0,
        gps_start: 1e9,
        ifo: "H1".into(),
        psd: NoiseCurve::Aligo,
        glitch_rate: 0.0,
        classes: vec![1],
        snr: Some((10.0, 20.0)),
        gaps: Vec::new(),
        seed: 11,
    };
    let (series, _) = simulate(&strain).unwrap();
    let band = (20.0, 2000.0);
    let w = whiten_series(&Whitener::new().unwrap(), &series, 4.0, &WhitenOptions { taper: 2.0, band, classifier_band: band }).unwrap();
    let explainer = Explainer::new(&ExplainOptions { sample_rate: SAMPLE_RATE, window: 2.0, band }).unwrap();
    for k in 0..4 {
        let gps = 1e9 + 10.0 + 12.0 * k as f64;
        let (_, _, e) = explain_at(&explainer, &w, gps, band).unwrap();
        assert!(e.best().is_none(), "GPS {gps}: {} beats noise by ln B {}", e.fits[0].family.scene, e.ln_bayes_vs_noise(&e.fits[0]));
        // χ²/dof of noise alone is 1 up to the band's share of the spectrum.
        let chi2 = 2.0 * e.noise_loss / e.samples as f64;
        assert!((chi2 - 1.0).abs() < 0.1, "noise χ²/dof {chi2}");
    }
    // A window reaching past the whitened data's usable part is an error.
    let err = window_at(&w, 1e9 + 1.5, explainer.samples()).unwrap_err();
    assert!(err.contains("too near an end"), "{err}");
}

/// The low-frequency families run at a quarter of the rate; their losses
/// must be the full-rate scene's (what the cut bins add is the same for
/// every template of the family).
#[test]
fn a_fit_at_a_lower_rate_has_the_full_rate_loss() {
    use gwml_compiler::Options;
    use gwml_runtime::Model;
    let strain = StrainOptions {
        duration: 64.0,
        gps_start: 1e9,
        ifo: "H1".into(),
        psd: NoiseCurve::Aligo,
        glitch_rate: 6.0,
        classes: vec![GLITCH_CLASSES.iter().position(|c| *c == "Tomte").unwrap()],
        snr: Some((20.0, 20.0)),
        gaps: Vec::new(),
        seed: 5,
    };
    let (series, injections) = simulate(&strain).unwrap();
    let band = (20.0, 2000.0);
    let w = whiten_series(&Whitener::new().unwrap(), &series, 4.0, &WhitenOptions { taper: 2.0, band, classifier_band: band }).unwrap();
    let win = window_at(&w, injections[1].gps_time, 8192).unwrap();
    let model = Model::from_source("explain.gw", EXPLAIN_SOURCE).unwrap();
    let loss_at = |rate: f64, d: &[f64], psd: &[f64], params: &[(&str, f64)]| {
        let knobs = [("sample_rate", format!("{rate:?} Hz")), ("f_high", format!("{:?} Hz", (0.5 * rate).min(2000.0)))];
        let options = Options { knobs: knobs.iter().map(|(k, v)| (k.to_string(), v.clone())).collect(), ..Options::default() };
        let scene = model.scene_with(Some("tomte"), options).unwrap();
        let mut run = scene.bind();
        run.input_real("d", d).unwrap();
        run.input_real("psd", psd).unwrap();
        for (name, v) in params {
            run.param(name, *v).unwrap();
        }
        run.forward().unwrap().scalar("loss").unwrap()
    };
    let low = decimate(&win.d, &win.psd, 4);
    for params in [
        vec![("dt", 0.0), ("snr", 18.0), ("phi", 1.0), ("f0", 45.0), ("q", 2.5), ("asym", 1.5)],
        vec![("dt", 0.1), ("snr", 5.0), ("phi", 4.0), ("f0", 60.0), ("q", 1.2), ("asym", 4.0)],
    ] {
        let full = loss_at(4096.0, &win.d, &win.psd, &params);
        let reduced = loss_at(1024.0, &low.d, &low.psd, &params) + low.cut_loss;
        // At the bounds' corner (f0 60 Hz, Q 1.2, asym 4) little of the
        // template's energy lies above 512 Hz (at f0 75 Hz ~1e-4: 0.002
        // in ln L at SNR 5).
        assert!((full - reduced).abs() < 0.01, "{params:?}: full rate {full}, quarter rate {reduced}");
    }
}

#[test]
fn the_campaign_strain_keeps_its_glitches_out_of_its_own_psd() {
    // The campaign whitens each stretch by the Welch PSD of that stretch.
    // Koi Fish are the loudest class (SNR 12-400): at 10 a minute, two in
    // three 4 s segments held one and the median PSD rose with them, so a
    // Koi Fish's whitened SNR came out 0.73-0.88 of its injected SNR. At
    // the campaign's rate it keeps ≥ 0.95 of it; the noise-free signal is
    // the strain less the same stretch simulated without glitches.
    let koi_fish = GLITCH_CLASSES.iter().position(|c| *c == "Koi Fish").unwrap();
    let o = CampaignOptions { per_class: 10, classes: vec![koi_fish], snr: None, window: 2.0, seed: 1 };
    let band = (20.0, 2000.0);
    let whitener = Whitener::new().unwrap();
    let kept = |rate: f64| {
        let strain = StrainOptions { glitch_rate: rate, ..campaign_strain(&o, koi_fish, 0) };
        let (noisy, injections) = simulate(&strain).unwrap();
        let (noise, _) = simulate(&StrainOptions { glitch_rate: 0.0, ..strain }).unwrap();
        let fs = noisy.sample_rate;
        let psd = Welch::new(fs, WelchOptions::seconds(4.0, fs)).unwrap().estimate(&noisy.samples).unwrap();
        let clean: Vec<f64> = noisy.samples.iter().zip(&noise.samples).map(|(a, b)| a - b).collect();
        let options = WhitenOptions { taper: 2.0, band, classifier_band: band };
        let scene = whitener.scene(clean.len(), fs, &options).unwrap();
        let mut run = scene.bind();
        let (w, _) = whiten_with(&mut run, &clean, &psd, (fs, noisy.gps_start, "clean")).unwrap();
        let whitened = Whitened { gps_start: noisy.gps_start, sample_rate: fs, w: w.clone(), w_clf: w, psd };
        let mut ratios: Vec<f64> = injections
            .iter()
            .map(|i| window_at(&whitened, i.gps_time, (2.0 * fs) as usize).unwrap().d.iter().map(|v| v * v).sum::<f64>().sqrt() / i.snr)
            .collect();
        assert!(ratios.len() >= 5, "{} injections at {rate} a minute", ratios.len());
        ratios.sort_by(f64::total_cmp);
        ratios[ratios.len() / 2]
    };
    let (campaign, dense) = (kept(CAMPAIGN_RATE), kept(10.0));
    assert!(campaign >= 0.95, "at the campaign's rate the median Koi Fish keeps {campaign:.3} of its SNR");
    assert!(dense < 0.92, "at 10 a minute the median Koi Fish keeps {dense:.3} of its SNR");
}

#[test]
fn loud_tomtes_are_fitted_on_their_own_ridge() {
    // A Tomte's Q, rise and decay trade along a ridge. From the two best
    // starts at the loudest tile's time, the Tomte fit of a loud Tomte
    // could end on its bounds (asym 1, Q 5) ten units of loss short of the
    // truth's, and the blip fit or a Koi Fish's head took the window: four
    // of the campaign's first 60 Tomtes (seed 1, SNR 26-47, as it drew
    // them before the Koi Fish rule reordered the draws). Starts a few ms
    // either side of the tile, six of them refined, find the ridge. Every
    // Tomte above SNR 35 of the campaign's first 40 (seven, SNR 39-48):
    let verdicts = campaign_verdicts("Tomte", 1, 40, |i| i.snr > 35.0);
    assert!(verdicts.len() >= 3, "{verdicts:?}");
    assert!(verdicts.iter().all(|v| v.1 == "Tomte"), "{verdicts:?}");
}

#[test]
fn a_blip_with_an_echo_below_it_is_not_a_koi_fish() {
    // An echo 0.7-0.8 times a blip's frequency, 18-30 ms after it, looks
    // like a Koi Fish's head when heads may reach 80 Hz: seed 2 named six
    // of its 100 Blips Koi Fish so (ln B 0.9-8.9, with heads fitted at
    // 58-80 Hz). A Koi Fish's head is low (std::glitch's 20-50 Hz), and
    // the scene's bound says so. The loud-echo Blips below 100 Hz and SNR
    // 25 of the campaign's first 60 (four: two of them were Koi Fish):
    let param = |i: &Injection, name: &str| i.params.iter().find(|p| p.0 == name).map_or(f64::NAN, |p| p.1);
    let verdicts = campaign_verdicts("Blip", 2, 60, |i| param(i, "echo") > 0.3 && param(i, "f0") < 100.0 && i.snr < 25.0);
    assert!(verdicts.len() >= 3, "{verdicts:?}");
    assert!(verdicts.iter().all(|v| v.1 != "Koi Fish"), "{verdicts:?}");
}

#[test]
fn blip_shapes_come_back_within_the_targets_in_the_median() {
    // The targets: f0 within 10 % and Q within 30 % of the truth
    // in the median. A low-Q blip's Q lies along a flat valley (σ ~30 %),
    // so the median of four moved from 0.2 to 0.36 with the rounding of
    // the loss (one fit landing 2.4 higher in loss): twelve, each class's
    // own SNR range (from 10 up).
    let outcomes = campaign_outcomes("Blip", 3, 12, |_| true);
    assert_eq!(outcomes.len(), 12);
    let median_error = |param: &str| {
        let mut errors: Vec<f64> =
            outcomes.iter().flat_map(|o| o.recovered()).filter(|r| r.0 == param).map(|(_, v, _, t)| ((v - t) / t).abs()).collect();
        assert_eq!(errors.len(), 12, "{param}: {errors:?}");
        errors.sort_by(f64::total_cmp);
        0.5 * (errors[5] + errors[6])
    };
    let (f0, q) = (median_error("f0"), median_error("q"));
    assert!(f0 < 0.1 && q < 0.3, "median relative errors: f0 {f0}, q {q}");
}

#[test]
fn a_scattered_light_fit_finds_the_lobe_of_the_surface_speed() {
    // The arches' phase splits the likelihood into lobes in `f_motion` a
    // few Fisher σ wide; the fringe search could start the fit in the
    // wrong one. Of seed 6's first 21 Scattered Light injections, four
    // surface speeds were outside 3σ (3-43 % off, 9-36σ) before the fit
    // tried its neighbours 1-12 % either way, two after, and one since a
    // slow surface's start stays where the data put it (0.16 Hz, not
    // moved to 0.245 Hz by the starts' margin).
    let outcomes = campaign_outcomes("Scattered Light", 6, 21, |_| true);
    assert_eq!(outcomes.len(), 21);
    let pulls: Vec<f64> = outcomes
        .iter()
        .flat_map(|o| o.recovered())
        .filter(|(name, ..)| *name == "f_motion")
        .map(|(_, value, sigma, truth)| sigma.map_or(f64::INFINITY, |s| (value - truth) / s))
        .collect();
    let outside = pulls.iter().filter(|z| z.abs() > 3.0).count();
    assert!(pulls.len() >= 20 && outside <= 1, "f_motion pulls {pulls:?}");
}

/// `(SNR, verdict)` of each of the first `first` injections of `class` in
/// the explain campaign of `seed` (each class's own SNR range) that `pick`
/// selects, explained as the campaign does.
fn campaign_verdicts(class: &str, seed: u64, first: usize, pick: impl Fn(&Injection) -> bool) -> Vec<(f64, &'static str)> {
    campaign_outcomes(class, seed, first, pick).iter().map(|o| (o.injection.snr, o.verdict())).collect()
}

/// The explanations of the first `first` injections of `class` in the
/// explain campaign of `seed` (each class's own SNR range) that `pick`
/// selects, explained as the campaign does.
fn campaign_outcomes(class: &str, seed: u64, first: usize, pick: impl Fn(&Injection) -> bool) -> Vec<Outcome> {
    let index = GLITCH_CLASSES.iter().position(|c| *c == class).unwrap();
    let o = CampaignOptions { per_class: 100, classes: vec![index], snr: None, window: 2.0, seed };
    let band = (20.0, 2000.0);
    let explainer = Explainer::new(&ExplainOptions { sample_rate: SAMPLE_RATE, window: 2.0, band }).unwrap();
    let whitener = Whitener::new().unwrap();
    let (mut seen, mut outcomes) = (0, Vec::new());
    for stretch in 0.. {
        let (w, injections) = campaign_stretch(&o, index, stretch, &whitener, band).unwrap();
        for injection in injections.iter().take(first - seen).filter(|i| pick(i)) {
            let (_, seed, explanation) = explain_at(&explainer, &w, injection.gps_time, band).unwrap();
            outcomes.push(Outcome { injection: injection.clone(), seed, explanation, seconds: 0.0 });
        }
        seen = (seen + injections.len()).min(first);
        if seen == first {
            break;
        }
    }
    outcomes
}
