//! The standard library: `.gw` files under `stdlib/`, embedded in the
//! binary so `use std::NAME::{...}` works from any directory.

/// `(name, source)` of every stdlib file; `use std::NAME` loads `NAME`.
pub const FILES: &[(&str, &str)] = &[
    ("antenna", include_str!("../../../stdlib/antenna.gw")),
    ("burst", include_str!("../../../stdlib/burst.gw")),
    ("chirp", include_str!("../../../stdlib/chirp.gw")),
    ("constrained", include_str!("../../../stdlib/constrained.gw")),
    ("detector", include_str!("../../../stdlib/detector.gw")),
    ("glitch", include_str!("../../../stdlib/glitch.gw")),
    ("imrphenom", include_str!("../../../stdlib/imrphenom.gw")),
    ("nn", include_str!("../../../stdlib/nn.gw")),
    ("psd", include_str!("../../../stdlib/psd.gw")),
    ("taylorf2", include_str!("../../../stdlib/taylorf2.gw")),
];

/// The source of stdlib file `name`.
pub fn source(name: &str) -> Option<&'static str> {
    FILES.iter().find(|f| f.0 == name).map(|f| f.1)
}
