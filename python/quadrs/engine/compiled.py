"""A scenario's compiled engine: validated and built once (vehicle, reference, gust filters),
then flown by every call that needs it (single flights, Monte Carlo chunks, stability,
linearisation, rare-event levels), instead of each call re-reading the scenario's JSON.

Engines are cached by the scenario's JSON, so a scenario that crosses a process boundary (a
Dask task, a pickled Scenario) compiles once per process too. An engine is immutable and
safe to share between threads.
"""

from __future__ import annotations

from functools import lru_cache

from quadrs import _core

__all__ = ["compiled"]

#: Engines kept per process (a tuning loop's scenarios come and go; a batch's stay).
CACHED_ENGINES = 16


@lru_cache(maxsize=CACHED_ENGINES)
def compiled(config_json: str) -> _core.Engine:
    """The engine of the scenario ``config_json`` (``Scenario.to_json()``), built on first use.
    A scenario the engine refuses raises :class:`quadrs.ScenarioError` (and is not cached)."""
    return _core.Engine(config_json)
