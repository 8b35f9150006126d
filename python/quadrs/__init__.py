"""quadrs: Monte Carlo of a quadrotor carrying a spring-attached payload through Dryden gusts.

The public API; see the README for a tour.
"""

from quadrs._core import EngineError, ScenarioError, __version__
from quadrs.design.constraints import Constraint
from quadrs.design.optimize import InfeasibleWarning, OptimizeResult, optimize
from quadrs.design.sensitivity import SensitivityResult, sensitivity
from quadrs.hover.linear import LinearModel, linearize
from quadrs.hover.stability import (
    StabilityNote,
    StabilityReport,
    StabilityWarning,
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

__all__ = [
    "Constraint",
    "EngineError",
    "Flight",
    "InfeasibleWarning",
    "LinearModel",
    "MonteCarloResult",
    "OptimizeResult",
    "PlausibilityWarning",
    "RareEventComparison",
    "RareEventResult",
    "Scenario",
    "ScenarioError",
    "SensitivityResult",
    "StabilityNote",
    "StabilityReport",
    "StabilityWarning",
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
