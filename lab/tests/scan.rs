//! `gwml scan`'s pipeline on simulated strain (`gwml data strain`): the
//! recovery of injected glitches, the false-alarm rate in pure noise, and
//! missing data skipped and reported.

use gwml_lab::strain::{simulate, Injection, NoiseCurve, StrainOptions};
use gwml_runtime::spectrum::{Kind, Spectrum};
use gwml_strain::classifier::{Classifier, Manifest};
use gwml_strain::scan::{Report, ScanOptions, Scanner};
use gwml_strain::series::SkipReason;

fn options(duration: f64, rate: f64, seed: u64) -> StrainOptions {
    StrainOptions {
        duration,
        gps_start: 1_264_000_000.0,
        ifo: "H1".into(),
        psd: NoiseCurve::Aligo,
        glitch_rate: rate,
        classes: vec![1, 2, 3, 4],
        snr: Some((8.0, 30.0)),
        gaps: Vec::new(),
        seed,
    }
}

fn scan(series: &gwml_strain::series::Series) -> Report {
    Scanner::new(ScanOptions::default(), None).unwrap().scan(series, &|_| {}).unwrap()
}

/// The shipped classifier (models/glitch-classifier).
fn shipped() -> Classifier {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../models/glitch-classifier/glitch-classifier.json");
    Classifier::load(Manifest::read(&path).unwrap()).unwrap()
}

/// Indices of the injections with a trigger within ±50 ms of their
/// energy's span.
fn found(report: &Report, injections: &[Injection]) -> Vec<usize> {
    (0..injections.len()).filter(|&i| report.rows.iter().any(|r| injections[i].is_marked_by(r.trigger.time, 0.05))).collect()
}

/// Found and injected glitches of one class alone at SNR `snr`, 10 a
/// minute over 256 s (seed 1).
fn found_alone(class: usize, snr: (f64, f64)) -> (usize, usize) {
    let (series, injections) = simulate(&StrainOptions { classes: vec![class], snr: Some(snr), ..options(256.0, 10.0, 1) }).unwrap();
    (found(&scan(&series), &injections).len(), injections.len())
}

#[test]
fn injected_glitches_are_found_within_50_ms() {
    // 256 s at 6 glitches a minute, SNR 8-30, the four glitch families.
    let (series, injections) = simulate(&options(256.0, 6.0, 7)).unwrap();
    let report = scan(&series);
    let hits = found(&report, &injections);
    assert!(injections.len() >= 15, "{} injections", injections.len());
    // Measured: 21 of 22 within 50 ms of their energy's span (a Blip at
    // SNR 8.4 missed); README "Scanning real strain".
    assert!(hits.len() as f64 >= 0.85 * injections.len() as f64, "{} of {} found", hits.len(), injections.len());
    // Triggers away from every injection are noise: at most one per 100 s.
    let stray = report.rows.iter().filter(|r| !injections.iter().any(|i| (r.trigger.time - i.gps_time).abs() < 1.0)).count();
    assert!(stray as f64 <= report.scanned_seconds / 100.0, "{stray} triggers near no injection");
    for r in &report.rows {
        let t = &r.trigger;
        assert!([t.snr, t.peak_frequency, t.q, t.duration()].iter().all(|v| v.is_finite() && *v > 0.0), "{t:?}");
    }
    assert_eq!(report.scanned_seconds, 256.0 - 8.0);
}

#[test]
fn quiet_whistles_are_found_by_excess_power() {
    // 256 s of Whistles alone at SNR 9.5-10.5, 10 a minute: their energy is
    // spread along a sweep, and its slow bottom is narrower than the rows of
    // the Q 11.3 plane. Measured: 38 of 43 found; on the draws before the
    // Koi Fish rule reordered them, 30 of 36 (29 with excess power up to
    // Q 22.6 over at most 1 s; 23 up to Q 11.3).
    let (hits, injected) = found_alone(3, (9.5, 10.5));
    assert_eq!(injected, 43);
    assert!(hits as f64 >= 0.75 * injected as f64, "{hits} of {injected} found");
}

#[test]
fn quiet_scratchies_are_found_by_2_s_sums_in_narrow_rows() {
    // 256 s of Scratchies alone at SNR 10-11, 10 a minute: 1-2.5 s of
    // arches whose carrier a narrow row of the Q 45 plane holds for 2 s.
    // Measured: 28 of 39 found; 23 with excess power over at most 1 s and
    // up to Q 22.6 (`EXCESS_POWER_WINDOWS` in strain/src/scan.rs).
    let (hits, injected) = found_alone(4, (10.0, 11.0));
    assert_eq!(injected, 39);
    assert!(hits >= 26, "{hits} of {injected} found");
}

#[test]
fn pure_noise_makes_at_most_one_trigger_per_100_s_above_snr_8() {
    let (series, injections) = simulate(&options(512.0, 0.0, 11)).unwrap();
    assert!(injections.is_empty());
    let report = scan(&series);
    let loud = report.rows.iter().filter(|r| r.trigger.snr >= 8.0).count();
    assert!(loud as f64 <= report.scanned_seconds / 100.0, "{loud} triggers above SNR 8 in {} s", report.scanned_seconds);
}

