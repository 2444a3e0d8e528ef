//! The leak probe: classifiers that see one number per row, trained on the
//! training split and scored on another. A feature that should carry no
//! information about the class (where in the row the signal peaks) must
//! do no better than always answering the majority class; features that
//! carry physics (loudness, energy per frequency band) may, and the table
//! says by how much, so a reader can judge whether the data give the label
//! away more than real glitches would.
//!
//! Each one-feature classifier cuts the feature's training values at
//! [`BINS`] quantiles and answers, per bin, the class most common there.

use super::metrics::{csv_table, markdown_table};
use gwml_runtime::dataset::Dataset;
use realfft::RealFftPlanner;

/// Quantile bins of a one-feature classifier.
pub const BINS: usize = 20;
/// Samples per second of the rows.
const RATE: f64 = 4096.0;
/// Frequency bands (Hz) of the energy-per-band features.
pub const BANDS: [(f64, f64); 7] =
    [(20.0, 40.0), (40.0, 80.0), (80.0, 160.0), (160.0, 320.0), (320.0, 640.0), (640.0, 1280.0), (1280.0, 2000.0)];
/// How much better than the majority class (in accuracy points) the time of
/// the peak may do, without the long classes, before the data count as
/// leaking position.
pub const POSITION_ALLOWANCE: f64 = 5.0;

/// One feature's probe result.
#[derive(Clone, Debug)]
pub struct Probe {
    /// The feature's name.
    pub feature: String,
    /// Accuracy of its one-feature classifier on the scored split (0–1).
    pub accuracy: f64,
    /// Accuracy of always answering the training split's most common class.
    pub majority: f64,
    /// What physics says about it.
    pub expectation: &'static str,
}

/// The features of one row, in [`feature_names`] order: excess energy
/// (Σx² − n), the time of the peak of x² smoothed over 8 ms (s), and the
/// excess energy in each of [`BANDS`].
pub fn features(row: &[f64], planner: &mut RealFftPlanner<f64>) -> Vec<f64> {
    let n = row.len();
    let energy = row.iter().map(|v| v * v).sum::<f64>() - n as f64;
    let half = 16;
    let mut prefix = vec![0.0; n + 1];
    for (i, v) in row.iter().enumerate() {
        prefix[i + 1] = prefix[i] + v * v;
    }
    let peak = (0..n).max_by(|a, b| {
        let s = |i: usize| prefix[(i + half).min(n)] - prefix[i.saturating_sub(half)];
        s(*a).total_cmp(&s(*b))
    });
    let fft = planner.plan_fft_forward(n);
    let mut input = row.to_vec();
    let mut spectrum = fft.make_output_vec();
    // The length always matches the plan, so the FFT cannot fail.
    let _ = fft.process(&mut input, &mut spectrum);
    let df = RATE / n as f64;
    // Unit-variance white noise has E|X_k|² = n per bin; Parseval's 2/n
    // turns the bins' excess into energy in the time domain.
    let band = |(lo, hi): (f64, f64)| {
        spectrum
            .iter()
            .enumerate()
            .filter(|(k, _)| (*k as f64 * df) >= lo && (*k as f64 * df) < hi)
            .map(|(_, c)| (c.norm_sqr() - n as f64) * 2.0 / n as f64)
            .sum::<f64>()
    };
    let mut out = vec![energy, peak.unwrap_or(0) as f64 / RATE];
    out.extend(BANDS.iter().map(|b| band(*b)));
    out
}

/// Names of the [`features`], with what physics says about each.
pub fn feature_names() -> Vec<(String, &'static str)> {
    let mut names = vec![
        (
            "excess energy".to_string(),
            "may separate some: Koi Fish are louder than most glitches (Gravity Spy), but the SNR ranges overlap",
        ),
        (
            "time of peak".to_string(),
            "separates long glitches (Scratchy, Scattered Light peak anywhere in the row) from short ones; nothing else",
        ),
    ];
    for (lo, hi) in BANDS {
        names.push((
            format!("energy {lo:.0}–{hi:.0} Hz"),
            "may separate: classes live in different bands (Tomte and Scattered Light low, Whistles high)",
        ));
    }
    names
}

