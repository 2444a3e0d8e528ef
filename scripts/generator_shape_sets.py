#!/usr/bin/env python3
"""Example sets for the glitch generator's realism benchmark (issue #30):
glitch shapes that no `std::glitch` formula draws, whitened (unit-variance
white noise at 4096 Hz, 1 s rows), written as .npz with `x` (the glitch in
noise), `clean` (the glitch alone, row for row) and `label` (1, so that
`gwml generator fit --family blip` takes every row).

Sets, each glitch at a time uniform in 0.3-0.7 s, random phase, SNR uniform
in 15-30:
  ringdown  fast rise (1 ms), then exp(-t/tau) sin(2 pi f t + phi):
            f log-uniform 60-500 Hz, tau 5-40 ms (a damped oscillator)
  asymmetric  two sine-Gaussian components 5-30 ms apart, the second
            0.3-0.8 times the first, f0 log-uniform 40-300 Hz each, Q 2-8
  chirplet  Gaussian envelope (sigma 10-60 ms) with a linear frequency
            sweep from f1 to f2, f1 log-uniform 50-300 Hz, f2 = f1 * 1.5-4
            (up or down at random)
  realfit   real O3 Blips as antiglitch fitted them: a strain spectrum
            exp(-gbw/2 ln^2(f/f0)) at one random phase, whitened by the
            O3-like ASD of lab/data/o3_asd.csv; (f0, gbw) drawn from the
            held-out half (odd positions) of the H1/L1 Blip fits in
            lab/data/real_glitch_fits.csv, which the glitch benchmark's
            training population never uses (see lab/src/synth/real_fits.rs)
  gengli    (only with --gengli) blips drawn from gengli 0.2.0's generative
            adversarial networks, trained on real whitened H1 and L1 Blips
            (Lopez et al., Phys. Rev. D 106, 023027, 2022, arXiv:2203.06494;
            arXiv:2205.09204): 0.23 s whitened shapes as `get_glitch`
            returns them by default (Tukey-windowed, no low-pass), each
            from a detector's network at random, centred at 0.3-0.7 s, SNR uniform
            in 12-30 as in issue #30's check. The nearest to real blips
            this script can make; gengli is GPL-3.0 and not vendored:
            `pip install torch ray gengli` into a virtualenv outside the
            repository (torch from PyPI is a ~6 GB install).

Usage: python3 scripts/generator_shape_sets.py OUT_DIR [--n 500] [--seed 1] [--gengli]
Needs numpy (and gengli with torch for --gengli).
"""
import argparse
import functools
import os

import numpy as np

FS = 4096
N = 4096


def ringdown(rng, t):
    t0, phi = rng.uniform(0.3, 0.7), rng.uniform(0, 2 * np.pi)
    f = np.exp(rng.uniform(np.log(60), np.log(500)))
    tau = rng.uniform(0.005, 0.04)
    u = t - t0
    s = np.where(u >= 0, (1 - np.exp(-np.maximum(u, 0) / 0.001)) * np.exp(-np.maximum(u, 0) / tau), 0.0)
    return s * np.sin(2 * np.pi * f * u + phi)


def sine_gaussian(t, t0, f0, q, phi):
    tau = q / (2 * np.pi * f0)
    return np.exp(-0.5 * ((t - t0) / tau) ** 2) * np.sin(2 * np.pi * f0 * (t - t0) + phi)


def asymmetric(rng, t):
    t0 = rng.uniform(0.3, 0.7)
    lag = rng.uniform(0.005, 0.03)
    first = sine_gaussian(t, t0, np.exp(rng.uniform(np.log(40), np.log(300))), rng.uniform(2, 8), rng.uniform(0, 2 * np.pi))
    second = sine_gaussian(t, t0 + lag, np.exp(rng.uniform(np.log(40), np.log(300))), rng.uniform(2, 8), rng.uniform(0, 2 * np.pi))
    a = first / np.linalg.norm(first)
    b = second / np.linalg.norm(second)
    return a + rng.uniform(0.3, 0.8) * b


def chirplet(rng, t):
    t0, phi = rng.uniform(0.3, 0.7), rng.uniform(0, 2 * np.pi)
    sigma = rng.uniform(0.01, 0.06)
    f1 = np.exp(rng.uniform(np.log(50), np.log(300)))
    f2 = f1 * rng.uniform(1.5, 4.0)
    if rng.uniform() < 0.5:
        f1, f2 = f2, f1
    u = t - t0
    rate = (f2 - f1) / (4 * sigma)  # the sweep spans +-2 sigma
    phase = 2 * np.pi * ((f1 + f2) / 2 * u + 0.5 * rate * u**2) + phi
    return np.exp(-0.5 * (u / sigma) ** 2) * np.sin(phase)


ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


