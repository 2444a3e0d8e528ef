#!/usr/bin/env python3
"""Generate LALSuite reference fixtures for gwml's Rust tests.

The Rust tests read the JSON files this script writes. They never need
Python or LALSuite at test time. The fixtures are committed to the
repository, and this script is only needed to regenerate them.

Regenerate (from the repository root; the virtualenv lives OUTSIDE the repo)::

    python3 -m venv /work/venv-lal
    /work/venv-lal/bin/pip install lalsuite numpy      # lalsuite 7.26.x
    /work/venv-lal/bin/python scripts/lal_fixtures.py

(or activate the venv and run ``python scripts/lal_fixtures.py``).  The output
is deterministic (fixed parameter lists, seeded RNG, no timestamps), so a
re-run with the same lalsuite/numpy versions reproduces the files
byte-for-byte.

Files written (under ``fixtures/lal/``)
--------------------------------------
``taylorf2.json``
    LALSimulation TaylorF2 h+(f) (and hx for the convention probes) at a
    subset of frequency bins, for 25 parameter points, an 8-entry phase
    PN-order sweep, and 5 "convention probes" (a base point plus non-zero
    inclination, phiRef and f_ref variants; these also record hx).
``psd_aligo_zerodet_highpower.json``
    ``XLALSimNoisePSDaLIGOZeroDetHighPower(f)`` (analytic model) on a log grid.
``antenna_patterns.json``
    F+, Fx for H1/L1/V1 via ``XLALComputeDetAMResponse`` plus the detector
    response tensors, vertex positions and geocentre/inter-site time delays.

Which TaylorF2 entry point, and why
-----------------------------------
We call ``lalsimulation.SimInspiralChooseFDWaveform(..., approximant=TaylorF2)``.
It is the public entry point used by parameter-estimation codes (bilby, PyCBC,
LALInference), and it is the only one that also applies the inclination
factors and produces hx.  In lalsimulation 6.2.x the call goes
ChooseFDWaveform -> XLALSimInspiralGenerateFDWaveform -> legacy generator ->
XLALSimInspiralChooseFDWaveform_legacy (LALSimInspiralGeneratorLegacy.c),
whose TaylorF2 branch calls ``XLALSimInspiralTaylorF2(hptilde, phiRef, deltaF,
m1, m2, S1z, S2z, f_min, f_max, f_ref, distance, params)`` and then sets
``hc = -I*cos(i)*h``, ``hp = 0.5*(1+cos(i)^2)*h``.  No conditioning, tapering or
time shift is added on this path.  For every point the script also calls
``SimInspiralTaylorF2`` directly and records the largest |difference|.  It is
exactly 0 at inclination 0.

TaylorF2 conventions (read from lalsimulation-v6.2.1 source, verified numerically)
------------------------------------------------------------------------------
Source files: lalsimulation/lib/LALSimInspiralTaylorF2.c
(XLALSimInspiralTaylorF2, XLALSimInspiralTaylorF2Core),
LALSimInspiralPNCoefficients.c (XLALSimInspiralPNPhasing_F2 and the
XLALSimInspiralTaylorF2Phasing_* coefficients) and
LALSimInspiralGeneratorLegacy.c (the TaylorF2 branch quoted above).

Let M = m1 + m2 (solar masses), eta = m1 m2 / M^2, v = cbrt(pi M MTSUN_SI f),
r = distance in METRES (the Python/C API takes SI: Mpc * 1e6 * lal.PC_SI).

* Phase (TaylorF2Core):
    phasing(f) = [sum_k (pfa_k + pfl_k ln v) v^k] / v^5        (k = 0..7)
                 + shft*f - 2*phi_ref - phasing_ref
    h(f)       = amp(f) * [cos(phasing - pi/4) - i sin(phasing - pi/4)]
               = amp(f) * exp(-i (phasing(f) - pi/4))
  where pfa_k = 3/(128 eta) * psi_k (psi_0 = 1, psi_1 = 0, psi_2..psi_7 the
  standard BIOPS-2009 Eq. 3.18 coefficients plus aligned-spin terms) and the
  log terms are written with ln(v) (NOT ln(v/v_lso)).  The 3PN constant
  includes -6848/21 ln 4, i.e. the textbook -6848/21 ln(4v).
  The sign is exp(-i Psi): LAL uses the Fourier convention
  h~(f) = int h(t) e^{-2 pi i f t} dt, so h+_LAL is (up to the amplitude sign
  below) the COMPLEX CONJUGATE of the textbook SPA
  h~ = A f^{-7/6} exp(+i Psi_tb), where Psi_tb = 2 pi f t_c - phi_c - pi/4 + psi_PN(f).
* phi_ref: the term -2*phi_ref (orbital phase, hence factor 2) inside
  `phasing`, i.e. arg h+ gains +2*phi_ref.
* f_ref: if f_ref > 0, phasing_ref = [sum_k ...](v_ref)/v_ref^5 (same truncated
  series, no shft term) is subtracted, i.e. arg h+ gains +phasing_ref.  If
  f_ref == 0 (default here), nothing is subtracted ("reference at
  coalescence", the integrals of BIOPS Eq. 3.15 vanish at f = infinity).
* Time shift: XLALSimInspiralTaylorF2 sets the series epoch to -1/deltaF
  ("coalesce at t=0") and shft = 2 pi * epoch = -2 pi / deltaF, so the term
  shft*f = -2 pi k on bin k: an exact multiple of 2 pi, invisible on the
  grid (it only costs round-off: |shft*f| reaches 2 pi * 2e6 ~ 1.3e7 rad at
  1024 Hz for deltaF = 1/2048, so LAL's own bins carry ~1e-9 rad of noise).  So
  effectively t_c = 0 (mod the segment length) and no linear-in-f term
  is applied.  A Rust implementation evaluated on f_k = k*deltaF with
  t_c = 0, phi_c = 0 reproduces LAL's complex bins.
* Amplitude (amplitude order -1 == 0 in TaylorF2Core: only the Newtonian
  SPA amplitude):
    amp0   = -4 m1 m2 / r * MRSUN_SI * MTSUN_SI * sqrt(pi/12)     (NEGATIVE)
    amp(f) = amp0 * sqrt(-dE/F) * v,  dE = -eta v, F = 32/5 eta^2 v^10
           = -sqrt(5/24) pi^(-2/3) (MRSUN_SI/r) (Mc MTSUN_SI)^(5/6) MTSUN_SI^(-1) f^(-7/6)
  i.e. minus the textbook A = sqrt(5/24) pi^(-2/3) c/r (G Mc/c^3)^(5/6).
  The minus sign is equivalent to an extra phase of pi.
* Polarisations: hp = (1+cos^2 i)/2 * h, hc = -i cos(i) * h (legacy
  ChooseFD branch).  If longAscNodes != 0 a polarisation rotation by 2*Omega
  is applied (not used here: Omega = 0).
* So, putting it together, with psi_PN^LAL(f) = sum_k (pfa_k + pfl_k ln v) v^(k-5):
    h+_LAL(f_k) = (1+cos^2 i)/2 * A(f) * exp(i [pi/4 + pi - psi_PN^LAL(f)
                                               + 2 phi_ref + psi_PN^LAL(f_ref)])
    A(f) = +sqrt(5/24) pi^(-2/3) (MRSUN_SI/r) (Mc MTSUN_SI)^(5/6) / MTSUN_SI * f^(-7/6)
  which equals  - (1+cos^2 i)/2 * conj( h~_textbook(f; t_c = 0, phi_c = 2 phi_ref + ...) ).
  (up to the ln(v_lso) constant below, if the textbook form uses it).
* Cut-off: if f_max > 0 is passed (1024 Hz here), LAL fills every bin from
  ceil(f_min/deltaF) up to floor(f_max/deltaF) with NO ISCO cut, even far
  above the Schwarzschild ISCO.  Only with f_max == 0 does it stop at
  f_ISCO = 6^(-3/2) / (pi M MTSUN_SI).  (For black holes the
  tidal "contact" frequency is larger, so ISCO wins.)  Both the last nonzero bin with f_max = 1024 and
  the one with f_max = 0 are recorded for every point.
* Constants: phases for light systems are ~1e4-1e5 rad, so a relative error
  of 1e-8 in MTSUN_SI shifts the phase by ~3e-4 rad (5/3 * 1e-8 * 1.7e4).  A Rust implementation
  MUST use LAL's exact constants (recorded under "lal_constants"), e.g.
  MTSUN_SI = 4.925490947641267e-06 s (= GMSUN/c^3 with IAU-2015 GM_sun),
  MRSUN_SI, MSUN_SI, PC_SI, and Euler's gamma.

Numerical verification (stored per point under "checks"):
  * "lal_model": a numpy transcription of the formula above (incl. spin terms)
    vs LAL's unwrapped phase over the full nonzero band: the difference is
    2 pi n (n recorded) to within <= ~2e-9 rad (largest at the finest deltaF;
    ~1e-11 rad at deltaF = 1/8), and amplitudes agree to ~4e-15.
  * "textbook_fit" (non-spinning points): an independent implementation of
    BIOPS 2009 (PRD 80 084043, Eq. 3.18; rational coefficients, 2.5PN log as
    ln(v/v_lso) with v_lso = 6^-1/2, 3PN log as ln(4v)) of
    -Psi_tb(f; t_c = 0, phi_c = 0); a least-squares fit LAL - (-Psi_tb) = c0 + c1 f
    over [f_min, min(f_isco, f_max)] gives c1 ~ 0 (i.e. no time shift) and
    c0 = pi + (9/(128 eta)) psi5' ln(6)/2 (mod 2 pi), where
    psi5' = pi (38645/756 - 65/9 eta); the residual is ~1e-9 rad.

Phase unwrapping and deltaF
---------------------------
The stored "arg" is np.unwrap(np.angle(h+)) over ALL nonzero bins (from
ceil(f_min/deltaF) up to LAL's last nonzero bin), then subsampled.  The
unwrapped phase therefore starts in (-pi, pi] at the first bin, and equals
the analytic phase above plus 2 pi n.  Unwrapping is only valid if the phase
changes by < pi per bin, i.e. 2 pi tau(f_min) deltaF < pi where tau is the time
to coalescence.  Light systems (tau(20 Hz) ~ 200 s for Mc = 1 Msun) therefore
need a FINER deltaF than 1/8 Hz, not a coarser one.  We use deltaF = 1/8 Hz
unless the Newtonian tau(f_min)*deltaF > 0.2, then halve it until it is
<= 0.2.  The actual max |phase step| per bin is recorded and asserted < pi/2.

Subsampling: 64 frequencies log-uniform in [f_min, min(f_isco, f_max)],
snapped to the nearest bin (duplicates removed), plus 8 log-uniform
frequencies in (f_isco, f_max] when f_isco < f_max (flagged by above_isco).
"""

