#!/usr/bin/env python3
"""PyTorch CPU peer of benches/cnn.rs, in float64 and float32, on 1 and 2
threads, for its two workloads: `burst`, the burst-detection CNN of
examples/burst_cnn.gw trained and evaluated on sine-Gaussian bursts in
white noise, and `glitch`, the CNN of benches/glitch_cnn.gw (the shape
issue #4 names) on white noise with random labels.

Setup (a venv outside the repository):

    python3 -m venv /work/venv-torch && /work/venv-torch/bin/pip install torch --index-url https://download.pytorch.org/whl/cpu numpy
    # (or plain PyPI when that index is unreachable: /work/venv-torch/bin/pip install torch numpy)
    /work/venv-torch/bin/python benches/peers/cnn_torch.py           # both workloads
    /work/venv-torch/bin/python benches/peers/cnn_torch.py glitch    # one of them

The network is the same as gwml's: input 256 samples (1 channel),
conv1d 8x1x16 padding 8 + ReLU, max pool 4 (257 -> 64), conv1d 16x8x8
padding 4 + ReLU (64 -> 65), max pool 65 (global), dense 2x16, softmax
cross-entropy on 2 classes; Adam lr 3e-3, batch 32. The data (not timed)
follows gwml_runtime::synth::bursts: unit white noise, half the rows with a
sine-Gaussian (f0 20..100 Hz, Q 3..12, SNR 6..15, t0 in the middle half)
at 256 Hz.

The glitch network: input 4,096 samples, conv1d 8x1x16 padding 8 + ReLU,
max pool 4 (4097 -> 1024), conv1d 16x8x8 padding 4 + ReLU, max pool 4
(1025 -> 256), conv1d 32x16x8 padding 4 + ReLU, max pool 4 (257 -> 64),
conv1d 32x32x8 padding 4 + ReLU (65), max pool 65 (global), dense 6x32.

Timed, median of REPS (default 7) after a warm-up, over 1,024 examples:
- infer: forward pass (no grad) over batches of 32 (logits + loss);
- train: one epoch of zero_grad / forward / loss / backward / Adam step
  over shuffled batches of 32.
Prints examples/s and the peak RSS (ru_maxrss) at the end. Lines starting
with `torch_` are machine-readable (`name value`).
"""

import os
import resource
import sys
import time

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

EXAMPLES = 1024
BATCH = 32
RATE, SAMPLES = 256.0, 256
REPS = int(os.environ.get("GWML_BENCH_REPS", "7"))


def bursts(n, seed):
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((n, SAMPLES))
    labels = rng.random(n) < 0.5
    t = np.arange(SAMPLES) / RATE
    duration = SAMPLES / RATE
    for i in np.nonzero(labels)[0]:
        f0 = rng.uniform(20.0, 100.0)
        q = rng.uniform(3.0, 12.0)
        snr = rng.uniform(6.0, 15.0)
        t0 = rng.uniform(0.25 * duration, 0.75 * duration)
        phi = rng.uniform(0.0, 2 * np.pi)
        tau = q / (np.sqrt(2) * np.pi * f0)
        dt = t - t0
        h = np.exp(-((dt / tau) ** 2)) * np.cos(2 * np.pi * f0 * dt + phi)
        x[i] += snr * h / np.sqrt(np.sum(h * h))
    return x, labels.astype(np.int64)


class Cnn(nn.Module):
    def __init__(self):
        super().__init__()
        self.c1 = nn.Conv1d(1, 8, 16, padding=8)
        self.c2 = nn.Conv1d(8, 16, 8, padding=4)
        self.d = nn.Linear(16, 2)
        for c in (self.c1, self.c2):
            nn.init.kaiming_normal_(c.weight, nonlinearity="relu")
            nn.init.zeros_(c.bias)
        nn.init.xavier_normal_(self.d.weight)
        nn.init.zeros_(self.d.bias)

    def forward(self, x):
        h1 = F.max_pool1d(F.relu(self.c1(x)), 4)  # 257 -> 64
        h2 = F.relu(self.c2(h1))  # 65
        return self.d(F.max_pool1d(h2, 65).flatten(1))


