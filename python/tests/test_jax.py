"""`gwml.jax.function` under jax.grad, jax.jit and jax.vmap: the gradient
is gwml's own, bit for bit."""

import numpy as np
import pytest

jax = pytest.importorskip("jax")
import jax.numpy as jnp  # noqa: E402

import gwml  # noqa: E402
import gwml.jax  # noqa: E402
from conftest import EXAMPLES  # noqa: E402

jax.config.update("jax_enable_x64", True)


@pytest.fixture(scope="module")
def scene():
    return gwml.compile(EXAMPLES / "taylorf2_fit.gw").scene()


def test_grad_equals_gwml_gradient(scene):
    f = gwml.jax.function(scene, "loss")
    assert f.params == ["mc", "q", "chi1", "chi2", "tc", "phic"]
    x = {"mc": 20.1, "q": 0.7, "chi1": 0.1, "chi2": -0.2, "tc": 0.0005, "phic": 0.3}
    outputs, grads = scene.value_and_grad(x)
    xs = jnp.array([x[p] for p in f.params])
    assert float(f(xs)) == outputs["loss"]
    for g in (jax.grad(f)(xs), jax.jit(jax.grad(f))(xs)):
        np.testing.assert_array_equal(np.asarray(g), [grads["loss"][p] for p in f.params])
    v, g = jax.value_and_grad(f)(xs)
    assert float(v) == outputs["loss"]


def test_dict_params_and_a_subset(scene):
    f = gwml.jax.function(scene, "loss", ["tc", "mc"])
    g = jax.grad(f)({"mc": 20.1, "tc": 0.0005})
    _, want = scene.value_and_grad({"mc": 20.1, "tc": 0.0005})
    assert float(g["mc"]) == want["loss"]["mc"] and float(g["tc"]) == want["loss"]["tc"]
    with pytest.raises(ValueError, match="no gradient of `loss` with respect to \\['dist'\\]"):
        gwml.jax.function(scene, "loss", ["dist"])


def test_vmap_is_one_batch(scene):
    f = gwml.jax.function(scene, "loss", ["mc", "tc"])
    xs = jnp.stack([jnp.linspace(19.0, 21.0, 7), jnp.full(7, 0.0005)], axis=-1)
    values = jax.vmap(f)(xs)
    grads = jax.jit(jax.vmap(jax.grad(f)))(xs)
    outs, want = scene.batch({"mc": np.asarray(xs[:, 0]), "tc": np.asarray(xs[:, 1])}, grad=True)
    np.testing.assert_array_equal(np.asarray(values), outs["loss"])
    np.testing.assert_array_equal(np.asarray(grads[:, 0]), want["loss"]["mc"])
    np.testing.assert_array_equal(np.asarray(grads[:, 1]), want["loss"]["tc"])


def test_chain_rule_through_jax_code(scene):
    # d/ds f(mc = 20 + s, tc = s / 1000) = df/dmc + df/dtc / 1000
    f = gwml.jax.function(scene, "loss", ["mc", "tc"])
    h = lambda s: 2.0 * f(jnp.stack([20.0 + s, s / 1000.0]))  # noqa: E731
    _, g = scene.value_and_grad({"mc": 20.3, "tc": 0.0003})
    want = 2.0 * (g["loss"]["mc"] + g["loss"]["tc"] / 1000.0)
    assert abs(float(jax.grad(h)(0.3)) - want) <= 1e-12 * abs(want)


def test_the_custom_call_reads_the_data_the_scene_holds():
    model = gwml.compile(EXAMPLES / "chirp_fit.gw")
    scene = model.scene()
    f = jax.jit(gwml.jax.function(scene, "loss", ["mc"]))
    x = jnp.array([29.0])
    at_default = float(f(x))
    assert at_default == scene.run({"mc": 29.0})["loss"]
    d = np.zeros(8033, dtype=np.complex128)
    scene.bind({"d": d})
    assert float(f(x)) == scene.run({"mc": 29.0})["loss"] != at_default
    scene.bind({"d": None})
    assert float(f(x)) == at_default


def test_errors_inside_jit_carry_the_diagnostic(scene):
    f = jax.jit(gwml.jax.function(scene, "loss", ["mc"]))
    with pytest.raises(Exception, match="param `mc` = 500 is outside its bounds"):
        f(jnp.array([500.0])).block_until_ready()
    # float32 params (without x64) come back as float32.
    g = gwml.jax.function(scene, "loss", ["mc"])
    v = g(jnp.array([20.1], dtype=jnp.float32))
    assert v.dtype == jnp.float32 and abs(float(v) - scene.run({"mc": float(np.float32(20.1))})["loss"]) < 1e-5 * abs(float(v))
