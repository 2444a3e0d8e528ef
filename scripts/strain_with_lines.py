#!/usr/bin/env python3
"""Adds spectral lines whose amplitudes wander to a strain file, as .npy.

    python scripts/strain_with_lines.py IN.hdf5 OUT.npy [--wander 0.1]
        [--every 5] [--seed 1]
    gwml scan OUT.npy --sample-rate 4096 --gps-start GPS --out T.csv

Real strain has lines (power mains at 60 Hz and harmonics, calibration
lines, violin modes near 500 Hz and 1 kHz) whose amplitudes drift. A
Welch PSD of 128 s whitens a steady line away, but a drifting one leaves
excess power in the narrow rows of the Q-transform. This puts such lines
into a `gwml data strain` file to count the triggers they make. Each line
stands `ratio` times above the noise PSD in a 0.25 Hz bin; its amplitude
is multiplied by 1 + wander * N(0, 1) at knots `every` seconds apart,
linearly interpolated. Needs numpy, scipy and h5py.
"""
import argparse

import h5py
import numpy as np
import scipy.signal as ss

# (frequency in Hz, power above the noise PSD in a 0.25 Hz bin)
LINES = [(60.0, 1e4), (120.0, 1e3), (180.0, 1e3), (331.9, 1e3), (500.2, 3e3), (503.1, 3e3), (1003.5, 1e3)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("strain", help="a GWOSC-layout HDF5 file (gwml data strain)")
    ap.add_argument("out", help="the strain with lines, .npy")
    ap.add_argument("--wander", type=float, default=0.1, help="relative spread of a line's amplitude")
    ap.add_argument("--every", type=float, default=5.0, help="seconds between amplitude knots")
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    with h5py.File(a.strain, "r") as f:
        x = f["strain/Strain"][:]
        fs = round(1.0 / f["strain/Strain"].attrs["Xspacing"])
    freqs, psd = ss.welch(x[: 256 * fs], fs=fs, nperseg=4 * fs, average="median")
    rng = np.random.default_rng(a.seed)
    t = np.arange(len(x)) / fs
    knots = np.arange(int(t[-1] / a.every) + 2) * a.every
    y = x.copy()
    for f0, ratio in LINES:
        amplitude = np.sqrt(2 * 0.25 * ratio * np.interp(f0, freqs, psd))
        envelope = np.interp(t, knots, 1 + a.wander * rng.standard_normal(len(knots)))
        y += amplitude * envelope * np.cos(2 * np.pi * f0 * t + rng.uniform(0, 2 * np.pi))
    np.save(a.out, y)
    print(f"wrote {a.out}: {len(y) / fs:.0f} s with {len(LINES)} lines")


if __name__ == "__main__":
    main()
