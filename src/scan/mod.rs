//! `gwml data strain` and `gwml scan`: the command-line shell over
//! `gwml_lab::strain` (simulated strain) and `gwml_strain` (the scan).

use crate::cluster::World;
use crate::commands::render;
use crate::explain::Explained;
use crate::strain_input::StrainInput;
use gwml_lab::generator::GeneratorShapes;
use gwml_lab::parse_range;
use gwml_lab::strain::{simulate_with, write_truth, NoiseCurve, StrainOptions};
use gwml_lab::synth::{real_fits::RealShapes, GlitchClass, Shape};
use gwml_strain::blocks::{self, deal, decode, encode, merge, plan_blocks, scan_blocks, Parts};
use gwml_strain::classifier::{probability_column, Classifier, Manifest};
use gwml_strain::gwosc::{self, WriteOptions};
use gwml_strain::input::{Source, StrainRun};
use gwml_strain::scan::{Report, ScanOptions, Scanner};
use gwml_strain::series::{plan, SkipReason, Span};
use indicatif::{ProgressBar, ProgressStyle};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(clap::Args)]
pub struct StrainArgs {
    /// Seconds of data (whole seconds, at least 32).
    #[arg(long)]
    pub duration: f64,
    /// The HDF5 file to write (GWOSC layout).
    #[arg(long, value_name = "FILE.hdf5")]
    pub out: PathBuf,
    /// Detector name written to meta/Detector.
    #[arg(long, default_value = "H1")]
    pub ifo: String,
    /// Noise PSD: `aligo` (aLIGO zero-detuned high power, std::psd) or a
    /// two-column text file of frequency and PSD (`asd:FILE` for an ASD).
    #[arg(long, default_value = "aligo")]
    pub psd: String,
    /// Mean glitches per minute (a Poisson process; 0 for noise alone).
    #[arg(long, value_name = "PER_MINUTE", default_value_t = 6.0)]
    pub glitch_rate: f64,
    /// Classes to inject, drawn uniformly.
    #[arg(long, value_enum, value_delimiter = ',', default_values = ["blip", "koi-fish", "whistle", "scratchy"])]
    pub classes: Vec<GlitchClass>,
    /// Optimal SNR range of injections (against the PSD, 20 Hz-2 kHz),
    /// drawn uniformly for every class; `class`: each class's own range,
    /// log-uniform, as in `gwml data glitch` (Blip 6.5-100, Koi Fish
    /// 25-400, Whistle 6.5-60, ...).
    #[arg(long, value_name = "LO..HI|class", default_value = "8..30")]
    pub snr: String,
    /// Missing data: NaN samples and the DQ DATA bit cleared over START:LENGTH
    /// seconds from the first sample (repeatable).
    #[arg(long, value_name = "START:LENGTH")]
    pub gap: Vec<String>,
    /// GPS time of the first sample.
    #[arg(long, default_value_t = 1_264_000_000.0)]
    pub gps_start: f64,
    /// Seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// CSV of the injections (gps_time, label, snr, the start and end of
    /// the central 90 % of each signal's whitened energy, shape params).
    #[arg(long, value_name = "TRUTH.csv")]
    pub truth: Option<PathBuf>,
    /// Store the strain contiguous instead of gzip-compressed chunks.
    #[arg(long)]
    pub uncompressed: bool,
    /// Draw the shapes of a class from a generator fitted by `gwml
    /// generator fit` (the file says which classes it draws; its 4096 Hz
    /// whitened glitches are coloured by the PSD) instead of its formula;
    /// repeat for several generators (at most one per class).
    #[arg(long, value_name = "GEN.json")]
    pub generator: Vec<PathBuf>,
    /// Half the Blips, Koi Fish and Tomtes take the shape of a real O3
    /// glitch's fit instead of their formula, as in `gwml data glitch` (a
    /// Koi Fish at its fitted SNR unless --snr fixes a range; their truth
    /// rows have no shape params).
    #[arg(long)]
    pub real_fits: bool,
}

