//! `gwml qscan`: Q-transform images of whitened strain around one GPS time,
//! at several durations (Gravity Spy's 0.5, 1, 2 and 4 s).

use crate::strain_input::StrainInput;
use gwml_lab::plot::{heatmaps_plot, Heatmap};
use gwml_strain::qimage::{ImageOptions, QImage, QTransform};
use gwml_strain::qtransform::QOptions;
use gwml_strain::series::Series;
use gwml_strain::whitening::{whiten_series, WhitenOptions, Whitened, Whitener};
use std::path::PathBuf;

/// Seconds of strain read around the time of interest: the PSD is estimated
/// from them and their outer 2 s are tapered before whitening.
pub const CONTEXT_SECONDS: f64 = 32.0;

/// Welch segment length for the PSD of that context (15 half-overlapping segments).
pub const CONTEXT_FFT_LENGTH: f64 = 4.0;

/// Normalised energy at which the colour scale saturates (Gravity Spy's 25.5).
const COLOUR_MAX: f64 = 25.5;

#[derive(clap::Args)]
pub struct QscanArgs {
    #[command(flatten)]
    pub input: StrainInput,
    /// GPS time at the centre of the images.
    #[arg(long)]
    pub gps: f64,
    /// Durations of the images in seconds (Gravity Spy's four by default).
    #[arg(long, value_delimiter = ',', default_values_t = [0.5, 1.0, 2.0, 4.0])]
    pub durations: Vec<f64>,
    /// Lowest frequency tiled (Hz).
    #[arg(long, default_value_t = 10.0)]
    pub fmin: f64,
    /// Highest frequency tiled (Hz); lowered to what Q and Nyquist allow.
    #[arg(long, default_value_t = 2048.0)]
    pub fmax: f64,
    /// The PNG to write (without it, only the loudest tiles are printed).
    #[arg(long, value_name = "Q.png")]
    pub out: Option<PathBuf>,
}

/// The whitening scene, compiled for the context's length on first use.
pub fn whitener() -> Result<Whitener, String> {
    Whitener::new().map_err(|e| format!("error: {e}"))
}

/// Whitened strain around `gps`: [`CONTEXT_SECONDS`] s read, whitened by
/// its own PSD over `band` with `whitener` (reused across times, so its
/// scene is compiled once); decimated to `rate` when the files are sampled
/// at a whole multiple of it.
pub fn whitened_around(
    whitener: &Whitener,
    input: &StrainInput,
    gps: f64,
    band: (f64, f64),
    rate: Option<f64>,
) -> Result<(Series, Whitened), String> {
    let series = input.around(gps, CONTEXT_SECONDS, rate)?;
    let top = band.1.min(series.sample_rate / 2.0);
    let options = WhitenOptions { taper: 2.0, band: (band.0, top), classifier_band: (band.0, top) };
    let w = whiten_series(whitener, &series, CONTEXT_FFT_LENGTH, &options).map_err(|e| format!("error: {e}"))?;
    Ok((series, w))
}

/// The Q-transform images of whitened data around `gps`, one per duration
/// (loudest plane within 0.25 s of `gps`, as gwpy's default search).
pub fn q_images(w: &Whitened, gps: f64, durations: &[f64], band: (f64, f64)) -> Result<Vec<QImage>, String> {
    let tiling = QOptions { f_range: band, ..QOptions::default() };
    let q = QTransform::new(&w.w, w.sample_rate, w.gps_start, &tiling).map_err(|e| format!("error: {e}"))?;
    let usable = (w.gps_start + 2.0, w.gps_start + w.w.len() as f64 / w.sample_rate - 2.0);
    durations
        .iter()
        .map(|&d| {
            if !(d > 0.0 && gps - d / 2.0 >= usable.0 && gps + d / 2.0 <= usable.1) {
                return Err(format!(
                    "error: a {d} s Q-scan around GPS {gps} needs GPS {:.2}..{:.2}, but the whitened data are usable over GPS {:.2}..{:.2} \
                     only (the time is too near an end of the data, or the duration too long)",
                    gps - d / 2.0,
                    gps + d / 2.0,
                    usable.0,
                    usable.1
                ));
            }
            let o = ImageOptions {
                outseg: (gps - d / 2.0, gps + d / 2.0),
                search: Some((gps - 0.25, gps + 0.25)),
                times: 400,
                frequencies: 250,
            };
            q.image(&o).map_err(|e| format!("error: {e}"))
        })
        .collect()
}

/// The Q-transform image of a whole array `x` (already white) sampled at
/// `sample_rate` from time `start`: every Q plane from 10 Hz (or 4 cycles of
/// the data's duration) to Nyquist, the loudest plane interpolated over
/// the array's span. The REPL's `:qscan EXPR`.
pub fn q_image_of(x: &[f64], sample_rate: f64, start: f64) -> Result<QImage, String> {
    let duration = x.len() as f64 / sample_rate;
    let tiling = QOptions { f_range: ((4.0 / duration).max(10.0), sample_rate / 2.0), ..QOptions::default() };
    let o = ImageOptions { outseg: (start, start + duration), search: None, times: 400, frequencies: 250 };
    gwml_strain::qimage::q_image(x, sample_rate, start, &tiling, &o).map_err(|e| format!("error: {e}"))
}

/// Draws Q images side by side (two columns), times relative to `gps`.
pub fn plot_q_images(path: &std::path::Path, title: &str, gps: f64, images: &[(String, &QImage)]) -> Result<(), String> {
    let times: Vec<Vec<f64>> = images.iter().map(|(_, i)| i.times.iter().map(|t| t - gps).collect()).collect();
    let panels: Vec<Heatmap> = images
        .iter()
        .zip(&times)
        .map(|((name, img), xs)| Heatmap { title: format!("{name} (Q = {:.1})", img.q), xs, ys: &img.frequencies, values: &img.values })
        .collect();
    heatmaps_plot(path, title, (&format!("time from GPS {gps:.3} (s)"), "frequency (Hz)"), &panels, 2, COLOUR_MAX)
}

/// `gwml qscan`.
pub fn qscan(a: QscanArgs) -> Result<(), String> {
    if a.durations.is_empty() {
        return Err("error: --durations needs at least one duration".into());
    }
    let band = (a.fmin, a.fmax);
    let (series, w) = whitened_around(&whitener()?, &a.input, a.gps, band, None)?;
    let images = q_images(&w, a.gps, &a.durations, band)?;
    let named: Vec<(String, &QImage)> = a.durations.iter().zip(&images).map(|(d, i)| (format!("{d} s"), i)).collect();
    let title = format!("{} Q-scan at GPS {:.3}", series.detector, a.gps);
    if let Some(out) = &a.out {
        plot_q_images(out, &title, a.gps, &named)?;
    }
    for (d, img) in a.durations.iter().zip(&images) {
        let m = img.max();
        println!(
            "{d:>4} s: Q {:5.1}, loudest tile {:+.3} s at {:.1} Hz, normalised energy {:.1} (image maximum {:.1} at {:+.3} s, {:.1} Hz)",
            img.q,
            img.peak.time - a.gps,
            img.peak.frequency,
            img.peak.energy,
            m.energy,
            m.time - a.gps,
            m.frequency
        );
    }
    if let Some(out) = &a.out {
        println!("wrote {}", out.display());
    }
    Ok(())
}