import importlib.metadata
import json
import math
import os
import platform
import sys
from fractions import Fraction as Fr

import numpy as np
import lal
import lalsimulation as ls

# --------------------------------------------------------------------------
# paths / metadata
# --------------------------------------------------------------------------
REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT_DIR = os.path.join(REPO_ROOT, "fixtures", "lal")

REGEN_COMMAND = (
    "python3 -m venv /work/venv-lal && /work/venv-lal/bin/pip install lalsuite numpy "
    "&& /work/venv-lal/bin/python scripts/lal_fixtures.py"
)


def generator_info(extra=None):
    """Top-level 'generator' block shared by all fixture files."""
    info = {
        "script": "scripts/lal_fixtures.py",
        "command": REGEN_COMMAND,
        "lalsuite_version": importlib.metadata.version("lalsuite"),
        "lal_version": lal.__version__,
        "lalsimulation_version": ls.__version__,
        "numpy_version": np.__version__,
        "python_version": platform.python_version(),
    }
    if extra:
        info.update(extra)
    return info


def write_json(name, obj):
    path = os.path.join(OUT_DIR, name)
    with open(path, "w") as fh:
        # json writes floats with repr(): shortest string that round-trips
        # exactly to the same IEEE double, so nothing is lost.
        json.dump(obj, fh, indent=1, allow_nan=False)
        fh.write("\n")
    return path


def fl(x):
    """Plain python float (json cannot serialise numpy scalars)."""
    return float(x)


def fl_list(a):
    return [float(x) for x in np.asarray(a, dtype=float)]


# LAL's constants: any Rust port must use exactly these values.
LAL_CONSTANTS = {
    "MTSUN_SI": lal.MTSUN_SI,
    "MRSUN_SI": lal.MRSUN_SI,
    "MSUN_SI": lal.MSUN_SI,
    "GMSUN_SI": lal.GMSUN_SI,
    "PC_SI": lal.PC_SI,
    "C_SI": lal.C_SI,
    "G_SI": lal.G_SI,
    "PI": lal.PI,
    "GAMMA": lal.GAMMA,
}

# ==========================================================================
# 1. TaylorF2
# ==========================================================================

F_MIN = 20.0
F_MAX = 1024.0
DIST_MPC = 100.0
N_SAMPLES_BAND = 64
N_SAMPLES_ABOVE_ISCO = 8


def masses_from_mc_q(mc, q):
    """(m1, m2) with m1 >= m2 from chirp mass and q = m2/m1 <= 1."""
    m1 = mc * (1.0 + q) ** 0.2 / q ** 0.6
    return m1, q * m1


def f_isco(m1, m2):
    """Schwarzschild ISCO GW frequency exactly as XLALSimInspiralTaylorF2 computes it."""
    v_isco = 1.0 / math.sqrt(6.0)
    return v_isco ** 3 / (lal.PI * (m1 + m2) * lal.MTSUN_SI)


