"""A scenario, a controller, a metric and a phase as a model of standard normals, for subset
simulation: the flight driven by explicit innovations xi (the unit white noise of the Dryden
filters' exact discretisation, docs/model.md section 4) instead of a seeded gust stream.

The protocol the sampler relies on (:class:`RareEventModel`):

- ``dimension``: standard normals per flight;
- ``evaluate(xi)``: (N, dimension) -> (N,) metric values, one batch of flights; a diverged
  flight counts as +inf (an exceedance, as in ``MonteCarloResult.exceedance``);
- ``fly(xi_row)``: the :class:`~quadrs.flight.Flight` of one row, with its trace.

The engine functions, in ``_core`` (see docs/rare-events.md, "The engine interface"):

- ``innovations_dimension(config_json) -> int``;
- ``run_innovations(config_json, controller, xi, progress, workers) -> metrics`` with ``xi``
  float64 (N, dimension), ``metrics`` (N, phases, len(METRIC_NAMES)), NaN after a divergence;
- ``simulate_innovations(config_json, controller, xi_row, record_every, progress) -> dict``,
  the dict :func:`quadrs._core.simulate` returns.

An engine built without them raises NotImplementedError naming what is missing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from quadrs import _core
from quadrs.guard import MAX_WORKERS, check_controller, check_int, run_cancellable
from quadrs.scenario import Scenario

if TYPE_CHECKING:  # pragma: no cover
    from quadrs.flight import Flight

__all__ = ["RareEventModel", "ScenarioModel", "engine_function"]


class RareEventModel(Protocol):
    """What :func:`quadrs.rare_event` needs of a model of flights."""

    @property
    def dimension(self) -> int: ...

    def evaluate(self, xi: np.ndarray) -> np.ndarray: ...

    def fly(self, xi_row: np.ndarray) -> Flight: ...


def engine_function(name: str) -> Callable[..., Any]:
    """The engine's ``name``, or NotImplementedError saying that the innovations interface
    (flights driven by explicit standard normals) is not in this build."""
    fn = getattr(_core, name, None)
    if fn is None:
        raise NotImplementedError(
            f"the engine's innovations interface (a flight driven by explicit standard normals "
            f"xi, quadrs._core.{name}) is not in this build of the engine; "
            f"rare_event(limit_state=...) runs the same algorithm on a function of standard "
            f"normals"
        )
    return fn


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
    ) -> None:
        from quadrs.flight import METRIC_COLUMNS

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
        if scenario.dispersed:
            raise ValueError(
                "rare_event flies a fixed scenario: its random inputs are the gust's innovations "
                f"only, and this one disperses {sorted(scenario.dispersions)}; fix them "
                "(scenario.fixed()) or study them with monte_carlo"
            )
        self.scenario = scenario
        self.metric = metric
        self.phase = phase
        self._metric_index = METRIC_COLUMNS.index(metric)
        self._phase_index = phases.index(phase)
        self._dimension: int | None = None
        #: Threads flying a batch (None: all cores); results do not depend on it.
        self.workers = None if workers is None else check_int("workers", workers, 1, MAX_WORKERS)

    @property
    def name(self) -> str:
        """How the value is named in tables: ``metric`` in ``phase``."""
        return f"{self.metric}_{self.phase}"

    @property
    def dimension(self) -> int:
        """Standard normals per flight (the engine's count of the gust filters' innovations)."""
        if self._dimension is None:
            count = engine_function("innovations_dimension")(self.scenario.to_json())
            self._dimension = int(count)
        return self._dimension

    def evaluate(self, xi: np.ndarray) -> np.ndarray:
        """The metric of each row's flight (+inf where the flight diverged)."""
        run = engine_function("run_innovations")
        xi = np.ascontiguousarray(xi, dtype=np.float64)
        if xi.ndim != 2 or xi.shape[1] != self.dimension:
            raise ValueError(f"xi must have shape (N, {self.dimension}), got {xi.shape}")
        progress = _core.Progress()
        config = self.scenario.to_json()
        metrics, interrupted = run_cancellable(
            lambda: run(config, self.controller, xi, progress, self.workers), progress
        )
        if interrupted:
            raise KeyboardInterrupt
        values = np.asarray(metrics, dtype=np.float64)[:, self._phase_index, self._metric_index]
        return np.where(np.isnan(values), np.inf, values)

    def fly(self, xi_row: np.ndarray) -> Flight:
        """The flight of one row of innovations, with its trace (about one row a millisecond)."""
        import pandas as pd

        from quadrs.flight import Flight, metrics_frame

        simulate = engine_function("simulate_innovations")
        row = np.ascontiguousarray(xi_row, dtype=np.float64)
        if row.shape != (self.dimension,):
            raise ValueError(f"xi_row must have shape ({self.dimension},), got {row.shape}")
        record_every = max(1, round(1e-3 / float(self.scenario["integrator.dt"])))
        progress = _core.Progress()
        config = self.scenario.to_json()
        out, interrupted = run_cancellable(
            lambda: simulate(config, self.controller, row, record_every, progress), progress
        )
        if interrupted:
            raise KeyboardInterrupt
        raw = out["trace"]
        # The scenario's own layout (its payload and actuator models add or drop columns).
        trace = pd.DataFrame(raw[:, 1:], index=pd.Index(raw[:, 0], name="t"),
                             columns=out["trace_columns"])  # fmt: skip
        phases = self.scenario.phase_names
        spectra = {
            name: pd.DataFrame({"frequency": f, "amplitude": a})
            for name, f, a in zip(
                phases, self.scenario.spectrum_frequencies, out["spectra"], strict=True
            )
        }
        return Flight(
            scenario=self.scenario,
            controller=self.controller,
            seed=0,
            realisation=0,
            metrics=metrics_frame(phases, out["metrics"]),
            trace=trace,
            spectra=spectra,
            diverged_at=float(out["diverged_at"]),
            record_every=record_every,
            status=out["status"],
        )
