"""The engine's innovations interface, called for a batch of rows: locally or on a Dask
worker (:mod:`quadrs.rare.distributed`), the same call."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from quadrs import _core
from quadrs.engine.calls import run_cancellable
from quadrs.engine.compiled import compiled

__all__ = ["engine_function", "run_rows"]


def engine_function(name: str, config: str) -> Callable[..., Any]:
    """The compiled engine's method ``name`` for the scenario ``config`` (its JSON), or
    NotImplementedError saying that the innovations interface (flights driven by explicit
    standard normals) is not in this build."""
    fn = getattr(_core, name, None) and getattr(compiled(config), name, None)
    if fn is None:
        raise NotImplementedError(
            f"the engine's innovations interface (a flight driven by explicit standard normals "
            f"xi, quadrs._core.{name}) is not in this build of the engine; "
            f"rare_event(limit_state=...) runs the same algorithm on a function of standard "
            f"normals"
        )
    return fn


def run_rows(
    config: str,
    controller: str,
    keys: list[str],
    gust: np.ndarray,
    values: np.ndarray | None,
    workers: int | None,
) -> np.ndarray:
    """The engine's metrics (N, phases, metrics) of rows of innovations (and parameter
    values), Ctrl-C turned into a prompt cancel and KeyboardInterrupt."""
    run = engine_function("run_innovations", config)
    progress = _core.Progress()
    extra = {} if values is None else {"dispersion_keys": keys, "dispersion_values": values}
    metrics, interrupted = run_cancellable(
        lambda: run(controller, gust, progress, workers, **extra), progress
    )
    if interrupted:
        raise KeyboardInterrupt
    return np.asarray(metrics, dtype=np.float64)