@functools.lru_cache(maxsize=None)
def real_fit_snrs(label):
    """The fitted SNRs of the held-out fits of `label`, in order."""
    return [snr for (_, _, snr) in _real_fit_table(label)[0]]


def _real_fit_table(label="Blip"):
    import csv

    rows = csv.DictReader(open(os.path.join(ROOT, "lab/data/real_glitch_fits.csv")))
    fits = [r for r in rows if r["label"] == label and r["ifo"] in ("H1", "L1")]
    held_out = [(float(r["f0"]), float(r["gbw"]), float(r["snr"])) for r in fits[1::2]]
    asd = np.zeros(N // 2 + 1)
    for r in csv.DictReader(open(os.path.join(ROOT, "lab/data/o3_asd.csv"))):
        asd[int(r["frequency_hz"])] = float(r["asd_per_sqrt_hz"])
    return held_out, asd


def realfit(rng, t, label="Blip", fit=None):
    """A held-out real fit of Gravity Spy class `label` (Blip, Tomte,
    Koi_Fish), at random or the one at position `fit` of the held-out half."""
    held_out, asd = _real_fit_table(label)
    f0, gbw, _ = held_out[rng.integers(len(held_out)) if fit is None else fit]
    f = np.fft.rfftfreq(N, 1 / FS)
    inband = asd > 0
    t0, phi = rng.uniform(0.3, 0.7), rng.uniform(0, 2 * np.pi)
    spectrum = np.zeros(N // 2 + 1, complex)
    l = np.log(f[inband] / f0)
    spectrum[inband] = np.exp(-0.5 * gbw * l * l) / asd[inband] * np.exp(1j * (phi - 2 * np.pi * f[inband] * t0))
    return np.fft.irfft(spectrum, N)


class Gengli:
    """Blips from gengli's published generators, each from one detector's
    network chosen at random (drawn a batch at a time per detector),
    centred at 0.3-0.7 s."""

    BATCH = 250

    def __init__(self):
        self.pools = {}
        self.networks = {}

    def __call__(self, rng, t):
        ifo = "H1" if rng.random() < 0.5 else "L1"
        if not self.pools.get(ifo):
            import gengli

            if ifo not in self.networks:
                self.networks[ifo] = gengli.glitch_generator(ifo)
            batch = self.networks[ifo].get_glitch(self.BATCH, srate=float(FS), seed=int(rng.integers(2**31)))
            self.pools[ifo] = list(np.atleast_2d(batch))
        shape = self.pools[ifo].pop()
        row = np.zeros(N)
        start = int(round(rng.uniform(0.3, 0.7) * FS)) - len(shape) // 2
        row[start : start + len(shape)] = shape
        return row


SETS = {"ringdown": ringdown, "asymmetric": asymmetric, "chirplet": chirplet}
# Not in SETS (which scripts/blip_realism.py reads as stand-ins); written too.
ALL_SETS = {**SETS, "realfit": realfit}


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("out")
    p.add_argument("--n", type=int, default=500)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--gengli", action="store_true", help="write only gengli.npz (needs gengli and torch)")
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    t = np.arange(N) / FS
    # The gengli set's index (4) keeps the other sets' seeds as they were.
    sets = {"gengli": (4, Gengli(), (12, 30))} if a.gengli else {n: (k, s, (15, 30)) for k, (n, s) in enumerate(ALL_SETS.items())}
    for name, (k, shape, (snr_lo, snr_hi)) in sets.items():
        rng = np.random.default_rng(a.seed * 1000 + k)
        clean = np.empty((a.n, N))
        noisy = np.empty((a.n, N))
        for i in range(a.n):
            s = shape(rng, t)
            s = s / np.linalg.norm(s) * rng.uniform(snr_lo, snr_hi)
            clean[i] = s
            noisy[i] = s + rng.standard_normal(N)
        path = os.path.join(a.out, f"{name}.npz")
        np.savez(path, x=noisy, clean=clean, label=np.ones(a.n, dtype=np.int64))
        print(f"wrote {path}: {a.n} {name} glitches")


if __name__ == "__main__":
    main()
