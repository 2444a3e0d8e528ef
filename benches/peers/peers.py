#!/usr/bin/env python3
"""Side-by-side peer timing of the standard workload W1: gwml vs LALSimulation vs ripplegw (JAX).

W1: TaylorF2 3.5PN, m1 = 36, m2 = 29 Msun, non-spinning, 400 Mpc, 20..1024 Hz
at df = 1/8 Hz (8,033 bins), float64, one thread.

Three variants of the strain, each measured in all three codes:
  cut             zero above the Schwarzschild ISCO f_isco = 1/(6^1.5 pi M) (67.6 Hz
                  here, 382 nonzero bins), std::taylorf2's model. gwml: scenes
                  `w1_strain`, `w1_fit`; its kernels split their loop at the cut
                  and evaluate the waveform below it only. LAL: f_max = 0, which
                  is LAL's own ISCO cut (a 542-bin series, 382 nonzero; its loop
                  stops at the ISCO too). ripple: the strain through
                  jnp.where(f <= f_isco, h, 0), as a JAX user would write the cut
                  (XLA still evaluates every bin).
  full            no cut, all 8,033 bins: gwml scenes `w1_strain_full`,
                  `w1_fit_full`; LAL f_max = 1024 (a 0..1024 Hz series of 8,193
                  bins, 8,033 nonzero); ripple as is.
  full, multiband gwml scenes `w1_strain_banded`, `w1_fit_banded`: the full
                  band with `multiband: 2e-3` (the phase computed on a coarse
                  subset of the bins, e^{i Psi} by rotation between them; its
                  mismatch and loss/gradient errors against gwml's exact full
                  band are printed); LAL and ripple exact, as in "full".
  relative binning
                  the full-band likelihood by relative binning over 100 bins:
                  gwml scene `w1_fit_relbin` (`relative_binning: 100`, fiducial
                  at the true system) beside jimgw's
                  HeterodynedTransientLikelihoodFD with n_bins = 100 on the same
                  W1 data (benches/peers/jimgw_heterodyne.py: ripplegw's
                  TaylorF2 projected on H1 from its zenith, face-on, which
                  reproduces W1's loss; fiducial the true system), and the
                  exact ripple likelihood. Each code's |Delta ln L| against its
                  own full likelihood at the evaluation point is printed.

Measured (median of --reps calls after warm-up, wall clock):
  forward         gwml: complex strain out (benches/taylorf2.rs)
                  LAL:  lalsimulation.SimInspiralChooseFDWaveform(..., TaylorF2),
                        f_min = 20, f_ref = 0, default (highest, 3.5PN) phase order,
                        Newtonian amplitude
                  ripple: jax.jit of ripplegw's gen_TaylorF2 (the function API in
                        ripplegw/waveforms/cbc/Taylor/TaylorF2.py; lambdas = 0),
                        block_until_ready
  value_and_grad  L = 0.5 (d-h|d-h) = 0.5 * 4 df sum |d-h|^2 / S(f), w.r.t.
                  (Mc, q, tc, phic); gwml: fused kernel; ripple:
                  jax.jit(jax.value_and_grad(L)) over a 4-vector (Mc, q, tc, phic);
                  ripple is parameterised by eta, so L converts eta = q/(1+q)^2
                  inside the jitted function (the gradient is w.r.t. q, as gwml's).
                  LAL has no gradient.
  S(f)            the toy PSD of examples/taylorf2_fit.gw: 1e-47 (y^-4 + 2 + 2 y^2),
                  y = f / 150 Hz, precomputed once as an array (gwml folds it into a
                  table at scene compile time, the same footing).
  data d          each code's own model (of the variant) at the true params
                  (Mc = 28.0956, q = 29/36, tc = 0, phic = 0); evaluation point
                  Mc = 28.1, q = 0.8, tc = 0.0005 s, phic = 0.1.
  grid            the frequency array is a closure constant of the jitted JAX
                  functions (gwml's grid is a compile-time constant too).

Differences that remain (stated, not fixed): ripple evaluates the tidal phase
terms (with lambda = 0) and its own f_ref = 20 Hz constant, so loss values
differ between gwml and ripple; timings are of the same grid and arithmetic.

JAX compilation (trace + XLA compile, the first call) is excluded from the
medians and reported separately; so is gwml's scene compilation.

Setup (a venv OUTSIDE the repository; nothing is created inside it):

    python3 -m venv /work/venv-peers
    /work/venv-peers/bin/pip install lalsuite ripplegw "jax[cpu]" numpy jimgw==0.5.2

(measured with lalsuite 7.26.16, ripplegw 0.4.1, jax/jaxlib 0.10.2, numpy 2.4.6,
jimgw 0.5.2 (0.6 needs Python >= 3.12); without jimgw its rows are skipped)

Run (from the repository root):

    taskset -c 0 env OMP_NUM_THREADS=1 \\
      XLA_FLAGS="--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1" \\
      /work/venv-peers/bin/python benches/peers/peers.py

The script sets those variables itself (before importing jax) and pins itself
and its children to one CPU with os.sched_setaffinity, so a plain
`/work/venv-peers/bin/python benches/peers/peers.py` is equivalent. It then runs
`cargo bench --bench taylorf2` (pinned to the same CPU), or reads that
bench's output from a file given with --gwml-output, and prints the table.
"""

