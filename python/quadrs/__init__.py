"""quadrs: Monte Carlo simulation of a quadrotor carrying a payload (a spring-attached mass as
in Geronel, Botez & Bueno 2023, or a cable-slung load) through turbulence, wind and gusts, with
a Rust engine: single flights, paired Monte Carlo batches, sweeps, stability and linear models
at hover, tuning, sensitivity, mission risk along a route, and rare events by subset
simulation.

The public API; see the README for a tour. The names below load on first use (PEP 562), so
``import quadrs`` is quick: pandas, scipy and matplotlib come with the first flight, table or
figure.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from quadrs._core import EngineError, ScenarioError, __version__

if TYPE_CHECKING:  # what mypy and editors see: the same names, imported eagerly
    from quadrs.design.constraints import Constraint
    from quadrs.design.optimize import (
        InfeasibleWarning,
        OptimizeOptions,
        OptimizeResult,
        optimize,
    )
    from quadrs.design.sensitivity import SensitivityResult, sensitivity
    from quadrs.hover.linear import LinearModel, SampledLawNote, linearize
    from quadrs.hover.stability import (
        StabilityNote,
        StabilityReport,
        StabilityWarning,
        StartWarning,
        StepSizeWarning,
        stability,
    )
    from quadrs.rare import RareEventComparison, RareEventResult, rare_event
    from quadrs.runs.flight import Flight, simulate
    from quadrs.runs.gust import gust_scales, gust_series
    from quadrs.runs.montecarlo import MonteCarloResult, monte_carlo
    from quadrs.runs.sweep import SweepResult, sweep
    from quadrs.scenario.plausibility import PlausibilityWarning
    from quadrs.scenario.scenario import Scenario

#: Public name -> the module that defines it (imported on first access).
_WHERE = {
    "Constraint": "quadrs.design.constraints",
    "InfeasibleWarning": "quadrs.design.optimize",
    "OptimizeOptions": "quadrs.design.optimize",
    "OptimizeResult": "quadrs.design.optimize",
    "optimize": "quadrs.design.optimize",
    "SensitivityResult": "quadrs.design.sensitivity",
    "sensitivity": "quadrs.design.sensitivity",
    "LinearModel": "quadrs.hover.linear",
    "linearize": "quadrs.hover.linear",
    "SampledLawNote": "quadrs.hover.linear",
    "StabilityNote": "quadrs.hover.stability",
    "StabilityReport": "quadrs.hover.stability",
    "StabilityWarning": "quadrs.hover.stability",
    "StartWarning": "quadrs.hover.stability",
    "StepSizeWarning": "quadrs.hover.stability",
    "stability": "quadrs.hover.stability",
    "RareEventComparison": "quadrs.rare",
    "RareEventResult": "quadrs.rare",
    "rare_event": "quadrs.rare",
    "Flight": "quadrs.runs.flight",
    "simulate": "quadrs.runs.flight",
    "gust_scales": "quadrs.runs.gust",
    "gust_series": "quadrs.runs.gust",
    "MonteCarloResult": "quadrs.runs.montecarlo",
    "monte_carlo": "quadrs.runs.montecarlo",
    "SweepResult": "quadrs.runs.sweep",
    "sweep": "quadrs.runs.sweep",
    "PlausibilityWarning": "quadrs.scenario.plausibility",
    "Scenario": "quadrs.scenario.scenario",
}

#: The layers, importable as attributes of the package as a regular import would make them.
_SUBPACKAGES = frozenset(
    {"cli", "design", "engine", "hover", "io", "paper", "plots", "present", "rare", "runs",
     "scenario", "stats"}
)  # fmt: skip

__all__ = [
    "Constraint",
    "EngineError",
    "Flight",
    "InfeasibleWarning",
    "LinearModel",
    "MonteCarloResult",
    "OptimizeOptions",
    "OptimizeResult",
    "PlausibilityWarning",
    "RareEventComparison",
    "RareEventResult",
    "SampledLawNote",
    "Scenario",
    "ScenarioError",
    "SensitivityResult",
    "StabilityNote",
    "StabilityReport",
    "StabilityWarning",
    "StartWarning",
    "StepSizeWarning",
    "SweepResult",
    "__version__",
    "gust_scales",
    "gust_series",
    "linearize",
    "monte_carlo",
    "optimize",
    "rare_event",
    "sensitivity",
    "simulate",
    "stability",
    "sweep",
]


def __getattr__(name: str) -> Any:
    """A public name, imported from its module on first use and then kept here."""
    module = _WHERE.get(name)
    if module is None:
        if name in _SUBPACKAGES:  # `quadrs.runs.flight` after a bare `import quadrs`
            return importlib.import_module(f"quadrs.{name}")
        raise AttributeError(f"module 'quadrs' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    """The public names and the layers (and the module's dunders): not the helpers this file
    imports for itself (``importlib``, ``Any``, ``TYPE_CHECKING``, ``annotations``)."""
    dunders = {n for n in globals() if n.startswith("__") and n.endswith("__")}
    return sorted({*__all__, *_SUBPACKAGES, *dunders})
