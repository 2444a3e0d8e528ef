//! A scan in blocks: the unit of work that is read, scanned, recorded and
//! dealt to processes (MPI ranks in `gwml scan --mpi`).
//!
//! Each run of consecutive files is cut into blocks of `--block` seconds
//! that overlap by twice the whitening margin, so the margin between two
//! blocks is searched in one of them. The plan depends only on the files
//! and the settings, never on the number of ranks, so any split of the
//! blocks gives the same triggers. Finished blocks can be recorded in a
//! parts directory beside the output (`OUT.parts/`), so a rerun after a
//! crash does only the missing ones.

use crate::input::{runs, Source, StrainRun as Run};
use crate::record::{report_from_json, report_to_json};
use crate::scan::{merge_rows, Report, ScanOptions, Scanner};
use crate::series::{Series, Skipped, Span};
use crate::Error;
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Samples `start..start + length` of run `run`. An end is open where the
/// run continues in a neighbouring block.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Block {
    pub run: usize,
    pub start: usize,
    pub length: usize,
    pub open: (bool, bool),
}

impl Block {
    /// The block's samples, read from its run.
    pub fn read(&self, runs: &[Run]) -> Result<Series, Error> {
        runs[self.run].block(self.start, self.length)
    }
}

/// The blocks of runs with extents `spans`, in time order: `seconds` long,
/// overlapping by twice the margin, and no last block shorter than a PSD
/// stretch or half a block, whichever is less (the one before it reaches
/// the run's end instead): a block's PSDs are estimated from its own
/// samples, and a 32 s remainder of a 4,096 s file in 1,024 s blocks,
/// whitened by a 32 s estimate, made 2-5 loud excess-power triggers in
/// Gaussian noise.
pub fn plan_blocks(spans: &[Span], seconds: f64, options: &ScanOptions) -> Vec<Block> {
    let shortest = options.min_segment().max(options.psd_stretch.min(0.5 * seconds));
    let mut blocks = Vec::new();
    for (run, span) in spans.iter().enumerate() {
        let fs = span.sample_rate;
        let block = (seconds * fs) as usize;
        let overlap = (2.0 * options.margin() * fs) as usize;
        let n = span.samples;
        let mut starts = vec![0];
        while starts[starts.len() - 1] + block < n {
            starts.push(starts[starts.len() - 1] + block - overlap);
        }
        if starts.len() > 1 && ((n - starts[starts.len() - 1]) as f64) < shortest * fs + overlap as f64 {
            starts.pop();
        }
        for (k, &start) in starts.iter().enumerate() {
            let length = starts.get(k + 1).map_or(n - start, |next| next + overlap - start);
            blocks.push(Block { run, start, length, open: (k > 0, k + 1 < starts.len()) });
        }
    }
    blocks
}

/// The blocks of `todo` that rank `rank` of `size` scans: every `size`-th,
/// so equal blocks are shared as evenly as they can be.
pub fn deal(todo: &[usize], rank: usize, size: usize) -> Vec<usize> {
    todo.iter().copied().skip(rank).step_by(size.max(1)).collect()
}

/// Scans blocks `mine` in order with `scanner` on the threads of `pool`,
/// reading each next block while one is scanned (`first` is `mine[0]`,
/// already read). `finished` is told each block's report as soon as it is
/// done.
pub fn scan_blocks(
    runs: &[Run],
    blocks: &[Block],
    mine: &[usize],
    first: Option<Series>,
    (scanner, pool): (&Scanner, &rayon::ThreadPool),
    progress: &(dyn Fn(f64) + Sync),
    finished: &mut dyn FnMut(usize, &Report) -> Result<(), Error>,
) -> Result<Vec<(usize, Report)>, Error> {
    let mut out = Vec::new();
    let mut next = match (first, mine.first()) {
        (Some(series), _) => Some(series),
        (None, Some(&i)) => Some(blocks[i].read(runs)?),
        (None, None) => None,
    };
    for (k, &index) in mine.iter().enumerate() {
        let series = next.take().expect("read ahead");
        let (report, ahead) = std::thread::scope(|scope| {
            let ahead = mine.get(k + 1).map(|&i| scope.spawn(move || blocks[i].read(runs)));
            let report = pool.install(|| scanner.scan_block(&series, blocks[index].open, progress));
            (report, ahead.map(|h| h.join().expect("the reading thread does not panic")))
        });
        let report = report?;
        finished(index, &report)?;
        out.push((index, report));
        next = ahead.transpose()?;
    }
    Ok(out)
}