def choose_delta_f(m1, m2, f_min):
    """Largest power-of-two deltaF <= 1/8 Hz with Newtonian tau(f_min)*deltaF <= 0.2.

    tau0 = 5/256 (pi f)^(-8/3) (Mc MTSUN)^(-5/3) is the leading-order time to
    coalescence; the per-bin phase step of the SPA is 2 pi tau deltaF, so this
    keeps it below ~0.4 pi and makes np.unwrap over the full band reliable.
    """
    mc = (m1 * m2) ** 0.6 / (m1 + m2) ** 0.2
    tau0 = 5.0 / 256.0 * (lal.PI * f_min) ** (-8.0 / 3.0) * (mc * lal.MTSUN_SI) ** (-5.0 / 3.0)
    df = 1.0 / 8.0
    while tau0 * df > 0.2:
        df /= 2.0
    return df, tau0


# ---- numpy transcription of LAL's TaylorF2 phasing (used only for checks) ----
# Coefficients from LALSimInspiralPNCoefficients.c (lalsimulation-v6.2.1),
# XLALSimInspiralPNPhasing_F2 with spin order ALL, qm_def = 1 (black holes,
# lambda = 0), no tides, no testing-GR deviations.

def lal_pfa(m1, m2, chi1, chi2):
    """Return (v[0..7], vlogv[0..7]) exactly as XLALSimInspiralPNPhasing_F2 builds them."""
    M = m1 + m2
    eta = m1 * m2 / M / M
    x1, x2 = m1 / M, m2 / M
    pi = lal.PI
    v = np.zeros(8)
    vl = np.zeros(8)
    v[0] = 1.0
    v[2] = 5.0 * (74.3 / 8.4 + 11.0 * eta) / 9.0
    v[3] = -16.0 * pi
    v[4] = 5.0 * (3058.673 / 7.056 + 5429.0 / 7.0 * eta + 617.0 * eta * eta) / 72.0
    v[5] = 5.0 / 9.0 * (772.9 / 8.4 - 13.0 * eta) * pi
    vl[5] = 5.0 / 3.0 * (772.9 / 8.4 - 13.0 * eta) * pi
    vl[6] = -684.8 / 2.1
    v[6] = (11583.231236531 / 4.694215680 - 640.0 / 3.0 * pi * pi - 684.8 / 2.1 * lal.GAMMA
            + eta * (-15737.765635 / 3.048192 + 225.5 / 1.2 * pi * pi)
            + eta * eta * 76.055 / 1.728 - eta ** 3 * 127.825 / 1.296 + vl[6] * math.log(4.0))
    v[7] = pi * (770.96675 / 2.54016 + 378.515 / 1.512 * eta - 740.45 / 7.56 * eta * eta)

    def so7(x):
        e = x * (1.0 - x)
        return x * (-17097.8035 / 4.8384 + e * 28764.25 / 6.72 + e * e * 47.35 / 1.44
                    + x * (-7189.233785 / 1.524096 + e * 458.555 / 3.024 - e * e * 534.5 / 7.2))

    def so6(x):
        return pi * x * (1490.0 / 3.0 + x * 260.0)

    def so5(x):
        return -x * (1391.5 / 8.4 - x * (1.0 - x) * 10.0 / 3.0 + x * (1276.0 / 8.1 + x * (1.0 - x) * 170.0 / 9.0))

    def so3(x):
        return x * (25.0 + 38.0 / 3.0 * x)

    s1s2_6 = (326.75 / 1.12 + 557.5 / 1.8 * eta) * eta
    self6 = lambda x: (-4108.25 / 6.72 - 108.5 / 1.2 * x + 125.5 / 3.6 * x * x) * x * x
    qm6 = lambda x: (4703.5 / 8.4 + 2935.0 / 6.0 * x - 120.0 * x * x) * x * x
    c1sq, c2sq = chi1 * chi1, chi2 * chi2
    v[7] += so7(x1) * chi1 + so7(x2) * chi2
    v[6] += (so6(x1) * chi1 + so6(x2) * chi2 + s1s2_6 * chi1 * chi2
             + (qm6(x1) + self6(x1)) * c1sq + (qm6(x2) + self6(x2)) * c2sq)
    v[5] += so5(x1) * chi1 + so5(x2) * chi2
    vl[5] += 3.0 * (so5(x1) * chi1 + so5(x2) * chi2)
    # 2PN: S1S2 (247/4.8 eta chi1.chi2 - 721/4.8 eta chi1L chi2L) + QM/self-spin
    v[4] += (247.0 / 4.8 * eta * chi1 * chi2 - 721.0 / 4.8 * eta * chi1 * chi2
             + (-720.0 / 9.6 * x1 * x1 + 1.0 / 9.6 * x1 * x1) * chi1 * chi1
             + (-720.0 / 9.6 * x2 * x2 + 1.0 / 9.6 * x2 * x2) * chi2 * chi2
             + (240.0 / 9.6 * x1 * x1 - 7.0 / 9.6 * x1 * x1) * c1sq
             + (240.0 / 9.6 * x2 * x2 - 7.0 / 9.6 * x2 * x2) * c2sq)
    v[3] += so3(x1) * chi1 + so3(x2) * chi2
    pfaN = 3.0 / (128.0 * eta)
    return v * pfaN, vl * pfaN


def lal_psi_pn(f, m1, m2, chi1, chi2, phase_order=-1):
    """sum_k (pfa_k + pfl_k ln v) v^(k-5), truncated like TaylorF2Core's switch."""
    pv, pl = lal_pfa(m1, m2, chi1, chi2)
    kmax = 7 if phase_order == -1 else phase_order
    f = np.asarray(f, dtype=float)
    v = np.cbrt(lal.PI * (m1 + m2) * lal.MTSUN_SI * f)
    lv = np.log(v)
    s = np.zeros_like(v)
    for k in range(kmax, -1, -1):
        s += (pv[k] + pl[k] * lv) * v ** k
    return s / v ** 5


def lal_model_arg(f, m1, m2, chi1, chi2, phase_order=-1, phi_ref=0.0, f_ref=0.0):
    """Analytic arg(h+) of LAL's TaylorF2 (continuous; equals LAL's wrapped phase mod 2 pi)."""
    ref = lal_psi_pn(f_ref, m1, m2, chi1, chi2, phase_order) if f_ref > 0 else 0.0
    return np.pi / 4 + np.pi - lal_psi_pn(f, m1, m2, chi1, chi2, phase_order) + 2.0 * phi_ref + ref


def textbook_amp(f, m1, m2, dist_m):
    """|h~| = sqrt(5/24) pi^(-2/3) (MRSUN/r) (Mc MTSUN)^(5/6)/MTSUN f^(-7/6)."""
    mc = (m1 * m2) ** 0.6 / (m1 + m2) ** 0.2
    return (math.sqrt(5.0 / 24.0) * math.pi ** (-2.0 / 3.0) * lal.MRSUN_SI / dist_m
            * (mc * lal.MTSUN_SI) ** (5.0 / 6.0) / lal.MTSUN_SI * np.asarray(f) ** (-7.0 / 6.0))


