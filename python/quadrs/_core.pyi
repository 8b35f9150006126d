"""Typed stub of the Rust extension (checked against it by mypy.stubtest)."""

from typing import Any, final

import numpy as np
import numpy.typing as npt

__version__: str
METRIC_NAMES: list[str]
TRACE_COLUMNS: list[str]
STATE_NAMES: list[str]

class ScenarioError(ValueError):
    """A scenario value is invalid; the message names the key and the value."""

class EngineError(RuntimeError):
    """The engine failed internally (a bug): the message says where."""

@final
class Progress:
    """Progress of a batch, shared between the polling Python thread and the workers."""

    def __new__(cls) -> Progress: ...
    def done(self) -> int: ...
    def cancel(self) -> None: ...
    def cancelled(self) -> bool: ...

def _panic_for_tests(message: str, in_pool: bool) -> None: ...
def describe(config_json: str) -> dict[str, Any]: ...
def simd_path() -> str: ...
def simulate(
    config_json: str,
    controller: str,
    seed: int,
    realisation: int = 0,
    record_every: int = 1,
    wind: npt.NDArray[np.float64] | None = None,
    progress: Progress | None = None,
) -> dict[str, Any]: ...
def stability(config_json: str, controller: str) -> dict[str, Any]: ...
def linearize(
    config_json: str, controller: str, wind: tuple[float, float, float] | list[float]
) -> dict[str, Any]: ...
def run_batch(
    config_json: str,
    controllers: list[str],
    seed: int,
    first: int,
    count: int,
    workers: int,
    spectra: bool = True,
    progress: Progress | None = None,
    dispersion_keys: list[str] = ...,
    dispersion_values: npt.NDArray[np.float64] | None = None,
    streams: npt.NDArray[np.uint64] | None = None,
    fused: bool = False,
) -> dict[str, Any]: ...
def low_altitude_scales(altitude: float, w20: float) -> tuple[list[float], list[float]]: ...
def gust_psd(
    model: str,
    component: str,
    sigma: float,
    length_scale: float,
    airspeed: float,
    dt: float,
    frequency: npt.NDArray[np.float64],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def gust_series(
    model: str,
    component: str,
    sigma: float,
    length_scale: float,
    airspeed: float,
    dt: float,
    steps: int,
    realisations: int,
    seed: int,
    first: int,
    workers: int,
) -> npt.NDArray[np.float64]: ...
