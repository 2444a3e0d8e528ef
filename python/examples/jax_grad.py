"""A gwml likelihood inside JAX: ``jax.grad`` and ``jax.jit`` through
gwml's fused gradient, and ``jax.vmap`` as one batch over all cores.

    python python/examples/jax_grad.py
"""

from pathlib import Path

import jax
import jax.numpy as jnp

import gwml
import gwml.jax

jax.config.update("jax_enable_x64", True)  # gwml computes in float64

W1 = Path(__file__).resolve().parents[2] / "benches" / "w1.gw"
model = gwml.compile(W1)
fit = model.scene("w1_fit_full")
fit.bind({"d": model.scene("w1_strain_full").run()["h"]})

# -log L(mc, q, tc, phic) from gwml; a Gaussian prior on mc written in JAX.
nll = gwml.jax.function(fit, "loss", ["mc", "q", "tc", "phic"])


def neg_log_posterior(x):
    return nll(x) + 0.5 * ((x[0] - 28.0) / 0.5) ** 2


x = jnp.array([28.1, 0.8, 0.0, 0.0])
print("value   ", neg_log_posterior(x))
print("gradient", jax.jit(jax.grad(neg_log_posterior))(x))

# Twenty chirp masses at once: one Scene.batch under jax.vmap.
xs = jnp.stack([jnp.linspace(28.0, 28.2, 20), jnp.full(20, 0.8), jnp.zeros(20), jnp.zeros(20)], axis=-1)
print("d/dmc over a line", jax.vmap(jax.grad(neg_log_posterior))(xs)[:, 0])
