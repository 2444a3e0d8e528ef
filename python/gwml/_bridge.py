"""What the JAX and PyTorch bridges share: which params a bridged function
takes, and (for PyTorch) a scene output as a function of an array of
params, evaluated on the host in float64 (one call per point, or one
``Scene.batch`` over all cores for a stack of points)."""

from __future__ import annotations

from typing import Optional, Sequence, Tuple

import numpy as np

from ._gwml import Scene


def differentiable_params(scene: Scene, output: str, params: Optional[Sequence[str]] = None) -> list:
    """The params a bridged function of ``output`` takes: ``params``, or
    every param ``output`` has a gradient with respect to. Raises when
    ``output`` is not a real scalar or lacks one of those gradients."""
    outputs = scene.outputs
    if output not in outputs:
        raise KeyError(f"scene `{scene.name}` has no output `{output}`; it has {sorted(outputs)}")
    info = outputs[output]
    if info.shape != () or info.dtype != "float64":
        raise ValueError(f"output `{output}` must be a real scalar to be differentiated, but has shape {info.shape} and dtype {info.dtype}")
    names = list(info.grads) if params is None else list(params)
    missing = [p for p in names if p not in info.grads]
    if missing:
        raise ValueError(
            f"scene `{scene.name}` has no gradient of `{output}` with respect to {missing}; "
            f"add them to its `grad {output} wrt [...]` (it has {info.grads})"
        )
    if not names:
        raise ValueError(f"output `{output}` has no gradients to differentiate by")
    return names


class Evaluator:
    """``output`` of ``scene`` as a function of ``params`` (names, in the
    order of the last axis of the arrays it takes); other params keep their
    defaults, and the scene's inputs are what ``Scene.bind`` holds."""

    def __init__(self, scene: Scene, output: str, params: Optional[Sequence[str]] = None) -> None:
        self.scene = scene
        self.output = output
        self.params = differentiable_params(scene, output, params)

    def _check(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=np.float64)
        if x.ndim == 0 or x.shape[-1] != len(self.params):
            raise ValueError(f"expected an array whose last axis holds the {len(self.params)} params {self.params}, got shape {x.shape}")
        return x

    def value(self, x: np.ndarray) -> np.ndarray:
        """The output at every point of ``x`` (shape ``x.shape[:-1]``)."""
        x = self._check(x)
        flat = x.reshape(-1, len(self.params))
        if flat.shape[0] == 1:
            out = self.scene.run(dict(zip(self.params, flat[0].tolist())))
            values = np.array([out[self.output]])
        else:
            out = self.scene.batch({p: flat[:, j] for j, p in enumerate(self.params)})
            values = out[self.output]
        return values.reshape(x.shape[:-1])

    def value_and_grad(self, x: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """The output and its gradient at every point of ``x`` (shapes
        ``x.shape[:-1]`` and ``x.shape``)."""
        x = self._check(x)
        flat = x.reshape(-1, len(self.params))
        if flat.shape[0] == 1:
            out, grads = self.scene.value_and_grad(dict(zip(self.params, flat[0].tolist())))
            values = np.array([out[self.output]])
            g = np.array([[grads[self.output][p] for p in self.params]])
        else:
            out, grads = self.scene.batch({p: flat[:, j] for j, p in enumerate(self.params)}, grad=True)
            values = out[self.output]
            g = np.stack([grads[self.output][p] for p in self.params], axis=-1)
        return values.reshape(x.shape[:-1]), g.reshape(x.shape)