import argparse
import os
import subprocess
import sys
import time

# One thread, before numpy/jax/lal are imported.
os.environ["OMP_NUM_THREADS"] = "1"
os.environ["OPENBLAS_NUM_THREADS"] = "1"
os.environ["MKL_NUM_THREADS"] = "1"
os.environ["XLA_FLAGS"] = (
    os.environ.get("XLA_FLAGS", "") + " --xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1"
).strip()
os.environ["JAX_PLATFORMS"] = "cpu"

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

M1, M2 = 36.0, 29.0
MTSUN = 4.925490947641267e-6  # G Msun / c^3 in s (LAL's MTSUN_SI)
DIST_MPC = 400.0
F_MIN, F_MAX, DF = 20.0, 1024.0, 0.125
NBINS = int(round((F_MAX - F_MIN) / DF)) + 1  # 8033
MC_TRUE = (M1 * M2) ** 0.6 / (M1 + M2) ** 0.2
Q_TRUE = M2 / M1
POINT = (28.1, 0.8, 0.0005, 0.1)  # Mc, q, tc, phic (as benches/taylorf2.rs)


def pin_cpu(cpu):
    try:
        os.sched_setaffinity(0, {cpu})
        return f"cpu {cpu} (os.sched_setaffinity)"
    except (AttributeError, OSError) as e:
        return f"not pinned ({e})"


