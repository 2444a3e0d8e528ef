//! Triggers: loud Q tiles clustered in time, as Omicron reports them
//! (Robinet et al. 2020, SoftwareX 12, 100620: time, start and end, peak
//! frequency, frequency span, SNR and Q of the loudest tile).

/// One tile above the clustering threshold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tile {
    /// Centre time (GPS seconds).
    pub time: f64,
    /// Centre frequency in Hz.
    pub frequency: f64,
    /// Its plane's Q.
    pub q: f64,
    /// SNR from the tile energy ([`crate::qtransform::tile_snr`]), or of
    /// the summed energy of an excess-power window.
    pub snr: f64,
    /// The single-tile SNR as unlikely in Gaussian noise (equal to `snr`
    /// for single tiles; lower for a long window's summed energy).
    pub significance: f64,
    /// Duration of the tile's envelope in seconds.
    pub duration: f64,
    /// Bandwidth in Hz.
    pub bandwidth: f64,
}

/// A cluster of tiles: one glitch candidate.
#[derive(Clone, Debug, PartialEq)]
pub struct Trigger {
    /// Time of the loudest tile (GPS seconds).
    pub time: f64,
    /// Start of the earliest tile.
    pub start: f64,
    /// End of the latest tile.
    pub end: f64,
    /// Frequency of the loudest tile in Hz.
    pub peak_frequency: f64,
    /// Lowest frequency covered by the cluster's tiles.
    pub f_start: f64,
    /// Highest frequency covered.
    pub f_end: f64,
    /// SNR of the most significant tile.
    pub snr: f64,
    /// Its significance (see [`Tile::significance`]); the threshold applies to it.
    pub significance: f64,
    /// Q of the most significant tile.
    pub q: f64,
    /// Duration of the most significant tile (its span decides which weaker
    /// triggers join this one).
    pub peak_duration: f64,
    /// Tiles in the cluster.
    pub tiles: usize,
}

impl Trigger {
    /// Duration from the earliest tile's start to the latest tile's end.
    pub fn duration(&self) -> f64 {
        self.end - self.start
    }
}

/// What a trigger's most significant tile must reach.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Threshold {
    /// Its SNR (Gravity Spy takes Omicron triggers above 7.5).
    pub snr: f64,
    /// Its significance: for a long excess-power window, how unlikely its
    /// energy is in Gaussian noise, so long windows of noise, whose summed
    /// energy is large, do not pass on their SNR alone.
    pub significance: f64,
}

impl Threshold {
    /// Both at `snr` (enough for single tiles, whose significance is their SNR).
    pub fn snr(snr: f64) -> Threshold {
        Threshold { snr, significance: snr }
    }
}

impl Tile {
    fn start(&self) -> f64 {
        self.time - 0.5 * self.duration
    }
    fn end(&self) -> f64 {
        self.time + 0.5 * self.duration
    }
}

