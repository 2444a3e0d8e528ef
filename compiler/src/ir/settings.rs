//! The scene's speed/accuracy settings: working precision, math mode and
//! multibanding.

use std::fmt;
use std::str::FromStr;

/// Working precision of generated code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum Precision {
    /// 64-bit floats everywhere.
    #[default]
    F64,
    /// 32-bit floats for arithmetic; reductions accumulate in f64; values
    /// far outside f32's range are stored scaled by powers of two
    /// (`passes::rescale`).
    F32,
    /// f32, rescaled as [`Precision::F32`] is, except two kinds of values,
    /// which are computed (and kept, in tables, scratch arrays and outputs)
    /// in f64: phases, i.e. every value that flows through elementwise
    /// arithmetic alone into the argument of a sine, cosine, tangent, `cis`
    /// or complex exponential, and that function itself; and values still
    /// outside f32's comfortable range after rescaling, i.e. whose largest
    /// magnitude, when the scene is evaluated at its default params and
    /// inputs, is below 2^-96 or above 2^96 (f32's normal range less 2^30
    /// of headroom; the result of `exp(100)`, say), and what is computed
    /// directly from those. Reductions accumulate in f64. Inputs, and what
    /// transforms and tensor ops read and write, stay f32. See
    /// `passes::precision::wide_values`.
    Mixed,
}

impl Precision {
    /// The element type of inputs, outputs and library-call buffers.
    pub fn storage(self) -> Precision {
        match self {
            Precision::F64 => Precision::F64,
            Precision::F32 | Precision::Mixed => Precision::F32,
        }
    }
}

impl fmt::Display for Precision {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Precision::F64 => "f64",
            Precision::F32 => "f32",
            Precision::Mixed => "mixed",
        })
    }
}

/// How generated code computes transcendental functions (the scene's
/// `math` knob); see `mathlib` for the measured errors.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MathMode {
    /// Within 2 ulp of glibc libm (f64); f32 within 1 ulp of glibc's f32 functions.
    #[default]
    Exact,
    /// About 1e-12 relative error (cheaper polynomials, no extra-precision tails).
    Fast,
    /// About 1e-7 relative error (f32 work and users who want speed).
    Fastest,
}

impl fmt::Display for MathMode {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            MathMode::Exact => "exact",
            MathMode::Fast => "fast",
            MathMode::Fastest => "fastest",
        })
    }
}

impl Precision {
    /// Every precision, in the order `--help` and error messages list them.
    pub const ALL: [Precision; 3] = [Precision::F64, Precision::F32, Precision::Mixed];
}

impl MathMode {
    /// Every math mode, from the most accurate.
    pub const ALL: [MathMode; 3] = [MathMode::Exact, MathMode::Fast, MathMode::Fastest];
}

/// A setting's spelling that names no value; its `Display` lists the valid ones.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownSetting {
    /// The setting (`precision` or `math`).
    pub setting: &'static str,
    /// What was written.
    pub found: String,
    /// What may be written, with a word on each.
    pub help: &'static str,
}

impl fmt::Display for UnknownSetting {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "unknown {} `{}`", self.setting, self.found)
    }
}

impl std::error::Error for UnknownSetting {}

/// The one parser of each setting's spelling (the scene's `precision:` and
/// `math:` settings, the CLI's `--precision`/`--math`, the REPL's
/// `:precision`, `gwml tradeoff`): the names [`Display`](fmt::Display) prints.
fn parse_setting<T: Copy + fmt::Display>(all: &[T], s: &str, setting: &'static str, help: &'static str) -> Result<T, UnknownSetting> {
    all.iter().copied().find(|v| v.to_string() == s).ok_or_else(|| UnknownSetting { setting, found: s.to_string(), help })
}

impl FromStr for Precision {
    type Err = UnknownSetting;
    fn from_str(s: &str) -> Result<Precision, UnknownSetting> {
        parse_setting(&Precision::ALL, s, "precision", "f64, f32 or mixed (f32 with phases in f64)")
    }
}

impl FromStr for MathMode {
    type Err = UnknownSetting;
    fn from_str(s: &str) -> Result<MathMode, UnknownSetting> {
        parse_setting(&MathMode::ALL, s, "math mode", "exact (libm accuracy), fast (~1e-12) or fastest (~1e-7)")
    }
}

/// Multibanding of complex exponentials `cis(phase)` on a grid (the
/// scene's `multiband` setting; `passes::multiband`): the phase is
/// computed on a coarse subset of the grid's points, chosen at compile
/// time so that linear interpolation between them is within `tolerance`
/// radians of the exact phase at the scene's defaults, and `e^{i phase}`
/// on the fine points between two nodes is advanced by one complex
/// multiply per point (Vinciguerra, Veitch & Mandel 2017,
/// arXiv:1703.02062; García-Quirós et al. 2020, arXiv:2001.10897).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Multiband {
    /// Every point computed exactly.
    #[default]
    Off,
    /// Largest phase error of the interpolation, in radians, at the defaults.
    Tolerance(f64),
}

