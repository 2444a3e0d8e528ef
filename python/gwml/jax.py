"""A gwml scene output inside JAX: ``jax.jit``, ``jax.grad`` and
``jax.vmap`` work through it, and its gradient is gwml's fused kernel.

>>> import jax, jax.numpy as jnp, gwml, gwml.jax
>>> jax.config.update("jax_enable_x64", True)   # gwml computes in float64
>>> scene = gwml.compile("examples/chirp_fit.gw").scene()
>>> f = gwml.jax.function(scene, "loss", ["mc", "tc"])
>>> jax.jit(jax.grad(f))(jnp.array([30.0, 0.0]))

The function is an XLA custom call on the CPU (``jax.ffi``): a jitted
program calls gwml's kernels directly, without going back to Python. Its
value comes from gwml's forward kernel, its vector–Jacobian product from
the value and gradient of one fused call (``jax.custom_vjp``). Under
``jax.vmap`` a batch of points is one ``Scene.batch`` over all cores. The
scene's inputs are what ``Scene.bind`` holds when the call runs (else
their defaults). Without ``jax_enable_x64`` JAX hands float32 params, and
results come back as float32.
"""

from __future__ import annotations

from typing import Callable, Mapping, Optional, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from . import _gwml
from ._bridge import differentiable_params
from ._gwml import Scene

__all__ = ["function"]


_TARGET = "gwml_scene_call"
_registered = False


def _register() -> None:
    """Registers gwml's XLA FFI handler (once per process)."""
    global _registered
    if not _registered:
        jax.ffi.register_ffi_target(_TARGET, _gwml.xla_handler(), platform="cpu")
        _registered = True


def function(scene: Scene, output: str, params: Optional[Sequence[str]] = None) -> Callable:
    """``output`` of ``scene`` as a JAX function of a params array.

    The function takes an array whose last axis holds ``params`` (default:
    every param ``output`` has a gradient with respect to, in the scene's
    order), or a dict ``{name: value}`` of them, and returns the output
    (an array of the leading shape). Params not named keep their defaults;
    data comes from ``scene.bind``.
    """
    names = differentiable_params(scene, output, params)
    _register()
    handle = _gwml.XlaFunction(scene, output, names)
    function_id = np.uint64(handle.id)

    def value(x):
        result = jax.ShapeDtypeStruct(x.shape[:-1], x.dtype)
        return jax.ffi.ffi_call(_TARGET, result, vmap_method="broadcast_all")(x, function=function_id)

    def value_and_grad(x):
        results = (jax.ShapeDtypeStruct(x.shape[:-1], x.dtype), jax.ShapeDtypeStruct(x.shape, x.dtype))
        return jax.ffi.ffi_call(_TARGET, results, vmap_method="broadcast_all")(x, function=function_id)

    @jax.custom_vjp
    def f(x):
        return value(x)

    def f_fwd(x):
        return value_and_grad(x)

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
        if x.ndim == 0 or x.shape[-1] != len(names):
            raise ValueError(f"expected an array whose last axis holds the {len(names)} params {names}, got shape {x.shape}")
        return f(x)

    call.__doc__ = f"`{output}` of scene `{scene.name}` as a function of {names}."
    call.params = names
    call._handle = handle  # keeps the function registered while `call` lives
    return call
