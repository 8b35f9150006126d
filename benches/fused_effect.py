"""The fused mode's effect on every metric: the same realisations in the default and the fused
mode, compared row by row.

    python benches/fused_effect.py                 # paper preset, 200 paired realisations
    python benches/fused_effect.py --runs 50 --preset paper

Prints, per metric, the largest relative difference |fused - exact| / |exact| over all
(realisation, controller, phase) rows, the relative difference of the ensemble means, and
whether any realisation's divergence verdict changed. Both runs use the same SIMD path (the
best this CPU has, or QUADRS_SIMD).
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import quadrs
from quadrs import _core


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args()
    warnings.simplefilter("ignore")  # the paper's SMC stability warning
    scenario = quadrs.Scenario.preset(args.preset)
    res, wall = {}, {}
    for fused in (False, True):
        t0 = time.perf_counter()
        res[fused] = quadrs.monte_carlo(
            scenario, args.runs, args.seed, workers=args.workers, progress=False, fused=fused
        )
        wall[fused] = time.perf_counter() - t0
    exact, fused = res[False].runs, res[True].runs
    print(f"quadrs {quadrs.__version__}, SIMD path {_core.simd_path()}, preset {args.preset}, ")
    print(f"{args.runs} paired realisations, seed {args.seed}")
    same = (exact["diverged"] == fused["diverged"]).all()
    print(f"divergence verdicts identical: {same} ({int(exact['diverged'].sum())} diverged rows)")
    ok = ~(exact["diverged"] | fused["diverged"]).to_numpy()
    print(f"{'metric':16s} {'max |rel diff|':>15s} {'mean rel diff':>15s} {'bit-equal rows':>15s}")
    for m in _core.METRIC_NAMES:
        a, b = exact[m].to_numpy()[ok], fused[m].to_numpy()[ok]
        rel = np.abs(b - a) / np.maximum(np.abs(a), np.finfo(float).tiny)
        mean_rel = abs(b.mean() - a.mean()) / abs(a.mean())
        equal = np.mean(a == b)
        print(f"{m:16s} {rel.max():15.2e} {mean_rel:15.2e} {equal:15.1%}")
    print(
        f"wall time, {args.workers} worker(s): exact {wall[False]:.1f} s, fused "
        f"{wall[True]:.1f} s (fused/exact throughput {wall[False] / wall[True]:.3f})"
    )


if __name__ == "__main__":
    main()
