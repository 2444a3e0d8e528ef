#!/usr/bin/env python3
"""How far the shipped classifier's template bank reaches for quiet blips:
a detection proxy for issue #25's target (>= 95 % of realistic blips at
SNR 8 labelled Blip).

For each weights file given (a `template_net` checkpoint: params lfK, lqK
are the log central frequency and log Q of sine-Gaussian template K), the
statistic of a whitened 1 s window is the largest matched-filter SNR over
the bank's sine-Gaussians and over time (both phases, band 20-2000 Hz).
The threshold is its 97th percentile over None windows (`gwml data glitch
--centred --class none`: noise with its flaws and weak transients) and
fresh white noise; the table gives the share of real-fit Blips at each SNR
above it. Real-fit Blips are the held-out real H1/L1 Blip fits of
scripts/generator_shape_sets.py, band-limited and centred at 0.4-0.6 s as
scripts/blip_realism.py draws them (a different seed by default).

The classifier's head sees more than this maximum, so the share is a
ceiling on what a bank lets it detect, not its accuracy.

Usage: python3 scripts/blip_bank_reach.py WEIGHTS.safetensors [...]
           [--gwml target/release/gwml] [--n 400] [--seed 8] [--snr 7,8,10]
Needs numpy.
"""
import argparse
import functools
import json
import os
import struct
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from blip_realism import noisy_row  # noqa: E402
from generator_shape_sets import FS, N, realfit  # noqa: E402

F = np.fft.rfftfreq(N, 1 / FS)
BAND = (F >= 20) & (F <= 2000)


def read_safetensors(path):
    """The tensors of a safetensors file (8-byte header length, JSON header, data)."""
    raw = open(path, "rb").read()
    n = struct.unpack("<Q", raw[:8])[0]
    header = json.loads(raw[8:8 + n])
    kinds = {"F32": np.float32, "F64": np.float64}
    out = {}
    for name, v in header.items():
        if name == "__metadata__":
            continue
        start, end = v["data_offsets"]
        out[name] = np.frombuffer(raw[8 + n + start:8 + n + end], dtype=kinds[v["dtype"]]).reshape(v["shape"])
    return out


def bank(weights):
    """(f0, Q) of every sine-Gaussian in a template_net checkpoint."""
    w = read_safetensors(weights)
    k, out = 1, []
    while f"lf{k}" in w:
        out.append((float(np.exp(w[f"lf{k}"].ravel()[0])), float(np.exp(w[f"lq{k}"].ravel()[0]))))
        k += 1
    return out


def sine_gaussian_fd(f0, q):
    """Its spectrum's positive-frequency lobe (std::burst::sine_gaussian_fd at t0 = 0), in band, unit norm."""
    tau = q / (np.sqrt(2) * np.pi * f0)
    h = np.exp(-(np.pi * tau * (F - f0)) ** 2) * BAND
    return h / np.linalg.norm(h)


def largest_snr(x, templates):
    """Per row of x: the largest |complex matched-filter SNR| over templates and time."""
    d = np.fft.rfft(x, axis=1)
    best = np.zeros(len(x))
    pad = np.zeros((len(x), N - len(F)))
    for h in templates:
        # Unit-variance white noise has rfft bins of variance N; the complex
        # SNR of a unit-norm one-sided template is sum(d conj h) e^{2 pi i f t} * sqrt(2/N).
        z = np.fft.ifft(np.concatenate([d * np.conj(h), pad], axis=1), axis=1) * N
        best = np.maximum(best, np.abs(z).max(axis=1) * np.sqrt(2.0 / N))
    return best


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("weights", nargs="+")
    p.add_argument("--gwml", default="target/release/gwml")
    p.add_argument("--n", type=int, default=400)
    p.add_argument("--seed", type=int, default=8)
    p.add_argument("--snr", default="7,8,10")
    a = p.parse_args()
    rng = np.random.default_rng(a.seed)
    t = np.arange(N) / FS
    with tempfile.TemporaryDirectory() as work:
        path = os.path.join(work, "none.npz")
        subprocess.run([a.gwml, "data", "glitch", "--centred", "--class", "none", "--n", str(a.n),
                        "--seed", str(a.seed), "--out", path], check=True, stdout=subprocess.DEVNULL)
        noise = np.concatenate([np.load(path)["x"], rng.standard_normal((a.n, N))])
    snrs = [float(s) for s in a.snr.split(",")]
    blip = functools.partial(realfit, label="Blip")
    blips = {snr: np.array([noisy_row(blip, rng, t, snr) for _ in range(a.n)]) for snr in snrs}
    print(f"share of real-fit Blips above the 97th percentile of None windows ({a.n} per cell)\n")
    print("| weights | templates | threshold | " + " | ".join(f"SNR {s:g}" for s in snrs) + " |")
    print("|---|---|---|" + "---|" * len(snrs))
    for weights in a.weights:
        templates = [sine_gaussian_fd(f0, q) for f0, q in bank(weights)]
        threshold = np.percentile(largest_snr(noise, templates), 97)
        cells = [f"{100 * np.mean(largest_snr(blips[s], templates) > threshold):.1f} %" for s in snrs]
        print(f"| {weights} | {len(templates)} | {threshold:.2f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
