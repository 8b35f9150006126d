"""Brute-force tail probabilities of docs/rare-events.md's worked example, the reference the
rare-event tests hold subset simulation to (tests/data/rare_brute_force.json).

The short gust scenario of the tests (tests/conftest.py SHORT: take-off, a 1 s vertical gust in
P2, landing; 1000 innovations a flight), PD, ``max_accel`` in P2: ``--flights`` flights driven by
independent standard normals (the same engine path as ``quadrs.rare_event``, in chunks), and
for each threshold the count of flights above it with its exact (Clopper-Pearson) 95 % interval.

    python benches/brute_force.py --flights 2000000 --workers 2 --out brute.json

About 6,000 flights a second a core on the machine of docs/performance.md; 1e7 flights take
about 15 minutes on 2 cores.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import binomtest

import quadrs
from quadrs.rare.scenario_model import ScenarioModel

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))
from conftest import SHORT  # noqa: E402

THRESHOLDS = (4.9, 7.0, 7.5)
CHUNK = 20_000


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--flights", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--controller", default="pd")
    ap.add_argument("--out", type=Path, help="write the counts as JSON here")
    args = ap.parse_args(argv)
    scenario = quadrs.Scenario.paper().override(SHORT)
    model = ScenarioModel(scenario, args.controller, "max_accel", "P2", workers=args.workers)
    rng = np.random.default_rng(args.seed)
    counts = dict.fromkeys(THRESHOLDS, 0)
    flown, start = 0, time.perf_counter()
    while flown < args.flights:
        n = min(CHUNK, args.flights - flown)
        values = model.evaluate(rng.standard_normal((n, model.dimension)))
        for t in THRESHOLDS:
            counts[t] += int((values > t).sum())
        flown += n
        print(f"\r{flown} flights, {time.perf_counter() - start:.0f} s", end="", file=sys.stderr)
    print(file=sys.stderr)
    rows = {}
    for t, k in counts.items():
        ci = binomtest(k, flown).proportion_ci(method="exact")
        rows[str(t)] = {"events": k, "flights": flown, "p": k / flown,
                        "low": float(ci.low), "high": float(ci.high)}  # fmt: skip
        print(f"max_accel in P2 > {t}: {k} of {flown}, p = {k / flown:.3g}, "
              f"95 % [{ci.low:.3g}, {ci.high:.3g}]")  # fmt: skip
    if args.out:
        args.out.write_text(json.dumps({"controller": args.controller, "seed": args.seed,
                                        "thresholds": rows}, indent=1) + "\n")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
