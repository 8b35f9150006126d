"""Typed stub of the Rust extension (checked against it by mypy.stubtest).

The engine's results are plain dicts; their keys and types are spelled out below as
TypedDicts (they exist only for the type checker), read off rust/src/bindings/.
"""

from collections.abc import Callable
from typing import Any, Concatenate, ParamSpec, TypedDict, TypeVar, final

import numpy as np
import numpy.typing as npt

__version__: str
METRIC_NAMES: list[str]
#: The metrics of an event (a touchdown, a release): NaN in a phase or flight without it.
EVENT_METRICS: list[str]
#: Each metric's unit (SI, as stored) and plain-English label (no unit), by name.
METRIC_UNITS: dict[str, str]
METRIC_LABELS: dict[str, str]
#: The unit and label of every scenario key the engine declares (dotted, indices dropped).
KEY_UNITS: dict[str, str]
KEY_LABELS: dict[str, str]
#: The paper layout's (vertical spring, ideal actuators); a scenario's own are in `describe`.
TRACE_COLUMNS: list[str]
STATE_NAMES: list[str]
#: Why a flight ended: `status` codes index these names and sentences.
EXIT_STATUSES: list[str]
EXIT_MESSAGES: list[str]
CONTROLLER_NAMES: list[str]
#: Hz, each law's own loop rates (position, attitude, inner; 0: every step) where the
#: scenario sets none.
CONTROLLER_RATES: dict[str, list[float]]
#: Steps of the longest period `stability` models a sampled law over (past it: the
#: continuous law's model, and the report says so).
MAX_PERIOD_STEPS: int
#: Each law's name as a person reads it ("PD", "SE(3)"), in the order of CONTROLLER_NAMES.
CONTROLLER_LABELS: list[str]
#: The payload and actuator models a scenario may name (`payload.model`, `actuator.model`).
PAYLOAD_MODELS: list[str]
ACTUATOR_MODELS: list[str]
BODY_MODELS: list[str]
#: Each controller kind's default table (JSON text), for the kinds that have one.
CONTROLLER_DEFAULTS: dict[str, str]
ONE_OF_KEYS: list[tuple[str, str]]

_Floats = npt.NDArray[np.float64]
_P = ParamSpec("_P")
_R = TypeVar("_R")

class Description(TypedDict):
    """:func:`describe`: quantities derived from a validated scenario."""

    stiffness: float
    hover_offset: float
    steps: int
    turbulence_w20: float
    phases: list[str]
    state_names: list[str]
    trace_columns: list[str]
    spectrum_frequencies: list[_Floats]
    #: (name, start s, end s) of every phase, the whole-flight phase last.
    phase_windows: list[tuple[str, float, float]]
    #: A route's schedule, one dict per hold or leg (empty without a route): name, kind,
    #: start, arrival, end, origin, target, length, peak_speed, ramp, cruise, payout.
    route: list[dict[str, Any]]

class StabilityResult(TypedDict):
    """:func:`stability`: the closed-loop poles at hover (one entry each, least stable
    first) and the verdict."""

    real: _Floats
    imag: _Floats
    mode: list[str]
    dominant: list[str]
    status: list[str]
    excited: npt.NDArray[np.bool_]
    verdict: str
    stable: bool
    lateral_sources: list[str]
    equilibrium: _Floats
    residual: float
    jacobian: _Floats
    tolerance: float
    period: float | None
    unmodelled_period: float | None

class LinearizeResult(TypedDict):
    """:func:`linearize`: the closed loop at hover as a state-space model."""

    A: _Floats
    B: _Floats
    C: _Floats
    D: _Floats
    state_names: list[str]
    input_names: list[str]
    output_names: list[str]
    equilibrium: _Floats
    residual: float

class SimulateResult(TypedDict):
    """:func:`simulate`: trace (rows, 1 + len(TRACE_COLUMNS)), time first; metrics
    (phases, len(METRIC_NAMES)); per phase the amplitude spectrum."""

    trace: _Floats
    metrics: _Floats
    diverged_at: float
    status: str
    trace_columns: list[str]
    spectra: list[_Floats]
    # With navigation.mode = "ekf": the samples the filter read and its final state
    # (imu, gnss, baro, heading, initial, state, covariance, truth); else None.
    navigation: dict[str, _Floats] | None

class _BatchSpectra(TypedDict, total=False):
    # present only when spectra were asked for: per phase (controllers, bins) sums
    spectrum_sum: list[_Floats]
    spectrum_sum_sq: list[_Floats]
    spectrum_count: list[int]

