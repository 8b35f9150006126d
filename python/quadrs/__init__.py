"""quadrs: Monte Carlo of a quadrotor carrying a spring-attached payload through Dryden gusts.

The public API; see the README for a tour.
"""

from quadrs._core import EngineError, ScenarioError, __version__
from quadrs.constraints import Constraint
from quadrs.flight import Flight, simulate
from quadrs.gust import gust_scales, gust_series
from quadrs.linear import LinearModel, linearize
from quadrs.montecarlo import MonteCarloResult, monte_carlo
from quadrs.optimize import InfeasibleWarning, OptimizeResult, optimize
from quadrs.plausibility import PlausibilityWarning
from quadrs.rare import RareEventComparison, RareEventResult, rare_event
from quadrs.scenario import Scenario
from quadrs.sensitivity import SensitivityResult, sensitivity
from quadrs.stability import (
    StabilityNote,
    StabilityReport,
    StabilityWarning,
    StepSizeWarning,
    stability,
)
from quadrs.sweep import sweep

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