/// `gwml data strain`.
pub fn data_strain(a: StrainArgs) -> Result<(), String> {
    let psd = match a.psd.as_str() {
        "aligo" => NoiseCurve::Aligo,
        other => {
            let (kind, path) = match other.strip_prefix("asd:") {
                Some(p) => (gwml::runtime::spectrum::Kind::Asd, p),
                None => (gwml::runtime::spectrum::Kind::Psd, other.strip_prefix("psd:").unwrap_or(other)),
            };
            NoiseCurve::File(gwml::runtime::spectrum::Spectrum::read(path, kind).map_err(render)?)
        }
    };
    let gaps = a
        .gap
        .iter()
        .map(|g| {
            let (s, l) = g.split_once(':').ok_or_else(|| format!("error: --gap `{g}`: expected START:LENGTH in seconds"))?;
            let num = |x: &str| x.trim().parse::<f64>().map_err(|_| format!("error: --gap `{g}`: `{x}` is not a number"));
            Ok((num(s)?, num(l)?))
        })
        .collect::<Result<Vec<_>, String>>()?;
    let options = StrainOptions {
        duration: a.duration,
        gps_start: a.gps_start,
        ifo: a.ifo.clone(),
        psd,
        glitch_rate: a.glitch_rate,
        classes: a.classes.iter().map(|c| c.label()).collect(),
        snr: if a.snr == "class" { None } else { Some(parse_range(&a.snr)?) },
        gaps,
        seed: a.seed,
    };
    if a.ifo.is_empty() || !a.ifo.chars().all(|c| c.is_ascii_alphanumeric()) {
        return Err(format!("error: --ifo `{}` must be a detector name such as H1", a.ifo));
    }
    let mut shapes = GeneratorShapes::open(&a.generator, a.seed, 1.0)?;
    // Real fits' shapes from their own stream, so the formula draws of a
    // seed stay as they are.
    let mut real = RealShapes::new(a.seed.wrapping_add(0x5eed));
    let (series, injections) = simulate_with(&options, &mut |class| {
        Ok(match shapes.shape(class)? {
            Some(s) => Some(Shape::from(s)),
            None if a.real_fits => real.draw(class),
            None => None,
        })
    })
    .map_err(render)?;
    let write = WriteOptions { chunk: (!a.uncompressed).then_some(16_384), gzip_level: 4 };
    gwosc::write(&a.out, &series, &write).map_err(|e| format!("error: {e}"))?;
    println!(
        "wrote {}: {} s of {} strain at {} Hz from GPS {}, {} injections",
        a.out.display(),
        a.duration,
        a.ifo,
        series.sample_rate,
        a.gps_start,
        injections.len()
    );
    if let Some(path) = &a.truth {
        write_truth(path, &injections).map_err(render)?;
        println!("wrote {} (gps_time,label,snr,start,end and shape params)", path.display());
    }
    Ok(())
}

