"""A scenario, a controller, a metric and a phase as a model of standard normals, for subset
simulation: the flight driven by explicit innovations xi (the unit white noise of the Dryden
filters' exact discretisation, docs/model.md section 4) instead of a seeded gust stream.

The protocol the sampler relies on (:class:`RareEventModel`):

- ``dimension``: standard normals per flight;
- ``evaluate(xi)``: (N, dimension) -> (N,) metric values, one batch of flights; a diverged
  flight counts as +inf (an exceedance, as in ``MonteCarloResult.exceedance``);
- ``fly(xi_row)``: the :class:`~quadrs.runs.flight.Flight` of one row, with its trace.

The engine functions, in ``_core`` (see docs/rare-events.md, "The engine interface"):

- ``innovations_dimension(config_json) -> int``;
- ``run_innovations(config_json, controller, xi, progress, workers) -> metrics`` with ``xi``
  float64 (N, dimension), ``metrics`` (N, phases, len(METRIC_NAMES)), NaN after a divergence;
- ``simulate_innovations(config_json, controller, xi_row, record_every, progress) -> dict``,
  the dict :func:`quadrs._core.simulate` returns.

An engine built without them raises NotImplementedError naming what is missing.
"""

from __future__ import annotations

import itertools
import warnings
from typing import TYPE_CHECKING, Protocol

import numpy as np

from quadrs import _core
from quadrs.engine.calls import MAX_WORKERS, check_controller, check_int, run_cancellable
from quadrs.rare.engine import engine_function, run_rows
from quadrs.scenario.dispersion import dispersed_keys, key_ranges, values_of_uniforms
from quadrs.scenario.scenario import Scenario, ScenarioError, scenario_error

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

    from quadrs.runs.flight import Flight

__all__ = ["RareEventModel", "ScenarioModel", "engine_function", "parameters_of_normals"]

#: Phi(z) is held this far inside (0, 1), as monte_carlo's uniforms are
#: (quadrs.scenario.dispersion): an unbounded distribution's quantile stays finite
#: (|z| <= about 8.2).
_EDGE = 1e-16


def parameters_of_normals(scenario: Scenario, z: np.ndarray) -> np.ndarray:
    """The dispersed keys' values (N, keys) of standard normals ``z`` (N, keys), keys sorted:
    theta_j = F_j^-1(Phi(z_j)) with F_j the key's distribution exactly as monte_carlo draws it
    (:func:`quadrs.scenario.dispersion.distribution`, scipy.stats ``ppf``), Phi(z) held in
    [1e-16, 1 - 1e-16] like monte_carlo's uniforms. So z ~ N(0, 1) gives theta ~ F_j."""
    from scipy.stats import norm

    z = np.asarray(z, dtype=np.float64)
    keys = dispersed_keys(scenario)
    if z.shape[-1] != len(keys):
        raise ValueError(f"z must have {len(keys)} columns (one per dispersed key), got {z.shape}")
    u = np.clip(norm.cdf(z), _EDGE, 1.0 - _EDGE)
    theta = np.empty_like(z)
    for j, column in enumerate(values_of_uniforms(scenario, keys, u).values()):
        theta[..., j] = column
    return theta


#: At most this many dispersed keys are checked at every corner of their ranges together
#: (2**keys scenarios); more are checked one key at a time.
_CORNER_KEYS = 4


def check_range(scenario: Scenario, what: str) -> None:
    """Before a run that may draw any value of each dispersed key's distribution (a rare-event
    run: theta = F^-1(Phi(z)) for z anywhere, Phi(z) held in [1e-16, 1 - 1e-16]): the
    scenario must accept the ends of every key's range, else a ScenarioError naming the key,
    the end and why, before anything flies. The ends of a few keys are tried in every
    combination; of many, one key at a time."""
    keys = dispersed_keys(scenario)
    if not keys:
        return
    ends = key_ranges(scenario, _EDGE)
    if len(keys) <= _CORNER_KEYS:
        trials = [dict(zip(keys, c, strict=True)) for c in itertools.product(*ends.values())]
    else:
        trials = [{k: x} for k in keys for x in ends[k]]
    for values in trials:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                scenario.fixed(values)
        except ScenarioError as e:
            named = getattr(e, "key", None)
            key = named if named in values else next(iter(values))
            lo, hi = ends[key]
            raise scenario_error(
                f"dispersions: {key} ranges over [{lo:.6g}, {hi:.6g}] and {what} may draw any "
                f"value of it; at {values[key]:.6g} the scenario refuses it: {e} (narrow or "
                f"truncate the distribution)",
                f"dispersions.{key}",
            ) from None


class RareEventModel(Protocol):
    """What :func:`quadrs.rare_event` needs of a model of flights."""

    @property
    def dimension(self) -> int: ...

    def evaluate(self, xi: np.ndarray) -> np.ndarray: ...

    def fly(self, xi_row: np.ndarray) -> Flight: ...


