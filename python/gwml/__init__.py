"""gwml from Python: compile ``.gw`` scenes, run them and their gradients
with NumPy data in and out, and use them inside JAX and PyTorch.

>>> import gwml
>>> model = gwml.compile("examples/chirp_fit.gw")
>>> scene = model.scene()
>>> outputs, grads = scene.value_and_grad({"mc": 30.0})
>>> outputs["loss"], grads["loss"]["mc"]

``gwml.jax.function`` and ``gwml.torch.function`` wrap a scene output as a
differentiable function of its params (JAX and PyTorch are optional).
``gwml.scan`` finds and classifies glitches in GWOSC strain files, as
``gwml scan`` does.
"""

from __future__ import annotations

import os
from typing import Any, Mapping, Optional, Sequence, Union

import numpy as np

from . import _gwml
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
    "scan",
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


def scan(
    paths: Union[str, os.PathLike, Sequence[Union[str, os.PathLike]]],
    *,
    frame: Optional[bool] = None,
    snr_threshold: float = 7.5,
    min_significance: Optional[float] = None,
    fmin: float = 10.0,
    fmax: float = 2048.0,
    psd_stretch: float = 128.0,
    fft_length: float = 4.0,
    block: float = 1024.0,
    threads: Optional[int] = None,
    classify: bool = True,
    sample_rate: Optional[float] = None,
    gps_start: Optional[float] = None,
    ifo: str = "X1",
) -> Any:
    """Glitch triggers in strain, as ``gwml scan PATHS`` writes them.

    ``paths`` is one GWOSC HDF5 file or several of one detector
    (consecutive files are joined; a gap between files is skipped), or one
    ``.npy`` with ``sample_rate`` and ``gps_start``. The options are
    ``gwml scan``'s flags (``min_significance=None`` takes the CLI's
    default); ``classify=False`` is ``--no-classify``. The rows
    are the CLI's, in time order, with the same columns (``gps_time``,
    ``ifo``, ``snr``, ``peak_frequency``, ``q``, ``duration``, ``label``,
    ``confidence``, ``start``, ``end``, ``f_start``, ``f_end``, ``tiles``
    and one ``p_<class>`` per class) in full precision.

    Returns a pandas ``DataFrame`` when pandas is installed (or
    ``frame=True``), else a dict of one NumPy array per column
    (``frame=False``). Scanning releases the GIL and uses ``threads``
    threads (default: all cores). Bad files raise :class:`RunError`.
    """
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    columns, _classes = _gwml.scan(
        [os.fspath(p) for p in paths],
        snr_threshold=snr_threshold,
        min_significance=min_significance,
        fmin=fmin,
        fmax=fmax,
        psd_stretch=psd_stretch,
        fft_length=fft_length,
        block=block,
        threads=threads,
        classify=classify,
        sample_rate=sample_rate,
        gps_start=gps_start,
        ifo=ifo,
    )
    columns = {k: np.asarray(v, dtype=str) if isinstance(v, list) else v for k, v in columns.items()}
    if frame is None:
        try:
            import pandas  # noqa: F401
        except ImportError:
            frame = False
        else:
            frame = True
    if frame:
        import pandas

        return pandas.DataFrame(columns)
    return columns
