"""Type stubs of the native module `gwml._gwml` (python/src)."""

from typing import Any, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

ParamValue = Union[float, int, str]
"""A param's value: a number in its declared unit, or text with a unit ("30 Msun")."""
InputValue = Union[float, complex, npt.ArrayLike]
"""An input's data: a float64 / complex128 array of its shape (or flat), or a number for a scalar input."""
Value = Union[float, complex, np.ndarray]

class GwmlError(Exception):
    """Base class of the errors gwml raises."""

class CompileError(GwmlError):
    """The source, a setting or a scene name is wrong, or code generation failed."""

    line: Optional[int]
    column: Optional[int]
    path: Optional[str]
    messages: list[str]

class RunError(GwmlError):
    """Binding params or data, or running the scene, failed."""

    index: Optional[int]

class ParamInfo:
    name: str
    unit: str
    default: Optional[float]
    bounds: Optional[Tuple[float, float]]

class InputInfo:
    name: str
    unit: str
    shape: Tuple[int, ...]
    dtype: str
    has_default: bool
    role: str

class OutputInfo:
    name: str
    unit: str
    shape: Tuple[int, ...]
    dtype: str
    grads: list[str]

class Scene:
    @property
    def name(self) -> str: ...
    @property
    def params(self) -> dict[str, ParamInfo]: ...
    @property
    def inputs(self) -> dict[str, InputInfo]: ...
    @property
    def outputs(self) -> dict[str, OutputInfo]: ...
    def bind(self, inputs: Mapping[str, Optional[InputValue]]) -> None: ...
    def run(
        self, params: Optional[Mapping[str, ParamValue]] = None, inputs: Optional[Mapping[str, InputValue]] = None
    ) -> dict[str, Value]: ...
    def value_and_grad(
        self, params: Optional[Mapping[str, ParamValue]] = None, inputs: Optional[Mapping[str, InputValue]] = None
    ) -> Tuple[dict[str, Value], dict[str, dict[str, Union[float, np.ndarray]]]]: ...
    def batch(
        self,
        params: Mapping[str, Union[float, npt.ArrayLike]],
        inputs: Optional[Mapping[str, InputValue]] = None,
        *,
        grad: bool = False,
        threads: Optional[int] = None,
    ) -> Any: ...
    def _time_native(self, params: Optional[Mapping[str, ParamValue]] = None, *, grad: bool = True, repeats: int = 1000) -> float: ...

class Model:
    def __init__(
        self,
        source: str,
        *,
        path: bool = False,
        name: Optional[str] = None,
        precision: Optional[str] = None,
        math: Optional[str] = None,
        multiband: Optional[str] = None,
        relative_binning: Optional[str] = None,
        knobs: Optional[Mapping[str, Union[str, float]]] = None,
    ) -> None: ...
    @property
    def scenes(self) -> list[str]: ...
    def scene(self, name: Optional[str] = None) -> Scene: ...

class XlaFunction:
    id: int
    def __init__(self, scene: Scene, output: str, params: Sequence[str]) -> None: ...

def xla_handler() -> Any: ...

def scan(
    paths: Sequence[str],
    *,
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
) -> tuple[dict[str, Any], list[str]]: ...