def textbook_psi_tb(f, m1, m2):
    """Independent non-spinning 3.5PN SPA phase, BIOPS 2009 (arXiv:0907.0700) Eq. 3.18,
    Psi_tb(f) = 2 pi f t_c - phi_c - pi/4 + 3/(128 eta v^5) sum_k psi_k v^k, with
    t_c = phi_c = 0, psi_5 written with [1 + 3 ln(v/v_lso)], v_lso = 6^-1/2,
    psi_6 with -6848/21 ln(4 v).  Coefficients typed from the paper as exact
    rationals (not copied from LAL's decimal forms)."""
    M = m1 + m2
    eta = m1 * m2 / M ** 2
    pi = math.pi
    gE = 0.5772156649015329
    f = np.asarray(f, dtype=float)
    v = np.cbrt(pi * M * lal.MTSUN_SI * f)
    v_lso = 1.0 / math.sqrt(6.0)
    q = lambda fr: float(Fr(fr))
    psi2 = q("3715/756") + q("55/9") * eta
    psi3 = -16.0 * pi
    psi4 = q("15293365/508032") + q("27145/504") * eta + q("3085/72") * eta ** 2
    psi5p = pi * (q("38645/756") - q("65/9") * eta)
    psi6c = (q("11583231236531/4694215680") - q("640/3") * pi ** 2 - q("6848/21") * gE
             + eta * (q("-15737765635/3048192") + q("2255/12") * pi ** 2)
             + q("76055/1728") * eta ** 2 - q("127825/1296") * eta ** 3)
    psi7 = pi * (q("77096675/254016") + q("378515/1512") * eta - q("74045/756") * eta ** 2)
    series = (1.0 + psi2 * v ** 2 + psi3 * v ** 3 + psi4 * v ** 4
              + psi5p * (1.0 + 3.0 * np.log(v / v_lso)) * v ** 5
              + (psi6c - q("6848/21") * np.log(4.0 * v)) * v ** 6 + psi7 * v ** 7)
    return -pi / 4 + 3.0 / (128.0 * eta * v ** 5) * series, psi5p


def sample_bins(k_first, k_last, df, f_lo, f_cut, f_hi):
    """~64 log-uniform bins in [f_lo, f_cut] + 8 in (f_cut, f_hi]; return (bins, above_isco)."""
    fs = np.geomspace(f_lo, f_cut, N_SAMPLES_BAND)
    kb = np.unique(np.clip(np.rint(fs / df).astype(np.int64), k_first, min(k_last, int(math.floor(f_cut / df)))))
    above = np.array([], dtype=np.int64)
    if f_cut < f_hi:
        fa = np.geomspace(f_cut, f_hi, N_SAMPLES_ABOVE_ISCO + 1)[1:]
        above = np.unique(np.clip(np.rint(fa / df).astype(np.int64), 0, k_last))
        above = above[above * df > f_cut]
    bins = np.concatenate([kb, above])
    flags = [False] * len(kb) + [True] * len(above)
    return bins, flags


def polarisation_samples(h, bins, k_first, k_last):
    """Unwrap over the full nonzero band [k_first, k_last], then pick bins."""
    band = h[k_first:k_last + 1]
    unwrapped = np.unwrap(np.angle(band))
    steps = np.abs(np.diff(unwrapped))
    idx = bins - k_first
    return {
        "re": fl_list(band.real[idx]),
        "im": fl_list(band.imag[idx]),
        "abs": fl_list(np.abs(band)[idx]),
        "arg_unwrapped": fl_list(unwrapped[idx]),
    }, unwrapped, float(steps.max()) if steps.size else 0.0