/// The blocks' reports (in block order) as one: rows merged across block
/// edges, skipped stretches (with the `gaps` between runs) in time order,
/// stage times summed.
pub fn merge(mut reports: Vec<Report>, mut gaps: Vec<Skipped>, cluster_gap: f64) -> Option<Report> {
    if reports.is_empty() {
        return None;
    }
    let mut report = reports.remove(0);
    for r in reports {
        let (a, b) = (&mut report.stage_seconds, r.stage_seconds);
        (a.psd, a.whiten, a.tiles, a.classify) = (a.psd + b.psd, a.whiten + b.whiten, a.tiles + b.tiles, a.classify + b.classify);
        report.rows.extend(r.rows);
        report.scanned_seconds += r.scanned_seconds;
        report.skipped.extend(r.skipped);
    }
    report.rows = merge_rows(std::mem::take(&mut report.rows), cluster_gap);
    report.skipped.append(&mut gaps);
    report.skipped.sort_by(|x, y| x.gps_start.total_cmp(&y.gps_start));
    Some(report)
}

/// Scans `sources` whole in blocks of `block_seconds`, one after another
/// (each over the threads of `pool`); `progress` is told the seconds of
/// each chunk done. What `gwml scan` does without --resume or --mpi.
pub fn scan_sources(
    sources: &[Source],
    block_seconds: f64,
    (scanner, pool): (&Scanner, &rayon::ThreadPool),
    progress: &(dyn Fn(f64) + Sync),
) -> Result<Report, Error> {
    let (runs, gaps) = runs(sources, scanner.classifier().map(|c| c.manifest.sample_rate))?;
    let spans: Vec<Span> = runs.iter().map(|r| r.span.clone()).collect();
    let blocks = plan_blocks(&spans, block_seconds, scanner.options());
    let all: Vec<usize> = (0..blocks.len()).collect();
    let reports = scan_blocks(&runs, &blocks, &all, None, (scanner, pool), progress, &mut |_, _| Ok(()))?;
    merge(reports.into_iter().map(|(_, r)| r).collect(), gaps, scanner.options().cluster_gap)
        .ok_or_else(|| Error::Data("no strain to scan".into()))
}

/// Block reports as bytes (to send between ranks) and back.
pub fn encode(reports: &[(usize, Report)]) -> Vec<u8> {
    let list: Vec<Value> = reports.iter().map(|(i, r)| json!([i, report_to_json(r)])).collect();
    serde_json::to_vec(&list).expect("JSON values serialise")
}

/// The reports [`encode`] wrote; `from` names the sender in errors.
pub fn decode(bytes: &[u8], from: &str) -> Result<Vec<(usize, Report)>, Error> {
    let list: Vec<Value> = serde_json::from_slice(bytes).map_err(|e| Error::Data(format!("{from} sent unreadable results: {e}")))?;
    list.iter()
        .map(|pair| {
            let index =
                pair.get(0).and_then(Value::as_u64).ok_or_else(|| Error::Data(format!("{from} sent a result without its block")))?;
            let report = report_from_json(&pair[1], &format!("block {index} from {from}"))?;
            Ok((index as usize, report))
        })
        .collect()
}

/// `OUT.parts/`: `plan.json` (what scan the parts belong to) and one
/// `block-NNNNNN.json` per finished block, each written whole (to a
/// temporary name, then renamed) so a killed process leaves no half record.
pub struct Parts {
    dir: PathBuf,
}

impl Parts {
    /// The parts directory of output `out`.
    pub fn dir_for(out: &Path) -> PathBuf {
        let mut name = out.file_name().map(|n| n.to_os_string()).unwrap_or_default();
        name.push(".parts");
        out.with_file_name(name)
    }

    /// Opens the parts directory of `out` for the scan described by
    /// `fingerprint` with `blocks` blocks, creating it (and, when `plan` is
    /// set, its `plan.json`). Parts of a different scan are an error: they
    /// cannot be merged with this one.
    pub fn open(out: &Path, fingerprint: &str, blocks: usize, plan: bool) -> Result<Parts, Error> {
        let dir = Parts::dir_for(out);
        std::fs::create_dir_all(&dir).map_err(|e| Error::file(&dir, format!("cannot create: {e}")))?;
        let parts = Parts { dir };
        let plan_path = parts.dir.join("plan.json");
        let want = json!({"fingerprint": fingerprint, "blocks": blocks});
        match std::fs::read(&plan_path) {
            Ok(bytes) => {
                let have: Value = serde_json::from_slice(&bytes).map_err(|e| Error::file(&plan_path, format!("not valid JSON: {e}")))?;
                if have != want {
                    return Err(Error::file(
                        &parts.dir,
                        "holds finished blocks of another scan (other files or settings); \
                         delete it to start again, or rerun with the settings it was made with",
                    ));
                }
            }
            Err(_) if plan => parts.write(&plan_path, &serde_json::to_vec(&want).expect("JSON values serialise"))?,
            Err(_) => {}
        }
        Ok(parts)
    }

    fn block_path(&self, index: usize) -> PathBuf {
        self.dir.join(format!("block-{index:06}.json"))
    }

