"""docs/model.md, "Loop rates": the delivery preset's answer as shipped (its loops at PX4's
rates, its wind at 100 Hz, a 2 ms step) against the same at a 1 ms step, and against every loop
and the wind at every 1 ms step (200 paired flights each, PD): means with their 95 % intervals
(Student), q95 with its distribution-free 95 % interval."""

import numpy as np
from scipy import stats

import quadrs

EVERY_STEP = {
    "controller.position_rate": 0.0,
    "controller.attitude_rate": 0.0,
    "controller.inner_rate": 0.0,
    "gust.rate": 0.0,
    "integrator.dt": 0.001,
}
d = quadrs.Scenario.preset("delivery")
cases = {
    "as shipped (2 ms)": d,
    "at rates, 1 ms": d.override({"integrator.dt": 0.001}),
    "every 1 ms step": d.override(EVERY_STEP),
}
for name, s in cases.items():
    mc = quadrs.monte_carlo(s, runs=200, seed=0, controllers=("pd",), progress=False)
    r = mc.runs[mc.runs.phase == "flight"]
    for m in ("touchdown_speed", "tracking_rms", "max_swing", "touchdown_miss"):
        x = np.sort(r[m].to_numpy())
        n = len(x)
        half = 1.96 * x.std(ddof=1) / np.sqrt(n)
        # The q95's distribution-free interval: the order statistics the binomial puts it between.
        lo, hi = stats.binom.ppf([0.025, 0.975], n, 0.95).astype(int)
        q = np.quantile(x, 0.95)
        print(f"{name:18s} {m:16s} mean {x.mean():.4g} +- {half:.2g}  "
              f"q95 {q:.4g} [{x[lo - 1]:.4g}, {x[min(hi, n - 1)]:.4g}]")  # fmt: skip
