"""Rare events: P(metric > threshold) far below what plain Monte Carlo can reach, by subset
simulation (Au & Beck 2001). See docs/rare-events.md.

:func:`rare_event` takes either a scenario (the flight as a function of its gust's standard
normal innovations, :mod:`quadrs.rare.scenario_model`) or a plain ``limit_state`` function of
standard normals; both go through :func:`quadrs.rare.subset.subset_simulation`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from quadrs.engine.calls import check_int
from quadrs.rare.result import RareEventComparison, RareEventResult
from quadrs.rare.scenario_model import RareEventModel, ScenarioModel
from quadrs.rare.subset import Level, Model, check_settings, check_threshold, subset_simulation
from quadrs.scenario.scenario import Scenario

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

__all__ = ["METHODS", "RareEventComparison", "RareEventResult", "rare_event"]

#: The methods :func:`rare_event` knows.
METHODS = ("subset",)

LimitState = Callable[[np.ndarray], Any]


def rare_event(
    scenario: Scenario | None = None,
    controller: str = "pd",
    metric: str | None = None,
    phase: str | None = None,
    threshold: float | None = None,
    method: str = "subset",
    per_level: int = 1000,
    p0: float = 0.1,
    seed: int = 0,
    *,
    limit_state: LimitState | Mapping[str, LimitState] | None = None,
    dimension: int | None = None,
    controllers: Sequence[str] | None = None,
    max_levels: int | None = None,
    workers: int | None = None,
    on_level: Callable[[Level], None] | None = None,
    client: Client | None = None,
) -> RareEventResult | RareEventComparison:
    """P(value > ``threshold``) by subset simulation, with its coefficient of variation and a
    95 % interval (see :class:`RareEventResult` and docs/rare-events.md).

    Scenario run: ``rare_event(s, controller="pd", metric="max_accel", phase="P2",
    threshold=8.0)``: the value is ``metric`` in ``phase`` of a flight of ``s``, whose random
    inputs are its gust's innovations and, if ``s`` has ``[dispersions]``, one standard normal
    per dispersed key (its value F^-1(Phi(z)), after the gust's in each row); a diverged
    flight counts as an exceedance.
    ``controllers=("pd", "smc")`` instead runs every controller on the same seed (the same
    first level of gusts, the same proposal normals) and returns a
    :class:`RareEventComparison` (``.ratio("smc", "pd")``).

    Limit-state run: ``rare_event(limit_state=f, dimension=n, threshold=t)``, with
    ``f((N, n) standard normals) -> (N,) values``, vectorised over rows. A mapping of names to
    functions runs them paired, as ``controllers`` does.

    ``per_level``: samples per level; ``p0``: the fraction of each level kept as seeds of the
    next (1/L for a whole L: 0.1, 0.2, 0.25, 0.5); ``p0 * per_level`` >= 10 chains.
    ``max_levels``: the deepest level tried before reporting that no failure was found
    (default: enough for about 1e-12). Flights: ``per_level * (1 + (levels - 1) * (1 - p0))``.
    ``workers``: threads flying each batch of a scenario run (default: all cores; the result
    does not depend on it). ``on_level(level)``: called as each level is done (progress).
    ``client``: a ``dask.distributed.Client``; each batch's flights are then spread over its
    workers (``workers`` is then theirs), with the same result as on one machine.

    Ctrl-C stops the run and returns what the finished levels found (``result.interrupted``;
    no estimate, ``upper_bound`` the probability of the last cut reached); a paired run
    stops there too, with the controllers done and the interrupted one.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if threshold is None:
        raise ValueError("threshold is required: rare_event estimates P(value > threshold)")
    # Every argument is checked before anything flies.
    threshold = check_threshold(threshold)
    settings: dict[str, Any] = {"per_level": per_level, "p0": p0, "max_levels": max_levels}
    settings["per_level"], settings["p0"], settings["max_levels"] = check_settings(**settings)
    settings["seed"] = check_int("seed", seed)
    settings["on_level"] = on_level

    if limit_state is not None:
        if scenario is not None:
            raise ValueError("give either a scenario or limit_state=, not both")
        scenario_only = (metric, phase, controllers, workers, client)
        if any(v is not None for v in scenario_only):
            raise ValueError(
                "metric, phase, controllers, workers and client belong to a scenario run; a "
                "limit_state run has its function and dimension only"
            )
        if dimension is None:
            raise ValueError("dimension is required with limit_state= (standard normals a row)")
        if isinstance(limit_state, Mapping):
            if not limit_state or not all(callable(f) for f in limit_state.values()):
                raise ValueError("limit_state must be a function or a non-empty mapping of "
                                 "names to functions")  # fmt: skip
            return RareEventComparison(
                {
                    str(name): _run(f, dimension, threshold, str(name), settings)
                    for name, f in limit_state.items()
                }
            )
        if not callable(limit_state):
            raise ValueError(f"limit_state must be a function, got {type(limit_state).__name__}")
        return _run(limit_state, dimension, threshold, "limit_state", settings)

    if scenario is None:
        raise ValueError("give a scenario (with metric and phase) or limit_state=")
    if dimension is not None:
        raise ValueError("dimension is set by the scenario (its gust's innovations); "
                         "it is only for limit_state=")  # fmt: skip
    if metric is None or phase is None:
        raise ValueError("a scenario run needs metric= and phase= (e.g. 'max_accel', 'P2')")
    names = tuple(controllers) if controllers is not None else (controller,)
    if not names or len(set(names)) != len(names):
        raise ValueError(f"controllers must be distinct and non-empty, got {names}")
    if client is not None and workers is not None:
        raise ValueError("give workers= or client=, not both: with a client, each Dask "
                         "worker's threads fly its rows")  # fmt: skip
    models = [ScenarioModel(scenario, c, metric, phase, workers, client) for c in names]
    from quadrs.hover.stability import warn_before_running

    warn_before_running(scenario, names, gains=True, stacklevel=2)
    results: dict[str, RareEventResult] = {}
    for m in models:
        results[m.controller] = _run_model(m, threshold, settings)
        if results[m.controller].interrupted:
            break
    if controllers is None:
        return results[controller]
    return RareEventComparison(results)


def _run(
    f: Model, dimension: int, threshold: float, name: str, settings: dict[str, Any]
) -> RareEventResult:
    run = subset_simulation(f, dimension, threshold, name=name, **settings)
    return RareEventResult(run, value_name=name)


def _run_model(
    model: RareEventModel, threshold: float, settings: dict[str, Any]
) -> RareEventResult:
    name = getattr(model, "name", "value")
    run = subset_simulation(model.evaluate, model.dimension, threshold, name=name, **settings)
    return RareEventResult(run, value_name=name, model=model)
