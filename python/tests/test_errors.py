"""Errors carry the command line's diagnostics and name what is wrong."""

import numpy as np
import pytest

import gwml
from conftest import EXAMPLES, ROOT, cli

BAD = "scene s {\n    param m: Msun = 1.0\n    output y = m + undefined_name\n}\n"


def test_compile_error_is_the_cli_diagnostic(tmp_path):
    path = tmp_path / "bad.gw"
    path.write_text(BAD)
    r = cli("compile", str(path))
    assert r.returncode != 0
    with pytest.raises(gwml.CompileError) as e:
        gwml.compile(str(path))
    assert str(e.value).strip() == r.stderr.strip()
    assert (e.value.line, e.value.column, e.value.path) == (3, 20, str(path))
    assert e.value.messages == ["unknown name `undefined_name`"]
    assert isinstance(e.value, gwml.GwmlError)


def test_compile_error_from_source_text():
    with pytest.raises(gwml.CompileError) as e:
        gwml.compile(BAD)
    assert e.value.path == "<string>" and e.value.line == 3
    assert "not defined here" in str(e.value)


def test_unknown_scene_and_missing_file():
    model = gwml.compile(EXAMPLES / "pn_orders.gw")
    with pytest.raises(gwml.CompileError, match="pn2"):
        model.scene("pn_two")
    with pytest.raises(gwml.CompileError) as e:
        gwml.compile("no/such/file.gw")
    assert e.value.line is None and "no/such/file.gw" in str(e.value)


@pytest.fixture(scope="module")
def scene():
    return gwml.compile(EXAMPLES / "chirp_fit.gw").scene()


@pytest.mark.parametrize(
    "kwargs,pattern",
    [
        (dict(params={"mx": 30.0}), "no param `mx`; did you mean `mc`"),
        (dict(params={"mc": 1000.0}), "outside its bounds"),
        (dict(params={"mc": float("nan")}), "not finite"),
        (dict(params={"tc": "2 Msun"}), "dimension"),
        (dict(params={"mc": [1.0]}), "needs a number"),
        (dict(inputs={"dd": np.zeros(3)}), "no input `dd`; did you mean `d`"),
        (dict(inputs={"d": np.zeros(3)}), r"needs 8033 values.*\(3,\)"),
        (dict(inputs={"d": np.zeros((2, 8033))}), r"shape \(2, 8033\)"),
        (dict(inputs={"d": np.zeros(8033, dtype=np.int32)}), "dtype is int32"),
        (dict(inputs={"d": np.zeros(8033, dtype=np.complex64)}), "dtype is complex64"),
        (dict(inputs={"d": "text"}), "input `d`"),
    ],
)
def test_bad_params_and_inputs_raise_run_errors(scene, kwargs, pattern):
    with pytest.raises(gwml.RunError, match=pattern):
        scene.run(**kwargs)


def test_nan_in_an_input_names_the_index(scene):
    d = np.zeros(8033, dtype=np.complex128)
    d[4321] = np.nan
    with pytest.raises(gwml.RunError, match="input `d` has a non-finite value .* at index 4321"):
        scene.value_and_grad(inputs={"d": d})
    # A failed call leaves the scene usable, at its defaults.
    assert scene.run()["loss"] == gwml.compile(EXAMPLES / "chirp_fit.gw").scene().run()["loss"]


def test_batch_errors_name_the_item(scene):
    with pytest.raises(gwml.RunError) as e:
        scene.batch({"mc": np.array([20.0, 30.0, 500.0, 40.0])})
    assert e.value.index == 2 and "batch item 2" in str(e.value)
    with pytest.raises(gwml.RunError, match="has 2 values"):
        scene.batch({"mc": np.array([20.0, 30.0, 31.0]), "tc": np.array([0.0, 0.0])})
