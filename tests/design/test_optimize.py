"""quadrs.optimize: lands on a known optimum, rejects unstable candidates, is deterministic,
penalises divergence and keeps the best so far on Ctrl-C."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs.design.optimize import _metric_values, optimize

KEY = "controller.smc.epsilon[2]"
RUNS = 6


def short(preset: str = "paper_stable_lateral", duration: float = 6.0) -> quadrs.Scenario:
    """Hover at 2 m in a strong vertical gust for a few seconds (no take-off)."""
    return quadrs.Scenario.preset(preset).override(
        {
            "initial.position": [0.0, 0.0, 2.0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.waypoints": [[0.0, 0.0, 0.0, 2.0, 0.0], [duration, 0.0, 0.0, 2.0, 0.0]],
            "phases": [{"name": "G", "start": 0.5, "end": duration}],
            "gust.start": 0.5,
            "gust.end": duration,
            "gust.w20": 20.0,
            "integrator.dt": 1e-3,
            "integrator.duration": duration,
        }
    )


@pytest.fixture(scope="module")
def sweep() -> tuple[np.ndarray, np.ndarray]:
    """The objective on a dense grid, on the same seed and realisations optimize uses."""
    s = short()
    grid = np.linspace(0.05, 3.0, 60)
    values = []
    for g in grid:
        mc = quadrs.monte_carlo(s.override({KEY: g}), runs=RUNS, seed=0, controllers=("smc",),
                                progress=False, spectra=False)  # fmt: skip
        v, diverged = _metric_values(mc, "iae", ["G"])
        assert diverged == 0
        values.append(v.mean())
    return grid, np.asarray(values)


@pytest.mark.parametrize(
    ("method", "maxiter"), [("differential_evolution", 8), ("nelder-mead", 40)]
)
def test_lands_within_the_grid_spacing_of_a_dense_sweeps_argmin(
    sweep: tuple[np.ndarray, np.ndarray], method: str, maxiter: int
) -> None:
    grid, values = sweep
    k = int(np.argmin(values))
    assert 0 < k < grid.size - 1  # an interior optimum, not a bound
    res = optimize(short(), "smc", {KEY: (0.05, 3.0)}, "iae", ("G",), runs=RUNS, seed=0,
                   method=method, maxiter=maxiter)  # fmt: skip
    spacing = grid[1] - grid[0]
    assert abs(res.best[KEY] - grid[k]) <= spacing, (res.best, grid[k])
    assert res.objective <= values[k] + 1e-12
    assert res.scenario[KEY] == res.best[KEY]
    assert res.history["flown"].all() and not res.history["penalised"].any()
    # The history's objective is the sweep's objective at the same value (same seeds).
    row = res.history.loc[res.history["objective"].idxmin()]
    mc = quadrs.monte_carlo(short().override({KEY: row[KEY]}), runs=RUNS, seed=0,
                            controllers=("smc",), progress=False, spectra=False)  # fmt: skip
    assert row["objective"] == _metric_values(mc, "iae", ["G"])[0].mean()
    # The held-out check flew fresh gusts: a different value, an interval around it.
    h = res.holdout
    assert h is not None and h.seed == 1_000_003 and h.runs == RUNS
    assert h.low < h.objective < h.high and h.objective != res.objective


def test_require_stable_rejects_every_unstable_candidate() -> None:
    # A lateral gust excites the lateral modes these gains move (unexcited modes are not judged).
    s = short("paper", duration=2.0).override({"gust.components": ["vertical", "lateral"]})
    params = {
        "controller.smc.epsilon[0]": (0.001, 0.12),
        "controller.smc.epsilon[1]": (0.001, 0.12),
    }
    res = optimize(s, "smc", params, "iae", ("G",), runs=2, seed=3, maxiter=2, popsize=4)
    # The untuned scenario is the last row, flown whatever its stability, never the best.
    assert res.history["role"].iloc[-1] == "baseline" and res.history["flown"].iloc[-1]
    h = res.history.iloc[:-1]
    assert len(h) == 4 * 2 * 3 and (h["role"] != "baseline").all()
    for row in h.itertuples(index=False):
        values = {k: getattr(row, f"_{i + 1}") for i, k in enumerate(params)}
        report = quadrs.stability(s.override(values), "smc")
        assert row.stable == report.stable
        assert bool(row.unstable_modes) == report.excited_unstable
        if not report.stable:
            assert not row.flown and row.penalised and row.objective >= 1e6
        else:
            assert row.flown and not row.penalised and row.objective < 1.0
    assert h["stable"].any() and not h["stable"].all()
    assert quadrs.stability(res.scenario, "smc").stable


def test_same_seed_and_budget_give_the_same_history() -> None:
    s = short(duration=2.0)
    params = {KEY: (0.05, 3.0), "controller.smc.lambda[2]": (1.0, 6.0)}
    a, b = (optimize(s, "smc", params, "rms", ("G",), runs=2, seed=5, maxiter=2, popsize=3)
            for _ in range(2))  # fmt: skip
    pd.testing.assert_frame_equal(a.history, b.history)
    assert a.best == b.best and a.holdout == b.holdout
    c = optimize(s, "smc", params, "rms", ("G",), runs=2, seed=6, maxiter=2, popsize=3)
    assert not c.history[list(params)].equals(a.history[list(params)])


def test_diverged_and_non_finite_candidates_are_penalised_not_nan() -> None:
    # Unstable lateral SMC, excited by a lateral gust, tripping a tight tilt limit.
    s = short("paper", duration=4.0).override(
        {"gust.components": ["lateral", "vertical"], "divergence.max_tilt": 0.01}
    )
    res = optimize(s, "smc", {"controller.smc.lambda[0]": (2.0, 4.0)}, "iae", ("G",), runs=2,
                   require_stable=False, method="nelder-mead", maxiter=3)  # fmt: skip
    h = res.history
    assert h["flown"].all() and (h["diverged"] > 0).all() and h["penalised"].all()
    assert np.isfinite(h["objective"]).all() and (h["objective"] >= 1e6).all()
    assert res.holdout is None
    # A callable returning NaN is penalised too.
    res = optimize(short(duration=2.0), "smc", {KEY: (0.5, 1.5)}, lambda mc: math.nan,
                   runs=2, method="nelder-mead", maxiter=2)  # fmt: skip
    assert res.history["penalised"].all() and np.isfinite(res.history["objective"]).all()


def test_ctrl_c_keeps_the_best_so_far() -> None:
    calls = []

    def objective(mc: quadrs.MonteCarloResult) -> float:
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return float(mc.runs["rms"].mean())

    res = optimize(short(duration=2.0), ("pd", "smc"), {KEY: (0.5, 1.5)}, objective, runs=2,
                   method="nelder-mead", maxiter=20)  # fmt: skip
    assert res.interrupted and res.holdout is None
    assert len(res.history) == 3
    assert res.objective == res.history["objective"].min()


def test_bad_input_names_the_key() -> None:
    s = short(duration=2.0)
    with pytest.raises(quadrs.ScenarioError, match=r"nonsense\.key"):
        optimize(s, params={"nonsense.key": (0, 1)})
    with pytest.raises(quadrs.ScenarioError, match=r"gust\.model"):
        optimize(s, params={"gust.model": (0, 1)})
    with pytest.raises(quadrs.ScenarioError, match=r"controller.smc.gamma.*low < high"):
        optimize(s, params={"controller.smc.gamma": (1.0, 0.5)})
    with pytest.raises(quadrs.ScenarioError, match=r"payload\.mass"):
        optimize(s, params={"payload.mass": (-1.0, 1.0)})
    with pytest.raises(ValueError, match="objective"):
        optimize(s, params={KEY: (0.5, 1.5)}, objective="nope")
    with pytest.raises(ValueError, match="phases"):
        optimize(s, params={KEY: (0.5, 1.5)}, phases=("P9",))
    with pytest.raises(ValueError, match="method"):
        optimize(s, params={KEY: (0.5, 1.5)}, phases=("G",), method="bfgs")


def test_a_gain_of_a_law_not_flown_is_refused_before_flying() -> None:
    """Tuning controller.pd.* while the SMC (the default) flies would search a flat objective
    and write a 'tuned' file that changes nothing: refused, naming the key and the law."""
    s = short(duration=2.0)
    with pytest.raises(ValueError, match=r"controller\.pd\.kp\[0\] is a gain of the pd law.*smc"):
        optimize(s, params={"controller.pd.kp[0]": (0.5, 1.5)}, phases=("G",))
    with pytest.raises(ValueError, match=r"controller\.px4\.\S+ is a gain of the px4 law"):
        optimize(s, "pd", params={"controller.pd.kp[0]": (0.5, 1.5),
                                  "controller.px4.MC_PITCH_P": (4.0, 8.0)},
                 phases=("G",))  # fmt: skip
    # Keys every law reads (not under one law's name) are tuned with any of them.
    from quadrs.design.optimize import check_tuning

    check_tuning(s, "smc", {"controller.tilt_limit": (0.3, 0.6)}, "iae", ("G",))


def test_tied_keys_share_one_value() -> None:
    tied = "controller.smc.lambda[0],controller.smc.lambda[1]"
    res = optimize(short(duration=2.0), "smc", {tied: (0.8, 1.6)}, "rms", ("G",), runs=2,
                   method="nelder-mead", maxiter=3)  # fmt: skip
    assert list(res.history.columns[:2]) == ["evaluation", tied]
    lam = res.scenario["controller.smc.lambda"]
    assert lam[0] == lam[1] == res.best[tied]
    with pytest.raises(quadrs.ScenarioError, match=r"nope\.key"):
        optimize(short(duration=2.0), params={"controller.smc.lambda[0],nope.key": (1, 2)})


def test_one_options_object_is_the_keyword_and_positional_calls() -> None:
    """``optimize(s, OptimizeOptions(...))`` flies the very search the keyword and the first
    release's positional calls fly; keywords after an options object replace its fields."""
    s = short(duration=2.0)
    options = quadrs.OptimizeOptions(controller="smc", params={KEY: (0.05, 3.0)},
                                     objective="rms", phases=("G",), runs=2, seed=5, maxiter=1,
                                     popsize=2)  # fmt: skip
    a = optimize(s, options)
    b = optimize(s, controller="smc", params={KEY: (0.05, 3.0)}, objective="rms", phases=("G",),
                 runs=2, seed=5, maxiter=1, popsize=2)  # fmt: skip
    c = optimize(s, "smc", {KEY: (0.05, 3.0)}, "rms", ("G",), 2, 5, maxiter=1, popsize=2)
    for other in (b, c):
        pd.testing.assert_frame_equal(a.history, other.history)
        assert (a.best, a.holdout) == (other.best, other.holdout)
    d = optimize(s, options, seed=6)
    assert d.seed == 6 and options.seed == 5
    assert not d.history[KEY].equals(a.history[KEY])


