#!/usr/bin/env python3
"""PSD estimation and whitening of long strain, gwml against gwpy, same file.

    gwml data strain --duration 4096 --out /tmp/s4096.hdf5 --seed 42
    python benches/peers/psd_whiten.py /tmp/s4096.hdf5 [--gwml target/release/gwml] [--reps 3]

gwpy (from PyPI): TimeSeries.read(path, format='hdf5.gwosc'), then
ts.psd(fftlength=4, overlap=2, method='median', window='hann') and
ts.whiten(fftlength=4, overlap=2, method='median', window='hann') (one PSD
for the whole file; whitening by a FIR filter). gwml: `gwml scan --threads 1
--no-classify`, whose summary gives the CPU time of its PSD stage (a Welch
median estimate for every 64 s chunk, from the 128 s around it: 64 PSDs
for 4096 s) and of its whitening stage (the gwml scene, two bands, per
chunk). Both single-threaded; medians of --reps runs. The machine is noisy:
quote the ratio.
"""
import argparse
import re
import statistics
import subprocess
import time


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("file")
    ap.add_argument("--gwml", default="target/release/gwml")
    ap.add_argument("--reps", type=int, default=3)
    a = ap.parse_args()
    from gwpy.timeseries import TimeSeries

    read, psd, whiten = [], [], []
    for _ in range(a.reps):
        t = time.perf_counter()
        ts = TimeSeries.read(a.file, format="hdf5.gwosc")
        read.append(time.perf_counter() - t)
        t = time.perf_counter()
        ts.psd(fftlength=4, overlap=2, method="median", window="hann")
        psd.append(time.perf_counter() - t)
        t = time.perf_counter()
        ts.whiten(fftlength=4, overlap=2, method="median", window="hann")
        whiten.append(time.perf_counter() - t)
    g_psd, g_white, g_read = [], [], []
    for _ in range(a.reps):
        out = subprocess.run([a.gwml, "scan", a.file, "--threads", "1", "--no-classify", "--out", "/tmp/psd_whiten_triggers.csv"],
                             check=True, capture_output=True, text=True).stdout
        m = re.search(r"reading \(and compiling alongside\) ([\d.]+) s.*PSD ([\d.]+), whitening ([\d.]+)", out)
        g_read.append(float(m.group(1)))
        g_psd.append(float(m.group(2)))
        g_white.append(float(m.group(3)))
    med = statistics.median
    print(f"samples {len(ts)} ({ts.duration.value:.0f} s at {ts.sample_rate.value:.0f} Hz)")
    print(f"gwpy_read_s {med(read):.3f}\ngwpy_psd_s {med(psd):.3f}\ngwpy_whiten_s {med(whiten):.3f}")
    print(f"gwml_read_and_compile_s {med(g_read):.3f}\ngwml_psd_s {med(g_psd):.3f}\ngwml_whiten_s {med(g_white):.3f}")
    print(f"| stage | gwpy s | gwml s | gwpy/gwml |\n|---|---|---|---|")
    print(f"| PSD (gwpy one, gwml {int(ts.duration.value // 64)} per-chunk) | {med(psd):.3f} | {med(g_psd):.3f} | {med(psd) / med(g_psd):.2f} |")
    print(f"| whitening (gwpy includes its own PSD) | {med(whiten):.3f} | {med(g_white):.3f} | {med(whiten) / med(g_white):.2f} |")
    both_g, both_p = med(g_psd) + med(g_white), med(whiten)
    print(f"| PSD + whitened series | {both_p:.3f} | {both_g:.3f} | {both_p / both_g:.2f} |")


if __name__ == "__main__":
    main()
