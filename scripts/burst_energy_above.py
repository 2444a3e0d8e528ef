"""The share of a glitch burst's whitened energy above a frequency: the
number behind `LOW_SEARCH_F0` in lab/src/explain/mod.rs (a blip or Koi
Fish search at a lower rate loses at most this share of its template).

    python3 scripts/burst_energy_above.py [--above 1024]

The burst is `std::glitch`'s `burst` (rise tau = q / (sqrt 2 pi f0), decay
asym * tau, frequency drifting by `drift` per tau), 2 s at 4096 Hz,
whitened by the O3 ASD of lab/data/o3_asd.csv above 20 Hz. Each cell is
the worst share over asym 0.4, 1, 3 and drift -0.5, 0, 0.5. Needs numpy.
"""

import argparse
import os

import numpy as np

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
RATE, SAMPLES = 4096, 8192


def share_above(f0, q, asym, drift, above, freqs, asd, t):
    tau = q / (np.sqrt(2.0) * np.pi * f0)
    dt = t - 1.0
    u = dt / np.where(dt < 0.0, tau, asym * tau)
    h = np.exp(-u * u) * np.cos(2.0 * np.pi * f0 * dt * (1.0 + 0.5 * drift * dt / tau))
    power = np.abs(np.fft.rfft(h) / asd) ** 2
    power[freqs < 20.0] = 0.0
    return power[freqs >= above].sum() / power.sum()


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--above", type=float, default=1024.0, help="frequency (Hz)")
    args = parser.parse_args()
    table = np.loadtxt(os.path.join(ROOT, "lab", "data", "o3_asd.csv"), delimiter=",", skiprows=1)
    freqs = np.fft.rfftfreq(SAMPLES, 1.0 / RATE)
    asd = np.interp(freqs, table[:, 0], table[:, 1])
    t = np.arange(SAMPLES) / RATE
    qs = [1.0, 1.5, 2.0, 3.0]
    print("f0 [Hz] | " + " | ".join(f"Q {q:g}" for q in qs))
    for f0 in [100, 150, 200, 250, 300, 350]:
        worst = [
            max(share_above(f0, q, a, d, args.above, freqs, asd, t) for a in (0.4, 1.0, 3.0) for d in (-0.5, 0.0, 0.5))
            for q in qs
        ]
        print(f"{f0} | " + " | ".join(f"{w:.1e}" for w in worst))


if __name__ == "__main__":
    main()