/// Trains each one-feature classifier on `train` and scores it on `scored`;
/// then the time of the peak again without the rows of `long` classes
/// (glitches longer than a row peak anywhere in it, which says "long", not
/// where the data put them).
pub fn probe(train: &Dataset, scored: &Dataset, classes: usize, long: &[usize]) -> Result<Vec<Probe>, String> {
    let mut planner = RealFftPlanner::new();
    let mut table = |d: &Dataset| -> Result<(Vec<Vec<f64>>, Vec<usize>), String> {
        let x = d.get("x").map_err(|e| e.to_string())?;
        let labels = d.get("label").map_err(|e| e.to_string())?.data.iter().map(|l| *l as usize).collect();
        Ok(((0..x.rows()).map(|i| features(x.row(i), &mut planner)).collect(), labels))
    };
    let (train_f, train_y) = table(train)?;
    let (scored_f, scored_y) = table(scored)?;
    if let Some(l) = train_y.iter().chain(&scored_y).find(|l| **l >= classes) {
        return Err(format!("label {l} is not one of {classes} classes"));
    }
    let one = |j: usize, feature: String, expectation: &'static str, keep: &dyn Fn(usize) -> bool| {
        let (column, labels): (Vec<f64>, Vec<usize>) =
            train_f.iter().zip(&train_y).filter(|(_, y)| keep(**y)).map(|(f, y)| (f[j], *y)).unzip();
        let mut counts = vec![0usize; classes];
        labels.iter().for_each(|l| counts[*l] += 1);
        let majority_class = (0..classes).max_by_key(|c| counts[*c]).unwrap_or(0);
        let classifier = BinClassifier::fit(&column, &labels, classes);
        let rows: Vec<(f64, usize)> = scored_f.iter().zip(&scored_y).filter(|(_, y)| keep(**y)).map(|(f, y)| (f[j], *y)).collect();
        let share = |hit: &dyn Fn(&(f64, usize)) -> bool| rows.iter().filter(|r| hit(r)).count() as f64 / rows.len().max(1) as f64;
        Probe {
            feature,
            accuracy: share(&|(v, y)| classifier.predict(*v) == *y),
            majority: share(&|(_, y)| *y == majority_class),
            expectation,
        }
    };
    let mut probes: Vec<Probe> =
        feature_names().into_iter().enumerate().map(|(j, (feature, expectation))| one(j, feature, expectation, &|_| true)).collect();
    probes.insert(
        2,
        one(1, POSITION_SHORT.to_string(), "must not separate: short signals and the None rows' triggers are placed alike", &|y| {
            !long.contains(&y)
        }),
    );
    Ok(probes)
}

/// The name of the position probe without the long classes.
pub const POSITION_SHORT: &str = "time of peak, classes shorter than a row";

/// A classifier on one number: quantile bins, the majority class per bin.
struct BinClassifier {
    /// Upper edges of all bins but the last.
    edges: Vec<f64>,
    /// The class answered in each bin.
    class: Vec<usize>,
}

impl BinClassifier {
    fn fit(values: &[f64], labels: &[usize], classes: usize) -> BinClassifier {
        let mut sorted: Vec<f64> = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        let edges: Vec<f64> = (1..BINS).map(|b| sorted[(b * sorted.len() / BINS).min(sorted.len().saturating_sub(1))]).collect();
        let mut counts = vec![vec![0usize; classes]; BINS];
        let mut c = BinClassifier { edges, class: Vec::new() };
        for (v, l) in values.iter().zip(labels) {
            counts[c.bin(*v)][*l] += 1;
        }
        c.class = counts.iter().map(|row| (0..classes).max_by_key(|k| row[*k]).unwrap_or(0)).collect();
        c
    }

    fn bin(&self, v: f64) -> usize {
        self.edges.partition_point(|e| *e < v)
    }