/// Clusters tiles around the most significant ones: the most significant
/// tile not yet taken starts a trigger and takes every tile that overlaps
/// it (within `gap` seconds) or covers its time (the span and band grow
/// with the taken tiles no longer than twice the peak tile); repeated while tiles reach
/// the `threshold`. Then a trigger whose peak falls inside a more significant
/// one's peak tile (± `gap`) joins it ([`absorbed_into`]). Unlike chaining
/// overlapping tiles, two glitches a second apart stay two triggers even
/// when long excess-power windows span both. Triggers come out in time order.
pub fn cluster(mut tiles: Vec<Tile>, gap: f64, threshold: Threshold) -> Vec<Trigger> {
    tiles.sort_by(|a, b| a.start().total_cmp(&b.start()));
    let longest = tiles.iter().map(|t| t.duration).fold(0.0, f64::max);
    let mut order: Vec<usize> = (0..tiles.len()).collect();
    order.sort_by(|&a, &b| tiles[b].significance.total_cmp(&tiles[a].significance));
    let mut taken = vec![false; tiles.len()];
    let mut out = Vec::new();
    for &i in &order {
        let peak = tiles[i];
        if peak.significance < threshold.significance {
            break;
        }
        if taken[i] || peak.snr < threshold.snr {
            continue;
        }
        let (lo, hi) = (peak.start() - gap, peak.end() + gap);
        let mut trigger = Trigger {
            time: peak.time,
            start: peak.start(),
            end: peak.end(),
            peak_frequency: peak.frequency,
            f_start: peak.frequency - 0.5 * peak.bandwidth,
            f_end: peak.frequency + 0.5 * peak.bandwidth,
            snr: peak.snr,
            significance: peak.significance,
            q: peak.q,
            peak_duration: peak.duration,
            tiles: 0,
        };
        let first = tiles.partition_point(|t| t.start() < lo - longest);
        for j in first..tiles.len() {
            let t = &tiles[j];
            if t.start() > hi {
                break;
            }
            let overlaps = t.end() >= lo && t.start() <= hi;
            let covers = t.start() <= peak.time && t.end() >= peak.time;
            if taken[j] || !(overlaps || covers) {
                continue;
            }
            taken[j] = true;
            trigger.tiles += 1;
            // Windows much longer than the peak tile (excess power over a
            // second that merely contains a short glitch) do not widen it.
            if t.duration > 2.0 * peak.duration {
                continue;
            }
            trigger.start = trigger.start.min(t.start());
            trigger.end = trigger.end.max(t.end());
            trigger.f_start = trigger.f_start.min(t.frequency - 0.5 * t.bandwidth);
            trigger.f_end = trigger.f_end.max(t.frequency + 0.5 * t.bandwidth);
        }
        out.push(trigger);
    }
    let into = absorbed_into(&out, gap);
    let mut kept: Vec<Trigger> = Vec::new();
    let mut index = vec![usize::MAX; out.len()];
    for (i, t) in out.iter().enumerate() {
        if into[i].is_none() {
            index[i] = kept.len();
            kept.push(t.clone());
        }
    }
    for (i, target) in into.iter().enumerate() {
        if let Some(k) = target {
            let (t, dst) = (&out[i], &mut kept[index[*k]]);
            dst.join(t);
        }
    }
    kept.sort_by(|a, b| a.time.total_cmp(&b.time));
    kept
}

impl Trigger {
    /// Widens this trigger's span and band to cover `other` and counts its
    /// tiles; the peak (time, frequency, SNR, Q) stays this one's.
    pub fn join(&mut self, other: &Trigger) {
        self.start = self.start.min(other.start);
        self.end = self.end.max(other.end);
        self.f_start = self.f_start.min(other.f_start);
        self.f_end = self.f_end.max(other.f_end);
        self.tiles += other.tiles;
    }
}

/// A trigger at least this many times quieter (in SNR) than a neighbour
/// whose span it lies within [`SHADOW_REACH`] seconds of is that neighbour's
/// leakage, not a glitch of its own: a glitch of SNR in the hundreds (a loud
/// Koi Fish) leaves excess power of SNR ~8-12 up to a second or two either
/// side, through the whitening filter and the long low-frequency Q tiles
/// (measured on `gwml data strain --snr class`: Koi Fish of SNR 240-330
/// gave side triggers of SNR 7.5-11.5 at 15-31 Hz, 0.6-1.2 s away).
pub const SHADOW_RATIO: f64 = 10.0;
/// How far (s) beyond a loud trigger's span its shadow reaches.
pub const SHADOW_REACH: f64 = 2.0;

