"""How the per-phase IAE of the relative oscillation e_o converges as the step dt shrinks.

    python benches/dt_convergence.py                 # paper preset, 100 gust realisations
    python benches/dt_convergence.py --runs 400 --dts 1e-4 2e-4 1e-3

Two studies, both through the public API (``quadrs.monte_carlo``):

1. Deterministic (gust off): one flight per controller and dt; the IAE of each phase and its
   relative difference from the finest dt. This is the integration (and controller sample
   rate) error alone, and what a dt must keep small.
2. With the gust: the mean IAE over ``--runs`` realisations and its standard error. The gust
   is discretised exactly for each dt, but drawn per step, so realisation i at one dt is not
   the same gust as at another dt: compare the means against their standard errors.

Note that dt is also the controller's sample period (controls are held over a step), so a
coarser dt is a slightly different closed loop, not only a coarser integration of the same one.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import quadrs


def iae_table(scenario: quadrs.Scenario, runs: int, seed: int) -> tuple[dict, dict, float]:
    """Mean IAE and its standard error per (controller, phase); seconds per paired run."""
    t0 = time.perf_counter()
    res = quadrs.monte_carlo(scenario, runs=runs, seed=seed, progress=False, spectra=False)
    secs = (time.perf_counter() - t0) / runs
    ok = res.runs[~res.runs["diverged"]]
    g = ok.groupby(["controller", "phase"], observed=True)["iae"]
    mean, sem = g.mean().to_dict(), (g.std(ddof=1) / np.sqrt(g.count())).to_dict()
    n_div = int(res.runs.groupby("realisation")["diverged"].any().sum())
    if n_div:
        print(f"  (dt = {scenario['integrator.dt']}: {n_div} realisations diverged, left out)")
    return mean, sem, secs


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--preset", default="paper")
    ap.add_argument("--runs", type=int, default=100, help="gust realisations per dt")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--dts", type=float, nargs="+", default=[1e-4, 2e-4, 5e-4, 1e-3, 2e-3, 5e-3])
    args = ap.parse_args()
    warnings.simplefilter("ignore")  # the paper SMC's lateral instability warning
    base = quadrs.Scenario.preset(args.preset)
    dts = sorted(args.dts)
    phases = base.phase_names
    ctrls = ("pd", "smc")

    print(f"preset {args.preset}; IAE of e_o per phase (m s)\n")
    print(
        "1. Gust off: one flight per dt; in brackets the difference from dt = "
        f"{dts[0]:g} s, relative"
    )
    det = {
        dt: iae_table(base.override({"integrator.dt": dt, "gust.enabled": False}), 1, 0)
        for dt in dts
    }
    header = f"{'dt (s)':>8} " + " ".join(
        f"{c.upper() + ' ' + p:>22}" for c in ctrls for p in phases
    )
    print(header)
    ref = det[dts[0]][0]
    for dt in dts:
        mean = det[dt][0]
        cells = []
        for c in ctrls:
            for p in phases:
                v, r = mean[(c, p)], ref[(c, p)]
                cells.append(f"{v:.6g} [{(v - r) / r:+.1e}]")
        print(f"{dt:>8g} " + " ".join(f"{x:>22}" for x in cells))

    print(
        f"\n2. Gust on: mean IAE over {args.runs} realisations +/- standard error;"
        " s per paired PD + SMC run (2 workers)"
    )
    print(
        f"{'dt (s)':>8} "
        + " ".join(f"{c.upper() + ' ' + p:>19}" for c in ctrls for p in phases)
        + f" {'s/run':>7}"
    )
    for dt in dts:
        mean, sem, secs = iae_table(base.override({"integrator.dt": dt}), args.runs, args.seed)
        cells = [f"{mean[(c, p)]:.4f}+/-{sem[(c, p)]:.4f}" for c in ctrls for p in phases]
        print(f"{dt:>8g} " + " ".join(f"{x:>19}" for x in cells) + f" {secs:7.4f}")


if __name__ == "__main__":
    main()
