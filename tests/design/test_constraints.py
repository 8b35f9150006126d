"""Constraints in the design loop: the constrained optimum of a dense sweep (computed here
without the constraint code), chance constraints on common random numbers, infeasibility
reported as such, the text and mapping forms, and ``quadrs tune --constraint``."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs.cli.main import main
from quadrs.design.constraints import Constraint, constraints_from, parse_constraint
from quadrs.design.optimize import InfeasibleWarning, optimize
from tests.cli.test_design import SHORT
from tests.design.test_optimize import KEY, RUNS, short

LOW, HIGH = 0.05, 3.0


@pytest.fixture(scope="module")
def sweep() -> dict[str, np.ndarray]:
    """On a dense grid of KEY, at the seed and realisations optimize flies: the objective (mean
    IAE), the mean tracking RMS and every realisation's max_accel, straight from the runs."""
    s = short()
    grid = np.linspace(LOW, HIGH, 60)
    iae, track, accel = [], [], []
    for g in grid:
        mc = quadrs.monte_carlo(s.override({KEY: g}), runs=RUNS, seed=0, controllers=("smc",),
                                progress=False, spectra=False)  # fmt: skip
        runs = mc.runs[mc.runs["phase"] == "G"].sort_values("realisation")  # optimize's phase
        assert not runs["diverged"].any()
        iae.append(runs["iae"].mean())
        track.append(runs["tracking_rms"].mean())
        accel.append(runs["max_accel"].to_numpy())
    return {"grid": grid, "iae": np.array(iae), "track": np.array(track),
            "accel": np.array(accel)}  # fmt: skip


def _lands_on(res: quadrs.design.optimize.OptimizeResult, grid: np.ndarray, feasible: np.ndarray,
              values: np.ndarray) -> None:  # fmt: skip
    k = int(np.argmin(np.where(feasible, values, np.inf)))
    spacing = grid[1] - grid[0]
    assert res.feasible
    assert abs(res.best[KEY] - grid[k]) <= spacing, (res.best, grid[k])
    best = res.history[res.history["role"] == "best"]
    assert len(best) == 1 and bool(best["feasible"].iloc[0])
    # Never chosen: every feasible candidate flown is at least as bad as the best.
    h = res.history[(res.history["role"] != "baseline") & res.history["feasible"]]
    assert res.objective == h["objective"].min()


def test_mean_constraint_lands_on_the_sweeps_constrained_optimum(
    sweep: dict[str, np.ndarray],
) -> None:
    grid, iae, track = sweep["grid"], sweep["iae"], sweep["track"]
    k0 = int(np.argmin(iae))
    # A bound that the unconstrained optimum breaks, met further up the grid.
    bound = float(track[min(k0 + 20, grid.size - 5)])
    feasible = track <= bound
    assert not feasible[k0] and feasible.any()
    res = optimize(short(), "smc", {KEY: (LOW, HIGH)}, "iae", ("G",), runs=RUNS, seed=0,
                   maxiter=8, constraints={"tracking_rms": ("<=", bound)})  # fmt: skip
    _lands_on(res, grid, feasible, iae)
    assert res.best[KEY] > grid[k0]  # pushed off the unconstrained optimum by the constraint
    h = res.history
    col = "tracking_rms"
    # Each candidate's recorded value is its mean tracking RMS; infeasible ones are marked.
    assert (h[f"{col}<={bound:g}"] == (h[col] <= bound)).all()
    assert (~h["feasible"]).any()


def test_chance_constraint_lands_on_the_sweeps_constrained_optimum(
    sweep: dict[str, np.ndarray],
) -> None:
    grid, iae, accel = sweep["grid"], sweep["iae"], sweep["accel"]
    k0 = int(np.argmin(iae))
    # The threshold under which 3 of the realisations at the unconstrained optimum exceed;
    # at most 2 of RUNS may.
    threshold = float(np.sort(accel[k0])[-3]) - 1e-9
    p = 2 / RUNS
    fraction = (accel > threshold).mean(axis=1)
    feasible = fraction <= p + 1e-12
    assert not feasible[k0] and feasible.any()
    res = optimize(short(), "smc", {KEY: (LOW, HIGH)}, "iae", ("G",), runs=RUNS, seed=0,
                   maxiter=8, constraints={("max_accel", "exceedance", threshold):
                                           ("<=", p + 1e-12)})  # fmt: skip
    _lands_on(res, grid, feasible, iae)


