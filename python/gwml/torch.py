"""A gwml scene output inside PyTorch autograd.

>>> import torch, gwml, gwml.torch
>>> scene = gwml.compile("examples/chirp_fit.gw").scene()
>>> f = gwml.torch.function(scene, "loss", ["mc", "tc"])
>>> x = torch.tensor([30.0, 0.0], dtype=torch.float64, requires_grad=True)
>>> f(x).backward(); x.grad

The forward pass runs gwml on the host (float64; CPU tensors in and out,
others are moved); when the params require gradients it runs the fused
forward+gradient kernel once and keeps the gradient for the backward pass.
A stack of points (leading axes) is one ``Scene.batch`` over all cores.
"""

from __future__ import annotations

from typing import Callable, Optional, Sequence

import numpy as np
import torch

from ._bridge import Evaluator
from ._gwml import Scene

__all__ = ["function"]


class _SceneOutput(torch.autograd.Function):
    @staticmethod
    def forward(ctx, x: torch.Tensor, ev: Evaluator) -> torch.Tensor:
        host = x.detach().to("cpu", torch.float64).numpy()
        if x.requires_grad:
            v, g = ev.value_and_grad(host)
            ctx.save_for_backward(torch.from_numpy(np.ascontiguousarray(g)).to(x.device, x.dtype))
        else:
            v = ev.value(host)
        return torch.from_numpy(np.ascontiguousarray(v)).to(x.device, x.dtype)

    @staticmethod
    def backward(ctx, grad_output: torch.Tensor):
        (g,) = ctx.saved_tensors
        return grad_output.unsqueeze(-1) * g, None


def function(scene: Scene, output: str, params: Optional[Sequence[str]] = None) -> Callable[[torch.Tensor], torch.Tensor]:
    """``output`` of ``scene`` as a differentiable PyTorch function of a
    tensor whose last axis holds ``params`` (default: every param
    ``output`` has a gradient with respect to, in the scene's order).
    Params not named keep their defaults; data comes from ``scene.bind``.
    Double backward (second derivatives) is not supported."""
    ev = Evaluator(scene, output, params)

    def call(x: torch.Tensor) -> torch.Tensor:
        if not torch.is_tensor(x):
            x = torch.as_tensor(x, dtype=torch.float64)
        return _SceneOutput.apply(x, ev)

    call.__doc__ = f"`{output}` of scene `{scene.name}` as a function of {ev.params}."
    call.params = ev.params
    return call