#[derive(clap::Args)]
pub struct ScanArgs {
    #[command(flatten)]
    pub input: StrainInput,
    /// Classifier: a manifest (glitch-classifier.json) or a .gw file with
    /// --weights [default: the shipped classifier, models/glitch-classifier].
    #[arg(long, value_name = "M.gw|MANIFEST.json")]
    pub model: Option<PathBuf>,
    /// Trained weights for a --model .gw file.
    #[arg(long, value_name = "W.safetensors")]
    pub weights: Option<PathBuf>,
    /// Report triggers without classifying them.
    #[arg(long, conflicts_with_all = ["model", "weights"])]
    pub no_classify: bool,
    /// Where to write triggers: .csv or .json.
    #[arg(long, value_name = "triggers.csv|triggers.json", default_value = "triggers.csv")]
    pub out: PathBuf,
    /// Minimum SNR of a trigger's most significant tile.
    #[arg(long, default_value_t = 7.5)]
    pub snr_threshold: f64,
    /// How unlikely in Gaussian noise a long glitch's summed excess power
    /// must be, as the SNR of a single tile equally unlikely: lower finds
    /// quieter Scratchy and Whistle glitches, higher makes fewer false
    /// alarms in noisy data (0.39-0.44 per 100 s above SNR 8 in Gaussian
    /// noise at 5.5).
    #[arg(long, value_name = "SNR", default_value_t = ScanOptions::default().min_significance)]
    pub min_significance: f64,
    /// Lowest frequency searched (Hz).
    #[arg(long, default_value_t = 10.0)]
    pub fmin: f64,
    /// Highest frequency searched (Hz); lowered to what Q and Nyquist allow.
    #[arg(long, default_value_t = 2048.0)]
    pub fmax: f64,
    /// Seconds of data each PSD estimate is made from (re-estimated per chunk).
    #[arg(long, default_value_t = 128.0)]
    pub psd_stretch: f64,
    /// Welch FFT length in seconds.
    #[arg(long, default_value_t = 4.0)]
    pub fft_length: f64,
    /// Worker threads [default: all cores].
    #[arg(long)]
    pub threads: Option<usize>,
    /// Directory for plots: triggers in time and frequency, coloured by label.
    #[arg(long, value_name = "DIR")]
    pub plots: Option<PathBuf>,
    /// Seconds of strain held in memory at a time: files are read and
    /// scanned in blocks this long, overlapping by 8 s (memory stays bounded
    /// whatever the files' length).
    #[arg(long, value_name = "SECONDS", default_value_t = 1024.0)]
    pub block: f64,
    /// Explain every trigger as `gwml explain` does (physics fits of each
    /// glitch family and a chirp, Bayes factors): adds the best family, its
    /// Bayes factors and params to each row. About 0.7 s per trigger.
    #[arg(long)]
    pub explain: bool,
    /// Record each finished block in OUT.parts/ beside the output; a rerun
    /// with the same files and settings then scans only the blocks missing
    /// (after a crash or a kill) and gives the same output. The directory is
    /// removed once the output is written.
    #[arg(long)]
    pub resume: bool,
    /// Run as one rank of an MPI job (`mpirun -n N gwml scan --mpi ...`):
    /// the blocks are dealt to the ranks, rank 0 gathers the triggers and
    /// writes them, the same as one process writes. Finished blocks are
    /// recorded as with --resume (OUT.parts/ must be on a filesystem every
    /// rank sees). Needs gwml built with `--features mpi`.
    #[arg(long)]
    pub mpi: bool,
}

/// The inputs opened and the work planned, before scanning.
struct Opened {
    sources: Vec<Source>,
    /// Runs of consecutive inputs (indices into `sources`).
    runs: Vec<Vec<usize>>,
    /// Gaps between files.
    gaps: Vec<gwml_strain::series::Skipped>,
    blocks: Vec<blocks::Block>,
    /// Where finished blocks are recorded (--resume, --mpi).
    parts: Option<Parts>,
    /// Blocks recorded as finished by an earlier run.
    done: BTreeMap<usize, Report>,
    /// Blocks to scan, by every rank.
    todo: Vec<usize>,
    /// Blocks this rank scans.
    mine: Vec<usize>,
    /// The first of `mine`, read.
    first: Option<gwml_strain::series::Series>,
}

/// Rank 0's plan of blocks still to do, checked on every rank; an error on
/// rank 0 stops every rank (the others quietly: rank 0 reports it).
fn agree(world: &World, opened: Result<Opened, String>) -> Result<Opened, String> {
    if world.size() == 1 {
        return opened;
    }
    let mine = match &opened {
        Ok(o) => serde_json::to_vec(&o.todo).expect("JSON values serialise"),
        Err(_) => Vec::new(),
    };
    let roots = world.broadcast(mine.clone());
    if roots.is_empty() {
        return Err(if world.is_root() { opened.err().unwrap_or_default() } else { String::new() });
    }
    let opened = opened?;
    if roots != mine {
        return Err(format!(
            "error: rank {} sees other finished blocks than rank 0: the parts directory must be on a filesystem every rank shares",
            world.rank()
        ));
    }
    Ok(opened)
}

