"""subset simulation on a flight-like analytic limit state with a known tail (docs/rare-events.md,
"What was wrong"): the peak |response| of a lightly damped oscillator driven by first-order
filtered white noise, over a window of 200 samples, a maximum of linear functionals of n
standard normals. Its exact tail comes from ALOE (Owen, Maximov & Chertkov 2019), an unbiased
importance sampler for a union of half-spaces, to about 0.1 %.

    python benches/rare_flight_like.py --threshold 5.6 --seeds 100
    python benches/rare_flight_like.py --threshold 5.6 --seeds 100 --method adaptive   # round 3
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
from scipy.stats import norm

from quadrs.rare.subset import _adaptive, _Evaluator, lognormal_interval, subset_simulation


def functionals(n: int = 400, window: tuple[int, int] = (200, 400), phi: float = 0.9,
                omega: float = 0.25, zeta: float = 0.05) -> np.ndarray:  # fmt: skip
    """Rows c_k: the oscillator's response at step k (in the window) to unit input normals."""
    r = math.exp(-zeta * omega)
    a1, a2 = 2 * r * math.cos(omega * math.sqrt(1 - zeta**2)), -r * r
    rows = np.zeros((n, n))
    u, y1, y2 = np.zeros(n), np.zeros(n), np.zeros(n)
    for k in range(n):
        e = np.zeros(n)
        e[k] = 1.0
        u = phi * u + math.sqrt(1 - phi**2) * e
        y = a1 * y1 + a2 * y2 + u
        rows[k], y2, y1 = y, y1, y
    c = rows[window[0] : window[1]]
    return c / np.linalg.norm(c, axis=1).max()


def exact_tail(c: np.ndarray, t: float, samples: int = 200_000, seed: int = 1) -> float:
    """P(max_k |c_k x| > t) by ALOE: pick a half-space by its probability, draw x in it, weight
    by 1 / (the half-spaces x lies in)."""
    rng = np.random.default_rng(seed)
    s = np.linalg.norm(c, axis=1)
    d = np.vstack([c / s[:, None], -c / s[:, None]])
    b = np.concatenate([t / s, t / s])
    pj = norm.sf(b)
    mu = float(pj.sum())
    pick = rng.choice(len(pj), size=samples, p=pj / mu)
    weights = np.empty(samples)
    for lo in range(0, samples, 20_000):
        j = pick[lo : lo + 20_000]
        z = rng.standard_normal((len(j), d.shape[1]))
        along = (z * d[j]).sum(axis=1)
        tail = norm.isf(rng.uniform(size=len(j)) * norm.sf(b[j]))
        z += (tail - along)[:, None] * d[j]
        weights[lo : lo + len(j)] = 1.0 / (z @ d.T > b).sum(axis=1)
    return mu * float(weights.mean())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--threshold", type=float, default=5.6)
    ap.add_argument("--seeds", type=int, default=100)
    ap.add_argument("--per-level", type=int, default=500)
    ap.add_argument("--method", default="two-stage", choices=["two-stage", "adaptive"])
    args = ap.parse_args(argv)
    c = functionals()
    ct = np.ascontiguousarray(c.T)

    def model(x: np.ndarray) -> np.ndarray:
        return np.abs(x @ ct).max(axis=1)

    p = exact_tail(c, args.threshold)
    est, covered = [], 0
    for seed in range(args.seeds):
        if args.method == "adaptive":
            run = _adaptive(_Evaluator(model, "model"), c.shape[1], args.threshold,
                            args.per_level, 0.1, seed, 12, np.random.default_rng(seed))  # fmt: skip
            ok = run.probability is not None and run.cov is not None
            lo, hi = lognormal_interval(run.probability, run.cov) if ok else (0.0, 1.0)
        else:
            run = subset_simulation(model, c.shape[1], args.threshold,
                                    per_level=args.per_level, seed=seed)  # fmt: skip
            lo, hi = run.interval or (0.0, 1.0)
        est.append(run.probability or 0.0)
        covered += lo <= p <= hi
    e = np.array(est)
    print(f"{args.method}, threshold {args.threshold}: p = {p:.3g}, mean / p = {e.mean() / p:.3f} "
          f"(se {e.std(ddof=1) / p / math.sqrt(len(e)):.3f}), {covered} of {len(e)} intervals "
          f"cover")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