class GlitchCnn(nn.Module):
    def __init__(self):
        super().__init__()
        self.convs = nn.ModuleList(
            [nn.Conv1d(1, 8, 16, padding=8), nn.Conv1d(8, 16, 8, padding=4), nn.Conv1d(16, 32, 8, padding=4), nn.Conv1d(32, 32, 8, padding=4)]
        )
        self.d = nn.Linear(32, 6)
        for c in self.convs:
            nn.init.kaiming_normal_(c.weight, nonlinearity="relu")
            nn.init.zeros_(c.bias)
        nn.init.xavier_normal_(self.d.weight)
        nn.init.zeros_(self.d.bias)

    def forward(self, x):
        for c in self.convs[:3]:
            x = F.max_pool1d(F.relu(c(x)), 4)
        h4 = F.relu(self.convs[3](x))  # 65
        return self.d(F.max_pool1d(h4, 65).flatten(1))


def noise(n, samples, classes, seed):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, samples)), rng.integers(0, classes, n)


def median_s(f):
    for _ in range(REPS // 10 + 1):
        f()
    t = []
    for _ in range(REPS):
        s = time.perf_counter()
        f()
        t.append(time.perf_counter() - s)
    return sorted(t)[REPS // 2]


def bench(tag, model_class, x_np, y_np):
    for dtype, prec in ((torch.float64, "f64"), (torch.float32, "f32")):
        x = torch.from_numpy(x_np).to(dtype).unsqueeze(1)
        y = torch.from_numpy(y_np)
        for threads in (1, 2):
            torch.set_num_threads(threads)
            torch.manual_seed(0)
            model = model_class().to(dtype)
            opt = torch.optim.Adam(model.parameters(), lr=3e-3)
            gen = torch.Generator().manual_seed(7)

            def infer():
                with torch.no_grad():
                    for i in range(0, EXAMPLES, BATCH):
                        F.cross_entropy(model(x[i : i + BATCH]), y[i : i + BATCH])

            def train():
                order = torch.randperm(EXAMPLES, generator=gen)
                for i in range(0, EXAMPLES, BATCH):
                    idx = order[i : i + BATCH]
                    opt.zero_grad(set_to_none=True)
                    loss = F.cross_entropy(model(x[idx]), y[idx])
                    loss.backward()
                    opt.step()

            for name, f in (("infer", infer), ("train", train)):
                s = median_s(f)
                per_s = EXAMPLES / s
                print(f"  {prec} {name}_{threads}thread {s * 1e3:10.2f} ms {per_s:14.0f} examples/s {s * 1e6 / EXAMPLES:10.2f} us/example")
                print(f"torch_{tag}_{prec}_{name}_{threads}thread_examples_per_s {per_s:.1f}")


def main():
    which = [a for a in sys.argv[1:] if not a.startswith("-")]
    if not which or "burst" in which:
        x_np, y_np = bursts(EXAMPLES, 1)
        print(f"torch {torch.__version__}: burst CNN, {EXAMPLES} examples of {SAMPLES} samples, batch {BATCH}, median of {REPS}")
        bench("cnn", Cnn, x_np, y_np)
    if not which or "glitch" in which:
        x_np, y_np = noise(EXAMPLES, 4096, 6, 1)
        print(f"torch {torch.__version__}: glitch CNN, {EXAMPLES} examples of 4096 samples, batch {BATCH}, median of {REPS}")
        bench("glitch_cnn", GlitchCnn, x_np, y_np)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"  peak RSS: {peak:.1f} MiB")
    print(f"torch_cnn_peak_rss_mib {peak:.1f}")


if __name__ == "__main__":
    main()