/// The manifest of the classifier the arguments ask for (`None` with
/// --no-classify): its rate decides whether the files are decimated.
fn manifest(a: &ScanArgs) -> Result<Option<Manifest>, String> {
    if a.no_classify {
        return Ok(None);
    }
    let fail = |e: gwml_strain::Error| format!("error: {e}");
    let manifest = match (&a.model, &a.weights) {
        (None, Some(_)) => return Err("error: --weights needs --model (the .gw file they belong to)".into()),
        (None, None) => Manifest::shipped().map_err(fail)?,
        (Some(m), w) if m.extension().is_some_and(|e| e == "json") => {
            if w.is_some() {
                return Err("error: a manifest names its own weights; drop --weights".into());
            }
            Manifest::read(m).map_err(fail)?
        }
        (Some(m), Some(w)) => {
            // A bare model: the shipped manifest's conventions (classes, rate, band).
            let mut manifest = Manifest::shipped().map_err(fail)?;
            (manifest.model, manifest.weights) = (m.clone(), w.clone());
            manifest
        }
        (Some(m), None) => return Err(format!("error: --model {} needs --weights (or give a manifest .json)", m.display())),
    };
    Ok(Some(manifest))
}

/// The classifier the arguments ask for.
fn classifier(a: &ScanArgs) -> Result<Option<Classifier>, String> {
    let fail = |e: gwml_strain::Error| format!("error: {e}");
    match manifest(a)? {
        None => Ok(None),
        Some(_) if a.model.is_none() => Classifier::shipped().map(Some).map_err(fail),
        Some(m) => Classifier::load(m).map(Some).map_err(fail),
    }
}

/// What identifies a scan's results: the files (path, size, modification
/// time) and every setting that changes a trigger. Parts recorded under
/// another fingerprint are not merged with this scan's.
fn fingerprint(a: &ScanArgs, options: &ScanOptions) -> String {
    let mut out = String::new();
    for path in &a.input.strain {
        let meta = std::fs::metadata(path).ok();
        let modified = meta.as_ref().and_then(|m| m.modified().ok()).and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
        let _ = write!(out, "{} {} {:?}; ", path.display(), meta.map_or(0, |m| m.len()), modified);
    }
    let _ = write!(
        out,
        "rate {:?} gps {:?} ifo {} block {} options {options:?} model {:?} weights {:?} classify {}",
        a.input.sample_rate, a.input.gps_start, a.input.ifo, a.block, a.model, a.weights, !a.no_classify
    );
    out
}

/// Opens the inputs, plans the blocks, finds those recorded as finished
/// (with --resume or --mpi) and reads the first block this rank scans.
fn open_and_plan(a: &ScanArgs, options: &ScanOptions, world: &World) -> Result<Opened, String> {
    let fail = |e: gwml_strain::Error| format!("error: {e}");
    let sources = a.input.open()?;
    let spans: Vec<Span> = sources.iter().map(Source::span).collect();
    let (runs, gaps) = plan(&spans).map_err(fail)?;
    let rate = manifest(a)?.map(|m| m.sample_rate);
    let run_spans: Vec<Span> = runs.iter().map(|r| StrainRun::new(&sources, r, rate).span).collect();
    let blocks = plan_blocks(&run_spans, a.block, options);
    let (parts, done) = match a.resume || a.mpi {
        true => {
            let parts = Parts::open(&a.out, &fingerprint(a, options), blocks.len(), world.is_root()).map_err(fail)?;
            let done = parts.finished(blocks.len()).map_err(fail)?;
            (Some(parts), done)
        }
        false => (None, BTreeMap::new()),
    };
    let todo: Vec<usize> = (0..blocks.len()).filter(|i| !done.contains_key(i)).collect();
    let mine = deal(&todo, world.rank(), world.size());
    let first = match mine.first() {
        Some(&i) => Some(StrainRun::new(&sources, &runs[blocks[i].run], rate).block(blocks[i].start, blocks[i].length).map_err(fail)?),
        None => None,
    };
    Ok(Opened { sources, runs, gaps, blocks, parts, done, todo, mine, first })
}

