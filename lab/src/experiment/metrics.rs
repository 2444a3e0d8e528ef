//! Scores of a classifier on a labelled test set: the confusion matrix and
//! per-class precision, recall and false-positive rate, with the macro
//! averages the glitch experiment reports.

/// Counts of (true class, predicted class) pairs.
#[derive(Clone, Debug, PartialEq)]
pub struct Confusion {
    /// `counts[truth][predicted]`.
    pub counts: Vec<Vec<usize>>,
}

/// Precision, recall and false-positive rate of one class.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClassScore {
    /// Of the examples predicted as the class, the fraction that are
    /// (NaN when nothing was predicted as it).
    pub precision: f64,
    /// Of the examples of the class, the fraction predicted as it.
    pub recall: f64,
    /// Of the examples of other classes, the fraction predicted as it.
    pub false_positive_rate: f64,
    /// Examples of the class in the test set.
    pub support: usize,
}

impl Confusion {
    /// Tallies `predicted` against `truth` over `classes` classes. Labels
    /// outside `0..classes` are an error.
    pub fn new(classes: usize, truth: &[usize], predicted: &[usize]) -> Result<Confusion, String> {
        if truth.len() != predicted.len() {
            return Err(format!("{} labels but {} predictions", truth.len(), predicted.len()));
        }
        let mut counts = vec![vec![0; classes]; classes];
        for (&t, &p) in truth.iter().zip(predicted) {
            if t >= classes || p >= classes {
                return Err(format!("class {} is outside 0..{classes}", t.max(p)));
            }
            counts[t][p] += 1;
        }
        Ok(Confusion { counts })
    }

    /// Number of classes.
    pub fn classes(&self) -> usize {
        self.counts.len()
    }

    /// Scores of class `c`.
    pub fn score(&self, c: usize) -> ClassScore {
        let n = self.classes();
        let tp = self.counts[c][c] as f64;
        let predicted: usize = (0..n).map(|t| self.counts[t][c]).sum();
        let support: usize = self.counts[c].iter().sum();
        let total: usize = self.counts.iter().flatten().sum();
        let negatives = total - support;
        let fp = predicted as f64 - tp;
        ClassScore {
            precision: if predicted > 0 { tp / predicted as f64 } else { f64::NAN },
            recall: if support > 0 { tp / support as f64 } else { f64::NAN },
            false_positive_rate: if negatives > 0 { fp / negatives as f64 } else { f64::NAN },
            support,
        }
    }

    /// Unweighted means of precision and recall over `classes` (a class
    /// never predicted counts as precision 0).
    pub fn macro_scores(&self, classes: &[usize]) -> (f64, f64) {
        let k = classes.len().max(1) as f64;
        let scores: Vec<ClassScore> = classes.iter().map(|&c| self.score(c)).collect();
        let precision = scores.iter().map(|s| if s.precision.is_nan() { 0.0 } else { s.precision }).sum::<f64>() / k;
        let recall = scores.iter().map(|s| if s.recall.is_nan() { 0.0 } else { s.recall }).sum::<f64>() / k;
        (precision, recall)
    }

    /// Unweighted mean over `classes` of the F1 score, the harmonic mean of
    /// precision and recall (0 for a class never predicted or never right).
    pub fn macro_f1(&self, classes: &[usize]) -> f64 {
        let f1 = |c: usize| {
            let s = self.score(c);
            let (p, r) = (s.precision, s.recall);
            if p > 0.0 && r > 0.0 {
                2.0 * p * r / (p + r)
            } else {
                0.0
            }
        };
        classes.iter().map(|&c| f1(c)).sum::<f64>() / classes.len().max(1) as f64
    }

    /// Fraction of all examples classified correctly.
    pub fn accuracy(&self) -> f64 {
        let total: usize = self.counts.iter().flatten().sum();
        let right: usize = (0..self.classes()).map(|c| self.counts[c][c]).sum();
        right as f64 / total.max(1) as f64
    }
}

/// A percentage with one decimal, or "–" for NaN.
pub fn percent(x: f64) -> String {
    if x.is_nan() {
        "–".to_string()
    } else {
        format!("{:.1}", 100.0 * x)
    }
}

