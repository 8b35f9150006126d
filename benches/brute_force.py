"""Brute-force tail probabilities, the reference the rare-event tests hold subset simulation to
(tests/data/rare_brute_force.json).

Two cases (``--case``):

- ``worked``: docs/rare-events.md's worked example, the short gust scenario of the tests
  (tests/conftest.py SHORT: take-off, a 1 s vertical gust in P2, landing; 1000 innovations a
  flight), PD, ``max_accel`` in P2. About 6,000 flights a second a core; 1e7 flights take
  about 15 minutes on 2 cores.
- ``delivery-drop``: the fourth round's delivery vehicle (paper body, no rotor aerodynamics, a
  fixed 1 m line, no ground contact, a start at rest), wind and turbulence over its drop point
  (tests/conftest.py FOURTH_ROUND_DELIVERY_DROP: a 2 m descent to 5 m, then the preset's 15 s
  hover), PD, the parcel's ``max_swing`` in the ``drop`` hover. About 60 flights a second a
  core.

``--flights`` flights driven by independent standard normals (the same engine path as
``quadrs.rare_event``, in chunks), and for each threshold the count of flights above it with
its exact (Clopper-Pearson) 95 % interval.

    python benches/brute_force.py --flights 2000000 --workers 2 --out brute.json
    python benches/brute_force.py --case delivery-drop --flights 100000 --workers 2
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import binomtest

from quadrs.rare.scenario_model import ScenarioModel

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benches"))
from rare_cases import CASES  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="worked", choices=sorted(CASES))
    ap.add_argument("--flights", type=int, default=1_000_000)
    ap.add_argument("--seed", type=int, default=12345)
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--controller", default="pd")
    ap.add_argument("--out", type=Path, help="write the counts as JSON here")
    args = ap.parse_args(argv)
    case = CASES[args.case]
    model = ScenarioModel(case.scenario(), args.controller, case.metric, case.phase,
                          workers=args.workers)  # fmt: skip
    rng = np.random.default_rng(args.seed)
    counts = dict.fromkeys(case.thresholds, 0)
    flown, start = 0, time.perf_counter()
    while flown < args.flights:
        n = min(case.chunk, args.flights - flown)
        values = model.evaluate(rng.standard_normal((n, model.dimension)))
        for t in case.thresholds:
            counts[t] += int((values > t).sum())
        flown += n
        print(f"\r{flown} flights, {time.perf_counter() - start:.0f} s", end="", file=sys.stderr)
    print(file=sys.stderr)
    rows = {}
    for t, k in counts.items():
        ci = binomtest(k, flown).proportion_ci(method="exact")
        rows[str(t)] = {"events": k, "flights": flown, "p": k / flown,
                        "low": float(ci.low), "high": float(ci.high)}  # fmt: skip
        print(f"{case.metric} in {case.phase} > {t}: {k} of {flown}, p = {k / flown:.3g}, "
              f"95 % [{ci.low:.3g}, {ci.high:.3g}]")  # fmt: skip
    if args.out:
        args.out.write_text(json.dumps({"case": args.case, "controller": args.controller,
                                        "seed": args.seed, "thresholds": rows},
                                       indent=1) + "\n")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