/// For each trigger, the more significant trigger it belongs to, if any: one
/// whose most significant tile (± `gap`) spans its peak time, or one
/// [`SHADOW_RATIO`] times louder whose span is within [`SHADOW_REACH`] of
/// it (the most significant such; the target itself kept). Used within a
/// chunk and across chunk boundaries.
pub fn absorbed_into(triggers: &[Trigger], gap: f64) -> Vec<Option<usize>> {
    let mut order: Vec<usize> = (0..triggers.len()).collect();
    order.sort_by(|&a, &b| triggers[b].significance.total_cmp(&triggers[a].significance));
    let mut into: Vec<Option<usize>> = vec![None; triggers.len()];
    let mut kept: Vec<usize> = Vec::new();
    for &i in &order {
        let t = &triggers[i];
        into[i] = kept.iter().copied().find(|&k| {
            let p = &triggers[k];
            let in_peak = (t.time - p.time).abs() <= 0.5 * p.peak_duration + gap;
            let shadowed = p.snr >= SHADOW_RATIO * t.snr && t.time >= p.start - SHADOW_REACH && t.time <= p.end + SHADOW_REACH;
            in_peak || shadowed
        });
        if into[i].is_none() {
            kept.push(i);
        }
    }
    into
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tile(time: f64, snr: f64, frequency: f64) -> Tile {
        Tile { time, frequency, q: 8.0, snr, significance: snr, duration: 0.02, bandwidth: 20.0 }
    }

    #[test]
    fn tiles_close_in_time_make_one_trigger_at_the_loudest() {
        let tiles = vec![tile(10.0, 6.0, 100.0), tile(10.05, 12.0, 140.0), tile(10.12, 7.0, 300.0), tile(20.0, 9.0, 50.0)];
        let triggers = cluster(tiles, 0.1, Threshold::snr(7.5));
        assert_eq!(triggers.len(), 2);
        let first = &triggers[0];
        assert_eq!((first.time, first.peak_frequency, first.snr, first.tiles), (10.05, 140.0, 12.0, 3));
        assert!((first.start - 9.99).abs() < 1e-12 && (first.end - 10.13).abs() < 1e-12);
        assert_eq!((first.f_start, first.f_end), (90.0, 310.0));
        assert_eq!(triggers[1].time, 20.0);
    }

    #[test]
    fn a_long_window_spanning_two_glitches_does_not_join_them() {
        let long = Tile { time: 11.0, frequency: 100.0, q: 5.7, snr: 9.0, significance: 8.0, duration: 2.0, bandwidth: 60.0 };
        let tiles = vec![tile(10.0, 15.0, 100.0), long, tile(12.0, 14.0, 120.0)];
        let triggers = cluster(tiles, 0.1, Threshold::snr(7.5));
        assert_eq!(triggers.iter().map(|t| t.time).collect::<Vec<_>>(), vec![10.0, 12.0]);
        // The long window covers the louder glitch's time: it joins that one.
        assert_eq!(triggers.iter().map(|t| t.tiles).collect::<Vec<_>>(), vec![2, 1]);
    }

    /// Side triggers of a very loud glitch join it; a glitch of its own
    /// (louder than a tenth of it, or farther than the reach) stays.
    #[test]
    fn a_very_loud_glitch_absorbs_its_quiet_side_triggers() {
        let tiles =
            vec![tile(10.0, 300.0, 100.0), tile(11.2, 9.0, 20.0), tile(8.9, 11.0, 25.0), tile(11.0, 40.0, 200.0), tile(12.5, 9.0, 30.0)];
        let triggers = cluster(tiles, 0.1, Threshold::snr(7.5));
        assert_eq!(triggers.iter().map(|t| t.time).collect::<Vec<_>>(), vec![10.0, 11.0, 12.5]);
        // The loud one's span now covers its side triggers.
        let loud = &triggers[0];
        assert!((loud.start - 8.89).abs() < 1e-12 && (loud.end - 11.21).abs() < 1e-12 && loud.tiles == 3, "{loud:?}");
    }

    #[test]
    fn quiet_clusters_are_dropped_and_order_does_not_matter() {
        let tiles = vec![tile(5.0, 6.0, 100.0), tile(1.0, 8.0, 100.0), tile(3.0, 7.0, 100.0)];
        let triggers = cluster(tiles, 0.1, Threshold::snr(7.5));
        assert_eq!(triggers.iter().map(|t| t.time).collect::<Vec<_>>(), vec![1.0]);
    }
}
