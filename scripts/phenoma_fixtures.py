#!/usr/bin/env python3
"""LALSimulation IMRPhenomA fixtures for `std::imrphenom` (tests/imrphenom_lal.rs).

Writes fixtures/lal/imrphenoma.json: for each (chirp mass, mass ratio) point,
LALSimulation's h+ at inclination 0 (`SimInspiralChooseFDWaveform`,
approximant IMRPhenomA, phiRef 0, f_min 20 Hz, f_max 0 so LAL cuts at its
f_cut, deltaF 0.5 Hz as a 2 s window has, distance 100 Mpc), at every 4th
bin from 20 Hz to f_cut, as real and imaginary parts, and the last nonzero
bin. LAL's IMRPhenomA has no time shift: bin k of its h+ is
A(f) exp(-i psi(f)) with A and psi as std::imrphenom documents them, which
the script also checks against its own numpy transcription of the model
before writing. std::imrphenom's strain is the complex conjugate (LAL's
frequency-domain IMRPhenomA runs backwards in time in LAL's own Fourier
convention); the Rust test conjugates.

Regenerate (the virtualenv lives outside the repository):
    python3 -m venv /tmp/lalvenv && /tmp/lalvenv/bin/pip install lalsuite numpy
    /tmp/lalvenv/bin/python scripts/phenoma_fixtures.py
"""
import importlib.metadata
import json
import os

import lal
import lalsimulation as ls
import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "fixtures", "lal", "imrphenoma.json")
DELTA_F = 0.5
F_MIN = 20.0
DIST_MPC = 100.0
# (chirp mass in Msun, q = m2 / m1 <= 1): light to heavy, equal to unequal.
POINTS = [(10.0, 1.0), (18.0, 0.5), (25.0, 0.8), (28.6, 0.81), (33.0, 0.3), (40.0, 1.0)]


def masses(mc, q):
    m1 = mc * (1.0 + q) ** 0.2 / q**0.6
    return m1, q * m1


def model(f, mc, q):
    """A numpy transcription of the model as std::imrphenom writes it."""
    m1, m2 = masses(mc, q)
    m = m1 + m2
    eta = m1 * m2 / m**2
    pim = np.pi * m * lal.MTSUN_SI

    def freq(a, b, c):
        return (a * eta**2 + b * eta + c) / pim

    f_merg = freq(6.6389e-01, -1.0321e-01, 1.0979e-01)
    f_ring = freq(1.3278e00, -2.0642e-01, 2.1957e-01)
    sigma = freq(1.1383e00, -1.7700e-01, 4.6834e-02)
    f_cut = freq(1.7086e00, -2.6592e-01, 2.8236e-01)
    coeffs = {
        0: (-1.5829e-01, 8.7016e-02, -3.3382e-02),
        2: (3.2967e01, -1.9000e01, 2.1345e00),
        3: (-3.0849e02, 1.8211e02, -2.1727e01),
        4: (1.1525e03, -7.1477e02, 9.9692e01),
        6: (1.2057e03, -8.4233e02, 1.8046e02),
    }
    x = pim * f
    psi = sum((a * eta**2 + b * eta + c) * x ** ((k - 5) / 3) for k, (a, b, c) in coeffs.items()) / eta
    dist = DIST_MPC * 1e6 * lal.PC_SI
    a0 = -((m * lal.MTSUN_SI) ** (5 / 6)) * f_merg ** (-7 / 6) * np.pi ** (-2 / 3) * np.sqrt(5 * eta / 24) / (dist / lal.C_SI)
    lorentz = sigma / (2 * np.pi * ((f - f_ring) ** 2 + sigma**2 / 4))
    shape = np.where(
        f <= f_merg,
        (f / f_merg) ** (-7 / 6),
        np.where(f <= f_ring, (f / f_merg) ** (-2 / 3), np.pi / 2 * (f_ring / f_merg) ** (-2 / 3) * sigma * lorentz),
    )
    return a0 * shape * np.exp(-1j * psi), f_cut


def point(mc, q):
    m1, m2 = masses(mc, q)
    hp, _ = ls.SimInspiralChooseFDWaveform(
        m1 * lal.MSUN_SI, m2 * lal.MSUN_SI, 0, 0, 0, 0, 0, 0,
        DIST_MPC * 1e6 * lal.PC_SI, 0.0, 0.0, 0.0, 0.0, 0.0,
        DELTA_F, F_MIN, 0.0, 0.0, None, ls.IMRPhenomA,
    )
    h = hp.data.data
    nonzero = np.nonzero(np.abs(h))[0]
    bins = np.arange(int(np.ceil(F_MIN / DELTA_F)), nonzero[-1] + 1, 4)
    f = bins * DELTA_F
    mine, f_cut = model(f, mc, q)
    err = np.max(np.abs(mine - h[bins]) / np.abs(h[bins]))
    assert err < 1e-9, f"the transcription differs from LAL by {err:.2e} at mc {mc}, q {q}"
    return {
        "mc_msun": mc,
        "q": q,
        "m1_msun": m1,
        "m2_msun": m2,
        "f_cut_hz": f_cut,
        "last_nonzero_hz": float(nonzero[-1] * DELTA_F),
        "f_hz": [float(v) for v in f],
        "re": [float(v) for v in h[bins].real],
        "im": [float(v) for v in h[bins].imag],
        "transcription_max_rel_error": float(err),
    }


def main():
    fixture = {
        "generator": {
            "script": "scripts/phenoma_fixtures.py",
            "lalsuite_version": importlib.metadata.version("lalsuite"),
            "lalsimulation_version": ls.__version__,
            "numpy_version": np.__version__,
        },
        "delta_f_hz": DELTA_F,
        "f_min_hz": F_MIN,
        "distance_mpc": DIST_MPC,
        "points": [point(mc, q) for mc, q in POINTS],
    }
    with open(OUT, "w") as fh:
        json.dump(fixture, fh, indent=1)
        fh.write("\n")
    for p in fixture["points"]:
        print(f"mc {p['mc_msun']} q {p['q']}: {len(p['f_hz'])} bins, f_cut {p['f_cut_hz']:.2f} Hz "
              f"(last nonzero {p['last_nonzero_hz']}), transcription {p['transcription_max_rel_error']:.1e}")
    print(f"wrote {os.path.relpath(OUT, ROOT)} ({os.path.getsize(OUT) / 1024:.1f} kB)")


if __name__ == "__main__":
    main()
