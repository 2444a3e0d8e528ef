//! Physical units, checked at compile time.
//!
//! A [`Dim`] is a vector of rational exponents over three base dimensions:
//! time (second), mass (solar mass) and length (metre). Every named unit is a
//! dimension and a scale into those base units; values are stored in base
//! units at run time, so `400 Mpc` is held as 1.234e25 (metres) and a param
//! declared `dist: Mpc` is converted on the way in and its gradient on the
//! way out.

use std::fmt;

/// A rational number `num/den` in lowest terms, `den > 0`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Ratio {
    /// Numerator.
    pub num: i32,
    /// Denominator (positive).
    pub den: i32,
}

fn gcd(a: i64, b: i64) -> i64 {
    if b == 0 {
        a.abs().max(1)
    } else {
        gcd(b, a % b)
    }
}

impl Ratio {
    /// `num/den`, reduced. Returns `None` on a zero denominator or overflow.
    pub fn new(num: i64, den: i64) -> Option<Ratio> {
        if den == 0 {
            return None;
        }
        let g = gcd(num, den) * den.signum();
        let (n, d) = (num / g, den / g);
        Some(Ratio { num: i32::try_from(n).ok()?, den: i32::try_from(d).ok()? })
    }
    /// The integer `n`.
    pub const fn int(n: i32) -> Ratio {
        Ratio { num: n, den: 1 }
    }
    /// Zero.
    pub const ZERO: Ratio = Ratio { num: 0, den: 1 };
    fn add(self, o: Ratio) -> Option<Ratio> {
        Ratio::new(self.num as i64 * o.den as i64 + o.num as i64 * self.den as i64, self.den as i64 * o.den as i64)
    }
    fn mul(self, o: Ratio) -> Option<Ratio> {
        Ratio::new(self.num as i64 * o.num as i64, self.den as i64 * o.den as i64)
    }
    /// The value as a float.
    pub fn to_f64(self) -> f64 {
        self.num as f64 / self.den as f64
    }
    /// The ratio exactly equal to `x` with denominator at most 12, if any.
    pub fn from_f64(x: f64) -> Option<Ratio> {
        (1..=12).find_map(|d| {
            let n = x * d as f64;
            (n.is_finite() && (n - n.round()).abs() < 1e-9 && n.abs() < 1e6).then(|| Ratio::new(n.round() as i64, d)).flatten()
        })
    }
}

const BASE_NAMES: [&str; 3] = ["s", "Msun", "m"];

/// Physical dimension: exponents of time, mass and length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Dim(pub [Ratio; 3]);

impl Dim {
    /// Dimensionless.
    pub const NONE: Dim = Dim([Ratio::ZERO; 3]);
    /// Time.
    pub const TIME: Dim = Dim([Ratio::int(1), Ratio::ZERO, Ratio::ZERO]);
    /// Frequency (1/time).
    pub const FREQ: Dim = Dim([Ratio::int(-1), Ratio::ZERO, Ratio::ZERO]);
    /// Mass.
    pub const MASS: Dim = Dim([Ratio::ZERO, Ratio::int(1), Ratio::ZERO]);
    /// Length.
    pub const LENGTH: Dim = Dim([Ratio::ZERO, Ratio::ZERO, Ratio::int(1)]);

    /// True when dimensionless.
    pub fn is_none(self) -> bool {
        self == Dim::NONE
    }
    /// Product of two dimensions (`None` on exponent overflow).
    pub fn times(self, o: Dim) -> Option<Dim> {
        Some(Dim([self.0[0].add(o.0[0])?, self.0[1].add(o.0[1])?, self.0[2].add(o.0[2])?]))
    }
    /// `self^p`.
    pub fn pow(self, p: Ratio) -> Option<Dim> {
        Some(Dim([self.0[0].mul(p)?, self.0[1].mul(p)?, self.0[2].mul(p)?]))
    }
    /// `1/self`.
    pub fn inv(self) -> Dim {
        self.pow(Ratio::int(-1)).unwrap_or(self)
    }
}

impl fmt::Display for Dim {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_none() {
            return write!(f, "1");
        }
        if *self == Dim::FREQ {
            return write!(f, "Hz");
        }
        let mut first = true;
        for (name, p) in BASE_NAMES.iter().zip(self.0) {
            if p.num == 0 {
                continue;
            }
            if !first {
                write!(f, "*")?;
            }
            first = false;
            match (p.num, p.den) {
                (1, 1) => write!(f, "{name}")?,
                (n, 1) => write!(f, "{name}^{n}")?,
                (n, d) => write!(f, "{name}^({n}/{d})")?,
            }
        }
        Ok(())
    }
}