/// `gwml scan`.
pub fn scan(a: ScanArgs) -> Result<(), String> {
    let started = Instant::now();
    let fail = |e: gwml_strain::Error| format!("error: {e}");
    let format = match a.out.extension().and_then(|e| e.to_str()) {
        Some("csv") => "csv",
        Some("json") => "json",
        _ => return Err(format!("error: --out {}: write .csv or .json", a.out.display())),
    };
    if !(a.block >= 64.0 && a.block.is_finite()) {
        return Err(format!("error: --block {}: blocks of at least 64 s are needed", a.block));
    }
    let options = ScanOptions {
        snr_threshold: a.snr_threshold,
        min_significance: a.min_significance,
        f_range: (a.fmin, a.fmax),
        psd_stretch: a.psd_stretch,
        fft_length: a.fft_length,
        ..ScanOptions::default()
    };
    // Compile the classifier and the whitening scene for 4096 Hz data
    // (GWOSC's usual rate) while MPI starts and the files are opened, the
    // blocks planned and this process's first one read.
    let (world, opened, scanner) = std::thread::scope(|scope| {
        // The classifier and the whitening scene take about as long to
        // compile: each on its own thread.
        let compiling = scope.spawn(|| {
            let mut scanner = Scanner::new(options.clone(), None).map_err(|e| format!("error: {e}"))?;
            scanner.expect_classifier_band(manifest(&a)?.map(|m| m.band_hz));
            let (c, _) = std::thread::scope(|inner| {
                let loading = inner.spawn(|| classifier(&a));
                let warm = scanner.warm_up(a.input.sample_rate.unwrap_or(4096.0));
                (loading.join().expect("the classifier's thread does not panic"), warm)
            });
            scanner.set_classifier(c?);
            Ok::<_, String>(scanner)
        });
        let world = World::new(a.mpi);
        let opened = match &world {
            Ok(w) => open_and_plan(&a, &options, w),
            Err(e) => Err(e.clone()),
        };
        (world, opened, compiling.join().expect("the compiling thread does not panic"))
    });
    let world = world?;
    // Every rank must scan the same plan: rank 0's list of blocks to do (or
    // its error) goes to all, and a rank that sees another list stops.
    let Opened { sources, runs, gaps, blocks, parts, done, todo, mine, first } = agree(&world, opened)?;
    let scanner = scanner?;
    let setup_seconds = started.elapsed().as_secs_f64();
    let rate = scanner.classifier().map(|c| c.manifest.sample_rate);
    let runs: Vec<StrainRun> = runs.iter().map(|r| StrainRun::new(&sources, r, rate)).collect();
    if let Some(run) = runs.iter().find(|r| r.decimation().is_some()).filter(|_| world.is_root()) {
        let k = run.decimation().unwrap_or(1);
        println!(
            "{} is sampled at {} Hz: read through a low-pass filter and decimated by {k} to the classifier's {} Hz",
            run.span.source,
            run.span.sample_rate * k as f64,
            run.span.sample_rate
        );
    }
    let threads = a.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads.max(1)).build().map_err(|e| format!("error: {e}"))?;
    let total: f64 = sources.iter().map(|s| s.span()).map(|s| s.samples as f64 / s.sample_rate).sum();
    let mine_seconds: f64 = mine.iter().map(|&i| blocks[i].length as f64 / runs[blocks[i].run].span.sample_rate).sum();
    let bar = if world.is_root() { ProgressBar::new(mine_seconds.round() as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("scan [{bar:30}] {pos}/{len} s of data, {per_sec} data-seconds, eta {eta}").expect("a valid template"),
    );
    if world.size() > 1 && world.is_root() {
        println!("MPI: {} ranks share {} of {} blocks ({} finished before)", world.size(), todo.len(), blocks.len(), done.len());
    } else if !done.is_empty() {
        println!("resuming: {} of {} blocks finished before, {} to do", done.len(), blocks.len(), todo.len());
    }
    let mut recorder = |index: usize, report: &Report| parts.as_ref().map_or(Ok(()), |p| p.record(index, report));
    let scanned = scan_blocks(&runs, &blocks, &mine, first, (&scanner, &pool), &|seconds| bar.inc(seconds.round() as u64), &mut recorder)
        .map_err(fail)?;
    bar.finish_and_clear();
    let Some(gathered) = world.gather(encode(&scanned)) else {
        // Other ranks are done: rank 0 writes.
        return Ok(());
    };
    let mut reports: BTreeMap<usize, Report> = done;
    for bytes in gathered {
        reports.extend(decode(&bytes, "a rank").map_err(fail)?);
    }
    if reports.len() != blocks.len() {
        return Err(format!("error: {} of {} blocks came back from the ranks", reports.len(), blocks.len()));
    }
    let report = merge(reports.into_values().collect(), gaps, options.cluster_gap).expect("every run has a block");
    let classes: Vec<String> = scanner.classifier().map_or(Vec::new(), |c| c.manifest.classes.clone());
    let explain_started = Instant::now();
    let explained = if a.explain {
        let bar = ProgressBar::new(report.rows.len() as u64);
        bar.set_style(ProgressStyle::with_template("{bar:40} {pos}/{len} triggers explained, ETA {eta}").expect("template"));
        let times: Vec<f64> = report.rows.iter().map(|r| r.trigger.time).collect();
        let explained = crate::explain::explain_times(&a.input, &times, || bar.inc(1));
        bar.finish_and_clear();
        explained
    } else {
        Vec::new()
    };
    let text = if format == "csv" { triggers_csv(&report, &classes, &explained) } else { triggers_json(&report, &classes, &explained) };
    std::fs::write(&a.out, text).map_err(|e| format!("error: cannot write {}: {e}", a.out.display()))?;
    if let Some(parts) = &parts {
        parts.remove();
    }
    if let Some(dir) = &a.plots {
        plot_triggers(dir, &report, &classes)?;
    }
    print!("{}", summary(&report, &classes, total, explain_started.duration_since(started).as_secs_f64()));
    let st = report.stage_seconds;
    println!(
        "time: reading the first block and compiling {setup_seconds:.2} s, reading and scanning {:.2} s on {threads} threads \
         (CPU s: PSD {:.2}, whitening {:.2}, Q tiles {:.2}, classifier {:.2})",
        explain_started.duration_since(started).as_secs_f64() - setup_seconds,
        st.psd,
        st.whiten,
        st.tiles,
        st.classify
    );
    if a.explain {
        let failed = explained.iter().filter(|e| e.is_err()).count();
        println!(
            "explained {} triggers in {:.2} s ({failed} without an explanation: their data are too near an end or a gap)",
            explained.len(),
            explain_started.elapsed().as_secs_f64()
        );
    }
    println!("wrote {} ({} triggers)", a.out.display(), report.rows.len());
    Ok(())
}

