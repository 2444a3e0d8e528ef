#!/usr/bin/env python3
"""Writes lab/data/real_glitch_fits.csv: the fitted parameters of 3,874 real
LIGO/Virgo glitches from antiglitch (Andrew Lundgren et al., MIT licence,
https://github.com/andrew-lundgren/antiglitch, data/all_PE_v3.json).

antiglitch fits each glitch (Gravity Spy label Blip, Koi_Fish,
Blip_Low_Frequency or Tomte; O3 data of H1, L1 and V1) with a quasi-physical
model: the strain spectrum is a Gaussian in log frequency,
    h(f) = A exp(-gbw/2 (ln f - ln f0)^2) exp(-2 pi i f t),
whitened by the detector's inverse ASD. The columns kept here are the
posterior means of f0 (Hz) and gbw, the matched-filter SNR, the peak
frequency of the whitened model (Hz) and the fit's residual (chi^2 per
degree of freedom; ~1 when the model explains the glitch, as it does for
Blips and Tomtes, and >> 1 for most Koi Fish).

These numbers are facts about real glitches; gwml uses them to draw
glitch shapes from real parameter distributions (lab/src/synth/real_fits.rs)
and to check its classifier on real-shaped blips (scripts/blip_realism.py).

It also writes lab/data/o3_asd.csv, the amplitude spectral density the
shapes are whitened with: LALSimulation's aLIGO 140 Mpc curve (LIGO-T1800545,
XLALSimNoisePSDaLIGO140MpcT1800545, an O3-like sensitivity) at 1 Hz steps
over 20-2000 Hz. Whitened by it, the fits' peak frequencies (10/50/90 %
of H1 and L1 Blips: 76/114/234 Hz) match the peak frequencies antiglitch
measured with the detectors' own ASDs (75/120/226 Hz); the design curve
gives 63/114/237 Hz and the O3-low curve 66/100/178 Hz.

Usage:
  git clone https://github.com/andrew-lundgren/antiglitch /tmp/antiglitch
  python3 -m venv /tmp/venv && /tmp/venv/bin/pip install lalsuite
  /tmp/venv/bin/python scripts/real_glitch_fits.py /tmp/antiglitch/data/all_PE_v3.json
Needs lalsuite (for the ASD).
"""
import argparse
import csv
import json

COLUMNS = ["label", "ifo", "f0", "gbw", "snr", "peak_frequency", "residual"]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("all_pe", help="antiglitch's data/all_PE_v3.json")
    p.add_argument("--out", default="lab/data/real_glitch_fits.csv")
    p.add_argument("--asd-out", default="lab/data/o3_asd.csv")
    a = p.parse_args()
    write_asd(a.asd_out)
    d = json.load(open(a.all_pe))
    keys = sorted(d["f0"], key=int)
    with open(a.out, "w", newline="") as out:
        w = csv.writer(out, lineterminator="\n")
        w.writerow(COLUMNS)
        for k in keys:
            row = [d["ml_label"][k], d["ifo"][k]]
            row += [f"{float(d[c][k]):.6g}" for c in COLUMNS[2:]]
            w.writerow(row)
    print(f"wrote {len(keys)} glitches to {a.out}")


def write_asd(path):
    import lal
    import lalsimulation

    n = 2049
    series = lal.CreateREAL8FrequencySeries("psd", 0, 0.0, 1.0, lal.DimensionlessUnit, n)
    lalsimulation.SimNoisePSDaLIGO140MpcT1800545(series, 10.0)
    with open(path, "w", newline="") as out:
        w = csv.writer(out, lineterminator="\n")
        w.writerow(["frequency_hz", "asd_per_sqrt_hz"])
        for f in range(20, 2001):
            w.writerow([f, f"{series.data.data[f] ** 0.5:.6e}"])
    print(f"wrote the aLIGO 140 Mpc (T1800545) ASD to {path}")


if __name__ == "__main__":
    main()
