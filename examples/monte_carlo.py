"""A Monte Carlo of paired PD/SMC gust realisations and its Table 3.

python examples/monte_carlo.py [RUNS]
"""

import sys
import warnings

import quadrs
from quadrs.present.table3 import format_table3

runs = int(sys.argv[1]) if len(sys.argv) > 1 else 20
s = quadrs.Scenario.paper().override({"integrator.dt": 0.002})  # coarser than the paper's
with warnings.catch_warnings():
    # The paper's SMC is unstable laterally, in modes its vertical flights never excite.
    warnings.simplefilter("ignore", quadrs.StabilityWarning)
    mc = quadrs.monte_carlo(s, runs=runs, seed=0, progress=False)
print(format_table3(mc.summary()))