class ScenarioModel:
    """``metric`` in ``phase`` of ``scenario`` flown by ``controller``, as a function of the
    gust's innovations (see the module docstring). Arguments are checked here, against the
    scenario, before anything flies."""

    def __init__(
        self,
        scenario: Scenario,
        controller: str,
        metric: str,
        phase: str,
        workers: int | None = None,
        client: Client | None = None,
    ) -> None:
        from quadrs.runs.flight import METRIC_COLUMNS

        if not isinstance(scenario, Scenario):
            raise ValueError(f"scenario must be a quadrs.Scenario, got {type(scenario).__name__}")
        self.controller = check_controller(controller)
        if metric not in METRIC_COLUMNS:
            raise ValueError(f"metric must be one of {METRIC_COLUMNS}, got {metric!r}")
        phases = scenario.phase_names
        if phase not in phases:
            raise ValueError(f"phase must be one of this scenario's phases {phases}, got {phase!r}")
        if not scenario["gust.enabled"]:
            raise ValueError(
                "the scenario's gust is off (gust.enabled = false): its flights are not random, "
                "so there is no probability to estimate"
            )
        self.scenario = scenario
        self.metric = metric
        self.phase = phase
        self._metric_index = METRIC_COLUMNS.index(metric)
        self._phase_index = phases.index(phase)
        self._dimension: int | None = None
        #: The dispersed keys (sorted), each driven by one standard normal after the gust's.
        self.parameter_keys: tuple[str, ...] = tuple(dispersed_keys(scenario))
        check_range(scenario, "a rare-event run")  # any value of the range may be drawn
        #: Threads flying a batch (None: all cores); results do not depend on it.
        self.workers = None if workers is None else check_int("workers", workers, 1, MAX_WORKERS)
        #: A dask.distributed Client: each batch's rows are spread over its workers.
        self.client = client

    @property
    def name(self) -> str:
        """How the value is named in tables: ``metric`` in ``phase``."""
        return f"{self.metric}_{self.phase}"

    @property
    def innovations(self) -> int:
        """The gust filters' innovations per flight (the first columns of a row)."""
        if self._dimension is None:
            count = engine_function("innovations_dimension", self.scenario.to_json())()
            self._dimension = int(count)
        return self._dimension

    @property
    def dimension(self) -> int:
        """Standard normals per flight: the gust's innovations, then one per dispersed key."""
        return self.innovations + len(self.parameter_keys)

    def parameters(self, xi: np.ndarray) -> np.ndarray:
        """The dispersed keys' values of each row, (N, keys): theta = F^-1(Phi(z)) of the
        row's last ``len(parameter_keys)`` normals (:func:`parameters_of_normals`)."""
        xi = np.asarray(xi, dtype=np.float64)
        return parameters_of_normals(self.scenario, xi[..., self.innovations :])

    def evaluate(self, xi: np.ndarray) -> np.ndarray:
        """The metric of each row's flight (+inf where the flight diverged; -inf where an
        event's metric, such as ``touchdown_speed``, has no event in the phase)."""
        xi = np.ascontiguousarray(xi, dtype=np.float64)
        if xi.ndim != 2 or xi.shape[1] != self.dimension:
            raise ValueError(f"xi must have shape (N, {self.dimension}), got {xi.shape}")
        gust = np.ascontiguousarray(xi[:, : self.innovations])
        values = np.ascontiguousarray(self.parameters(xi)) if self.parameter_keys else None
        if self.client is not None:
            from quadrs.rare.distributed import evaluate_on_dask

            metrics = evaluate_on_dask(self.client, self._engine_args(), gust, values)
        else:
            metrics = run_rows(*self._engine_args(), gust, values, self.workers)
        row = metrics[:, self._phase_index, :]
        picked = row[:, self._metric_index]
        diverged = np.isnan(row).all(axis=1)
        return np.where(diverged, np.inf, np.where(np.isnan(picked), -np.inf, picked))

    def _engine_args(self) -> tuple[str, str, list[str]]:
        return self.scenario.to_json(), self.controller, list(self.parameter_keys)

    def flown_scenario(self, xi_row: np.ndarray) -> Scenario:
        """The fixed scenario a row flies: the dispersed keys set to the row's values."""
        if not self.parameter_keys:
            return self.scenario
        theta = self.parameters(np.asarray(xi_row, dtype=np.float64)[None, :])[0]
        return self.scenario.fixed(
            {k: float(v) for k, v in zip(self.parameter_keys, theta, strict=True)}
        )

    def fly(self, xi_row: np.ndarray) -> Flight:
        """The flight of one row of innovations, with its trace (about one row a millisecond)."""
        from quadrs.runs.flight import default_record_every, flight_of

        row = np.ascontiguousarray(xi_row, dtype=np.float64)
        if row.shape != (self.dimension,):
            raise ValueError(f"xi_row must have shape ({self.dimension},), got {row.shape}")
        # The fixed scenario of the row's parameter values, set by override: the batch's
        # per-row values fly exactly this (tested bit for bit).
        scenario = self.flown_scenario(row)
        gust = np.ascontiguousarray(row[: self.innovations])
        record_every = default_record_every(self.scenario)
        progress = _core.Progress()
        simulate = engine_function("simulate_innovations", scenario.to_json())
        out, interrupted = run_cancellable(
            lambda: simulate(self.controller, gust, record_every, progress), progress
        )
        if interrupted:
            raise KeyboardInterrupt
        return flight_of(out, scenario, self.controller, (0, 0), record_every)
