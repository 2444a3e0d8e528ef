"""gwml from Python on W1, side by side with ripplegw in the same process.

    /work/venv-peers/bin/python benches/peers/python_api.py [--reps N]

(a virtualenv with ripplegw, jax and the gwml package built in release:
`VIRTUAL_ENV=... maturin develop --release` in python/, or
`pip install ./python`). Pinned to one core. Measures, as medians:
- the call overhead of `Scene.value_and_grad` from Python over the same
  call made from Rust (`Scene._time_native`), on W1 full band and with
  multibanding (2e-3 rad) and relative binning (100 bins);
- `jax.jit(jax.grad(f))` through `gwml.jax.function` against calling
  `Scene.value_and_grad` directly;
- W1 full-band value and gradient from Python against ripplegw's
  `jax.jit(jax.value_and_grad(loss))` (the loss of peers.py's ripple rows).
"""

import argparse
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from peers import POINT, REPO, median_us, pin_cpu, time_ripple  # noqa: E402  (sets the one-thread environment)

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402

import gwml  # noqa: E402
import gwml.jax  # noqa: E402

jax.config.update("jax_enable_x64", True)
NAMES = ["mc", "q", "tc", "phic"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=2000)
    args = ap.parse_args()
    pinned = pin_cpu(0)
    reps = args.reps
    warm = max(reps // 10, 20)

    model = gwml.compile(os.path.join(REPO, "benches", "w1.gw"))
    data = model.scene("w1_strain_full").run()["h"]
    params = dict(zip(NAMES, POINT))
    x = jnp.array(POINT)
    print(f"gwml Python package on W1 at {params}; {pinned}; medians of {reps} calls")
    rows = {}
    for label, scene_name in (("full band", "w1_fit_full"), ("multiband", "w1_fit_banded"), ("relbin 100", "w1_fit_relbin")):
        scene = model.scene(scene_name)
        scene.bind({"d": data})
        native = scene._time_native(params, grad=True, repeats=reps)
        python = median_us(lambda: scene.value_and_grad(params), reps, warm)
        f = gwml.jax.function(scene, "loss", NAMES)
        grad = jax.jit(jax.grad(f))
        jax_us = median_us(lambda: grad(x).block_until_ready(), reps, warm)
        value_and_grad = jax.jit(jax.value_and_grad(f))
        jax_vg_us = median_us(lambda: jax.block_until_ready(value_and_grad(x)), reps, warm)
        loss = scene.value_and_grad(params)[0]["loss"]
        rows[label] = dict(native=native, python=python, jax=jax_us, jax_vg=jax_vg_us, loss=loss)
        print(
            f"{label:11} Rust {native:8.2f} µs  Python {python:8.2f} µs  (+{python - native:5.2f} µs)  "
            f"jax.jit(grad) {jax_us:8.2f} µs ({jax_us / python:.2f}× direct)  "
            f"jax.jit(value_and_grad) {jax_vg_us:8.2f} µs ({jax_vg_us / python:.2f}×)  loss {loss:.6g}"
        )
    ripple = time_ripple(reps, cut=False)
    r_us = ripple["value_and_grad_us"]
    print(f"ripplegw {ripple['version']} (jax {ripple['jax']}) jit(value_and_grad) {r_us:.1f} µs, loss {ripple['loss']:.6g}")
    for label, row in rows.items():
        print(f"  {label:11} from Python: {r_us / row['python']:6.1f}× faster than ripplegw; through jax.jit(grad): {r_us / row['jax']:6.1f}×")


if __name__ == "__main__":
    main()
