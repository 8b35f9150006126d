"""The paper's tables and figures, and report.md, from small runs (minutes at full size).

python examples/paper.py [OUT_DIR] [RUNS]
"""

import sys
import warnings

import quadrs
from quadrs.paper.pipeline import paper

out = sys.argv[1] if len(sys.argv) > 1 else "paper_output"
runs = int(sys.argv[2]) if len(sys.argv) > 2 else 8
s = quadrs.Scenario.paper().override({"integrator.dt": 0.002})
with warnings.catch_warnings():
    warnings.simplefilter("ignore", quadrs.StabilityWarning)  # see examples/monte_carlo.py
    result = paper(
        out, s, runs=runs, sweep_runs=2, frequencies=[1.0, 4.0], masses=[0.22], progress=False
    )
print(f"wrote {len(result.files)} files to {result.out}; read {result.out}/report.md")
