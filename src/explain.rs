//! `gwml explain`: fit every glitch family and a chirp to the whitened
//! strain around one GPS time, rank them by Bayes factor, name a likely
//! cause, and draw the fit with the Q-scans of the data and the residual.

use crate::qscan::{q_images, whitened_around, whitener};
use crate::strain_input::StrainInput;
use gwml_lab::explain::{explain_at, explanation_json, explanation_text, ExplainOptions, Explainer, Explanation, Window};
use gwml_lab::plot::{lines_over_heatmaps_plot, Heatmap};
use gwml_strain::whitening::Whitened;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The band data and models are whitened over (Hz), capped below Nyquist.
pub const EXPLAIN_BAND: (f64, f64) = (20.0, 2000.0);

/// The rate the fits run at when the files allow it: data sampled at a
/// whole multiple of it (GWOSC's 16384 Hz) are decimated to it, as a scan
/// does for its classifier. The band ends at 2 kHz either way, and a
/// quarter of the samples makes every fit cheaper.
pub const EXPLAIN_RATE: f64 = 4096.0;

#[derive(clap::Args)]
pub struct ExplainArgs {
    #[command(flatten)]
    pub input: StrainInput,
    /// GPS time of the trigger (the centre of the fitted window).
    #[arg(long)]
    pub gps: f64,
    /// Seconds of whitened data fitted, centred on --gps.
    #[arg(long, default_value_t = 2.0)]
    pub window: f64,
    /// Write the fits, Bayes factors and cause as JSON.
    #[arg(long, value_name = "OUT.json")]
    pub json: Option<PathBuf>,
    /// Draw the whitened data with the best fit over it, and the Q-scans of
    /// the data and of the residual (PNG).
    #[arg(long, value_name = "OUT.png")]
    pub plot: Option<PathBuf>,
}

/// The band for data at `sample_rate`: [`EXPLAIN_BAND`] below 0.49 × the rate.
pub fn band_for(sample_rate: f64) -> (f64, f64) {
    (EXPLAIN_BAND.0, EXPLAIN_BAND.1.min(0.49 * sample_rate))
}

/// The fits compiled for data at `sample_rate` and a `window` s window.
pub fn explainer(sample_rate: f64, window: f64) -> Result<Explainer, String> {
    if !(window > 0.0 && window <= 8.0) {
        return Err(format!("error: --window {window}: give 0 < seconds <= 8 (the data read around the time are 32 s)"));
    }
    Explainer::new(&ExplainOptions { sample_rate, window, band: band_for(sample_rate) }).map_err(|e| format!("error: {}", e.render(false)))
}