/// The O3-like ASD of `lab/data/o3_asd.csv` with narrow lines far above it,
/// of the orders of magnitude real LIGO spectra have: mains at 60, 120 and
/// 180 Hz (ASD ×100, ×30, ×30), calibration-like lines (×100), violin
/// modes near 500, 1000 and 1500 Hz (×3000, ×1000, ×300), each a Lorentzian
/// 0.01 Hz wide in power on a 0.002 Hz grid.
fn o3_with_lines() -> Spectrum {
    let base = Spectrum::read(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/o3_asd.csv"), Kind::Asd).unwrap();
    let mut lines = vec![(60.0, 100.0), (120.0, 30.0), (180.0, 30.0), (17.1, 100.0), (410.3, 100.0), (1083.7, 100.0)];
    lines.extend((0..6).map(|i| (500.0 + 3.1 * i as f64, 3000.0)));
    lines.extend((0..6).map(|i| (1000.0 + 6.2 * i as f64, 1000.0)));
    lines.extend((0..4).map(|i| (1500.0 + 9.3 * i as f64, 300.0)));
    let mut freqs: Vec<f64> = (0..40_760).map(|k| 10.0 + 0.05 * k as f64).collect();
    for (f, _) in &lines {
        freqs.extend((0..500).map(|k| f - 0.5 + 0.002 * k as f64));
    }
    freqs.sort_by(f64::total_cmp);
    freqs.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
    let width: f64 = 0.01;
    let psd = freqs
        .iter()
        .map(|&f| {
            let peaks: f64 =
                lines.iter().map(|(fl, k)| k * k * base.psd_at(*fl) * width * width / ((f - fl).powi(2) + width * width)).sum();
            base.psd_at(f) + peaks
        })
        .collect();
    Spectrum::new(freqs, psd, "O3-like ASD with lines").unwrap()
}

#[test]
fn narrow_lines_far_above_the_noise_make_no_triggers() {
    // Stationary lines up to 3000 times the ASD's floor: the Welch PSD of
    // each stretch holds them, so whitening leaves noise. Measured in 1,024
    // s of seeds 42 and 43 (`gwml data strain --psd` with these lines): 1
    // and 5 triggers (0.1-0.5 per 100 s, at 528-1054 Hz, none on a line),
    // against 2 without the lines.
    let (series, _) = simulate(&StrainOptions { psd: NoiseCurve::File(o3_with_lines()), ..options(512.0, 0.0, 11) }).unwrap();
    let report = scan(&series);
    assert_eq!(report.scanned_seconds, 512.0 - 8.0);
    let loud = report.rows.iter().filter(|r| r.trigger.snr >= 8.0).count();
    assert!(loud as f64 <= report.scanned_seconds / 100.0, "{loud} triggers above SNR 8 in {} s", report.scanned_seconds);
}

#[test]
fn missing_data_is_skipped_and_reported_never_scanned() {
    let mut o = options(128.0, 6.0, 5);
    o.gaps = vec![(40.0, 10.0)];
    let (series, _) = simulate(&o).unwrap();
    assert!(series.samples[40 * 4096..50 * 4096].iter().all(|v| v.is_nan()));
    let report = scan(&series);
    let by_reason = report.skipped_by_reason();
    assert_eq!(by_reason.get(&SkipReason::NoDataFlag), Some(&10.0), "{by_reason:?}");
    // Two segments (0-40 s, 50-128 s), each losing 4 s at both edges.
    assert_eq!(by_reason.get(&SkipReason::SegmentEdges), Some(&16.0));
    assert_eq!(report.scanned_seconds, 128.0 - 10.0 - 16.0);
    let gap = (series.gps_start + 40.0, series.gps_start + 50.0);
    assert!(report.rows.iter().all(|r| r.trigger.time < gap.0 || r.trigger.time > gap.1));

    // All data missing: nothing scanned, everything reported, no error.
    let mut empty = series.clone();
    empty.samples.iter_mut().for_each(|v| *v = f64::NAN);
    empty.dq = None;
    let report = scan(&empty);
    assert_eq!((report.scanned_seconds, report.rows.len()), (0.0, 0));
    assert_eq!(report.skipped_by_reason().get(&SkipReason::MissingSamples), Some(&128.0));
}

#[test]
fn the_shipped_classifier_names_found_glitches() {
    let (series, injections) = simulate(&options(256.0, 6.0, 8)).unwrap();
    let classifier = shipped();
    let classes = classifier.manifest.classes.clone();
    let report = Scanner::new(ScanOptions::default(), Some(classifier)).unwrap().scan(&series, &|_| {}).unwrap();
    let (mut found, mut right) = (0, 0);
    for inj in &injections {
        let near = report.rows.iter().filter(|r| inj.is_marked_by(r.trigger.time, 0.05));
        if let Some(row) = near.max_by(|a, b| a.trigger.snr.total_cmp(&b.trigger.snr)) {
            let verdict = row.verdict.as_ref().expect("classified");
            assert!((verdict.probabilities.iter().sum::<f64>() - 1.0).abs() < 1e-9);
            found += 1;
            right += usize::from(classes[verdict.label] == gwml_lab::synth::GLITCH_CLASSES[inj.class]);
        }
    }
    eprintln!("{right} of {found} found glitches labelled right ({} injected)", injections.len());
    // Measured here: 23 of 23 (the CNN shipped before: 19 of 22).
    assert!(right as f64 >= 0.8 * found as f64, "{right} of {found} labelled right");
}