def median_us(fn, reps, warm):
    for _ in range(warm):
        fn()
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        fn()
        ts.append((time.perf_counter() - t0) * 1e6)
    ts.sort()
    return ts[len(ts) // 2]


def time_lal(reps, f_max):
    """LAL's TaylorF2 with the given f_max (0: LAL's ISCO cut): median µs, series length, nonzero bins."""
    import lal
    import lalsimulation as ls

    params = lal.CreateDict()
    dist_m = DIST_MPC * 1e6 * lal.PC_SI

    def call():
        return ls.SimInspiralChooseFDWaveform(
            M1 * lal.MSUN_SI, M2 * lal.MSUN_SI, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
            dist_m, 0.0, 0.0, 0.0, 0.0, 0.0, DF, F_MIN, f_max, 0.0, params, ls.TaylorF2)

    hp, _ = call()
    nonzero = int((abs(hp.data.data) > 0).sum())
    us = median_us(call, reps, max(reps // 10, 5))
    return us, hp.data.length, nonzero


def time_ripple(reps, cut):
    """ripplegw's TaylorF2 (masked at the ISCO with jnp.where if `cut`): forward, likelihood, value_and_grad."""
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np
    from ripplegw.waveforms.cbc.Taylor.TaylorF2 import gen_TaylorF2
    import ripplegw

    f_np = F_MIN + DF * np.arange(NBINS)
    f = jnp.asarray(f_np)
    y = f_np / 150.0
    psd = jnp.asarray(1e-47 * (y ** -4.0 + 2.0 + 2.0 * y ** 2.0))
    f_ref = 20.0

    def theta(mc, q, tc, phic):
        eta = q / (1.0 + q) ** 2
        z = jnp.zeros_like(mc)
        return jnp.stack([mc, eta, z, z, z, z, z + DIST_MPC, tc, phic])

    def strain(p):
        h = gen_TaylorF2(f, theta(p[0], p[1], p[2], p[3]), f_ref, use_lambda_tildes=False)
        if not cut:
            return h
        total_mass = p[0] * (p[1] / (1.0 + p[1]) ** 2) ** -0.6
        f_isco = 1.0 / (6.0 ** 1.5 * np.pi * total_mass * MTSUN)
        return jnp.where(f <= f_isco, h, 0.0)

    p_true = jnp.array([MC_TRUE, Q_TRUE, 0.0, 0.0])
    p = jnp.array(POINT)
    fwd = jax.jit(strain)
    t0 = time.perf_counter()
    d = fwd(p_true).block_until_ready()  # first call: trace + compile of the forward
    fwd_compile_ms = (time.perf_counter() - t0) * 1e3
    assert d.dtype == jnp.complex128 and d.shape == (NBINS,), (d.dtype, d.shape)

    def loss(p):
        r = d - strain(p)
        return 0.5 * 4.0 * DF * jnp.sum((r.real ** 2 + r.imag ** 2) / psd)

    out = {"version": ripplegw.__version__, "jax": jax.__version__}
    for name, fn in (("forward", fwd), ("loss_forward", jax.jit(loss)),
                     ("value_and_grad", jax.jit(jax.value_and_grad(loss)))):
        t0 = time.perf_counter()
        jax.block_until_ready(fn(p))
        out[name + "_compile_ms"] = (time.perf_counter() - t0) * 1e3 if name != "forward" else fwd_compile_ms
        out[name + "_us"] = median_us(lambda: jax.block_until_ready(fn(p)), reps, max(reps // 10, 5))
    val, g = jax.jit(jax.value_and_grad(loss))(p)
    out["loss"] = float(val)
    out["grad"] = [float(x) for x in g]
    return out


def gwml_results(path):
    if path:
        text = open(path).read()
    else:
        r = subprocess.run(["cargo", "bench", "--bench", "taylorf2"], cwd=REPO, capture_output=True, text=True)
        if r.returncode != 0:
            sys.exit(f"cargo bench failed:\n{r.stderr[-3000:]}")
        text = r.stdout
    vals = {}
    for line in text.splitlines():
        parts = line.split()
        if len(parts) == 2 and parts[0].startswith("gwml_"):
            vals[parts[0]] = float(parts[1])
    return vals, text


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reps", type=int, default=400)
    ap.add_argument("--gwml-output", help="read `cargo bench --bench taylorf2` output from this file")
    ap.add_argument("--cpu", type=int, default=0, help="CPU to pin to (default 0)")
    args = ap.parse_args()

    pinned = pin_cpu(args.cpu)
    print(f"W1: TaylorF2 3.5PN, m1 = {M1}, m2 = {M2} Msun, {NBINS} bins "
          f"({F_MIN}..{F_MAX} Hz, df = {DF}), f64, one thread; pinned: {pinned}; median of {args.reps}")

    gw, _ = gwml_results(args.gwml_output)
    rows = []
    variants = (("cut at ISCO", "", 0.0), ("full band", "_full", F_MAX), ("full, multiband", "_banded", F_MAX))
    for variant, suffix, f_max in variants:
        # The multibanded gwml scenes approximate the full band: the peers
        # compute the full band exactly, timed again beside them.
        lal_us, lal_len, lal_nz = time_lal(args.reps, f_max)
        rp = time_ripple(args.reps, cut=(suffix == ""))
        print(f"{variant}: LAL (f_max = {f_max}) {lal_len} bins in the series, {lal_nz} nonzero; "
              f"ripplegw {rp['version']}, jax {rp['jax']}")
        print(f"  gwml scene compile: {gw.get('gwml_compile' + suffix + '_ms', float('nan')):.1f} ms; "
              f"JAX trace+compile (first call): forward {rp['forward_compile_ms']:.1f} ms, "
              f"loss {rp['loss_forward_compile_ms']:.1f} ms, value_and_grad {rp['value_and_grad_compile_ms']:.1f} ms")
        print(f"  loss at (Mc, q, tc, phic) = {POINT}: gwml {gw.get('gwml_loss' + suffix, float('nan')):.6e}, "
              f"ripple {rp['loss']:.6e} (ripple's tidal terms and f_ref differ; not expected to agree)")
        print(f"  ripple grad (Mc, q, tc, phic): {', '.join(f'{x:.4e}' for x in rp['grad'])}")
        print("  gwml   grad (Mc, q, tc, phic): " + ", ".join(
            f"{gw.get('gwml_grad_' + n + suffix, float('nan')):.4e}" for n in ("mc", "q", "tc", "phic")))
        g = {k: gw["gwml_" + k + suffix + "_us"] for k in ("forward", "loss_forward", "value_and_grad")}
        rows.append((f"forward, {variant}", g["forward"], lal_us, rp["forward_us"]))
        rows.append((f"likelihood, {variant}", g["loss_forward"], None, rp["loss_forward_us"]))
        rows.append((f"value_and_grad, {variant}", g["value_and_grad"], None, rp["value_and_grad_us"]))
        print(f"peers_lal_forward{suffix}_us {lal_us:.3f}")
        for k in ("forward", "loss_forward", "value_and_grad"):
            print(f"peers_ripple_{k}{suffix}_us {rp[k + '_us']:.3f}")
            print(f"peers_ripple_{k}{suffix}_compile_ms {rp[k + '_compile_ms']:.3f}")
    # Relative binning: gwml and jimgw at 100 bins, ripple's exact likelihood.
    if "gwml_value_and_grad_relbin_us" in gw:
        try:
            sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
            import jimgw_heterodyne

            jim = jimgw_heterodyne.run(args.reps, [100])
        except ImportError as e:
            print(f"jimgw not importable ({e}): its relative-binning rows are skipped")
            jim = {}
        rp = time_ripple(args.reps, cut=False)
        print(f"relative binning, 100 bins: gwml |dlnL| {gw.get('gwml_relbin_dlogl', float('nan')):.2e}, "
              f"gradient rel. error {gw.get('gwml_relbin_grad_error', float('nan')):.2e}; "
              f"jimgw {jim.get('version', '-')} |dlnL| {jim.get('peers_jimgw_het100_dlogl', float('nan')):.2e}, "
              f"gradient rel. error (2-norm) {jim.get('peers_jimgw_het100_grad_rel_err', float('nan')):.2e}")
        for kind, g_key, j_key in (("likelihood", "loss_forward", "loglike"), ("value_and_grad", "value_and_grad", "value_and_grad")):
            g = gw[f"gwml_{g_key}_relbin_us"]
            rows.append((f"{kind}, relbin 100 (jimgw)", g, jim.get(f"peers_jimgw_het100_{j_key}_us"), rp[f"{g_key}_us"]))
            print(f"peers_ripple_{g_key}_relbin_us {rp[g_key + '_us']:.3f}")
    if "gwml_banded_mismatch" in gw:
        print(f"multiband 2e-3 against gwml's exact full band: mismatch {gw['gwml_banded_mismatch']:.2e}, "
              f"loss rel. error {gw['gwml_banded_loss_error']:.2e}, gradient rel. error {gw['gwml_banded_grad_error']:.2e}")
    print()
    # For the relative-binning rows the middle peer is jimgw's heterodyned likelihood.
    hdr = f"| {'measurement':<34} | {'gwml µs':>9} | {'LAL/jim µs':>10} | {'ripple µs':>9} | {'peer/gwml':>9} | {'ripple/gwml':>11} |"
    print(hdr)
    print("|" + "|".join("-" * (len(c)) for c in hdr.split("|")[1:-1]) + "|")
    for name, g, lal_us, rp_us in rows:
        lal_cell = f"{lal_us:>10.1f}" if lal_us else f"{'-':>10}"
        lal_ratio = f"{lal_us / g:>9.2f}" if lal_us else f"{'-':>9}"
        print(f"| {name:<34} | {g:>9.1f} | {lal_cell} | {rp_us:>9.1f} | {lal_ratio} | {rp_us / g:>11.2f} |")


if __name__ == "__main__":
    main()
