"""gwml from Python: compile ``.gw`` scenes, run them and their gradients
with NumPy data in and out, and use them inside JAX and PyTorch.

>>> import gwml
>>> model = gwml.compile("examples/chirp_fit.gw")
>>> scene = model.scene()
>>> outputs, grads = scene.value_and_grad({"mc": 30.0})
>>> outputs["loss"], grads["loss"]["mc"]

``gwml.jax.function`` and ``gwml.torch.function`` wrap a scene output as a
differentiable function of its params (JAX and PyTorch are optional).
"""

from __future__ import annotations

import os
from typing import Mapping, Optional, Union

from ._gwml import (
    CompileError,
    GwmlError,
    InputInfo,
    Model,
    OutputInfo,
    ParamInfo,
    RunError,
    Scene,
)

__all__ = [
    "compile",
    "Model",
    "Scene",
    "ParamInfo",
    "InputInfo",
    "OutputInfo",
    "GwmlError",
    "CompileError",
    "RunError",
]


def compile(
    path_or_source: Union[str, os.PathLike],
    *,
    precision: Optional[str] = None,
    math: Optional[str] = None,
    knobs: Optional[Mapping[str, Union[str, float]]] = None,
    multiband: Optional[str] = None,
    relative_binning: Optional[Union[str, int]] = None,
) -> Model:
    """Checks a ``.gw`` program and returns its :class:`Model`.

    ``path_or_source`` is a path (a ``pathlib.Path``, or a string naming an
    existing file or ending in ``.gw``) or the source text itself. The
    options override every scene's settings, as ``gwml compile``'s flags do:
    ``precision`` ("f64", "f32", "mixed"), ``math`` ("exact", "fast"),
    ``multiband`` ("off" or a phase tolerance such as "1e-3"),
    ``relative_binning`` ("off" or a number of bins), and ``knobs``
    (``{"df": "0.25 Hz"}``: a knob's value as source text or a number).
    Errors raise :class:`CompileError` with the diagnostic ``gwml compile``
    prints.
    """
    options = dict(
        precision=precision,
        math=math,
        multiband=multiband,
        relative_binning=None if relative_binning is None else str(relative_binning),
        knobs=dict(knobs) if knobs is not None else None,
    )
    if isinstance(path_or_source, os.PathLike):
        return Model(os.fspath(path_or_source), path=True, **options)
    if not isinstance(path_or_source, str):
        raise TypeError(f"gwml.compile takes a path or source text, not {type(path_or_source).__name__}")
    text = path_or_source
    looks_like_path = "\n" not in text and (text.endswith(".gw") or os.path.isfile(text))
    return Model(text, path=looks_like_path, **options)
