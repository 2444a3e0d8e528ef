"""Fit the standard workload W1 (TaylorF2 3.5PN, 8,033 frequency bins) with
SciPy: gwml gives the loss and its gradient in one fused call, and
``scipy.optimize.minimize(jac=True)`` takes both.

    python python/examples/fit_w1.py
"""

from pathlib import Path

import numpy as np
import scipy.optimize

import gwml

W1 = Path(__file__).resolve().parents[2] / "benches" / "w1.gw"

model = gwml.compile(W1)
# The data: W1's strain at the true params (the params' defaults), no noise.
truth = {name: p.default for name, p in model.scene("w1_strain_full").params.items()}
data = model.scene("w1_strain_full").run()["h"]

fit = model.scene("w1_fit_full")
fit.bind({"d": data})  # held for every call: bound (and checked) once

names = ["mc", "q", "tc", "phic"]
# The optimiser's variables: mc in 1e-3 Msun, q in 1e-2, tc in ms and phic
# in rad, so a unit step changes the loss by a similar amount in each.
scale = np.array([1e-3, 1e-2, 1e-3, 1.0])


def loss_and_grad(x):
    outputs, grads = fit.value_and_grad(dict(zip(names, x * scale)))
    return outputs["loss"], np.array([grads["loss"][p] for p in names]) * scale


start = np.array([28.098, 0.79, 0.2, 0.3]) / scale
bounds = [(28.05 / 1e-3, 28.15 / 1e-3), (60.0, 100.0), (-2.0, 2.0), (-np.pi, np.pi)]
result = scipy.optimize.minimize(
    loss_and_grad, start, jac=True, method="L-BFGS-B", bounds=bounds, options={"ftol": 1e-15, "gtol": 1e-10, "maxiter": 500}
)

best = dict(zip(names, result.x * scale))
print(f"loss {result.fun:.3e} after {result.nfev} value+gradient calls")
for p in names:
    print(f"{p:5} fit {best[p]: .6f}   truth {truth[p]: .6f}")
