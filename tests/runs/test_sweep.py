"""Sweeps: the grid, the tidy table, common random numbers, summaries, persistence, Ctrl-C."""

import importlib

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs import MonteCarloResult, Scenario
from quadrs.runs.sweep import SweepResult, check_grid, grid_points, is_sweep_file

sweep_module = importlib.import_module("quadrs.runs.sweep")

KEY = "payload.natural_frequency"


def test_grid_is_the_cartesian_product_first_key_outermost() -> None:
    points = grid_points({"a": [1, 2], "b": ["x", "y", "z"]})
    assert points[:3] == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 1, "b": "z"}]
    assert len(points) == 6


@pytest.mark.parametrize(
    "grid",
    [{}, {"a": [1], "b": [2], "c": [3]}, {"a": []}, {"a": "12"}, {"phase": [1]}],
)
def test_bad_grids_are_refused(grid: dict) -> None:
    with pytest.raises(ValueError):
        check_grid(grid)


def test_one_key_sweep_table(short: Scenario) -> None:
    res = quadrs.sweep(short, {KEY: [1.5, 3.0]}, runs=3, seed=2, workers=2, progress=False)
    r = res.runs
    assert list(r.columns[:4]) == [KEY, "realisation", "controller", "phase"]
    assert len(r) == 2 * 3 * 2 * 4  # P1-P3 and the whole flight
    assert sorted(r[KEY].unique()) == [1.5, 3.0]
    assert not res.interrupted
    # Each point is exactly the Monte Carlo batch of its scenario with the same seed.
    for fn in (1.5, 3.0):
        mc = quadrs.monte_carlo(short.override({KEY: fn}), 3, seed=2, progress=False)
        got = r[r[KEY] == fn].drop(columns=KEY).reset_index(drop=True)
        pd.testing.assert_frame_equal(got, mc.runs)


def test_same_seed_at_every_point_common_random_numbers(short: Scenario) -> None:
    # The spectrum rate changes only the spectra: with common random numbers every point
    # flies the very same gusts, so the time-domain indices agree to the last bit.
    res = quadrs.sweep(
        short, {"metrics.spectrum_rate": [100.0, 50.0]}, runs=4, seed=5, progress=False
    )
    a = res.runs[res.runs["metrics.spectrum_rate"] == 100.0]
    b = res.runs[res.runs["metrics.spectrum_rate"] == 50.0]
    np.testing.assert_array_equal(a["iae"].to_numpy(), b["iae"].to_numpy())
    assert a["iae"].nunique() > 1  # the gust does vary between realisations


def test_two_key_grid_and_summary(short: Scenario) -> None:
    grid = {KEY: [1.5, 3.0], "payload.mass": [0.1, 0.2]}
    res = quadrs.sweep(short, grid, runs=2, seed=0, progress=False)
    assert len(res.points) == 4
    summ = res.summary()
    assert summ.index.names == [KEY, "payload.mass", "metric", "phase"]
    assert {"pd_mean", "smc_mean", "P", "P_ci_low", "P_ci_high"} <= set(summ.columns)
    row = summ.loc[(3.0, 0.2, "iae", "P2")]
    sub = res.runs[(res.runs[KEY] == 3.0) & (res.runs["payload.mass"] == 0.2)]
    sub = sub[sub["phase"] == "P2"]
    assert row["pd_mean"] == pytest.approx(sub[sub["controller"] == "pd"]["iae"].mean())
    compact = res.compact()
    assert list(compact.columns) == [
        "IAE PD",
        "IAE SMC",
        "P_IAE %",
        "ITAE PD",
        "ITAE SMC",
        "P_ITAE %",
        "n",
        "diverged",
    ]
    assert len(compact) == 4 * 4  # P1-P3 and the whole flight


def test_stiffer_attachment_swings_less_on_take_off(short: Scenario) -> None:
    res = quadrs.sweep(short, {KEY: [1.0, 4.0]}, runs=2, seed=0, progress=False)
    amp = res.summary().xs(("max_abs", "P1"), level=("metric", "phase"))["pd_mean"]
    assert amp.loc[4.0] < amp.loc[1.0]


def test_parquet_round_trip(short: Scenario, tmp_path) -> None:
    res = quadrs.sweep(short, {"gust.w20": [5.0, 10.0]}, runs=2, seed=1, progress=False)
    path = tmp_path / "sweep.parquet"
    res.to_parquet(path)
    assert is_sweep_file(path)
    back = SweepResult.read_parquet(path)
    pd.testing.assert_frame_equal(back.runs, res.runs)
    assert back.grid == res.grid and back.seed == 1 and back.scenario == short
    with pytest.raises(ValueError, match="not written by quadrs"):
        MonteCarloResult.read_parquet(path)


def test_bad_value_fails_before_anything_runs(short: Scenario, monkeypatch) -> None:
    calls = []
    monkeypatch.setattr(sweep_module, "monte_carlo", lambda *a, **k: calls.append(a))
    with pytest.raises(quadrs.ScenarioError, match=r"payload\.mass"):
        quadrs.sweep(short, {"payload.mass": [0.2, -1.0]}, runs=2, progress=False)
    with pytest.raises(quadrs.ScenarioError, match=r"payload\.mas\b"):
        quadrs.sweep(short, {"payload.mas": [0.2]}, runs=2, progress=False)
    assert calls == []


def test_ctrl_c_keeps_the_points_that_finished(short: Scenario, monkeypatch) -> None:
    real = sweep_module.monte_carlo
    seen = []

    def flaky(scenario, *args, **kwargs):
        seen.append(scenario)
        if len(seen) == 2:
            raise KeyboardInterrupt
        return real(scenario, *args, **kwargs)

    monkeypatch.setattr(sweep_module, "monte_carlo", flaky)
    res = quadrs.sweep(short, {KEY: [1.5, 3.0, 4.0]}, runs=2, progress=False)
    assert res.interrupted
    assert list(res.runs[KEY].unique()) == [1.5]
    assert len(res.runs) == 2 * 2 * 4
