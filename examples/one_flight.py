"""One flight of the paper preset with the SMC, its metrics and its figures.

python examples/one_flight.py [OUT_DIR]
"""

import sys
from pathlib import Path

import quadrs
from quadrs import plots

out = Path(sys.argv[1] if len(sys.argv) > 1 else "example_output")
# A short flight: take-off, a 2 s gust, landing, in 10 s (the paper's is 70 s).
s = quadrs.Scenario.paper().override(
    {
        "integrator.duration": 10.0,
        "integrator.dt": 0.001,
        "trajectory.waypoints": [[0, 0, 0, 2, 0], [7, 0, 0, 0, 0]],
        "phases": [
            {"name": "P1", "start": 0, "end": 3},
            {"name": "P2", "start": 3, "end": 7},
            {"name": "P3", "start": 7, "end": 10},
        ],
        "gust.start": 4.0,
        "gust.end": 6.0,
    }
)
flight = quadrs.simulate(s, controller="smc", seed=0)
print(flight.metrics.round(5).to_string(index=False))
plots.altitude(flight, path=out / "altitude")
plots.oscillation(flight, path=out / "oscillation")
print(f"figures in {out}")