impl fmt::Display for Multiband {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Multiband::Off => f.write_str("off"),
            Multiband::Tolerance(t) => write!(f, "{t:e}"),
        }
    }
}

impl FromStr for Multiband {
    type Err = UnknownSetting;
    fn from_str(s: &str) -> Result<Multiband, UnknownSetting> {
        let help = "off, or the largest phase error in radians of the interpolated phase, a number in (0, 1] such as 1e-4";
        match s {
            "off" => Ok(Multiband::Off),
            _ => match s.parse::<f64>() {
                Ok(t) if t > 0.0 && t <= 1.0 => Ok(Multiband::Tolerance(t)),
                _ => Err(UnknownSetting { setting: "multiband tolerance", found: s.to_string(), help }),
            },
        }
    }
}

/// Relative binning (heterodyning) of likelihood sums (the scene's
/// `relative_binning` setting; `passes::relbin`): each sum over a grid of
/// an expression at most quadratic in one waveform `h` is computed from
/// summary data of the fiducial waveform `h0` (the waveform at the
/// params' defaults) over `bins` frequency bins, with `h / h0` linear in
/// each bin (Zackay, Dai & Venumadhav 2018, arXiv:1806.08792).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum RelativeBinning {
    /// Every sum computed over every point.
    #[default]
    Off,
    /// Number of bins, equal in the bound on the phase difference (as
    /// jimgw's `HeterodynedTransientLikelihoodFD` chooses them).
    Bins(u32),
}

impl RelativeBinning {
    /// Most bins accepted.
    pub const MAX_BINS: u32 = 100_000;
}

impl fmt::Display for RelativeBinning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RelativeBinning::Off => f.write_str("off"),
            RelativeBinning::Bins(n) => write!(f, "{n}"),
        }
    }
}

impl FromStr for RelativeBinning {
    type Err = UnknownSetting;
    fn from_str(s: &str) -> Result<RelativeBinning, UnknownSetting> {
        let help = "off, or the number of frequency bins, a whole number from 2 to 100000 such as 100";
        match s {
            "off" => Ok(RelativeBinning::Off),
            _ => match s.parse::<u32>() {
                Ok(n) if (2..=Self::MAX_BINS).contains(&n) => Ok(RelativeBinning::Bins(n)),
                _ => Err(UnknownSetting { setting: "relative binning", found: s.to_string(), help }),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn multiband_parses_off_and_tolerances() {
        assert_eq!("off".parse::<Multiband>(), Ok(Multiband::Off));
        assert_eq!("1e-4".parse::<Multiband>(), Ok(Multiband::Tolerance(1e-4)));
        assert_eq!(Multiband::Tolerance(1e-4).to_string().parse::<Multiband>(), Ok(Multiband::Tolerance(1e-4)));
        for bad in ["0", "-1e-3", "2", "fine", "nan"] {
            let e = bad.parse::<Multiband>().unwrap_err();
            assert!(e.help.contains("radians"), "{bad}: {}", e.help);
        }
    }

    #[test]
    fn relative_binning_parses_off_and_bin_counts() {
        assert_eq!("off".parse::<RelativeBinning>(), Ok(RelativeBinning::Off));
        assert_eq!("100".parse::<RelativeBinning>(), Ok(RelativeBinning::Bins(100)));
        assert_eq!(RelativeBinning::Bins(60).to_string().parse::<RelativeBinning>(), Ok(RelativeBinning::Bins(60)));
        for bad in ["0", "1", "0.5", "-3", "1e2", "many", "100001"] {
            let e = bad.parse::<RelativeBinning>().unwrap_err();
            assert!(e.help.contains("bins"), "{bad}: {}", e.help);
        }
    }

    #[test]
    fn every_setting_parses_from_the_name_it_prints() {
        for p in Precision::ALL {
            assert_eq!(p.to_string().parse::<Precision>(), Ok(p));
        }
        for m in MathMode::ALL {
            assert_eq!(m.to_string().parse::<MathMode>(), Ok(m));
        }
    }

    #[test]
    fn an_unknown_spelling_names_the_valid_ones() {
        let e = "f16".parse::<Precision>().unwrap_err();
        assert_eq!(e.to_string(), "unknown precision `f16`");
        assert!(e.help.contains("f64") && e.help.contains("f32") && e.help.contains("mixed"), "{}", e.help);
        let e = "Fast".parse::<MathMode>().unwrap_err();
        assert_eq!(e.to_string(), "unknown math mode `Fast`");
        assert!(e.help.contains("fastest"), "{}", e.help);
    }
}
