//! A stretch of strain from one detector, joined from consecutive files,
//! and the segments of it that hold usable data.

use crate::Error;

/// Strain samples of one detector from `gps_start` on, with the data-quality
/// mask if the source had one.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Detector name, e.g. `H1` (empty when the source does not say).
    pub detector: String,
    /// GPS time of the first sample.
    pub gps_start: f64,
    /// Samples per second.
    pub sample_rate: f64,
    /// The strain; NaN where data are missing.
    pub samples: Vec<f64>,
    /// GWOSC `DQmask`, one word per second from `gps_start` (bit 0: data present).
    pub dq: Option<Vec<u32>>,
    /// Where the samples came from (file names), for messages.
    pub source: String,
}

impl Series {
    /// Duration in seconds.
    pub fn duration(&self) -> f64 {
        self.samples.len() as f64 / self.sample_rate
    }

    /// GPS time just after the last sample.
    pub fn gps_end(&self) -> f64 {
        self.gps_start + self.duration()
    }
}

/// Why a stretch of data was not scanned.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SkipReason {
    /// Samples are NaN or infinite (missing data in GWOSC files).
    MissingSamples,
    /// The data-quality mask's bit 0 (data present) is clear.
    NoDataFlag,
    /// No file covers these seconds (a gap between consecutive files).
    GapBetweenFiles,
    /// A run of good data too short to estimate a PSD and whiten.
    TooShort,
    /// The first and last seconds of each segment, which whitening needs
    /// as margins.
    SegmentEdges,
}

impl SkipReason {
    /// A short phrase for summaries.
    pub fn describe(self) -> &'static str {
        match self {
            SkipReason::MissingSamples => "NaN or infinite samples (missing data)",
            SkipReason::NoDataFlag => "data-quality bit 0 (DATA) clear",
            SkipReason::GapBetweenFiles => "no file covers them",
            SkipReason::TooShort => "good-data segment too short to whiten",
            SkipReason::SegmentEdges => "whitening margins at segment edges",
        }
    }
}

/// Seconds left out of a scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Skipped {
    /// GPS start.
    pub gps_start: f64,
    /// Length in seconds.
    pub seconds: f64,
    /// Why.
    pub reason: SkipReason,
}

/// Samples `start..end` of a [`Series`]: good data without a break.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Segment {
    /// First sample.
    pub start: usize,
    /// One past the last sample.
    pub end: usize,
}

/// Where a stretch of strain lies, without its samples: what joining files
/// needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Span {
    /// Detector name.
    pub detector: String,
    /// GPS time of the first sample.
    pub gps_start: f64,
    /// Samples per second.
    pub sample_rate: f64,
    /// Number of samples.
    pub samples: usize,
    /// File name, for messages.
    pub source: String,
}

impl Span {
    fn gps_end(&self) -> f64 {
        self.gps_start + self.samples as f64 / self.sample_rate
    }
}

impl Series {
    /// Its [`Span`].
    pub fn span(&self) -> Span {
        Span {
            detector: self.detector.clone(),
            gps_start: self.gps_start,
            sample_rate: self.sample_rate,
            samples: self.samples.len(),
            source: self.source.clone(),
        }
    }
}

/// Orders stretches of one detector given in any order into runs of
/// consecutive ones (indices into `spans`, in time order); a gap starts a
/// new run (reported as skipped seconds); an overlap, a second detector or a
/// different sample rate is an error.
pub fn plan(spans: &[Span]) -> Result<(Vec<Vec<usize>>, Vec<Skipped>), Error> {
    let mut order: Vec<usize> = (0..spans.len()).collect();
    order.sort_by(|&a, &b| spans[a].gps_start.total_cmp(&spans[b].gps_start));
    let mut runs: Vec<Vec<usize>> = Vec::new();
    let mut skipped = Vec::new();
    for i in order {
        let part = &spans[i];
        let Some(&j) = runs.last().and_then(|r| r.last()) else {
            runs.push(vec![i]);
            continue;
        };
        let last = &spans[j];
        if part.detector != last.detector {
            return Err(Error::Data(format!(
                "{} is from detector {} but {} is from {}: scan one detector at a time",
                part.source, part.detector, last.source, last.detector
            )));
        }
        if part.sample_rate != last.sample_rate {
            return Err(Error::Data(format!(
                "{} is sampled at {} Hz but {} at {} Hz",
                part.source, part.sample_rate, last.source, last.sample_rate
            )));
        }
        let gap = part.gps_start - last.gps_end();
        let tolerance = 0.5 / last.sample_rate;
        if gap < -tolerance {
            return Err(Error::Data(format!(
                "{} (GPS {}..{}) overlaps {} (GPS {}..{}) by {} s",
                part.source,
                part.gps_start,
                part.gps_end(),
                last.source,
                last.gps_start,
                last.gps_end(),
                -gap
            )));
        }
        if gap > tolerance {
            skipped.push(Skipped { gps_start: last.gps_end(), seconds: gap, reason: SkipReason::GapBetweenFiles });
            runs.push(vec![i]);
        } else {
            runs.last_mut().expect("a run").push(i);
        }
    }
    Ok((runs, skipped))
}