def run_taylorf2_point(pid, label, m1, m2, chi1, chi2, phase_order=-1, inclination=0.0,
                       phi_ref=0.0, f_ref=0.0, want_hcross=False):
    dist_m = DIST_MPC * 1e6 * lal.PC_SI
    df, tau0 = choose_delta_f(m1, m2, F_MIN)
    params = lal.CreateDict()
    if phase_order != -1:
        ls.SimInspiralWaveformParamsInsertPNPhaseOrder(params, phase_order)
    amp_order = ls.SimInspiralWaveformParamsLookupPNAmplitudeOrder(params)
    spin_order = ls.SimInspiralWaveformParamsLookupPNSpinOrder(params)
    tidal_order = ls.SimInspiralWaveformParamsLookupPNTidalOrder(params)
    looked_up_phase_order = ls.SimInspiralWaveformParamsLookupPNPhaseOrder(params)

    hp, hc = ls.SimInspiralChooseFDWaveform(
        m1 * lal.MSUN_SI, m2 * lal.MSUN_SI, 0.0, 0.0, chi1, 0.0, 0.0, chi2,
        dist_m, inclination, phi_ref, 0.0, 0.0, 0.0, df, F_MIN, F_MAX, f_ref,
        params, ls.TaylorF2)
    h = hp.data.data.copy()
    x = hc.data.data.copy()
    nz = np.nonzero(h)[0]
    k_first, k_last = int(nz[0]), int(nz[-1])
    assert k_first == int(math.ceil(F_MIN / df)), (k_first, F_MIN / df)

    # Same call with f_max = 0: LAL then stops at its own ISCO cut-off.
    hp0, _ = ls.SimInspiralChooseFDWaveform(
        m1 * lal.MSUN_SI, m2 * lal.MSUN_SI, 0.0, 0.0, chi1, 0.0, 0.0, chi2,
        dist_m, inclination, phi_ref, 0.0, 0.0, 0.0, df, F_MIN, 0.0, f_ref,
        params, ls.TaylorF2)
    k_last_isco = int(np.nonzero(hp0.data.data)[0][-1])

    # Direct driver call (no inclination factors): must agree with hp at i = 0.
    hdir = ls.SimInspiralTaylorF2(phi_ref, df, m1 * lal.MSUN_SI, m2 * lal.MSUN_SI, chi1, chi2,
                                  F_MIN, F_MAX, f_ref, dist_m, params)
    pfac = 0.5 * (1.0 + math.cos(inclination) ** 2)
    direct_diff = float(np.max(np.abs(pfac * hdir.data.data - h)))

    fis = f_isco(m1, m2)
    f_cut = min(fis, F_MAX)
    bins, above = sample_bins(k_first, k_last, df, F_MIN, f_cut, k_last * df)
    freqs = bins * df

    hp_s, unwrapped, max_step = polarisation_samples(h, bins, k_first, k_last)
    assert max_step < np.pi / 2, (pid, max_step)

    # ---- checks against the analytic model (full nonzero band) ----
    fb = np.arange(k_first, k_last + 1) * df
    model = lal_model_arg(fb, m1, m2, chi1, chi2, phase_order, phi_ref, f_ref)
    n2pi = int(np.rint(np.median(unwrapped - model) / (2 * np.pi)))
    resid = unwrapped - (model + 2 * np.pi * n2pi)
    amp_model = pfac * textbook_amp(fb, m1, m2, dist_m)
    amp_rel = np.abs(np.abs(h[k_first:k_last + 1]) / amp_model - 1.0)
    checks = {
        "unwrap_max_abs_step_rad": max_step,
        "direct_SimInspiralTaylorF2_max_abs_diff": direct_diff,
        "lal_model": {
            "description": "arg h+ = pi/4 + pi - psi_PN^LAL(f) + 2 phi_ref + psi_PN^LAL(f_ref) + 2 pi n "
                           "over ALL nonzero bins; |h+| = (1+cos^2 i)/2 * textbook A f^-7/6",
            "n_2pi": n2pi,
            "max_abs_phase_residual_rad": float(np.max(np.abs(resid))),
            "max_rel_amp_error": float(np.max(amp_rel)),
        },
    }
    if chi1 == 0.0 and chi2 == 0.0 and phase_order == -1 and phi_ref == 0.0 and f_ref == 0.0:
        # Independent BIOPS textbook phase; fit LAL - conj-convention textbook = c0 + c1 f
        sel = fb <= f_cut
        psi_tb, psi5p = textbook_psi_tb(fb[sel], m1, m2)
        d = unwrapped[sel] - (-psi_tb)
        A = np.vstack([np.ones(sel.sum()), fb[sel]]).T
        # centre f for conditioning
        fmean = fb[sel].mean()
        A[:, 1] -= fmean
        (c0c, c1), *_ = np.linalg.lstsq(A, d, rcond=None)
        c0 = c0c - c1 * fmean
        fit_res = d - (c0 + c1 * fb[sel])
        eta = m1 * m2 / (m1 + m2) ** 2
        expected_c0 = np.pi + 9.0 / (128.0 * eta) * psi5p * math.log(6.0) / 2.0
        wrap = lambda a: float((a + np.pi) % (2 * np.pi) - np.pi)
        checks["textbook_fit"] = {
            "description": "LAL unwrapped arg h+ minus -Psi_tb(f; t_c=0, phi_c=0) [BIOPS 2009 Eq 3.18, "
                           "ln(v/v_lso) in 2.5PN] fitted as c0 + c1*f over [f_min, min(f_isco, f_max)]",
            "c0_rad": float(c0),
            "c0_mod_2pi_rad": wrap(c0),
            "c1_rad_per_hz": float(c1),
            "equivalent_t_c_s": float(-c1 / (2 * np.pi)),
            "expected_c0_mod_2pi_rad": wrap(expected_c0),
            "expected_c0_formula": "pi + 9/(128 eta) * pi(38645/756 - 65/9 eta) * ln(6)/2",
            "max_abs_residual_rad": float(np.max(np.abs(fit_res))),
            "n_bins_fitted": int(sel.sum()),
        }

    mc = (m1 * m2) ** 0.6 / (m1 + m2) ** 0.2
    entry = {
        "id": pid,
        "label": label,
        "params": {
            "approximant": "TaylorF2",
            "m1_msun": fl(m1), "m2_msun": fl(m2),
            "chirp_mass_msun": fl(mc), "q_m2_over_m1": fl(m2 / m1),
            "eta": fl(m1 * m2 / (m1 + m2) ** 2),
            "chi1z": fl(chi1), "chi2z": fl(chi2),
            "distance_mpc": DIST_MPC, "distance_m": fl(dist_m),
            "f_min_hz": F_MIN, "f_max_hz": F_MAX, "delta_f_hz": df,
            "phase_order": looked_up_phase_order,
            "amplitude_order": amp_order,
            "spin_order": spin_order,
            "tidal_order": tidal_order,
            "f_ref_hz": fl(f_ref), "phi_ref_rad": fl(phi_ref),
            "inclination_rad": fl(inclination), "long_asc_nodes_rad": 0.0,
            "newtonian_tau_at_f_min_s": fl(tau0),
        },
        "lal_output": {
            "n_bins": int(h.size),
            "epoch_s": fl(float(hp.epoch)),
            "first_nonzero_bin": k_first,
            "first_nonzero_freq_hz": fl(k_first * df),
            "last_nonzero_bin": k_last,
            "last_nonzero_freq_hz": fl(k_last * df),
            "f_isco_hz": fl(fis),
            "last_nonzero_bin_if_f_max_0": k_last_isco,
            "last_nonzero_freq_hz_if_f_max_0": fl(k_last_isco * df),
        },
        "samples": {
            "bin": [int(b) for b in bins],
            "freq_hz": fl_list(freqs),
            "above_isco": above,
            "hplus": hp_s,
        },
        "checks": checks,
    }
    if want_hcross:
        xs, x_unwrapped, x_step = polarisation_samples(x, bins, k_first, k_last)
        entry["samples"]["hcross"] = xs
        ratio = x[k_first:k_last + 1] / h[k_first:k_last + 1]
        expected = -1j * math.cos(inclination) / pfac
        checks["hcross_over_hplus_max_abs_dev_from_-i_cos_i_over_pfac"] = float(np.max(np.abs(ratio - expected)))
    return entry


# Main grid: (Mc [Msun], q = m2/m1, chi1z, chi2z, label).  Extremes:
# q from 1 to 1/50, Mc from 1 to 80 Msun, spins in {0, +-0.5, +-0.9}.
# Mc/q combinations keep f_isco > f_min = 20 Hz (Mc = 80, q = 1 has f_isco ~ 24 Hz).
TF2_GRID = [
    (1.0, 1.0, 0.0, 0.0, "Mc=1 equal mass, non-spinning"),
    (None, None, 0.0, 0.0, "1.4+1.4 Msun BNS, non-spinning"),  # set by masses below
    (1.0, 1.0, 0.5, 0.5, "Mc=1 equal mass, aligned spins +0.5"),
    (1.0, 1.0, -0.9, 0.9, "Mc=1 equal mass, anti/aligned spins"),
    (1.5, 0.5, 0.9, 0.0, "Mc=1.5 q=1/2 chi1=0.9"),
    (2.0, 0.2, 0.0, -0.5, "Mc=2 q=1/5 chi2=-0.5"),
    (3.0, 0.1, 0.5, -0.9, "Mc=3 q=1/10 mixed spins"),
    (5.0, 1.0 / 50.0, 0.0, 0.0, "Mc=5 q=1/50 non-spinning"),
    (5.0, 1.0 / 50.0, 0.9, 0.9, "Mc=5 q=1/50 spins +0.9"),
    (8.0, 1.0 / 50.0, -0.9, 0.5, "Mc=8 q=1/50 mixed spins"),
    (10.0, 1.0 / 50.0, -0.5, 0.0, "Mc=10 q=1/50 chi1=-0.5"),
    (8.7, 1.0, 0.0, 0.0, "Mc=8.7 (~10+10) non-spinning"),
    (10.0, 1.0, 0.9, 0.9, "Mc=10 equal mass, spins +0.9"),
    (10.0, 1.0, -0.9, -0.9, "Mc=10 equal mass, spins -0.9"),
    (15.0, 0.5, 0.5, -0.5, "Mc=15 q=1/2 mixed spins"),
    (20.0, 0.25, 0.9, 0.0, "Mc=20 q=1/4 chi1=0.9"),
    (25.0, 1.0 / 3.0, -0.5, 0.9, "Mc=25 q=1/3 mixed spins"),
    (30.0, 1.0, 0.0, 0.0, "Mc=30 equal mass non-spinning"),
    (30.0, 0.125, 0.5, 0.5, "Mc=30 q=1/8 spins +0.5"),
    (None, None, 0.0, 0.0, "36+29 Msun (GW150914-like), non-spinning"),
    (40.0, 1.0, -0.9, 0.5, "Mc=40 equal mass mixed spins"),
    (50.0, 0.7, 0.9, -0.9, "Mc=50 q=0.7 mixed spins"),
    (60.0, 1.0, 0.5, 0.5, "Mc=60 equal mass spins +0.5"),
    (80.0, 1.0, 0.0, 0.0, "Mc=80 equal mass non-spinning (f_isco ~ 24 Hz)"),
    (80.0, 1.0, 0.9, 0.9, "Mc=80 equal mass spins +0.9"),
]
EXPLICIT_MASSES = {1: (1.4, 1.4), 19: (36.0, 29.0)}