/// `gwml explain`.
pub fn explain(a: ExplainArgs) -> Result<(), String> {
    let compile = Instant::now();
    let (series, w) = whitened_around(&whitener()?, &a.input, a.gps, EXPLAIN_BAND, Some(EXPLAIN_RATE))?;
    let band = band_for(w.sample_rate);
    let explainer = explainer(w.sample_rate, a.window)?;
    let compile_seconds = compile.elapsed().as_secs_f64();
    let started = Instant::now();
    let (win, seed, e) = explain_at(&explainer, &w, a.gps, band).map_err(|e| format!("error: {e}"))?;
    let seconds = started.elapsed().as_secs_f64();
    println!("{} {}", series.detector, series.source);
    print!("{}", explanation_text(&e, &win, &seed));
    println!(
        "time: {seconds:.2} s for the fits ({} scene evaluations), after {compile_seconds:.2} s reading, whitening and compiling",
        e.evaluations()
    );
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&explanation_json(&e, &win, &seed)).expect("JSON values") + "\n";
        std::fs::write(path, text).map_err(|err| format!("error: cannot write {}: {err}", path.display()))?;
        println!("wrote {}", path.display());
    }
    if let Some(path) = &a.plot {
        plot_explanation(path, &format!("{} GPS {:.3}", series.detector, a.gps), &w, &win, &e, band)?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// The data with the best fit over it (top) and the 1 s Q-scans of the
/// data and the residual (below).
fn plot_explanation(path: &Path, title: &str, w: &Whitened, win: &Window, e: &Explanation, band: (f64, f64)) -> Result<(), String> {
    let model = e.best().map_or_else(|| vec![0.0; win.d.len()], |b| b.model.clone());
    let mut residual = w.clone();
    residual.w[win.offset..win.offset + model.len()].iter_mut().zip(&model).for_each(|(r, m)| *r -= m);
    let gps = win.gps_centre;
    let duration = (win.d.len() as f64 / win.sample_rate).min(1.0);
    let data_q = q_images(w, gps, &[duration], band)?;
    let residual_q = q_images(&residual, gps, &[duration], band)?;
    let times: Vec<f64> = (0..win.d.len()).map(|j| win.gps_start + j as f64 / win.sample_rate - gps).collect();
    let best = e.best().map_or("noise alone".to_string(), |b| format!("best fit: {}", b.family.scene));
    let lines: [(&str, &[f64], &[f64]); 2] = [("whitened data", &times, &win.d), (&best, &times, &model)];
    let q_times: Vec<Vec<f64>> = [&data_q[0], &residual_q[0]].iter().map(|i| i.times.iter().map(|t| t - gps).collect()).collect();
    let panels = [
        Heatmap { title: format!("data (Q = {:.1})", data_q[0].q), xs: &q_times[0], ys: &data_q[0].frequencies, values: &data_q[0].values },
        Heatmap {
            title: format!("residual (Q = {:.1})", residual_q[0].q),
            xs: &q_times[1],
            ys: &residual_q[0].frequencies,
            values: &residual_q[0].values,
        },
    ];
    let x_label = format!("time from GPS {gps:.3} (s)");
    lines_over_heatmaps_plot(path, title, (&lines, (&x_label, "whitened strain")), (&panels, (&x_label, "frequency (Hz)")), 25.5)
}

/// `gwml experiment explain`: the injection campaign of
/// `lab::explain::run_campaign` (the `classes`, or every family when
/// empty, `per_class` each, at SNR `snr` or each class's own from 10 up),
/// written to `out` as `outcomes.csv` and `summary.md`.
pub fn campaign(out: &Path, per_class: usize, seed: u64, snr: Option<(f64, f64)>, classes: Vec<usize>) -> Result<(), String> {
    use gwml_lab::explain::{run_campaign, summarise, CampaignOptions, MIN_SNR};
    use gwml_lab::synth::GLITCH_CLASSES;
    use std::fmt::Write;
    std::fs::create_dir_all(out).map_err(|e| format!("error: cannot create {}: {e}", out.display()))?;
    let classes = if classes.is_empty() { (1..GLITCH_CLASSES.len()).collect() } else { classes };
    let o = CampaignOptions { per_class, classes, snr, window: 2.0, seed };
    let bar = indicatif::ProgressBar::new((per_class * o.classes.len()) as u64);
    bar.set_style(indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} injections explained, ETA {eta}").expect("template"));
    let outcomes = run_campaign(&o, |_| bar.inc(1)).map_err(|e| format!("error: {}", e.render(false)))?;
    bar.finish_and_clear();
    let mut csv =
        String::from("class,snr,verdict,ln_b_vs_second,injected_fit_snr,injected_ln_b_vs_noise,seconds,evaluations,params,injected\n");
    for o in &outcomes {
        let e = &o.explanation;
        let second = e.fits.get(1).map_or(f64::NAN, |s| e.fits[0].ln_z() - s.ln_z());
        let injected = e.fits.iter().find(|f| f.family.label == GLITCH_CLASSES[o.injection.class]);
        let fit_snr = injected.map_or(f64::NAN, |f| (2.0 * (e.noise_loss - f.score.loss)).max(0.0).sqrt());
        let injected_ln_b = injected.map_or(f64::NAN, |f| e.ln_bayes_vs_noise(f));
        let params: Vec<String> = o
            .recovered()
            .iter()
            .map(|(n, v, s, t)| format!("{n}={v:.5}±{}/truth {t:.5}", s.map_or("-".into(), |s| format!("{s:.5}"))))
            .collect();
        let class = GLITCH_CLASSES[o.injection.class];
        let _ = writeln!(
            csv,
            "{class},{:.3},{},{second:.3},{fit_snr:.3},{injected_ln_b:.3},{:.3},{},{},{}",
            o.injection.snr,
            o.verdict(),
            o.seconds,
            e.evaluations(),
            params.join(" "),
            o.injection.params.iter().map(|(n, v)| format!("{n}={v:.5}")).collect::<Vec<_>>().join(" ")
        );
    }
    let mut seconds: Vec<f64> = outcomes.iter().map(|o| o.seconds).collect();
    seconds.sort_by(f64::total_cmp);
    let families: Vec<String> = gwml_lab::explain::FAMILIES
        .iter()
        .map(|family| {
            let mut s: Vec<f64> = outcomes
                .iter()
                .flat_map(|o| o.explanation.fits.iter().chain(&o.explanation.worse_variants))
                .filter(|f| f.family.scene == family.scene)
                .map(|f| f.seconds)
                .collect();
            s.sort_by(f64::total_cmp);
            match s.get(s.len() / 2) {
                Some(median) => format!("{} {median:.3} s", family.scene),
                None => format!("{} not fitted", family.scene),
            }
        })
        .collect();
    let mut md = format!(
        "# gwml explain: injection campaign\n\n`gwml experiment explain --seed {seed}{}{}{}`: {per_class} injections per class into simulated aLIGO strain \
         {}, each explained in a 2 s window. Time per trigger (one thread): median {:.2} s, 90th percentile {:.2} s; per family \
         (median): {}.\n\n\
         | class | injections | right family | param: within 3σ (of those with σ), median relative error |\n|---|---|---|---|\n",
        if per_class == 100 { String::new() } else { format!(" --per-class {per_class}") },
        snr.map_or(String::new(), |(lo, hi)| format!(" --snr {lo}..{hi}")),
        if o.classes.len() == GLITCH_CLASSES.len() - 1 {
            String::new()
        } else {
            o.classes.iter().map(|c| format!(" --class '{}'", GLITCH_CLASSES[*c])).collect()
        },
        snr.map_or(format!("at each class's own SNR range after Gravity Spy, from {MIN_SNR} up"), |(lo, hi)| format!("at SNR {lo}–{hi}")),
        seconds[seconds.len() / 2],
        seconds[seconds.len() * 9 / 10],
        families.join(", "),
    );
    for (label, n, right, params) in summarise(&outcomes) {
        let p: Vec<String> =
            params.iter().map(|(name, with, within, median)| format!("{name}: {within}/{with}, {:.1} %", 100.0 * median)).collect();
        let _ = writeln!(md, "| {label} | {n} | {right} ({:.0} %) | {} |", 100.0 * right as f64 / n as f64, p.join("; "));
    }
    std::fs::write(out.join("outcomes.csv"), csv).map_err(|e| format!("error: cannot write outcomes.csv: {e}"))?;
    std::fs::write(out.join("summary.md"), &md).map_err(|e| format!("error: cannot write summary.md: {e}"))?;
    print!("{md}");
    println!("wrote {}/summary.md and outcomes.csv", out.display());
    Ok(())
}

/// One trigger's explanation, or why there is none.
pub type Explained = Result<(Window, gwml_lab::explain::Seed, Explanation), String>;

/// Explains the trigger at each of `times` in `input` (`gwml scan
/// --explain`): the fits are compiled once per sample rate; a time whose
/// data cannot be whitened (near an end or a gap) gets its error.
pub fn explain_times(input: &StrainInput, times: &[f64], progress: impl Fn()) -> Vec<Explained> {
    let mut compiled: Option<(f64, Explainer)> = None;
    let mut out = Vec::with_capacity(times.len());
    let whitening = whitener();
    for &gps in times {
        let mut one = || -> Explained {
            let (_, w) = whitened_around(whitening.as_ref().map_err(Clone::clone)?, input, gps, EXPLAIN_BAND, Some(EXPLAIN_RATE))?;
            if compiled.as_ref().is_none_or(|(fs, _)| *fs != w.sample_rate) {
                compiled = Some((w.sample_rate, explainer(w.sample_rate, 2.0)?));
            }
            let (_, e) = compiled.as_ref().expect("compiled above");
            explain_at(e, &w, gps, band_for(w.sample_rate)).map_err(|e| format!("error: {e}"))
        };
        out.push(one());
        progress();
    }
    out
}

/// The columns `gwml scan --explain` adds to its CSV.
pub const CSV_COLUMNS: &str = "family,ln_b_vs_noise,ln_b_vs_second,family_params";

/// A trigger's [`CSV_COLUMNS`]: the best family (`noise` when none beats
/// it; empty with the reason in the params column when there is no
/// explanation), its Bayes factors, and its params as `name=value±sigma`
/// separated by `;`.
pub fn csv_fields(r: &Explained) -> String {
    match r {
        Ok((win, _, e)) => {
            let Some(best) = e.fits.first() else { return "noise,,,".into() };
            let second = e.fits.get(1).map_or(String::new(), |s| format!("{:.3}", best.ln_z() - s.ln_z()));
            let params: Vec<String> = best
                .params
                .iter()
                .map(|p| {
                    let value = if p.name == "dt" { win.gps_centre + p.value } else { p.value };
                    let name = if p.name == "dt" { "t0_gps" } else { p.name.as_str() };
                    format!("{name}={value:.6}±{}", p.sigma.map_or("nan".to_string(), |s| format!("{s:.3e}")))
                })
                .collect();
            let family = if e.best().is_some() { best.family.scene } else { "noise" };
            format!("{family},{:.3},{second},{}", e.ln_bayes_vs_noise(best), params.join(";"))
        }
        Err(err) => format!(",,,\"{}\"", err.replace('"', "'")),
    }
}

/// A trigger's explanation as JSON (`{"error": ...}` when there is none).
pub fn json_field(r: &Explained) -> serde_json::Value {
    match r {
        Ok((win, seed, e)) => gwml_lab::explain::explanation_json(e, win, seed),
        Err(err) => serde_json::json!({ "error": err }),
    }
}