/// The label and confidence of a row (empty and 0 without a classifier).
fn label_of<'c>(row: &gwml_strain::scan::Row, classes: &'c [String]) -> (&'c str, f64) {
    match &row.verdict {
        Some(v) => (classes[v.label].as_str(), v.probabilities[v.label]),
        None => ("", 0.0),
    }
}

fn triggers_csv(report: &Report, classes: &[String], explained: &[Explained]) -> String {
    let mut out = String::from("gps_time,ifo,snr,peak_frequency,q,duration,label,confidence,start,end,f_start,f_end,tiles");
    if !explained.is_empty() {
        let _ = write!(out, ",{}", crate::explain::CSV_COLUMNS);
    }
    for c in classes {
        let _ = write!(out, ",{}", probability_column(c));
    }
    out.push('\n');
    for (i, row) in report.rows.iter().enumerate() {
        let t = &row.trigger;
        let (label, confidence) = label_of(row, classes);
        let confidence = if row.verdict.is_some() { format!("{confidence:.4}") } else { String::new() };
        let _ = write!(
            out,
            "{:.4},{},{:.3},{:.2},{:.2},{:.4},{},{},{:.4},{:.4},{:.2},{:.2},{}",
            t.time,
            report.ifo,
            t.snr,
            t.peak_frequency,
            t.q,
            t.duration(),
            label,
            confidence,
            t.start,
            t.end,
            t.f_start,
            t.f_end,
            t.tiles
        );
        if let Some(e) = explained.get(i) {
            let _ = write!(out, ",{}", crate::explain::csv_fields(e));
        }
        if let Some(v) = &row.verdict {
            v.probabilities.iter().for_each(|p| {
                let _ = write!(out, ",{p:.4}");
            });
        }
        out.push('\n');
    }
    out
}

