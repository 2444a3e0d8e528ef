#!/usr/bin/env python3
"""Peer timing of jimgw's relative-binning ("heterodyned") likelihood on a W1-like problem.

W1 (as benches/peers/peers.py): TaylorF2 3.5PN, m1 = 36, m2 = 29 Msun, non-spinning,
400 Mpc, 20..1024 Hz at df = 1/8 Hz (8,033 bins), float64, one pinned CPU, one thread.

jimgw setup (jimgw.core.single_event, jimgw 0.5.2):
  detector   H1 (get_H1), data of duration 8 s at 2048 Hz (rfft grid 0..1024 Hz,
             df = 1/8), likelihood band f_min = 20, f_max = 1024 Hz: 8,033 bins.
  PSD        the toy PSD of peers.py, 1e-47 (y^-4 + 2 + 2 y^2), y = f / 150 Hz
             (set on the full rfft grid; below 20 Hz it is held at its 20 Hz value,
             never used by the likelihood).
  waveform   RippleTaylorF2(f_ref=20) = ripplegw's TaylorF2 class (lambda_1 = lambda_2 = 0),
             the same model as peers.py's ripple run (its tidal terms evaluate to zero).
  projection jimgw's detector response F+ h+ + Fx hx with a time shift; the source is put
             at H1's zenith (ra = longitude + GMST, dec = latitude, psi = 0) face-on
             (iota = 0), so |F+ h+ + Fx hx| = |h0| up to H1's small arm tilts; the SNR
             is printed.
  data       Detector.inject_signal at the true parameters, zero noise (or seeded
             Gaussian noise of the PSD with --noise-seed).
  params     the likelihood is w.r.t. (M_c, q, t_c, phase_c): a 4-vector mapped to
             jimgw's param dict with eta = q / (1 + q)^2 inside the jitted function.
  fiducial   reference_parameters = the true parameters, passed directly (no CMA-ES).
  point      Mc = 28.1, q = 0.8, t_c = 0.0005 s, phase_c = 0.1, others true.

jimgw's binning (HeterodynedTransientLikelihoodFD, 0.5.2): n_bins counts BINS; the
n_bins + 1 edges are equally spaced in a PN-motivated phase proxy. Each likelihood
call evaluates the waveform twice, at the n_bins lower edges and at the n_bins upper
edges (2 n_bins points, n_bins + 1 distinct), never at bin centres; the centres
enter only the precomputed summary data (A0, A1, B0, B1).

Measured: median wall-clock µs of --reps calls after warm-up, first call (trace +
compile) excluded and reported separately, for jax.jit(loglike) and
jax.jit(jax.value_and_grad(loglike)), heterodyned per n_bins and full
(TransientLikelihoodFD, all 8,033 bins). Accuracy: |Δ ln L| (het - full) at the
point and at the fiducial, and the gradient error relative to the full likelihood.

Setup (a venv OUTSIDE the repository; jimgw 0.5.2 installs beside peers.py's packages
without changing jax or ripplegw; jimgw 0.6.0 needs Python >= 3.12):

    python3 -m venv /work/venv-peers
    /work/venv-peers/bin/pip install lalsuite ripplegw "jax[cpu]" numpy jimgw==0.5.2

(measured with jimgw 0.5.2, flowMC 0.6.4, ripplegw 0.4.1, jax/jaxlib 0.10.2, numpy 2.4.6)

Run (from the repository root; the script pins itself to CPU 0 and sets the
single-thread variables before importing jax):

    /work/venv-peers/bin/python benches/peers/jimgw_heterodyne.py [--reps 400] [--bins 50,100,200]

benches/peers/peers.py imports `run` for its relative-binning rows.
"""

import argparse
import time

# The environment (one thread, before jax is imported), the W1 constants
# and the timing helpers are peers.py's.
from peers import DF, DIST_MPC, F_MAX, F_MIN, M1, M2, MC_TRUE, POINT, Q_TRUE, median_us, pin_cpu