/// A named unit: its dimension and its size in base units.
#[derive(Clone, Copy, Debug)]
pub struct UnitDef {
    /// The name written in source.
    pub name: &'static str,
    /// Its dimension.
    pub dim: Dim,
    /// How many base units one of it is.
    pub scale: f64,
}

/// Metres in one megaparsec (IAU 2015 Resolution B2 parsec, 3.0856775814913673e16 m).
pub const MPC_IN_M: f64 = 3.085_677_581_491_367e22;

/// All unit names the language knows.
pub const UNITS: &[UnitDef] = &[
    UnitDef { name: "s", dim: Dim::TIME, scale: 1.0 },
    UnitDef { name: "ms", dim: Dim::TIME, scale: 1e-3 },
    UnitDef { name: "Hz", dim: Dim::FREQ, scale: 1.0 },
    UnitDef { name: "kHz", dim: Dim::FREQ, scale: 1e3 },
    UnitDef { name: "Msun", dim: Dim::MASS, scale: 1.0 },
    UnitDef { name: "m", dim: Dim::LENGTH, scale: 1.0 },
    UnitDef { name: "km", dim: Dim::LENGTH, scale: 1e3 },
    UnitDef { name: "Mpc", dim: Dim::LENGTH, scale: MPC_IN_M },
    UnitDef { name: "rad", dim: Dim::NONE, scale: 1.0 },
];

/// True if `name` is a unit name (used by the parser for `20 Hz`).
pub fn is_unit_name(name: &str) -> bool {
    UNITS.iter().any(|u| u.name == name)
}

/// Looks up a unit by name.
pub fn unit(name: &str) -> Option<&'static UnitDef> {
    UNITS.iter().find(|u| u.name == name)
}

/// A value written as a number and an optional unit name (`2 ms`, `30Msun`,
/// `1e-3 s`, `0.5`), as `--set` and `:run` take them: the number and the
/// unit, or a message saying what is wrong.
pub fn parse_quantity(text: &str) -> Result<(f64, Option<&'static UnitDef>), String> {
    let t = text.trim();
    let split = t.len() - t.chars().rev().take_while(|c| c.is_ascii_alphabetic()).map(char::len_utf8).sum::<usize>();
    let (number, name) = (t[..split].trim(), &t[split..]);
    // `1e3` ends in a digit, but `2e` or `inf` would take letters: a suffix
    // that is not a unit belongs to the number.
    let (number, unit) = match unit(name) {
        Some(u) if !number.is_empty() => (number, Some(u)),
        _ if name.is_empty() || number.is_empty() || number.parse::<f64>().is_err() => (t, None),
        _ => {
            let names: Vec<&str> = UNITS.iter().map(|u| u.name).collect();
            return Err(format!("`{name}` is not a unit (units: {})", names.join(", ")));
        }
    };
    let x: f64 = number.parse().map_err(|_| format!("`{text}` is not a number, with or without a unit (e.g. `2 ms`)"))?;
    if !x.is_finite() {
        return Err(format!("`{text}` is not finite"));
    }
    Ok((x, unit))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantities_parse_with_and_without_units() {
        let q = |s: &str| parse_quantity(s).map(|(x, u)| (x, u.map(|u| u.name)));
        assert_eq!(q("2 ms"), Ok((2.0, Some("ms"))));
        assert_eq!(q("30Msun"), Ok((30.0, Some("Msun"))));
        assert_eq!(q(" 1e-3 s "), Ok((1e-3, Some("s"))));
        assert_eq!(q("0.5"), Ok((0.5, None)));
        assert_eq!(q("1e3"), Ok((1000.0, None)));
        assert!(q("2 furlongs").unwrap_err().contains("`furlongs` is not a unit"));
        assert!(q("ms").unwrap_err().contains("not a number"));
        assert!(q("inf").is_err() && q("").is_err());
    }

    #[test]
    fn hz_times_seconds_is_dimensionless() {
        assert!(Dim::FREQ.times(Dim::TIME).unwrap().is_none());
    }

    #[test]
    fn fractional_powers_print() {
        let d = Dim::TIME.pow(Ratio::new(-7, 6).unwrap()).unwrap();
        assert_eq!(d.to_string(), "s^(-7/6)");
        assert_eq!(Dim::MASS.times(Dim::LENGTH.inv()).unwrap().to_string(), "Msun*m^-1");
    }
}