def test_the_options_are_checked_when_made_naming_the_field() -> None:
    from dataclasses import FrozenInstanceError

    from quadrs.design.optimize import OptimizeOptions

    for field, value in (("runs", 0), ("popsize", 0), ("maxiter", 0), ("holdout_runs", 0)):
        with pytest.raises(ValueError, match=rf"^{field} must be >= 1, got 0"):
            OptimizeOptions(**{field: value})
    with pytest.raises(ValueError, match="method must be one of"):
        OptimizeOptions(method="bfgs")
    with pytest.raises(ValueError, match="penalty must be finite and > 0, got nan"):
        OptimizeOptions(penalty=math.nan)
    with pytest.raises(ValueError, match="seed"):
        OptimizeOptions(seed=-1)
    with pytest.raises(FrozenInstanceError):
        OptimizeOptions().runs = 3  # type: ignore[misc]
    s = short(duration=2.0)
    with pytest.raises(TypeError, match="unexpected keyword argument 'run'"):
        optimize(s, run=3)
    with pytest.raises(TypeError, match="multiple values for argument 'controller'"):
        optimize(s, "smc", controller="pd")
    with pytest.raises(TypeError, match="at most 11 positional options"):
        optimize(s, "smc", {}, "iae", ("G",), 2, 0, True, "nelder-mead", 1, None, False, 8)
    with pytest.raises(TypeError, match="one options object"):
        optimize(s, OptimizeOptions(), 3)