# Phase PN-order sweep on one spinning point (spin terms are truncated with
# the phase order because they live inside pfa_k).
SWEEP_POINT = (10.0, 5.0, 0.9, -0.5)   # m1, m2, chi1z, chi2z

# Convention probes (hx recorded too): inclination, phi_ref, f_ref.
PROBE_POINT = (10.0, 5.0, 0.5, -0.5)
PROBES = [
    ("inclination pi/3", math.pi / 3, 0.0, 0.0),
    ("phi_ref 0.7 rad", 0.0, 0.7, 0.0),
    ("f_ref 30 Hz", 0.0, 0.0, 30.0),
    ("inclination 2.5 rad, phi_ref 0.7, f_ref 50 Hz", 2.5, 0.7, 50.0),
]

CONVENTIONS = {
    "entry_point": "lalsimulation.SimInspiralChooseFDWaveform(m1_SI, m2_SI, 0,0,chi1z, 0,0,chi2z, distance_m, "
                   "inclination, phiRef, longAscNodes=0, ecc=0, meanPerAno=0, deltaF, f_min, f_max, f_ref, "
                   "LALDict, lalsimulation.TaylorF2); path: GenerateFDWaveform -> legacy generator -> "
                   "XLALSimInspiralTaylorF2 + inclination factors (LALSimInspiralGeneratorLegacy.c). "
                   "Chosen because it is the public PE entry point and applies the polarisation factors; "
                   "SimInspiralTaylorF2 called directly gives identical h+ at inclination 0 (checked per point).",
    "fourier_convention": "h~(f) = int h(t) exp(-2 pi i f t) dt; TaylorF2Core writes "
                          "data = amp*(cos(phasing - pi/4) - i sin(phasing - pi/4)) = amp*exp(-i(phasing - pi/4)).",
    "phase_sign": "arg h+ = -psi_PN(f) + ... : the COMPLEX CONJUGATE of the textbook SPA A f^-7/6 exp(+i Psi), "
                  "Psi = 2 pi f t_c - phi_c - pi/4 + psi_PN (Cutler-Flanagan/BIOPS convention, e^{+2 pi i f t}).",
    "psi_PN": "psi_PN^LAL(f) = sum_{k=0}^{order} (pfa_k + pfl_k ln v) v^(k-5), v = cbrt(pi (m1+m2) MTSUN_SI f), "
              "pfa_k = 3/(128 eta) psi_k (BIOPS 2009 Eq 3.18 + aligned-spin terms of "
              "LALSimInspiralPNCoefficients.c); logs are ln(v), not ln(v/v_lso); 3PN constant contains "
              "-6848/21 ln 4 (textbook ln(4v)). phase_order -1 == 7 (3.5PN); order 1 == order 0 (pfa_1 = 0). "
              "Spin order -1 = all spin terms (1.5PN SO, 2PN S1S2/QM/self-spin with quadrupole kappa=1, "
              "2.5PN SO incl. its log, 3PN SO/S1S2/QM/self, 3.5PN SO); spin terms are truncated by phase order.",
    "full_formula": "h+(f_k) = (1+cos^2 i)/2 * A(f) * exp(i [pi/4 + pi - psi_PN^LAL(f) + 2 phi_ref "
                    "+ (f_ref>0 ? psi_PN^LAL(f_ref) : 0)]);  hx(f_k) = -i cos(i) * h+(f_k) / ((1+cos^2 i)/2)",
    "amplitude": "A(f) = sqrt(5/24) pi^(-2/3) (MRSUN_SI/r) (Mc MTSUN_SI)^(5/6) / MTSUN_SI * f^(-7/6) with r in metres; "
                 "LAL's prefactor amp0 = -4 m1 m2/r MRSUN_SI MTSUN_SI sqrt(pi/12) is NEGATIVE, which is the "
                 "extra +pi in the phase above. Amplitude order -1 (default) == 0: Newtonian SPA amplitude only.",
    "extra_pi": "The constant in arg h+ is pi/4 (from 'phasing - pi/4' with the minus sign of exp(-i...)) plus pi "
                "(negative amp0): total 5 pi/4 mod 2 pi when phi_ref = 0, f_ref = 0.",
    "phi_ref": "-2*phi_ref inside 'phasing' (phi_ref is an ORBITAL phase): arg h+ increases by +2 phi_ref.",
    "f_ref": "f_ref = 0 (used here): no reference subtraction (reference at coalescence). f_ref > 0: "
             "psi_PN^LAL(f_ref) (same truncation) is subtracted from 'phasing', i.e. added to arg h+.",
    "time_shift": "Epoch = -1/deltaF and phasing += shft*f with shft = 2 pi epoch = -2 pi/deltaF; on bin k "
                  "this is -2 pi k, an exact multiple of 2 pi, so NO effective linear-in-f term: evaluate with "
                  "t_c = 0, phi_c = 0 at f_k = k deltaF. (Continuous-f view: coalescence at t = 0 = end of "
                  "the segment [ -1/deltaF, 0 ].)",
    "cutoff": "With f_max > 0 LAL fills bins ceil(f_min/deltaF)..floor(f_max/deltaF) with NO ISCO cut. "
              "Only with f_max = 0 does it stop at f_isco = 6^-1.5/(pi M MTSUN_SI) (bins up to "
              "floor(f_isco/deltaF)); both recorded. Bins below ceil(f_min/deltaF) are exactly 0.",
    "distance_unit": "metres in the API (distance_m = distance_mpc * 1e6 * PC_SI).",
    "masses": "kg in the API (m * MSUN_SI); internally converted back to Msun; m1 gets chi1z.",
    "unwrap": "samples.*.arg_unwrapped = np.unwrap(np.angle(h)) over ALL nonzero bins [first..last_nonzero_bin], "
              "then subsampled; equals the full_formula phase + 2 pi * checks.lal_model.n_2pi.",
    "how_to_test": "Compute psi_PN in Rust at samples.freq_hz; assert |arg_unwrapped - (5pi/4 - psi_PN + 2 phi_ref "
                   "+ psi_ref) - 2 pi n_2pi| < 1e-7 and | |h+| / ((1+cos^2 i)/2 A(f)) - 1 | < 1e-9; or compare "
                   "re/im directly.",
}


