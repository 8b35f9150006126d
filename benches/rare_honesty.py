"""Is subset simulation honest on real flights? Repeated runs of docs/rare-events.md's worked
example (or of the delivery preset over its drop point, ``--case delivery-drop``: see
benches/rare_cases.py) against the brute-force probabilities of
tests/data/rare_brute_force.json: the mean
estimate over the true p (with its standard error), how many stated 95 % intervals cover p,
the mean flights, and the measured CoV (the spread of the estimates over p, not the stated one)
with what plain Monte Carlo would need for it.

    python benches/rare_honesty.py --threshold 7.0 --seeds 100
    python benches/rare_honesty.py --threshold 7.0 --seeds 100 --method adaptive   # round 3
    python benches/rare_honesty.py --case delivery-drop --threshold 0.22 --per-level 200

``--method adaptive`` runs the round-3 estimator (adaptive levels, Au & Beck's CoV, a 1.96
lognormal interval), which is now only the pilot of ``quadrs.rare_event``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from quadrs.rare.scenario_model import ScenarioModel
from quadrs.rare.subset import _adaptive, _Evaluator, lognormal_interval, subset_simulation

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benches"))
from rare_cases import CASES  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="worked", choices=sorted(CASES))
    ap.add_argument("--threshold", default="7.0", help="one of the case's brute-force thresholds")
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--first-seed", type=int, default=0)
    ap.add_argument("--per-level", type=int, default=500)
    ap.add_argument("--method", default="two-stage", choices=["two-stage", "adaptive"])
    ap.add_argument("--workers", type=int, default=None)
    args = ap.parse_args(argv)
    brute = json.loads((ROOT / "tests" / "data" / "rare_brute_force.json").read_text())
    if args.case != "worked":
        brute = brute["cases"][args.case]
    p = brute["thresholds"][args.threshold]["p"]
    t = float(args.threshold)
    case = CASES[args.case]
    model = ScenarioModel(case.scenario(), "pd", case.metric, case.phase, workers=args.workers)
    est, covered, flights = [], 0, []
    start = time.perf_counter()
    for seed in range(args.first_seed, args.first_seed + args.seeds):
        if args.method == "adaptive":
            ev = _Evaluator(model.evaluate, "flights")
            rng = np.random.default_rng(seed)
            r = _adaptive(ev, model.dimension, t, args.per_level, 0.1, seed, 12, rng)
            interval = lognormal_interval(r.probability, r.cov) if r.probability else (0, 1)
        else:
            r = subset_simulation(model.evaluate, model.dimension, t, per_level=args.per_level,
                                  seed=seed)  # fmt: skip
            interval = r.interval or (0.0, 1.0)
        est.append(r.probability or 0.0)
        covered += interval[0] <= p <= interval[1]
        flights.append(r.flights)
    e = np.array(est)
    cov = e.std(ddof=1) / p
    mc = (1 - p) / (p * cov * cov)
    took = time.perf_counter() - start
    print(f"{args.method}, {case.metric} in {case.phase} > {t}, p = {p:.3g}, {args.seeds} seeds "
          f"from "
          f"{args.first_seed}, per_level {args.per_level}: mean / p = {e.mean() / p:.3f} "
          f"(se {cov / math.sqrt(len(e)):.3f}), {covered} of {len(e)} intervals cover, "
          f"{np.mean(flights):.0f} flights, measured CoV {cov:.2f}, plain Monte Carlo for it "
          f"{mc:.3g} ({mc / np.mean(flights):.1f}x), {took:.0f} s")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