def test_an_infeasible_constraint_is_reported_not_passed_off_as_best(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    s = short(duration=2.0)
    with pytest.warns(InfeasibleWarning, match=r"tracking_rms<=1e-06"):
        res = optimize(s, "smc", {KEY: (LOW, HIGH)}, "iae", ("G",), runs=2, seed=0,
                       method="nelder-mead", maxiter=6,
                       constraints=["tracking_rms<=1e-6"])  # fmt: skip
    assert not res.feasible and "NO FEASIBLE" in repr(res)
    h = res.history
    assert not h["feasible"].any()
    searched = h[h["role"] != "baseline"]
    # The least violating: the smallest tracking RMS flown.
    assert (
        res.history.loc[h["role"] == "best", "tracking_rms"].iloc[0]
        == searched["tracking_rms"].min()
    )
    # On the command line: exit 1, nothing written, said on stderr.
    out = tmp_path / "t.toml"
    rc = main(["tune", *SHORT, "--param", f"{KEY}=0.05:3", "--phase", "G", "--runs", "2",
               "--method", "nelder-mead", "--maxiter", "4", "--constraint",
               "tracking_rms<=1e-6", "--out", str(out)])  # fmt: skip
    assert rc == 1 and not out.exists()
    assert "no candidate met every constraint" in capsys.readouterr().err


def test_the_history_shows_the_baseline_beside_the_best() -> None:
    s = short(duration=2.0)
    res = optimize(s, "smc", {KEY: (LOW, HIGH)}, "iae", ("G",), runs=2, seed=0,
                   method="nelder-mead", maxiter=5,
                   constraints=["P(max_accel>100)<=0", "quantile(max_accel,0.5)<=100"])  # fmt: skip
    cmp = res.comparison
    assert list(cmp.index) == ["baseline", "best"]
    assert cmp.loc["baseline", KEY] == s[KEY]
    assert cmp.loc["baseline", "objective"] == res.baseline
    assert cmp.loc["best", "objective"] == res.objective
    mc = quadrs.monte_carlo(s, runs=2, seed=0, controllers=("smc",), progress=False,
                            spectra=False)  # fmt: skip
    assert cmp.loc["baseline", "quantile(max_accel,0.5)"] == np.quantile(
        mc.runs.loc[mc.runs["phase"] == "G", "max_accel"], 0.5, method="inverted_cdf"
    )
    assert cmp.loc["baseline", "P(max_accel>100)"] == 0.0
    assert bool(cmp.loc["best", "feasible"])
    # Re-checked on the held-out seed, with intervals, from flights flown here again.
    held = res.holdout_constraints.set_index("constraint")
    fresh = quadrs.monte_carlo(res.scenario, runs=2, seed=1_000_003, controllers=("smc",),
                               progress=False, spectra=False)  # fmt: skip
    x = fresh.runs.loc[fresh.runs["phase"] == "G", "max_accel"].to_numpy()
    q = held.loc["quantile(max_accel,0.5)<=100"]
    assert q["value"] == np.quantile(x, 0.5, method="inverted_cdf") and bool(q["met"])
    p = held.loc["P(max_accel>100)<=0"]
    assert p["value"] == 0.0 and p["ci_low"] == 0.0 and p["ci_high"] > 0.5  # 0 of 2
    assert bool(p["met"]) and not bool(p["certain"])


def test_values_agree_with_the_risk_tables() -> None:
    s = short(duration=3.0)
    mc = quadrs.monte_carlo(s, runs=40, seed=2, controllers=("smc",), progress=False,
                            spectra=False)  # fmt: skip
    t = float(mc.runs["max_accel"].median())
    p = Constraint("max_accel", "<=", 0.5, "exceedance", t).value(mc.runs, ["G"])
    assert p == mc.exceedance("max_accel", t)["probability"].iloc[0]
    q = Constraint("max_accel", "<=", 9.0, "quantile", 0.9).value(mc.runs, ["G"])
    assert q == mc.quantile("max_accel", 0.9)["quantile"].iloc[0]
    m = Constraint("rms", ">=", 0.0).value(mc.runs, ["G"])
    assert m == pytest.approx(mc.summary().loc[("rms", "G"), "smc_mean"], rel=1e-12)


def test_text_and_mapping_forms_agree() -> None:
    a = constraints_from({"tracking_rms@P2": ("<=", 0.5),
                          ("max_accel", "exceedance", 8.0): ("<=", 0.01),
                          ("max_accel", "quantile", 0.99): (">=", 1)})  # fmt: skip
    b = constraints_from(["tracking_rms@P2<=0.5", "P(max_accel>8)<=0.01",
                          "quantile(max_accel, 0.99) >= 1"])  # fmt: skip
    assert a == b
    assert parse_constraint("mean(tracking_rms@P2)<=0.5") == a[0]
    assert str(a[1]) == "P(max_accel>8)<=0.01" and parse_constraint(str(a[2])) == a[2]
    for bad in ["tracking_rms", "P(max_accel>8)", "nope<=1", "P(max_accel>x)<=0.1",
                "quantile(max_accel,1.5)<=3", "tracking_rms=<0.5"]:  # fmt: skip
        with pytest.raises(ValueError, match=r"expected|metric|q must"):
            parse_constraint(bad)
    with pytest.raises(ValueError, match="P9"):
        optimize(short(duration=2.0), params={KEY: (0.5, 1.5)}, phases=("G",),
                 constraints=["tracking_rms@P9<=1"])  # fmt: skip


@pytest.mark.parametrize(
    "text", ["tracking_rms", "P(max_accel>8)", "nope<=1", "quantile(max_accel,2)<=1", "a<=b"]
)
def test_bad_constraint_on_the_command_line_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    rc = main(["tune", *SHORT, "--param", f"{KEY}=0.05:3", "--phase", "G",
               "--constraint", text, "--out", str(tmp_path / "t.toml")])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2
    assert len(err.strip().splitlines()) == 1 and "--constraint" in err
    assert not (tmp_path / "t.toml").exists()


def test_tune_with_constraints_records_them_in_the_history(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out, hist = tmp_path / "t.toml", tmp_path / "h.csv"
    rc = main(["tune", *SHORT, "--param", f"{KEY}=0.05:3", "--phase", "G", "--runs", "2",
               "--maxiter", "2", "--popsize", "3", "--constraint", "tracking_rms@G<=1",
               "--constraint", "P(max_accel>100)<=0.01", "--out", str(out),
               "--history", str(hist)])  # fmt: skip
    assert rc == 0
    text = capsys.readouterr().out
    assert "untuned (the scenario's own values) and best" in text
    h = pd.read_csv(hist)
    assert {"tracking_rms@G", "tracking_rms@G<=1", "P(max_accel>100)", "feasible",
            "role"} <= set(h.columns)  # fmt: skip
    assert list(h["role"].fillna(""))[-1] == "baseline" and (h["role"] == "best").sum() == 1


def test_the_value_is_the_worst_phase_and_controller_for_the_bound() -> None:
    # Means: pd/A 1, pd/B 4, smc/A 2, smc/B 3 (two realisations each).
    rows = [
        {"realisation": r, "controller": c, "phase": p, "rms": v + d, "diverged": False}
        for (c, p, v) in [("pd", "A", 1.0), ("pd", "B", 4.0), ("smc", "A", 2.0), ("smc", "B", 3.0)]
        for r, d in [(0, -0.5), (1, 0.5)]
    ]
    runs = pd.DataFrame(rows)
    assert Constraint("rms", "<=", 9.0).value(runs, ["A", "B"]) == 4.0
    assert Constraint("rms", ">=", 0.0).value(runs, ["A", "B"]) == 1.0
    assert Constraint("rms", "<=", 9.0, phase="A").value(runs, ["B"]) == 2.0
    p = Constraint("rms", "<=", 1.0, "exceedance", 3.0)
    assert p.value(runs, ["A", "B"]) == 1.0  # pd/B: both above 3
    assert p.value(runs, ["A"]) == 0.0
    # A realisation that diverged exceeds and makes a mean undefined (never met).
    runs.loc[(runs["controller"] == "smc") & (runs["realisation"] == 0), "diverged"] = True
    runs.loc[(runs["controller"] == "smc") & (runs["realisation"] == 0), "rms"] = np.nan
    assert p.value(runs, ["A"]) == 0.5
    mean = Constraint("rms", "<=", 9.0)
    assert np.isnan(mean.value(runs, ["A"])) and not mean.satisfied(mean.value(runs, ["A"]))
    assert mean.violation(np.nan) == np.inf and mean.violation(4.0) == 0.0
    assert Constraint("rms", "<=", 2.0).violation(3.0) == pytest.approx(0.5)