def build_taylorf2():
    entries = []
    for i, (mc, q, c1, c2, label) in enumerate(TF2_GRID):
        m1, m2 = EXPLICIT_MASSES[i] if i in EXPLICIT_MASSES else masses_from_mc_q(mc, q)
        entries.append(run_taylorf2_point("p%02d" % i, label, m1, m2, c1, c2))
    sweep = []
    m1, m2, c1, c2 = SWEEP_POINT
    for order in range(0, 8):
        sweep.append(run_taylorf2_point("order%d" % order, "phase PN order %d (%.1fPN)" % (order, order / 2),
                                        m1, m2, c1, c2, phase_order=order))
    probes = []
    m1, m2, c1, c2 = PROBE_POINT
    probes.append(run_taylorf2_point("probe_base", "probe base (i=0, phi_ref=0, f_ref=0)", m1, m2, c1, c2,
                                     want_hcross=True))
    for j, (label, inc, phr, fref) in enumerate(PROBES):
        probes.append(run_taylorf2_point("probe%d" % j, label, m1, m2, c1, c2, inclination=inc,
                                         phi_ref=phr, f_ref=fref, want_hcross=True))
    return {
        "generator": generator_info(),
        "description": "LALSimulation TaylorF2 frequency-domain h+ (complex) at subsampled grid bins. "
                       "See 'conventions' and the docstring of scripts/lal_fixtures.py.",
        "conventions": CONVENTIONS,
        "lal_constants": LAL_CONSTANTS,
        "points": entries,
        "phase_order_sweep": sweep,
        "convention_probes": probes,
    }


# ==========================================================================
# 2. aLIGO ZeroDetHighPower PSD (analytic model)
# ==========================================================================

def build_psd():
    f_grid = np.geomspace(9.0, 4096.0, 200)
    exact = [10.0, 20.0, 100.0, 1000.0]
    below = [0.0, 0.1, 1.0, 2.0, 5.0, 8.0, 8.999]
    fn = ls.SimNoisePSDaLIGOZeroDetHighPower
    quantum = ls.SimNoisePSDaLIGOQuantumZeroDetHighPower
    thermal = ls.SimNoisePSDaLIGOThermal

    def val(f):
        x = fn(float(f))
        return float(x) if math.isfinite(x) else repr(x)

    below_vals = [val(f) for f in below]
    return {
        "generator": generator_info(),
        "function": "lalsimulation.SimNoisePSDaLIGOZeroDetHighPower(f) == XLALSimNoisePSDaLIGOZeroDetHighPower "
                    "(LALSimNoisePSD.c): analytic quantum (Buonanno-Chen, zero detuning, high power, "
                    "homodyne angle 116 deg, eta=0.9) + thermal noise; one-sided PSD in 1/Hz. NOT the "
                    "tabulated GWINC file version (SimNoisePSDaLIGOZeroDetHighPowerGWINC / ZERO_DET_high_P.txt), "
                    "which differs.",
        "low_frequency_behaviour": "The analytic function has NO low-frequency cut: it returns finite, rapidly "
                                   "growing nonzero values below its documented validity limit (~9 Hz), and "
                                   "NaN at f = 0 (stored as the string 'nan'). Callers (e.g. PyCBC/bilby) apply "
                                   "their own f_low cut.",
        "freq_hz": fl_list(f_grid),
        "psd": [fn(float(f)) for f in f_grid],
        "psd_quantum": [quantum(float(f)) for f in f_grid],
        "psd_thermal": [thermal(float(f)) for f in f_grid],
        "exact_points": [{"freq_hz": f, "psd": fn(f), "asd": math.sqrt(fn(f))} for f in exact],
        "below_validity": [{"freq_hz": f, "psd": v} for f, v in zip(below, below_vals)],
    }


# ==========================================================================
# 3. Antenna patterns and time delays
# ==========================================================================

def det_info(prefix):
    d = lal.cached_detector_by_prefix[prefix]
    d2 = ls.DetectorPrefixToLALDetector(prefix)
    resp = np.array(d.response)          # REAL4 (float32) 3x3 as stored by LAL
    assert np.array_equal(resp, np.array(d2.response)) and np.array_equal(d.location, d2.location)
    idx = [i for i in range(len(lal.CachedDetectors)) if lal.CachedDetectors[i].frDetector.prefix == prefix][0]
    fr = d.frDetector
    return d, {
        "prefix": prefix,
        "name": fr.name,
        "lal_cached_detectors_index": idx,
        "response_float32_as_float64": [[float(x) for x in row] for row in resp],
        "location_m": fl_list(d.location),
        "frDetector": {
            "vertexLongitudeRadians": fr.vertexLongitudeRadians,
            "vertexLatitudeRadians": fr.vertexLatitudeRadians,
            "vertexElevation": float(fr.vertexElevation),
            "xArmAltitudeRadians": float(fr.xArmAltitudeRadians),
            "xArmAzimuthRadians": float(fr.xArmAzimuthRadians),
            "yArmAltitudeRadians": float(fr.yArmAltitudeRadians),
            "yArmAzimuthRadians": float(fr.yArmAzimuthRadians),
            "xArmMidpoint": float(fr.xArmMidpoint),
            "yArmMidpoint": float(fr.yArmMidpoint),
        },
    }