fn triggers_json(report: &Report, classes: &[String], explained: &[Explained]) -> String {
    let rows: Vec<serde_json::Value> = report
        .rows
        .iter()
        .enumerate()
        .map(|(i, row)| {
            let t = &row.trigger;
            let (label, confidence) = label_of(row, classes);
            let mut v = serde_json::json!({
                "gps_time": t.time, "ifo": report.ifo, "snr": t.snr, "peak_frequency": t.peak_frequency,
                "q": t.q, "duration": t.duration(), "start": t.start, "end": t.end,
                "f_start": t.f_start, "f_end": t.f_end, "tiles": t.tiles,
            });
            if let Some(verdict) = &row.verdict {
                v["label"] = label.into();
                v["confidence"] = confidence.into();
                v["probabilities"] = classes.iter().cloned().zip(verdict.probabilities.iter().copied()).collect();
            }
            if let Some(e) = explained.get(i) {
                v["explanation"] = crate::explain::json_field(e);
            }
            v
        })
        .collect();
    let skipped: Vec<serde_json::Value> = report
        .skipped
        .iter()
        .map(|s| serde_json::json!({"gps_start": s.gps_start, "seconds": s.seconds, "reason": s.reason.describe()}))
        .collect();
    let doc = serde_json::json!({
        "ifo": report.ifo, "scanned_seconds": report.scanned_seconds,
        "tiled_band_hz": [report.tiled_band.0, report.tiled_band.1],
        "classes": classes, "skipped": skipped, "triggers": rows,
    });
    serde_json::to_string_pretty(&doc).expect("JSON values") + "\n"
}

/// The summary printed after a scan.
fn summary(report: &Report, classes: &[String], total: f64, elapsed: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "scanned {:.0} s of {} data ({:.0} s in the files) in {:.2} s: {:.0}× real time; band {:.0}-{:.0} Hz",
        report.scanned_seconds,
        report.ifo,
        total,
        elapsed,
        report.scanned_seconds / elapsed.max(1e-9),
        report.tiled_band.0,
        report.tiled_band.1
    );
    for (reason, seconds) in report.skipped_by_reason() {
        let _ = writeln!(s, "skipped {seconds:.0} s: {}", reason.describe());
    }
    if report.skipped.iter().any(|k| k.reason == SkipReason::MissingSamples || k.reason == SkipReason::NoDataFlag) {
        let spans: Vec<String> = report
            .skipped
            .iter()
            .filter(|k| k.reason != SkipReason::SegmentEdges)
            .take(5)
            .map(|k| format!("GPS {:.0}+{:.0} s", k.gps_start, k.seconds))
            .collect();
        let _ = writeln!(s, "  first missing stretches: {}", spans.join(", "));
    }
    let mut counts = vec![0usize; classes.len()];
    for row in &report.rows {
        if let Some(v) = &row.verdict {
            counts[v.label] += 1;
        }
    }
    if classes.is_empty() {
        let _ = writeln!(s, "{} triggers (not classified)", report.rows.len());
    } else {
        let per: Vec<String> = classes.iter().zip(&counts).map(|(c, n)| format!("{n} {c}")).collect();
        let _ = writeln!(s, "{} triggers: {}", report.rows.len(), per.join(", "));
    }
    s
}

/// `DIR/triggers.png`: peak frequency against time, one colour per label.
fn plot_triggers(dir: &Path, report: &Report, classes: &[String]) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("error: cannot create {}: {e}", dir.display()))?;
    let t0 = report.rows.first().map_or(0.0, |r| r.trigger.time.floor());
    let names: Vec<String> = if classes.is_empty() { vec!["trigger".into()] } else { classes.to_vec() };
    let points: Vec<Vec<(f64, f64)>> = (0..names.len())
        .map(|c| {
            report
                .rows
                .iter()
                .filter(|r| r.verdict.as_ref().map_or(0, |v| v.label) == c)
                .map(|r| (r.trigger.time - t0, r.trigger.peak_frequency))
                .collect()
        })
        .collect();
    let series: Vec<(&str, &[(f64, f64)])> =
        names.iter().zip(&points).filter(|(_, p)| !p.is_empty()).map(|(n, p)| (n.as_str(), p.as_slice())).collect();
    let path = dir.join("triggers.png");
    gwml_lab::plot::scatter_plot(
        &path,
        &format!("{} triggers of {}", report.rows.len(), report.ifo),
        &format!("time since GPS {t0:.0} [s]"),
        "peak frequency [Hz]",
        &series,
    )?;
    println!("wrote {}", path.display());
    Ok(())
}
