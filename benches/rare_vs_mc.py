"""Subset simulation against brute-force Monte Carlo on a quadrs scenario.

The scenario is the tests' short one (take-off, a 1 s gust, landing; dt = 2 ms: 1000
innovations a flight). A pilot Monte Carlo (its own seed) sets the threshold at a high
quantile of ``max_accel`` in the gust phase; then plain Monte Carlo on many flights (another
seed) and one subset simulation estimate P(max_accel > threshold), and the script prints
both estimates, their 95 % intervals, the flights each used and the ratio.

    PYTHONPATH=python python benches/rare_vs_mc.py [--mc-runs 40000] [--per-level 500]

A diverged flight counts as an exceedance on both sides (as in ``rare_event``).
Results: docs/rare-events.md, "Cost on a quadrs scenario".
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
from scipy.stats import beta

import quadrs

SHORT = {
    "integrator.duration": 6.0,
    "integrator.dt": 0.002,
    "trajectory.waypoints": [[0, 0, 0, 2, 0], [4, 0, 0, 0, 0]],
    "phases": [
        {"name": "P1", "start": 0, "end": 2},
        {"name": "P2", "start": 2, "end": 4},
        {"name": "P3", "start": 4, "end": 6},
    ],
    "gust.start": 2.5,
    "gust.end": 3.5,
}


def mc_values(s: quadrs.Scenario, runs: int, seed: int, controller: str, metric: str,
              phase: str, workers: int | None) -> np.ndarray:  # fmt: skip
    """``metric`` in ``phase`` of ``runs`` seeded flights; +inf where a flight diverged."""
    mc = quadrs.monte_carlo(s, runs=runs, seed=seed, controllers=(controller,),
                            workers=workers, progress=False, spectra=False)  # fmt: skip
    rows = mc.runs[(mc.runs["phase"] == phase) & (mc.runs["controller"] == controller)]
    values = rows[metric].to_numpy(np.float64)
    return np.where(rows["diverged"].to_numpy(bool), np.inf, values)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--controller", default="pd")
    ap.add_argument("--metric", default="max_accel")
    ap.add_argument("--phase", default="P2")
    ap.add_argument("--quantile", type=float, default=0.995, help="of the pilot run")
    ap.add_argument("--pilot-runs", type=int, default=2000)
    ap.add_argument("--mc-runs", type=int, default=40000)
    ap.add_argument("--per-level", type=int, default=500)
    ap.add_argument("--seed", type=int, default=0, help="subset simulation's seed")
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args()
    s = quadrs.Scenario.paper().override(SHORT)
    print(f"scenario: the tests' short one, {quadrs._core.innovations_dimension(s.to_json())} "
          f"innovations a flight; {a.controller}, {a.metric} in {a.phase}")  # fmt: skip

    t0 = time.perf_counter()
    pilot = mc_values(s, a.pilot_runs, 1, a.controller, a.metric, a.phase, a.workers)
    threshold = float(np.quantile(pilot, a.quantile))
    print(f"threshold: {threshold:.6g} (quantile {a.quantile} of a {a.pilot_runs}-flight pilot "
          f"run, seed 1; {time.perf_counter() - t0:.0f} s)")  # fmt: skip

    t0 = time.perf_counter()
    values = mc_values(s, a.mc_runs, 2, a.controller, a.metric, a.phase, a.workers)
    t_mc = time.perf_counter() - t0
    k, n = int((values > threshold).sum()), len(values)
    p_mc = k / n
    # Clopper-Pearson 95 % interval of a binomial proportion.
    lo = float(beta.ppf(0.025, k, n - k + 1)) if k else 0.0
    hi = float(beta.ppf(0.975, k + 1, n - k)) if k < n else 1.0
    cov_mc = math.sqrt((1 - p_mc) / (n * p_mc)) if k else math.inf
    print(f"monte carlo: p = {p_mc:.4g} ({k} of {n} flights), cov {cov_mc:.3f}, "
          f"95 % [{lo:.4g}, {hi:.4g}], {t_mc:.0f} s")  # fmt: skip

    t0 = time.perf_counter()
    r = quadrs.rare_event(s, controller=a.controller, metric=a.metric, phase=a.phase,
                          threshold=threshold, per_level=a.per_level, seed=a.seed,
                          workers=a.workers)  # fmt: skip
    t_ss = time.perf_counter() - t0
    assert isinstance(r, quadrs.RareEventResult)
    if r.probability is None or r.interval is None or r.cov is None:
        print(f"subset: {r!r}")
        return
    print(f"subset simulation: p = {r.probability:.4g}, cov {r.cov:.3f}, "
          f"95 % [{r.interval[0]:.4g}, {r.interval[1]:.4g}], {len(r.levels)} levels, "
          f"{r.flights} flights, {t_ss:.0f} s")  # fmt: skip
    overlap = max(lo, r.interval[0]) <= min(hi, r.interval[1])
    z = math.log(r.probability / p_mc) / math.sqrt(math.log1p(r.cov**2) + math.log1p(cov_mc**2))
    print(f"intervals overlap: {overlap}; log-ratio z = {z:+.2f}")
    print(f"flights: monte carlo {n} / subset {r.flights} = {n / r.flights:.1f}x")
    need = r.monte_carlo_flights
    if need is not None:
        print(f"monte carlo flights for the subset's cov ({r.cov:.3f}): {need:.0f} = "
              f"{need / r.flights:.1f}x the subset's")  # fmt: skip


if __name__ == "__main__":
    main()