def build_antenna():
    dets = {}
    infos = []
    for p in ("H1", "L1", "V1"):
        d, info = det_info(p)
        dets[p] = d
        infos.append(info)

    rng = np.random.default_rng(20240601)
    pts = [
        (0.0, 0.0, 0.0, 0.0),
        (0.0, math.pi / 2, 0.0, 0.0),
        (1.0, -math.pi / 2, 0.3, 2.0),
        (math.pi, 0.0, math.pi / 4, math.pi),
        # ~overhead H1 (ra = gmst + lon, dec = geodetic lat): F+^2 + Fx^2 ~ 1
        (1.5 + dets["H1"].frDetector.vertexLongitudeRadians, dets["H1"].frDetector.vertexLatitudeRadians, 0.0, 1.5),
    ]
    for _ in range(25):
        pts.append((float(rng.uniform(0, 2 * math.pi)), float(math.asin(rng.uniform(-1, 1))),
                    float(rng.uniform(0, math.pi)), float(rng.uniform(0, 2 * math.pi))))

    rows = []
    for ra, dec, psi, gmst in pts:
        row = {"ra": ra, "dec": dec, "psi": psi, "gmst": gmst}
        for p, d in dets.items():
            fp, fx = lal.ComputeDetAMResponse(d.response, ra, dec, psi, gmst)
            row[p] = {"fplus": fp, "fcross": fx}
        rows.append(row)

    # time delays at a fixed GPS time
    gps = lal.LIGOTimeGPS(1126259462, 400000000)
    gmst = lal.GreenwichMeanSiderealTime(gps)
    sky = [(0.0, 0.0), (1.0, 0.5), (2.5, -0.9), (4.0, 1.2), (5.5, -0.2), (3.0, math.pi / 2 - 1e-3),
           (1.95, -1.27), (0.3, -0.6)]
    delays = []
    for ra, dec in sky:
        row = {"ra": ra, "dec": dec}
        row["delay_from_geocenter_s"] = {p: lal.TimeDelayFromEarthCenter(d.location, ra, dec, gps)
                                         for p, d in dets.items()}
        row["arrival_time_diff_s"] = {
            "%s-%s" % (a, b): lal.ArrivalTimeDiff(dets[a].location, dets[b].location, ra, dec, gps)
            for a, b in (("H1", "L1"), ("H1", "V1"), ("L1", "V1"))}
        delays.append(row)

    gmst_table = []
    for s, ns in ((1000000000, 0), (1126259462, 400000000), (1187008882, 430000000), (1300000000, 0)):
        g = lal.GreenwichMeanSiderealTime(lal.LIGOTimeGPS(s, ns))
        gmst_table.append({"gps_seconds": s, "gps_nanoseconds": ns, "gmst_rad": g,
                           "gmst_mod_2pi_rad": g % (2 * math.pi)})

    return {
        "generator": generator_info(),
        "conventions": {
            "antenna": "lal.ComputeDetAMResponse(D, ra, dec, psi, gmst) == XLALComputeDetAMResponse "
                       "(lal/lib/tools/DetResponse.c): gha = gmst - ra; X = (-cos psi sin gha - sin psi cos gha sin dec, "
                       "-cos psi cos gha + sin psi sin gha sin dec, sin psi cos dec); Y = (sin psi sin gha - cos psi "
                       "cos gha sin dec, sin psi cos gha + cos psi sin gha sin dec, cos psi cos dec); "
                       "F+ = X.D.X - Y.D.Y, Fx = X.D.Y + Y.D.X (D symmetric).",
            "response_precision": "LAL stores the response tensor D as REAL4 (float32); the values here are "
                                  "those float32 numbers exactly, written as float64. Using them reproduces LAL's "
                                  "F+/Fx to ~1e-16; recomputing D in float64 from frDetector gives ~1e-8 differences.",
            "time_delay": "TimeDelayFromEarthCenter(loc, ra, dec, gps) = ArrivalTimeDiff(loc, 0, ...) = "
                          "-(n . loc)/c with n = (cos dec cos gha, -cos dec sin gha, sin dec), gha = gmst(gps) - ra; "
                          "positive when the wave reaches the detector after the geocentre. "
                          "ArrivalTimeDiff(loc1, loc2) = n.(loc2 - loc1)/c = t1 - t2.",
            "gmst": "lal.GreenwichMeanSiderealTime(gps) in radians, NOT reduced mod 2 pi (sin/cos only); "
                    "equation of equinoxes = 0, leap seconds from LAL's table.",
            "detectors": "lal.cached_detector_by_prefix[prefix] (identical to "
                         "lalsimulation.DetectorPrefixToLALDetector(prefix)); index into lal.CachedDetectors given.",
            "c_si": lal.C_SI,
        },
        "detectors": infos,
        "antenna_points": rows,
        "time_delays": {
            "gps_seconds": 1126259462, "gps_nanoseconds": 400000000,
            "gmst_rad": gmst, "gmst_mod_2pi_rad": gmst % (2 * math.pi),
            "points": delays,
        },
        "gmst_table": gmst_table,
    }


# ==========================================================================

def main():
    os.makedirs(OUT_DIR, exist_ok=True)
    out = {}
    out["taylorf2.json"] = build_taylorf2()
    out["psd_aligo_zerodet_highpower.json"] = build_psd()
    out["antenna_patterns.json"] = build_antenna()
    for name, obj in out.items():
        path = write_json(name, obj)
        print("wrote %s (%.1f kB)" % (os.path.relpath(path, REPO_ROOT), os.path.getsize(path) / 1024))

    # ---- summary / sanity checks ----
    tf2 = out["taylorf2.json"]
    allpts = tf2["points"] + tf2["phase_order_sweep"] + tf2["convention_probes"]
    print("\nTaylorF2: %d grid points, %d PN-order entries, %d probes" % (
        len(tf2["points"]), len(tf2["phase_order_sweep"]), len(tf2["convention_probes"])))
    print("%-8s %7s %7s %5s %5s %9s %6s %9s %9s %10s %9s %9s" % (
        "id", "m1", "m2", "chi1", "chi2", "dF", "nsamp", "f_isco", "f_lastnz", "max|arg|",
        "model_res", "amp_rel"))
    for e in allpts:
        p, o, s, c = e["params"], e["lal_output"], e["samples"], e["checks"]
        print("%-8s %7.3f %7.3f %5.2f %5.2f %9.6f %6d %9.2f %9.2f %10.3e %9.1e %9.1e" % (
            e["id"], p["m1_msun"], p["m2_msun"], p["chi1z"], p["chi2z"], p["delta_f_hz"], len(s["bin"]),
            o["f_isco_hz"], o["last_nonzero_freq_hz"], max(abs(x) for x in s["hplus"]["arg_unwrapped"]),
            c["lal_model"]["max_abs_phase_residual_rad"], c["lal_model"]["max_rel_amp_error"]))
    print("\ntextbook (BIOPS) fits, non-spinning points:")
    for e in allpts:
        t = e["checks"].get("textbook_fit")
        if t:
            print("  %-8s c0 mod 2pi = %+.10f (expected %+.10f)  c1 = %+.3e rad/Hz  resid = %.2e" % (
                e["id"], t["c0_mod_2pi_rad"], t["expected_c0_mod_2pi_rad"], t["c1_rad_per_hz"],
                t["max_abs_residual_rad"]))
    worst = max(e["checks"]["lal_model"]["max_abs_phase_residual_rad"] for e in allpts)
    worst_amp = max(e["checks"]["lal_model"]["max_rel_amp_error"] for e in allpts)
    worst_direct = max(e["checks"]["direct_SimInspiralTaylorF2_max_abs_diff"] for e in allpts)
    print("worst model phase residual %.2e rad, amp rel err %.2e, direct-call diff %.2e" % (
        worst, worst_amp, worst_direct))
    assert worst < 1e-7 and worst_amp < 1e-9

    psd = out["psd_aligo_zerodet_highpower.json"]
    print("\nPSD: %d grid points, min %.3e at %.1f Hz; exact: %s; below-validity: %s" % (
        len(psd["psd"]), min(psd["psd"]), psd["freq_hz"][int(np.argmin(psd["psd"]))],
        ", ".join("%g Hz: %.4e" % (x["freq_hz"], x["psd"]) for x in psd["exact_points"]),
        ", ".join("%g: %s" % (x["freq_hz"], x["psd"]) for x in psd["below_validity"])))

    ant = out["antenna_patterns.json"]
    fmax = max(max(abs(r[p]["fplus"]), abs(r[p]["fcross"])) for r in ant["antenna_points"] for p in ("H1", "L1", "V1"))
    print("Antenna: %d points, max |F| = %.6f; overhead-H1 point F+ = %.6f" % (
        len(ant["antenna_points"]), fmax, ant["antenna_points"][4]["H1"]["fplus"]))
    hl = max(abs(r["arrival_time_diff_s"]["H1-L1"]) for r in ant["time_delays"]["points"])
    print("Time delays: %d sky points, max |dt(H1-L1)| = %.6f s (light travel time %.6f s)" % (
        len(ant["time_delays"]["points"]), hl, lal.LightTravelTime(
            lal.cached_detector_by_prefix["H1"], lal.cached_detector_by_prefix["L1"]) * 1e-9))


if __name__ == "__main__":
    sys.exit(main())