/// Fractions over seeds as a percentage "mean ± sd" (sample sd, one
/// decimal); a single value has no spread and prints as [`percent`].
pub fn percent_spread(xs: &[f64]) -> String {
    let n = xs.len() as f64;
    if xs.len() < 2 {
        return xs.first().map_or_else(|| percent(f64::NAN), |x| percent(*x));
    }
    let mean = xs.iter().sum::<f64>() / n;
    let sd = (xs.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0)).sqrt();
    format!("{} ± {}", percent(mean), percent(sd))
}

/// A Markdown table: a header row, a separator and the rows.
pub fn markdown_table(header: &[&str], rows: &[Vec<String>]) -> String {
    let mut out = format!("| {} |\n|{}\n", header.join(" | "), header.iter().map(|_| "---|").collect::<String>());
    for r in rows {
        out += &format!("| {} |\n", r.join(" | "));
    }
    out
}

/// The same table as CSV (fields with commas or quotes are quoted).
pub fn csv_table(header: &[&str], rows: &[Vec<String>]) -> String {
    let field = |s: &str| if s.contains([',', '"']) { format!("\"{}\"", s.replace('"', "\"\"")) } else { s.to_string() };
    let line = |cells: Vec<String>| cells.iter().map(|c| field(c)).collect::<Vec<_>>().join(",") + "\n";
    let mut out = line(header.iter().map(|h| h.to_string()).collect());
    for r in rows {
        out += &line(r.clone());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mean and sample sd in percent: 0.90 and 0.94 give 92.0 ± 2.8.
    #[test]
    fn spreads_are_mean_and_sample_sd() {
        assert_eq!(percent_spread(&[0.90, 0.94]), "92.0 ± 2.8");
        assert_eq!(percent_spread(&[0.5]), "50.0");
        assert_eq!(percent_spread(&[]), "–");
    }

    #[test]
    fn scores_follow_their_definitions() {
        // truth:     0 0 0 1 1 2
        // predicted: 0 1 0 1 2 2
        let c = Confusion::new(3, &[0, 0, 0, 1, 1, 2], &[0, 1, 0, 1, 2, 2]).unwrap();
        assert_eq!(c.counts, vec![vec![2, 1, 0], vec![0, 1, 1], vec![0, 0, 1]]);
        let s1 = c.score(1);
        assert_eq!((s1.precision, s1.recall, s1.support), (0.5, 0.5, 2));
        assert_eq!(s1.false_positive_rate, 0.25); // one of four non-1 examples
        let s2 = c.score(2);
        assert_eq!((s2.precision, s2.recall, s2.false_positive_rate), (0.5, 1.0, 0.2));
        assert_eq!(c.macro_scores(&[1, 2]), (0.5, 0.75));
        // F1: class 1 has 0.5 and 0.5, class 2 has 2 · 0.5 · 1 / 1.5 = 2/3.
        assert!((c.macro_f1(&[1, 2]) - (0.5 + 2.0 / 3.0) / 2.0).abs() < 1e-15);
        assert_eq!(c.macro_f1(&[]), 0.0);
        assert!((c.accuracy() - 4.0 / 6.0).abs() < 1e-15);
    }

    #[test]
    fn a_class_never_predicted_has_no_precision_and_counts_as_zero() {
        let c = Confusion::new(2, &[0, 1], &[0, 0]).unwrap();
        assert!(c.score(1).precision.is_nan());
        assert_eq!(c.macro_scores(&[1]), (0.0, 0.0));
        assert_eq!(percent(c.score(1).precision), "–");
    }

    #[test]
    fn bad_labels_and_lengths_are_errors() {
        assert!(Confusion::new(2, &[0, 2], &[0, 1]).is_err());
        assert!(Confusion::new(2, &[0], &[0, 1]).is_err());
    }

    #[test]
    fn tables_render_as_markdown_and_csv() {
        let rows = vec![vec!["CNN, 5k".to_string(), "91.0".to_string()]];
        assert_eq!(markdown_table(&["method", "precision"], &rows), "| method | precision |\n|---|---|\n| CNN, 5k | 91.0 |\n");
        assert_eq!(csv_table(&["method", "precision"], &rows), "method,precision\n\"CNN, 5k\",91.0\n");
    }
}
