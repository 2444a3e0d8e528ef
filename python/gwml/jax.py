"""A gwml scene output inside JAX: ``jax.jit``, ``jax.grad`` and
``jax.vmap`` work through it, and its gradient is gwml's fused kernel.

>>> import jax, jax.numpy as jnp, gwml, gwml.jax
>>> jax.config.update("jax_enable_x64", True)   # gwml computes in float64
>>> scene = gwml.compile("examples/chirp_fit.gw").scene()
>>> f = gwml.jax.function(scene, "loss", ["mc", "tc"])
>>> jax.jit(jax.grad(f))(jnp.array([30.0, 0.0]))

The function runs on the host through ``jax.pure_callback``: its value with
gwml's forward kernel, its vector–Jacobian product from the value and
gradient of one fused call (``jax.custom_vjp``). Under ``jax.vmap`` a batch
of points is one ``Scene.batch`` over all cores. Without
``jax_enable_x64`` JAX hands float32 params, and results come back as
float32.
"""

from __future__ import annotations

from typing import Callable, Mapping, Optional, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from ._bridge import Evaluator
from ._gwml import Scene

__all__ = ["function"]


def function(
    scene: Scene,
    output: str,
    params: Optional[Sequence[str]] = None,
    *,
    inputs: Optional[Mapping[str, object]] = None,
) -> Callable:
    """``output`` of ``scene`` as a JAX function of a params array.

    The function takes an array whose last axis holds ``params`` (default:
    every param ``output`` has a gradient with respect to, in the scene's
    order), or a dict ``{name: value}`` of them, and returns the output
    (an array of the leading shape). Params not named keep their defaults;
    ``inputs`` are bound at every call (bind large data once with
    ``scene.bind`` instead).
    """
    ev = Evaluator(scene, output, params, inputs)
    names = ev.params

    def host_value(x):
        return np.asarray(ev.value(np.asarray(x)), dtype=x.dtype)

    def host_value_and_grad(x):
        v, g = ev.value_and_grad(np.asarray(x))
        return np.asarray(v, dtype=x.dtype), np.asarray(g, dtype=x.dtype)

    def shapes(x):
        return jax.ShapeDtypeStruct(x.shape[:-1], x.dtype), jax.ShapeDtypeStruct(x.shape, x.dtype)

    @jax.custom_vjp
    def f(x):
        return jax.pure_callback(host_value, shapes(x)[0], x, vmap_method="expand_dims")

    def f_fwd(x):
        v, g = jax.pure_callback(host_value_and_grad, shapes(x), x, vmap_method="expand_dims")
        return v, g

    def f_bwd(g, ct):
        return (ct[..., None] * g,)

    f.defvjp(f_fwd, f_bwd)

    def call(x):
        if isinstance(x, Mapping):
            unknown = sorted(set(x) - set(names))
            if unknown:
                raise KeyError(f"{unknown} are not among this function's params {names}")
            x = jnp.stack([jnp.asarray(x[p]) for p in names], axis=-1)
        x = jnp.asarray(x)
        if not jnp.issubdtype(x.dtype, jnp.floating):
            x = x.astype(jnp.result_type(float))
        return f(x)

    call.__doc__ = f"`{output}` of scene `{scene.name}` as a function of {names}."
    call.params = names
    return call
