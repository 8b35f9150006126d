"""Sweep the payload's natural frequency: peak |e_o| per controller and point.

python examples/sweep.py [RUNS]
"""

import sys
import warnings

import quadrs

runs = int(sys.argv[1]) if len(sys.argv) > 1 else 4
s = quadrs.Scenario.paper().override({"integrator.dt": 0.002})
with warnings.catch_warnings():
    warnings.simplefilter("ignore", quadrs.StabilityWarning)  # see examples/monte_carlo.py
    result = quadrs.sweep(s, {"payload.natural_frequency": [1.0, 2.0, 4.0]}, runs=runs)
print(result.compact().round(4).to_string())
