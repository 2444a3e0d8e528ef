//! The full-band TaylorF2 likelihood scene the accuracy tests of the
//! speed settings (multibanding, relative binning) compile.

/// A TaylorF2 likelihood from `f_low` over 1/8 Hz bins to 1024 Hz, no ISCO
/// cut, aligned spins (chi, −chi), params defaulting to (mc, q); the data
/// input defaults to the template at those params when `data_default`
/// (else the caller binds it). Outputs `loss`, `strain` and `psd_out`.
pub fn taylorf2_likelihood(f_low: f64, (mc, q, chi): (f64, f64, f64), data_default: bool) -> String {
    let default =
        if data_default { format!(" = tf2_strain_uncut(f, {mc} Msun, {q}, {chi}, {chi}, 400 Mpc, 0 s, 0.0)") } else { String::new() };
    format!(
        "use std::taylorf2::{{tf2_strain_uncut}}
use std::detector::{{inner}}
use std::psd::{{psd_aligo_zerodet_highpower}}
scene w {{
    grid f = frequencies(from: {f_low} Hz, to: 1024 Hz, step: 0.125 Hz)
    input d: complex[f] s{default}
    param mc: Msun = {mc} in 0.5..200.0
    param q = {q} in 0.01..1.0
    param tc: s = 0.0 in -0.1..0.1
    param phic = 0.0
    let psd = psd_aligo_zerodet_highpower(f)
    let h = tf2_strain_uncut(f, mc, q, {chi}, -{chi}, 400 Mpc, tc, phic)
    output loss = 0.5 * inner(d - h, d - h, psd, spacing(f))
    output strain = h
    output psd_out = psd
    grad loss wrt [mc, q, tc, phic]
}}"
    )
}
