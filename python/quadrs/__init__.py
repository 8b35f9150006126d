"""quadrs: Monte Carlo of a quadrotor carrying a spring-attached payload through Dryden gusts.

The public API; see the README for a tour.
"""

from quadrs._core import EngineError, ScenarioError, __version__
from quadrs.flight import Flight, simulate
from quadrs.gust import gust_scales, gust_series
from quadrs.montecarlo import MonteCarloResult, monte_carlo
from quadrs.scenario import Scenario
from quadrs.stability import StabilityReport, StabilityWarning, StepSizeWarning, stability
from quadrs.sweep import sweep

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
