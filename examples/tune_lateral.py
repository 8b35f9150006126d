"""Tune the SMC's lateral (y / roll) gains of the paper preset for the least lateral tracking
error under a lateral Dryden gust, and compare with the hand-retuned `paper_stable_lateral`.

    .venv/bin/python examples/tune_lateral.py            # about 2 minutes on 2 cores

The paper's lateral SMC gains are unstable at hover, so every candidate is screened with
quadrs.stability first (require_stable). The objective is a callable: the mean over the
realisations of the RMS of y - y_ref inside the gust window, read from the traces of the very
realisations the Monte Carlo flew (same seed and index give the same gust).
"""

from __future__ import annotations

import sys

import numpy as np

import quadrs

T0, T1 = 2.0, 22.0
RUNS = 8


def lateral(preset: str) -> quadrs.Scenario:
    return quadrs.Scenario.preset(preset).override(
        {
            "initial.position": [0.0, 0.0, 2.0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.waypoints": [[0.0, 0.0, 0.0, 2.0, 0.0], [T1, 0.0, 0.0, 2.0, 0.0]],
            "phases": [{"name": "G", "start": T0, "end": T1}],
            "gust.components": ["lateral"],
            "gust.start": T0,
            "gust.end": T1,
            "integrator.dt": 1e-3,
            "integrator.duration": T1,
        }
    )


def lateral_rms(mc: quadrs.MonteCarloResult) -> float:
    """Mean over realisations of the RMS lateral tracking error (m) in the gust window."""
    out = []
    for i in mc.realisations:
        tr = quadrs.simulate(mc.scenario, "smc", mc.seed, realisation=int(i), record_every=10).trace
        w = tr.loc[T0:T1]
        out.append(float(np.sqrt(np.mean((w["y"] - w["y_ref"]) ** 2))))
    return float(np.mean(out))


def main() -> None:
    # x and y (and roll and pitch) tied: Ixx = Iyy, so equal gains keep the poles at any yaw.
    xy = "controller.smc.{0}[0],controller.smc.{0}[1]"
    params = {
        xy.format("lambda"): (0.2, 4.0),
        xy.format("epsilon"): (0.01, 1.0),
        xy.format("lambda_attitude"): (1.0, 12.0),
        xy.format("epsilon_attitude"): (0.2, 3.0),
    }
    start = lateral("paper")
    print(quadrs.stability(start, "smc"))
    res = quadrs.optimize(start, "smc", params, lateral_rms, runs=RUNS, seed=0,
                          maxiter=8, popsize=5, progress=sys.stderr.isatty())  # fmt: skip
    h = res.evaluations  # the search (res.history also has the untuned baseline)
    print(f"{len(h)} evaluations, {int((~h['stable']).sum())} rejected as unstable at hover")
    for k, v in res.best.items():
        print(f"  {k} = {v:.4g}")
    print(f"tuning objective (seed 0, {RUNS} runs): {res.objective:.4g} m")
    ho = res.holdout
    assert ho is not None
    print(f"held out (seed {ho.seed}): {ho.objective:.4g} m [95% CI {ho.low:.4g}, {ho.high:.4g}]")
    print(quadrs.stability(res.scenario, "smc"))
    ref = lateral("paper_stable_lateral")
    mc = quadrs.monte_carlo(ref, runs=RUNS, seed=ho.seed, controllers=("smc",), progress=False)
    print(f"paper_stable_lateral on the held-out seed: {lateral_rms(mc):.4g} m")


if __name__ == "__main__":
    main()
