//! Noise curves from text files: the two-column amplitude or power spectral
//! densities that detector groups publish, read and interpolated onto a
//! scene's frequency grid.
//!
//! File format: one point per line, frequency in Hz then value, separated
//! by whitespace or by one comma (CSV). Everything from `#` or `%` to the
//! end of a line is a comment; blank lines (and a UTF-8 byte-order mark)
//! are skipped. The first
//! non-comment line may be a header whose two fields are both not numbers
//! (`frequency,asd`). Frequencies must be positive, finite and strictly
//! increasing; values positive and finite; at least two points. Values are
//! an ASD (strain/√Hz, squared on load) or a PSD (strain²/Hz = s), as the
//! caller says with [`Kind`].
//!
//! Interpolation: **log(PSD) is linear in log(frequency)** between file
//! points, i.e. the curve is a power law `S ∝ f^α` on each interval, a
//! straight line on the log-log axes such curves are drawn on. Exactly at
//! a file frequency the file's value is returned unchanged (squared for an
//! ASD). At f = 0, below the first file frequency (or negative), the first
//! value is held; above the last file frequency, the last value is held.
//! Interpolating log ASD and squaring gives the same curve, since
//! log PSD = 2 log ASD.
//!
//! ```no_run
//! use gwml_runtime::spectrum::{Kind, Spectrum};
//! let s = Spectrum::read("fixtures/spectra/aligo_zerodet_highpower_asd.txt", Kind::Asd)?;
//! let psd_at_100_hz = s.psd_at(100.0);
//! # Ok::<(), gwml_runtime::Error>(())
//! ```

use crate::{unknown, Error, Run};
use gwml_compiler::ir::{Elem, Grid, Shape};
use std::path::Path;

/// What a file's second column holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Amplitude spectral density (strain/√Hz); squared on load.
    Asd,
    /// Power spectral density (strain²/Hz, i.e. s), used as it is.
    Psd,
}

impl Kind {
    /// `"ASD"` or `"PSD"`.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Asd => "ASD",
            Kind::Psd => "PSD",
        }
    }
}

/// A one-sided PSD given at increasing frequencies, as read from a file.
#[derive(Clone, Debug, PartialEq)]
pub struct Spectrum {
    /// Frequencies in Hz, positive and strictly increasing (at least two).
    pub freqs: Vec<f64>,
    /// PSD at each frequency (the file's values, squared if it held an ASD).
    pub psd: Vec<f64>,
    /// Where the data came from (the file path), for messages.
    pub origin: String,
    log_f: Vec<f64>,
    log_s: Vec<f64>,
}