DURATION, SAMPLING = 1.0 / DF, 2.0 * F_MAX
TRIGGER_TIME = 1_000_000_000.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reps", type=int, default=400)
    ap.add_argument("--bins", default="50,100,200", help="comma list of jimgw n_bins (gwml's relative_binning counts bins too)")
    ap.add_argument("--noise-seed", type=int, default=None, help="add Gaussian noise of the PSD (default: none)")
    ap.add_argument("--cpu", type=int, default=0)
    args = ap.parse_args()
    pinned = pin_cpu(args.cpu)
    run(args.reps, [int(s) for s in args.bins.split(",") if s.strip()], args.noise_seed, pinned)


def run(reps, bins, noise_seed=None, pinned="by the caller"):
    """Measures the full and the heterodyned likelihoods (one per entry of
    `bins`), prints the lines described above, and returns the
    machine-readable values as a dict (`peers_jimgw_...` keys)."""
    import logging

    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import numpy as np
    import jimgw, flowMC, ripplegw
    from jimgw.core.single_event.data import PowerSpectrum
    from jimgw.core.single_event.detector import get_H1
    from jimgw.core.single_event.likelihood import HeterodynedTransientLikelihoodFD, TransientLikelihoodFD
    from jimgw.core.single_event.time_utils import greenwich_mean_sidereal_time
    from jimgw.core.single_event.waveform import RippleTaylorF2

    logging.getLogger("jimgw").setLevel(logging.WARNING)  # its INFO lines would interleave the output

    h1 = get_H1()
    f_all = np.fft.rfftfreq(int(DURATION * SAMPLING), 1.0 / SAMPLING)  # 0..1024 Hz, 8,193 bins
    y = np.maximum(f_all, F_MIN) / 150.0
    h1.set_psd(PowerSpectrum(jnp.asarray(1e-47 * (y ** -4.0 + 2.0 + 2.0 * y ** 2.0)), jnp.asarray(f_all), "toy"))

    gmst = float(greenwich_mean_sidereal_time(TRIGGER_TIME))
    true = {"M_c": MC_TRUE, "eta": Q_TRUE / (1 + Q_TRUE) ** 2, "s1_z": 0.0, "s2_z": 0.0,
            "lambda_1": 0.0, "lambda_2": 0.0, "d_L": DIST_MPC, "phase_c": 0.0, "iota": 0.0,
            "ra": (float(h1.longitude) + gmst) % (2 * np.pi), "dec": float(h1.latitude), "psi": 0.0, "t_c": 0.0}
    wf = RippleTaylorF2(f_ref=20.0)
    key = None if noise_seed is None else jax.random.key(noise_seed)
    h1.inject_signal(DURATION, SAMPLING, TRIGGER_TIME, wf, true, F_MIN, F_MAX,
                     zero_noise=key is None, rng_key=key)
    ant = h1.antenna_pattern(true["ra"], true["dec"], true["psi"], gmst)
    n_freq = len(h1.sliced_frequencies)

    def params_of(x):  # (M_c, q, t_c, phase_c) -> jimgw's parameter dict
        p = dict(true)
        p.update(M_c=x[0], eta=x[1] / (1.0 + x[1]) ** 2, t_c=x[2], phase_c=x[3])
        return p

    x_true = jnp.array([MC_TRUE, Q_TRUE, 0.0, 0.0])
    x_pt = jnp.array(POINT)

    def measure(like):
        def loglike(x):
            return like.evaluate(params_of(x))

        out = {}
        for name, fn in (("loglike", jax.jit(loglike)), ("value_and_grad", jax.jit(jax.value_and_grad(loglike)))):
            t0 = time.perf_counter()
            jax.block_until_ready(fn(x_pt))
            out[name + "_compile_ms"] = (time.perf_counter() - t0) * 1e3
            out[name + "_us"] = median_us(lambda: jax.block_until_ready(fn(x_pt)), reps, max(reps // 10, 5))
            out[name + "_fn"] = fn
        out["l_pt"], g = out["value_and_grad_fn"](x_pt)
        out["grad"] = np.asarray(g)
        out["l_pt"] = float(out["l_pt"])
        out["l_true"] = float(out["loglike_fn"](x_true))
        return out

    full = measure(TransientLikelihoodFD([h1], wf, f_min=F_MIN, f_max=F_MAX, trigger_time=TRIGGER_TIME))

    print(f"jimgw {jimgw.__version__}, flowMC {getattr(flowMC, '__version__', '?')}, "
          f"ripplegw {ripplegw.__version__}, jax {jax.__version__}")
    print(f"W1-like: RippleTaylorF2 into H1, m1 = {M1}, m2 = {M2} Msun, {DIST_MPC} Mpc, {n_freq} bins "
          f"({F_MIN}..{F_MAX} Hz, df = {DF}); pinned: {pinned}; median of {reps}")
    print(f"  H1 at zenith, face-on: F+ = {float(ant['p']):+.4f}, Fx = {float(ant['c']):+.4f}; "
          f"optimal SNR {float(h1.optimal_snr):.2f}; noise: {'none' if key is None else f'seed {noise_seed}'}")
    print(f"  full: ln L(point) = {full['l_pt']:.6f}, ln L(fiducial) = {full['l_true']:.6f}; W1 loss "
          f"0.5 (d-h|d-h) = ln L(fiducial) - ln L(point) = {full['l_true'] - full['l_pt']:.6f}"
          + ("" if key is None else " (W1 only without noise)"))
    print(f"  full grad (Mc, q, t_c, phase_c): {', '.join(f'{v:.6e}' for v in full['grad'])}")
    values = {"version": jimgw.__version__}

    def emit(key, value):
        values[key] = value
        print(f"{key} {value:.6g}")

    for k in ("loglike_us", "value_and_grad_us", "loglike_compile_ms", "value_and_grad_compile_ms"):
        emit(f"peers_jimgw_full_{k}", full[k])

    rows = [("full", n_freq, n_freq, full, None, None, None)]
    for n in bins:
        like = HeterodynedTransientLikelihoodFD([h1], wf, f_min=F_MIN, f_max=F_MAX, trigger_time=TRIGGER_TIME,
                                                n_bins=n, reference_parameters=dict(true))
        het = measure(like)
        d_pt, d_true = abs(het["l_pt"] - full["l_pt"]), abs(het["l_true"] - full["l_true"])
        g_err = float(np.linalg.norm(het["grad"] - full["grad"]) / np.linalg.norm(full["grad"]))
        comp = np.abs(het["grad"] - full["grad"]) / np.abs(full["grad"])
        print(f"het n_bins = {n}: {like.n_bins} bins, {like.n_bins + 1} edges "
              f"({float(like.freq_grid_low[0]):.3f}..{float(like.freq_grid_high[-1]):.3f} Hz), "
              f"2 x {like.n_bins} waveform points per call")
        print(f"  ln L(point) = {het['l_pt']:.6f}, |dlnL| point {d_pt:.3e}, fiducial {d_true:.3e}; "
              f"grad rel. err. (2-norm) {g_err:.3e}, per component (Mc, q, t_c, phase_c) "
              + ", ".join(f"{v:.2e}" for v in comp))
        for k in ("loglike_us", "value_and_grad_us", "loglike_compile_ms", "value_and_grad_compile_ms"):
            emit(f"peers_jimgw_het{n}_{k}", het[k])
        emit(f"peers_jimgw_het{n}_dlogl", d_pt)
        emit(f"peers_jimgw_het{n}_dlogl_fiducial", d_true)
        emit(f"peers_jimgw_het{n}_grad_rel_err", g_err)
        rows.append((f"het {n}", like.n_bins, 2 * like.n_bins, het, d_pt, d_true, g_err))

    print()
    hdr = (f"| {'likelihood':<10} | {'bins':>5} | {'wf points':>9} | {'loglike µs':>10} | {'v&g µs':>9} "
           f"| {'dlnL pt':>9} | {'dlnL fid':>10} | {'grad err':>9} |")
    print(hdr)
    print("|" + "|".join("-" * len(c) for c in hdr.split("|")[1:-1]) + "|")
    fmt = lambda v, w: f"{'-':>{w}}" if v is None else f"{v:>{w}.2e}"
    for name, nb, npts, r, d_pt, d_true, g_err in rows:
        print(f"| {name:<10} | {nb:>5} | {npts:>9} | {r['loglike_us']:>10.1f} | {r['value_and_grad_us']:>9.1f} "
              f"| {fmt(d_pt, 9)} | {fmt(d_true, 10)} | {fmt(g_err, 9)} |")
    return values


if __name__ == "__main__":
    main()