    fn predict(&self, v: f64) -> usize {
        self.class[self.bin(v)]
    }
}

/// The probe as a Markdown table and as CSV.
pub fn tables(probes: &[Probe]) -> (String, String) {
    let header = ["feature", "accuracy %", "majority class %", "gain (points)", "physics says"];
    let rows: Vec<Vec<String>> = probes
        .iter()
        .map(|p| {
            vec![
                p.feature.clone(),
                format!("{:.1}", 100.0 * p.accuracy),
                format!("{:.1}", 100.0 * p.majority),
                format!("{:+.1}", 100.0 * (p.accuracy - p.majority)),
                p.expectation.to_string(),
            ]
        })
        .collect();
    (markdown_table(&header, &rows), csv_table(&header, &rows))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{glitches, GlitchOptions, GLITCH_CLASSES};
    use gwml_runtime::dataset::Array;
    use std::collections::BTreeMap;

    fn dataset(x: Vec<f64>, labels: Vec<f64>, width: usize) -> Dataset {
        let n = labels.len();
        let mut arrays = BTreeMap::new();
        arrays.insert("x".to_string(), Array::new(vec![n, width], x).unwrap());
        arrays.insert("label".to_string(), Array::new(vec![n], labels).unwrap());
        Dataset { arrays }
    }

    /// The probe finds a planted leak: rows whose class sets where a spike
    /// sits are classified by the time of the peak alone.
    #[test]
    fn a_planted_position_leak_is_found() {
        let (n, width) = (400, 4096);
        let mut x = vec![0.0; n * width];
        let labels: Vec<f64> = (0..n).map(|i| (i % 4) as f64).collect();
        for i in 0..n {
            x[i * width + 500 + 800 * (i % 4)] = 50.0;
        }
        let d = dataset(x, labels, width);
        let probes = probe(&d, &d, 4, &[]).unwrap();
        let time = probes.iter().find(|p| p.feature == "time of peak").unwrap();
        assert!(time.accuracy > 0.95 && (time.majority - 0.25).abs() < 1e-9, "{time:?}");
        let energy = &probes[0];
        assert!(energy.accuracy < 0.4, "every row has the same energy: {energy:?}");
    }

    /// The band energies see where the power is: a 100 Hz tone's excess
    /// energy lands in the 80–160 Hz band and nowhere else.
    #[test]
    fn band_energies_find_a_tone() {
        let row: Vec<f64> = (0..4096).map(|i| 3.0 * (std::f64::consts::TAU * 100.0 * i as f64 / RATE).cos()).collect();
        let f = features(&row, &mut RealFftPlanner::new());
        // Energy of the tone: 4096 · 9 / 2; no noise, so the "excess" of
        // every band is its energy minus the noise's expectation n·(bins)·2/n.
        let tone = 4096.0 * 9.0 / 2.0;
        assert!((f[2 + 2] - (tone - 2.0 * 80.0)).abs() < 1e-6, "80-160 Hz: {}", f[4]);
        assert!((f[2 + 3] + 2.0 * 160.0).abs() < 1e-6, "160-320 Hz: {}", f[5]);
    }

    /// The benchmark data pass the position check: where a row peaks says
    /// no more about its class than the majority class does (design check
    /// on small splits; `gwml experiment glitch` reports it at full size).
    #[test]
    fn the_benchmark_does_not_leak_position() {
        let train = glitches(&GlitchOptions { n: 1200, seed: 21, ..Default::default() }).unwrap();
        let val = glitches(&GlitchOptions { n: 600, seed: 22, ..Default::default() }).unwrap();
        let probes = probe(&train, &val, GLITCH_CLASSES.len(), &crate::experiment::LONG_CLASSES).unwrap();
        eprintln!("{}", tables(&probes).0);
        let time = probes.iter().find(|p| p.feature == POSITION_SHORT).unwrap();
        assert!(100.0 * (time.accuracy - time.majority) <= POSITION_ALLOWANCE, "{time:?}");
    }
}
