#!/usr/bin/env python3
"""Folds a deployment class prior into a classifier's output bias.

A classifier trained on classes drawn uniformly (the benchmark population
draws each of its K classes with probability 1/K) gives posteriors for that
prior. Where it is used, the classes come in other shares: a scan only
classifies windows where a trigger crossed its threshold, and few of those
are noise. Bayes' rule moves the posteriors to the new prior by multiplying
each by prior_c / (1/K) and normalising (Saerens, Latinne & Decaestecker
2002, Neural Computation 14, 21), which for a softmax is adding
ln(prior_c * K) to logit c. Added to the last layer's bias, every user of the
weights (gwml scan, gwml predict, the Python package) sees the same
posteriors.

`--prior None=0.04` gives the None class 4 % and the other classes the rest
in equal shares. The shares used are written to the checkpoint's metadata
(`deployment_prior`, `prior_folded_into`), and a checkpoint that already
carries a folded prior is refused, so a prior is never folded twice.

Usage: python3 scripts/fold_prior.py IN.safetensors OUT.safetensors
           --manifest models/glitch-classifier/glitch-classifier.json
           --bias head.bo --prior None=0.04
Standard library only.
"""
import argparse
import json
import math
import struct

DTYPES = {"F64": "d", "F32": "f"}


def read(path):
    raw = open(path, "rb").read()
    n = struct.unpack("<Q", raw[:8])[0]
    return json.loads(raw[8 : 8 + n]), bytearray(raw[8 + n :])


def write(path, header, data):
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(text)) + text + bytes(data))


def shares(classes, given):
    """The prior of every class: the named ones as given, the rest equal."""
    unknown = set(given) - set(classes)
    if unknown:
        raise SystemExit(f"--prior names {sorted(unknown)}, not classes of the manifest {classes}")
    left = 1.0 - sum(given.values())
    rest = [c for c in classes if c not in given]
    if any(p <= 0 for p in given.values()) or left <= 0 < len(rest) or (not rest and abs(left) > 1e-9):
        raise SystemExit(f"--prior shares must be positive and sum to 1 with the unnamed classes: {given}")
    return [given.get(c, left / len(rest) if rest else 0.0) for c in classes]


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("input")
    p.add_argument("output")
    p.add_argument("--manifest", required=True)
    p.add_argument("--bias", default="head.bo", help="the output layer's bias tensor (one value per class)")
    p.add_argument("--prior", action="append", required=True, help="CLASS=SHARE, repeatable")
    a = p.parse_args()
    classes = json.load(open(a.manifest))["classes"]
    given = {}
    for item in a.prior:
        name, _, share = item.rpartition("=")
        given[name] = float(share)
    prior = shares(classes, given)
    header, data = read(a.input)
    meta = header.setdefault("__metadata__", {})
    if "deployment_prior" in meta:
        raise SystemExit(f"{a.input} already has a prior folded in: {meta['deployment_prior']}")
    if a.bias not in header:
        raise SystemExit(f"{a.input} has no tensor `{a.bias}`")
    spec = header[a.bias]
    if spec["shape"] != [len(classes)] or spec["dtype"] not in DTYPES:
        raise SystemExit(f"`{a.bias}` is {spec['dtype']} {spec['shape']}, not one float per class ({len(classes)})")
    code = "<" + DTYPES[spec["dtype"]] * len(classes)
    start, end = spec["data_offsets"]
    bias = struct.unpack(code, data[start:end])
    moved = [b + math.log(pc * len(classes)) for b, pc in zip(bias, prior)]
    data[start:end] = struct.pack(code, *moved)
    meta["deployment_prior"] = json.dumps(dict(zip(classes, prior)))
    meta["prior_folded_into"] = a.bias
    write(a.output, header, data)
    for c, pc, b, m in zip(classes, prior, bias, moved):
        print(f"{c:16s} prior {pc:.4f}  bias {b:+.4f} -> {m:+.4f}")


if __name__ == "__main__":
    main()