impl Spectrum {
    /// Reads a spectrum file (see the [module docs](self) for the format).
    /// Errors name the file and, for bad content, the line.
    pub fn read(path: impl AsRef<Path>, kind: Kind) -> Result<Spectrum, Error> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io(format!("cannot read {}: {e}", path.display())))?;
        Spectrum::parse(&text, &path.display().to_string(), kind)
    }

    /// Parses the text of a spectrum file; `origin` (a path) labels errors.
    pub fn parse(text: &str, origin: &str, kind: Kind) -> Result<Spectrum, Error> {
        let err = |line: usize, msg: String| Error::Io(format!("{origin}:{line}: {msg}"));
        let mut freqs: Vec<f64> = Vec::new();
        let mut psd = Vec::new();
        let mut last_line = 0;
        let mut prev_text = "";
        let mut seen_content = false;
        for (k, raw) in text.strip_prefix('\u{feff}').unwrap_or(text).lines().enumerate() {
            let line = k + 1;
            let content = raw.split(['#', '%']).next().unwrap_or("").trim();
            if content.is_empty() {
                continue;
            }
            let first_content = !seen_content;
            seen_content = true;
            let fields: Vec<&str> =
                if content.contains(',') { content.split(',').map(str::trim).collect() } else { content.split_whitespace().collect() };
            if fields.len() != 2 || fields.iter().any(|s| s.is_empty()) {
                return Err(err(line, format!("expected two columns (frequency in Hz, {}), found `{content}`", kind.name())));
            }
            let (f, v) = (fields[0].parse::<f64>(), fields[1].parse::<f64>());
            if first_content && f.is_err() && v.is_err() {
                continue; // a header such as `frequency,asd`
            }
            let f = f.map_err(|_| err(line, format!("the frequency `{}` is not a number", fields[0])))?;
            let v = v.map_err(|_| err(line, format!("the {} value `{}` is not a number", kind.name(), fields[1])))?;
            // Messages quote the numbers as the file has them.
            let (f_text, v_text) = (fields[0], fields[1]);
            if !(f.is_finite() && f > 0.0) {
                return Err(err(line, format!("the frequency {f_text} Hz must be positive and finite (values are interpolated in log f)")));
            }
            if let Some(&prev) = freqs.last() {
                if f <= prev {
                    return Err(err(
                        line,
                        format!("frequencies must increase strictly, but {f_text} Hz follows {prev_text} Hz (line {last_line})"),
                    ));
                }
            }
            if !(v.is_finite() && v > 0.0) {
                return Err(err(line, format!("the {} value {v_text} at {f_text} Hz must be positive and finite", kind.name())));
            }
            let s = match kind {
                Kind::Asd => v * v,
                Kind::Psd => v,
            };
            if !(s.is_finite() && s > 0.0) {
                return Err(err(line, format!("the ASD value {v_text} at {f_text} Hz squares to {s:e}, outside the range of f64")));
            }
            freqs.push(f);
            psd.push(s);
            last_line = line;
            prev_text = f_text;
        }
        if freqs.len() < 2 {
            return Err(Error::Io(format!(
                "{origin}: a spectrum needs at least two points (frequency, {}), found {}",
                kind.name(),
                freqs.len()
            )));
        }
        Ok(Spectrum::from_points(freqs, psd, origin.to_string()))
    }

    /// A spectrum from PSD points computed in memory: at least two, positive
    /// finite strictly increasing frequencies, positive finite values.
    pub fn new(freqs: Vec<f64>, psd: Vec<f64>, origin: impl Into<String>) -> Result<Spectrum, Error> {
        let origin = origin.into();
        let increasing = freqs.windows(2).all(|w| w[1] > w[0]) && freqs.first().is_some_and(|f| *f > 0.0);
        let positive = psd.iter().all(|s| *s > 0.0 && s.is_finite()) && freqs.iter().all(|f| f.is_finite());
        if freqs.len() < 2 || freqs.len() != psd.len() || !increasing || !positive {
            return Err(Error::Bind(format!(
                "{origin}: a spectrum needs at least two points of positive increasing frequency and positive finite PSD"
            )));
        }
        Ok(Spectrum::from_points(freqs, psd, origin))
    }

    /// A spectrum from PSD points already checked: positive, finite, strictly
    /// increasing frequencies, positive finite values, at least two.
    fn from_points(freqs: Vec<f64>, psd: Vec<f64>, origin: String) -> Spectrum {
        let log_f = freqs.iter().map(|f| f.ln()).collect();
        let log_s = psd.iter().map(|s| s.ln()).collect();
        Spectrum { freqs, psd, origin, log_f, log_s }
    }

    /// The PSD at frequency `f` (Hz): the file's value at a file frequency,
    /// a power law between file frequencies, the end values held outside.
    pub fn psd_at(&self, f: f64) -> f64 {
        let n = self.freqs.len();
        // First file point at or above f.
        let i = self.freqs.partition_point(|x| *x < f);
        if i == 0 {
            return self.psd[0];
        }
        if i == n {
            return self.psd[n - 1];
        }
        if self.freqs[i] == f {
            return self.psd[i];
        }
        let t = (f.ln() - self.log_f[i - 1]) / (self.log_f[i] - self.log_f[i - 1]);
        (self.log_s[i - 1] + t * (self.log_s[i] - self.log_s[i - 1])).exp()
    }

    /// The PSD at every point `start + k step` (k < len) of a frequency
    /// grid (coordinates in Hz); an error for a grid of times.
    pub fn on_grid(&self, grid: &Grid) -> Result<Vec<f64>, Error> {
        if grid.unit != "Hz" {
            return Err(Error::Bind(format!(
                "grid `{}` is in {}, not Hz: a spectrum from {} can only be put on a frequency grid",
                grid.name, grid.unit, self.origin
            )));
        }
        Ok((0..grid.len).map(|k| self.psd_at(grid.start + k as f64 * grid.step)).collect())
    }
}