/// Joins series of one detector given in any order ([`plan`]): consecutive
/// ones are concatenated (their DQ masks too, when every part has one of
/// whole seconds).
pub fn join(parts: Vec<Series>) -> Result<(Vec<Series>, Vec<Skipped>), Error> {
    let spans: Vec<Span> = parts.iter().map(Series::span).collect();
    let (runs, skipped) = plan(&spans)?;
    let mut parts: Vec<Option<Series>> = parts.into_iter().map(Some).collect();
    let mut out = Vec::new();
    for run in runs {
        let mut it = run.into_iter().map(|i| parts[i].take().expect("each part in one run"));
        let mut joined = it.next().expect("runs are not empty");
        for part in it {
            let whole_seconds = |s: &Series| (s.samples.len() as f64 / s.sample_rate).fract() == 0.0;
            let whole = whole_seconds(&joined);
            match (&mut joined.dq, part.dq) {
                (Some(a), Some(b)) if whole => a.extend(b),
                (dq, _) => *dq = None,
            }
            joined.samples.extend_from_slice(&part.samples);
            joined.source = format!("{} + {}", joined.source, part.source);
        }
        out.push(joined);
    }
    Ok((out, skipped))
}

/// The segments of whole good seconds (every sample finite, DQ bit 0 set
/// where there is a mask) at least `min_seconds` long, and the seconds
/// left out with their reasons. A trailing partial second counts as a
/// second of its own.
pub fn good_segments(series: &Series, min_seconds: f64) -> (Vec<Segment>, Vec<Skipped>) {
    let fs = series.sample_rate;
    let n = series.samples.len();
    let seconds = (n as f64 / fs).ceil() as usize;
    let bounds = |s: usize| ((s as f64 * fs).round() as usize).min(n);
    let verdict = |s: usize| -> Option<SkipReason> {
        if let Some(dq) = &series.dq {
            if dq.get(s).is_some_and(|w| w & 1 == 0) {
                return Some(SkipReason::NoDataFlag);
            }
        }
        let (a, b) = (bounds(s), bounds(s + 1));
        if series.samples[a..b].iter().any(|v| !v.is_finite()) {
            return Some(SkipReason::MissingSamples);
        }
        None
    };
    let mut segments = Vec::new();
    let mut skipped: Vec<Skipped> = Vec::new();
    let skip = |from: usize, to: usize, reason: SkipReason, skipped: &mut Vec<Skipped>| {
        let (a, b) = (bounds(from), bounds(to));
        let gps_start = series.gps_start + a as f64 / fs;
        let seconds = (b - a) as f64 / fs;
        match skipped.last_mut() {
            Some(last) if last.reason == reason && (last.gps_start + last.seconds - gps_start).abs() < 0.5 / fs => last.seconds += seconds,
            _ => skipped.push(Skipped { gps_start, seconds, reason }),
        }
    };
    let mut s = 0;
    while s < seconds {
        if let Some(reason) = verdict(s) {
            skip(s, s + 1, reason, &mut skipped);
            s += 1;
            continue;
        }
        let start = s;
        while s < seconds && verdict(s).is_none() {
            s += 1;
        }
        let (a, b) = (bounds(start), bounds(s));
        if ((b - a) as f64) < min_seconds * fs {
            skip(start, s, SkipReason::TooShort, &mut skipped);
        } else {
            segments.push(Segment { start: a, end: b });
        }
    }
    (segments, skipped)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(gps: f64, seconds: usize, rate: f64) -> Series {
        Series {
            detector: "H1".into(),
            gps_start: gps,
            sample_rate: rate,
            samples: vec![0.0; seconds * rate as usize],
            dq: Some(vec![127; seconds]),
            source: format!("f{gps}"),
        }
    }

    #[test]
    fn nan_seconds_and_cleared_dq_bits_split_segments() {
        let mut s = series(100.0, 40, 16.0);
        s.samples[16 * 10 + 3] = f64::NAN;
        s.dq.as_mut().unwrap()[20] = 126;
        s.dq.as_mut().unwrap()[21] = 0;
        let (segments, skipped) = good_segments(&s, 5.0);
        assert_eq!(segments, vec![Segment { start: 0, end: 160 }, Segment { start: 176, end: 320 }, Segment { start: 352, end: 640 }]);
        assert_eq!(
            skipped,
            vec![
                Skipped { gps_start: 110.0, seconds: 1.0, reason: SkipReason::MissingSamples },
                Skipped { gps_start: 120.0, seconds: 2.0, reason: SkipReason::NoDataFlag },
            ]
        );
        let (segments, skipped) = good_segments(&s, 10.5);
        assert_eq!(segments.len(), 1);
        assert_eq!(skipped.iter().filter(|k| k.reason == SkipReason::TooShort).map(|k| k.seconds).sum::<f64>(), 19.0);
    }

    #[test]
    fn consecutive_files_join_gaps_are_skipped_overlaps_are_errors() {
        let (joined, skipped) = join(vec![series(116.0, 16, 16.0), series(100.0, 16, 16.0)]).unwrap();
        assert_eq!(joined.len(), 1);
        assert_eq!((joined[0].gps_start, joined[0].samples.len(), joined[0].dq.as_ref().unwrap().len()), (100.0, 512, 32));
        assert!(skipped.is_empty());
        let (joined, skipped) = join(vec![series(100.0, 16, 16.0), series(120.0, 16, 16.0)]).unwrap();
        assert_eq!(joined.len(), 2);
        assert_eq!(skipped, vec![Skipped { gps_start: 116.0, seconds: 4.0, reason: SkipReason::GapBetweenFiles }]);
        let err = join(vec![series(100.0, 16, 16.0), series(110.0, 16, 16.0)]).unwrap_err().to_string();
        assert!(err.contains("overlaps") && err.contains("6 s"), "{err}");
        let mut other = series(116.0, 16, 16.0);
        other.detector = "L1".into();
        assert!(join(vec![series(100.0, 16, 16.0), other]).unwrap_err().to_string().contains("detector"));
    }
}
