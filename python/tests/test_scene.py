"""The package against the command line: same values and gradients on every
example, params and inputs by name, NumPy arrays in and out, batches."""

import threading
import time

import numpy as np
import pytest

import gwml
from conftest import EXAMPLES, ROOT, cli, cli_run, close, example_scenes


@pytest.mark.parametrize("path,scene", example_scenes(), ids=lambda x: getattr(x, "name", x))
def test_values_and_gradients_equal_the_cli(path, scene):
    want = cli_run(path, scene)
    outputs, grads = gwml.compile(path).scene(scene).value_and_grad()
    for name, value in want["outputs"].items():
        if isinstance(value, float):
            assert close(outputs[name], value), (name, outputs[name], value)
        else:
            assert np.shape(outputs[name])[0] == value["len"] or np.size(outputs[name]) == value["len"]
    # The command line prints param gradients; weights' come as arrays.
    assert grads.keys() >= want["grads"].keys()
    for out, per_param in want["grads"].items():
        assert grads[out].keys() >= per_param.keys()
        for p, g in per_param.items():
            assert close(grads[out][p], g), (out, p, grads[out][p], g)


def test_params_with_units_and_array_outputs_equal_the_cli(tmp_path):
    path = EXAMPLES / "chirp_fit_pn.gw"
    sets = {"mc": 3.2, "tc": "2 ms", "q": 0.6}
    npy = tmp_path / "h.npy"
    want = cli_run(path, "chirp_fit_pn", sets, ("--output", f"h={npy}"))
    outputs, grads = gwml.compile(str(path)).scene().value_and_grad(sets)
    assert close(outputs["loss"], want["outputs"]["loss"])
    for p, g in want["grads"]["loss"].items():
        assert close(grads["loss"][p], g)
    h = np.load(npy)
    assert outputs["h"].dtype == np.complex128 and outputs["h"].shape == h.shape
    np.testing.assert_allclose(outputs["h"], h, rtol=1e-12, atol=1e-12 * np.abs(h).max())


def test_compile_takes_a_path_or_source_and_settings():
    text = (EXAMPLES / "chirp_fit.gw").read_text()
    by_path = gwml.compile(EXAMPLES / "chirp_fit.gw").scene().run()["loss"]
    by_text = gwml.compile(text).scene().run()["loss"]
    assert by_path == by_text
    f32 = gwml.compile(text, precision="f32").scene().run()["loss"]
    assert f32 != by_text and abs(f32 - by_text) < 1e-3 * abs(by_text)
    with pytest.raises(gwml.CompileError, match="precision"):
        gwml.compile(text, precision="f16")


def test_knobs_recompile_like_the_cli():
    path = EXAMPLES / "taylorf2_tradeoff.gw"
    r = cli("run", str(path), "--knob", "df=0.5 Hz", "--format", "json")
    assert r.returncode == 0, r.stderr
    import json

    want = json.loads(r.stdout)["outputs"]["loss"]
    got = gwml.compile(path, knobs={"df": "0.5 Hz"}).scene().run()["loss"]
    assert close(got, want)


def test_scene_describes_params_inputs_and_outputs():
    scene = gwml.compile(EXAMPLES / "chirp_fit.gw").scene()
    assert scene.name == "chirp_fit"
    mc = scene.params["mc"]
    assert (mc.unit, mc.default, mc.bounds) == ("Msun", 28.0, (5.0, 100.0))
    assert scene.params["phic"].bounds is None
    d = scene.inputs["d"]
    assert (d.shape, d.dtype, d.has_default, d.role) == ((8033,), "complex128", True, "data")
    loss = scene.outputs["loss"]
    assert (loss.shape, loss.dtype, loss.grads) == ((), "float64", ["mc", "tc", "phic"])
    assert list(scene.params) == ["mc", "tc", "phic"]


def test_inputs_bound_per_call_held_by_bind_and_reset():
    scene = gwml.compile(EXAMPLES / "chirp_fit.gw").scene()
    default = scene.run()["loss"]
    d = np.zeros(8033, dtype=np.complex128)
    zero = scene.run(inputs={"d": d})["loss"]
    assert zero != default
    # A call's inputs do not outlive it.
    assert scene.run()["loss"] == default
    scene.bind({"d": d})
    assert scene.run()["loss"] == zero
    # Real data for a complex input, and a strided (non-contiguous) view.
    assert scene.run(inputs={"d": np.zeros(2 * 8033)[::2]})["loss"] == zero
    scene.bind({"d": None})
    assert scene.run()["loss"] == default


def test_params_not_given_take_their_defaults():
    scene = gwml.compile(EXAMPLES / "chirp_fit.gw").scene()
    at_default = scene.run()["loss"]
    assert scene.run({"mc": 30.0})["loss"] != at_default
    assert scene.run()["loss"] == at_default


def test_batch_equals_single_runs_and_releases_the_lock():
    scene = gwml.compile(EXAMPLES / "chirp_fit.gw").scene()
    mc = np.linspace(20.0, 40.0, 64)
    outputs, grads = scene.batch({"mc": mc, "tc": 0.001}, grad=True)
    assert outputs["loss"].shape == (64,)
    for k in (0, 17, 63):
        o, g = scene.value_and_grad({"mc": mc[k], "tc": 0.001})
        assert outputs["loss"][k] == o["loss"]
        assert grads["loss"]["mc"][k] == g["loss"]["mc"]
    # Another Python thread runs while a batch computes.
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=tick)
    many = np.linspace(20.0, 40.0, 4000)
    t.start()
    time.sleep(0.01)
    start = time.perf_counter()
    scene.batch({"mc": many}, grad=True, threads=1)
    end = time.perf_counter()
    stop.set()
    t.join()
    assert sum(start < x < end for x in ticks) >= 5, "the batch held the interpreter's lock"


def test_batch_array_outputs_stack_along_items():
    scene = gwml.compile(EXAMPLES / "chirp_fit_pn.gw").scene()
    out = scene.batch({"mc": np.array([2.9, 3.0, 3.1])})
    assert out["h"].shape == (3, scene.outputs["h"].shape[0]) and out["h"].dtype == np.complex128
    np.testing.assert_array_equal(out["h"][1], scene.run({"mc": 3.0})["h"])


@pytest.mark.parametrize("example", ["fit_w1.py", "jax_grad.py"])
def test_readme_examples_run(example):
    import subprocess
    import sys

    if example == "jax_grad.py":
        pytest.importorskip("jax")
    r = subprocess.run([sys.executable, str(ROOT / "python" / "examples" / example)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    if example == "fit_w1.py":
        # The fit finds the injected params.
        rows = {line.split()[0]: line.split() for line in r.stdout.splitlines()[1:]}
        assert abs(float(rows["mc"][2]) - float(rows["mc"][4])) < 1e-4
        assert abs(float(rows["q"][2]) - float(rows["q"][4])) < 1e-3