class BatchResult(_BatchSpectra):
    """:func:`run_batch`: metrics (count, controllers, phases, len(METRIC_NAMES)),
    diverged_at (count, controllers; NaN if not), done (count,), and with spectra the sums."""

    metrics: _Floats
    diverged_at: _Floats
    status: npt.NDArray[np.uint8]
    done: npt.NDArray[np.bool_]

class ScenarioError(ValueError):
    """A scenario value is invalid; the message names the key and the value."""

    #: The dotted scenario key at fault (None when the error names no single key).
    key: str | None

class EngineError(RuntimeError):
    """The engine failed internally (a bug): the message says where."""

@final
class Progress:
    """Progress of a batch, shared between the polling Python thread and the workers."""

    def __new__(cls) -> Progress: ...
    def done(self) -> int: ...
    def cancel(self) -> None: ...
    def cancelled(self) -> bool: ...

@final
class Engine:
    """A scenario compiled once (validated; vehicle, reference and gust filters built) and
    flown many times: the module's functions without ``config_json``, bit for bit the same."""

    def __new__(cls, config_json: str) -> Engine: ...
    @property
    def steps(self) -> int: ...
    @property
    def start_balanced(self) -> bool: ...
    @property
    def start_wind(self) -> list[float]: ...
    def innovations_dimension(self) -> int: ...
    def innovations(self, seed: int, realisation: int) -> _Floats: ...
    def loop_steps(self, controller: str) -> list[int]: ...
    def every_step(self, controller: str) -> list[bool]: ...
    def stability(self, controller: str) -> StabilityResult: ...
    def linearize(
        self, controller: str, wind: tuple[float, float, float] | list[float]
    ) -> LinearizeResult: ...
    def simulate(
        self,
        controller: str,
        seed: int,
        realisation: int = 0,
        record_every: int = 1,
        wind: npt.NDArray[np.float64] | None = None,
        progress: Progress | None = None,
        xi: npt.NDArray[np.float64] | None = None,
        dispersion_keys: list[str] = ...,
        dispersion_values: npt.NDArray[np.float64] | None = None,
    ) -> SimulateResult: ...
    def simulate_innovations(
        self,
        controller: str,
        xi_row: npt.NDArray[np.float64],
        record_every: int = 1,
        progress: Progress | None = None,
        dispersion_keys: list[str] = ...,
        dispersion_values: npt.NDArray[np.float64] | None = None,
    ) -> SimulateResult: ...
    def run_batch(
        self,
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
    ) -> BatchResult: ...
    def run_innovations(
        self,
        controller: str,
        xi: npt.NDArray[np.float64],
        progress: Progress | None = None,
        workers: int | None = None,
        dispersion_keys: list[str] = ...,
        dispersion_values: npt.NDArray[np.float64] | None = None,
    ) -> _Floats: ...

def _panic_for_tests(message: str, in_pool: bool) -> None: ...
def describe(config_json: str) -> Description: ...
def simd_path() -> str: ...
def lanes_per_set() -> int: ...

# Not in the module: the stub's way of saying "the method, with config_json first".
def _engine_function(
    method: Callable[Concatenate[Engine, _P], _R], /
) -> Callable[Concatenate[str, _P], _R]: ...

# The module's engine functions, each ``Engine(config_json).<name>(...)``: the Rust side builds
# them from the methods (rust/src/bindings/engine_functions.rs) and so does this stub, so each
# signature is written once, on the method (``config_json`` typed positional; it may also be
# given by keyword).
simulate = _engine_function(Engine.simulate)
simulate_innovations = _engine_function(Engine.simulate_innovations)
run_batch = _engine_function(Engine.run_batch)
run_innovations = _engine_function(Engine.run_innovations)
innovations = _engine_function(Engine.innovations)
innovations_dimension = _engine_function(Engine.innovations_dimension)
stability = _engine_function(Engine.stability)
linearize = _engine_function(Engine.linearize)

def low_altitude_scales(altitude: float, w20: float) -> tuple[list[float], list[float]]: ...
def lane_math(
    function: str, x: npt.NDArray[np.float64], path: str = "scalar", y: float = 0.0
) -> npt.NDArray[np.float64]: ...
def mean_wind(config_json: str, altitudes: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]: ...

# A forming filter's numbers: (model, component, sigma, length_scale, airspeed, dt).
_GustSpec = tuple[str, str, float, float, float, float]

def gust_psd(
    spec: _GustSpec, frequency: npt.NDArray[np.float64]
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]: ...
def gust_series(
    spec: _GustSpec,
    steps: int,
    realisations: int,
    seed: int,
    first: int,
    workers: int,
) -> npt.NDArray[np.float64]: ...
