#!/usr/bin/env python3
"""Recovery and labelling of `gwml scan` against the truth of `gwml data strain`.

    python3 scripts/scan_recovery.py TRUTH.csv TRIGGERS.csv [--window 0.05]

An injection is found when a trigger's time (its loudest tile, as Omicron
reports it) lies within --window seconds of the span holding the central
90 % of the injection's whitened energy (the truth's start and end
columns; for a short glitch, its centre); its label is that of the
loudest such trigger. A long glitch (a Scratchy's arches, a Whistle's
sweep) has no single time, and its loudest tile may fall anywhere in
it. The figure against the centre alone (gps_time) is printed too.
Prints the found and correctly-labelled fractions, per class, and
triggers matched to no injection (within 1 s). Standard library only.
"""
import argparse
import csv
from collections import Counter, defaultdict


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("truth")
    ap.add_argument("triggers")
    ap.add_argument("--window", type=float, default=0.05)
    a = ap.parse_args()
    truth = list(csv.DictReader(open(a.truth)))
    trig = list(csv.DictReader(open(a.triggers)))
    times = sorted((float(r["gps_time"]), r) for r in trig)
    found, right = Counter(), Counter()
    total = Counter(t["label"] for t in truth)
    confusion = defaultdict(Counter)
    by_centre = 0
    for t in truth:
        g = float(t["gps_time"])
        lo, hi = (float(t["start"]), float(t["end"])) if "start" in t else (g, g)
        near = [r for (x, r) in times if lo - a.window <= x <= hi + a.window]
        by_centre += any(abs(x - g) <= a.window for (x, _) in times)
        if near:
            found[t["label"]] += 1
            label = max(near, key=lambda r: float(r["snr"]))["label"]
            confusion[t["label"]][label] += 1
            right[t["label"]] += label == t["label"]
    stray = sum(1 for (x, _) in times if not any(abs(x - float(t["gps_time"])) <= 1.0 for t in truth))
    n, f, r = sum(total.values()), sum(found.values()), sum(right.values())
    print(f"{n} injections: found {f} ({100 * f / max(n, 1):.1f} %) within ±{a.window * 1000:.0f} ms, "
          f"right label {r} ({100 * r / max(f, 1):.1f} % of found); {len(trig)} triggers, {stray} near no injection")
    print(f"  within ±{a.window * 1000:.0f} ms of the centre alone: {by_centre} ({100 * by_centre / max(n, 1):.1f} %)")
    for c in sorted(total):
        print(f"  {c:10s} found {found[c]:4d}/{total[c]:4d}, right {right[c]:4d}; labelled as {dict(confusion[c])}")


if __name__ == "__main__":
    main()