    fn write(&self, path: &Path, bytes: &[u8]) -> Result<(), Error> {
        let tmp = path.with_extension(format!("tmp{}", std::process::id()));
        std::fs::write(&tmp, bytes).and_then(|_| std::fs::rename(&tmp, path)).map_err(|e| Error::file(path, format!("cannot write: {e}")))
    }

    /// The finished blocks among the first `blocks`, by index.
    pub fn finished(&self, blocks: usize) -> Result<BTreeMap<usize, Report>, Error> {
        let mut out = BTreeMap::new();
        for index in 0..blocks {
            let path = self.block_path(index);
            let Ok(bytes) = std::fs::read(&path) else { continue };
            let value: Value = serde_json::from_slice(&bytes).map_err(|e| Error::file(&path, format!("not valid JSON: {e}")))?;
            out.insert(index, report_from_json(&value, &path.display().to_string())?);
        }
        Ok(out)
    }

    /// Records block `index` as finished.
    pub fn record(&self, index: usize, report: &Report) -> Result<(), Error> {
        let bytes = serde_json::to_vec(&report_to_json(report)).expect("JSON values serialise");
        self.write(&self.block_path(index), &bytes)
    }

    /// Removes the directory (once the merged output is written).
    pub fn remove(&self) {
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn span(seconds: usize) -> Span {
        Span { detector: "H1".into(), gps_start: 0.0, sample_rate: 16.0, samples: seconds * 16, source: "test".into() }
    }

    /// Blocks cover each run, overlap by twice the margin, and the last one
    /// is never shorter than what whitening needs.
    #[test]
    fn blocks_cover_runs_with_overlaps() {
        let options = ScanOptions::default();
        let blocks = plan_blocks(&[span(1000), span(100)], 256.0, &options);
        let first: Vec<&Block> = blocks.iter().filter(|b| b.run == 0).collect();
        assert_eq!(first[0].start, 0);
        let last = first[first.len() - 1];
        assert_eq!(last.start + last.length, 1000 * 16);
        for pair in first.windows(2) {
            assert_eq!(pair[0].start + pair[0].length - pair[1].start, (2.0 * options.margin() * 16.0) as usize);
            assert!(pair[0].open.1 && pair[1].open.0);
        }
        assert!(!first[0].open.0 && !last.open.1);
        assert!(last.length as f64 / 16.0 >= options.min_segment());
        // 4,096 s in 1,024 s blocks would leave a 32 s remainder: the block
        // before it takes it, so every block holds a whole PSD stretch.
        let long = plan_blocks(&[span(4096)], 1024.0, &options);
        assert_eq!(long.len(), 4);
        assert!(long.iter().all(|b| b.length as f64 / 16.0 >= options.psd_stretch), "{long:?}");
        assert_eq!(long[3].start + long[3].length, 4096 * 16);
        // Blocks shorter than a PSD stretch (the user's choice) keep a
        // remainder of most of a block: 224 s in 64 s blocks ends in 56 s.
        let short = plan_blocks(&[span(224)], 64.0, &options);
        assert_eq!(short.iter().map(|b| b.length / 16).collect::<Vec<_>>(), [64, 64, 64, 56]);
        let second: Vec<&Block> = blocks.iter().filter(|b| b.run == 1).collect();
        assert_eq!(second.len(), 1);
        assert_eq!((second[0].start, second[0].length, second[0].open), (0, 1600, (false, false)));
    }

    #[test]
    fn dealing_gives_every_block_once() {
        let todo = vec![0, 2, 3, 5, 8, 9, 11];
        let mut all: Vec<usize> = (0..3).flat_map(|r| deal(&todo, r, 3)).collect();
        all.sort_unstable();
        assert_eq!(all, todo);
        assert_eq!(deal(&todo, 0, 3), vec![0, 5, 11]);
    }

    #[test]
    fn parts_of_another_scan_are_refused() {
        let out = std::env::temp_dir().join(format!("gwml-parts-{}.csv", std::process::id()));
        let parts = Parts::open(&out, "files a, block 256", 4, true).unwrap();
        let report = Report {
            ifo: "H1".into(),
            rows: Vec::new(),
            scanned_seconds: 248.0,
            skipped: Vec::new(),
            tiled_band: (10.0, 1000.0),
            stage_seconds: Default::default(),
        };
        parts.record(2, &report).unwrap();
        let again = Parts::open(&out, "files a, block 256", 4, true).unwrap();
        assert_eq!(again.finished(4).unwrap().into_keys().collect::<Vec<_>>(), vec![2]);
        let e = Parts::open(&out, "files a, block 512", 4, true).err().unwrap().to_string();
        assert!(e.contains("another scan") && e.contains(".parts"), "{e}");
        again.remove();
        assert!(!Parts::dir_for(&out).exists());
    }
}