/// Reads a spectrum file and interpolates it onto `grid`: one PSD value per
/// grid point (see the [module docs](self)).
pub fn load(path: impl AsRef<Path>, kind: Kind, grid: &Grid) -> Result<Vec<f64>, Error> {
    Spectrum::read(path, kind)?.on_grid(grid)
}

impl Run<'_> {
    /// Binds `spectrum`, interpolated onto the input's grid, to the real
    /// input `name` declared over a frequency grid (the PSD in s = 1/Hz is
    /// taken in the input's declared unit).
    pub fn input_spectrum(&mut self, name: &str, spectrum: &Spectrum) -> Result<&mut Self, Error> {
        let f = self.func();
        let info =
            f.inputs.iter().find(|i| i.name == name).ok_or_else(|| unknown("input", name, f.inputs.iter().map(|i| i.name.as_str())))?;
        if info.ty.elem != Elem::Real {
            return Err(Error::Bind(format!("input `{name}` is complex; a spectrum file gives real values")));
        }
        let Shape::Grid(g) = info.ty.shape else {
            return Err(Error::Bind(format!("input `{name}` is a scalar; a spectrum file needs an input over a frequency grid")));
        };
        let data = spectrum.on_grid(f.grid(g))?;
        self.input_real(name, &data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(start: f64, step: f64, len: usize) -> Grid {
        Grid { name: "f".into(), start, step, len, unit: "Hz".into(), dims: vec![len] }
    }

    #[test]
    fn holds_the_end_values_outside_the_file() {
        let s = Spectrum::parse("10 4\n100 1\n", "t", Kind::Psd).unwrap();
        assert_eq!(s.on_grid(&grid(0.0, 5.0, 3)).unwrap(), [4.0, 4.0, 4.0]);
        assert_eq!(s.psd_at(-1.0), 4.0);
        assert_eq!(s.psd_at(1e6), 1.0);
        assert_eq!(s.psd_at(f64::INFINITY), 1.0);
    }

    /// Each bad file is an error naming its line and value.
    #[test]
    fn bad_values_and_files_are_errors_naming_the_line() {
        let err = |text: &str| Spectrum::parse(text, "f.txt", Kind::Psd).unwrap_err().to_string();
        assert!(err("10 1e-46\n20 nan\n30 1e-46\n").contains("f.txt:2: the PSD value nan at 20 Hz must be positive and finite"));
        assert!(err("10 -1e-46\n20 1e-46\n").contains("f.txt:1: the PSD value -1e-46 at 10 Hz must be positive"));
        assert!(err("").contains("f.txt: a spectrum needs at least two points"));
        assert!(err("\u{0}\u{1}\u{2}binary\n").contains("f.txt:1: expected two columns"));
        assert!(err("10 1e-46\n5 1e-46\n").contains("f.txt:2: frequencies must increase strictly"));
    }

    #[test]
    fn time_grids_are_refused() {
        let s = Spectrum::parse("10 4\n100 1\n", "t", Kind::Psd).unwrap();
        let t = Grid { name: "t".into(), start: 0.0, step: 0.5, len: 4, unit: "s".into(), dims: vec![4] };
        let e = s.on_grid(&t).unwrap_err().to_string();
        assert!(e.contains("not Hz"), "{e}");
    }
}
