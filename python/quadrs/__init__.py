"""quadrs: Monte Carlo of a quadrotor carrying a spring-attached payload through Dryden gusts.

The public API; see the README for a tour. Names are imported on first use (PEP 562), so that
``import quadrs`` and ``quadrs --version`` stay fast: pandas, scipy and matplotlib load only
when something needs them.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from quadrs._core import EngineError, ScenarioError, __version__

if TYPE_CHECKING:  # pragma: no cover
    from quadrs.flight import Flight, simulate
    from quadrs.gust import gust_scales, gust_series
    from quadrs.montecarlo import MonteCarloResult, monte_carlo
    from quadrs.scenario import Scenario
    from quadrs.stability import StabilityReport, StabilityWarning, StepSizeWarning, stability
    from quadrs.sweep import sweep

#: Public name -> the module that defines it.
_LAZY = {
    "Flight": "quadrs.flight",
    "simulate": "quadrs.flight",
    "gust_scales": "quadrs.gust",
    "gust_series": "quadrs.gust",
    "MonteCarloResult": "quadrs.montecarlo",
    "monte_carlo": "quadrs.montecarlo",
    "Scenario": "quadrs.scenario",
    "StabilityReport": "quadrs.stability",
    "StabilityWarning": "quadrs.stability",
    "StepSizeWarning": "quadrs.stability",
    "stability": "quadrs.stability",
    "sweep": "quadrs.sweep",
}

__all__ = [
    "EngineError",
    "Flight",
    "MonteCarloResult",
    "Scenario",
    "ScenarioError",
    "StabilityReport",
    "StabilityWarning",
    "StepSizeWarning",
    "__version__",
    "gust_scales",
    "gust_series",
    "monte_carlo",
    "simulate",
    "stability",
    "sweep",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'quadrs' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
