"""`gwml.torch.function` as a torch.autograd.Function: gradcheck in float64."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import gwml  # noqa: E402
import gwml.torch  # noqa: E402
from conftest import EXAMPLES  # noqa: E402


@pytest.fixture(scope="module")
def scene():
    return gwml.compile(EXAMPLES / "chirp_fit.gw").scene()


def test_gradcheck_float64(scene):
    f = gwml.torch.function(scene, "loss")
    x = torch.tensor([29.0, 0.0004, 0.2], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(f, (x,), eps=1e-6, atol=1e-5, rtol=1e-4)
    stack = torch.tensor([[29.0, 0.0004, 0.2], [31.0, -0.0002, 1.0]], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(f, (stack,), eps=1e-6, atol=1e-5, rtol=1e-4)


def test_backward_is_gwml_gradient(scene):
    f = gwml.torch.function(scene, "loss", ["mc", "tc"])
    x = torch.tensor([30.0, 0.001], dtype=torch.float64, requires_grad=True)
    (3.0 * f(x)).backward()
    outputs, grads = scene.value_and_grad({"mc": 30.0, "tc": 0.001})
    np.testing.assert_array_equal(x.grad.numpy(), [3.0 * grads["loss"]["mc"], 3.0 * grads["loss"]["tc"]])
    with torch.no_grad():
        assert float(f(x)) == outputs["loss"]
