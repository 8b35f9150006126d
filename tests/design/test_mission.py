"""``quadrs mission`` and :func:`quadrs.design.mission.mission_report`: the per-phase answers equal
direct counts on the runs, the whole flight is the worst over the phases (or the results' own
``flight`` phase), metric columns the results lack are left out, an independent batch agrees
within its standard error, and the command saves, draws, fits 100 columns and exits 130 on
Ctrl-C keeping what finished."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs.cli.main import main
from quadrs.design.mission import ALL_PHASES, FLIGHT_PHASE, mission_report
from quadrs.scenario.scenario import parse_value

TWO_PHASES = [
    "--set", "initial.position=[0.0,0.0,2.0]",
    "--set", "initial.attitude=[0.0,0.0,0.0]",
    "--set", "trajectory.waypoints=[[0.0,0.0,0.0,2.0,0.0],[3.0,0.0,0.0,2.0,0.0]]",
    "--set", 'phases=[{name="calm",start=0.0,end=1.0},{name="gusty",start=1.0,end=3.0}]',
    "--set", "gust.start=1.0",
    "--set", "gust.end=3.0",
    "--set", "gust.w20=20.0",
    "--set", "integrator.dt=0.001",
    "--set", "integrator.duration=3.0",
]  # fmt: skip


def two_phases() -> quadrs.Scenario:
    """Hover at 2 m: a calm second, then two seconds of strong vertical gust."""
    changes = {}
    for key, value in zip(TWO_PHASES[1::2], TWO_PHASES[1::2], strict=True):
        k, _, v = value.partition("=")
        changes[k] = parse_value(v)
        assert key == value
    return quadrs.Scenario.preset("paper_stable_lateral").override(changes)


def batch(runs: int, seed: int = 0) -> quadrs.MonteCarloResult:
    return quadrs.monte_carlo(two_phases(), runs=runs, seed=seed, controllers=("smc",),
                              progress=False, spectra=False)  # fmt: skip


def per_realisation(mc: quadrs.MonteCarloResult, phase: str, metric: str) -> np.ndarray:
    sel = mc.runs[mc.runs["phase"] == phase].sort_values("realisation")
    return sel[metric].to_numpy(float)


def test_the_answers_are_direct_counts_on_the_runs() -> None:
    mc = batch(40)
    limit = float(np.median(per_realisation(mc, "gusty", "max_accel")))
    r = mission_report(mc, limit, quantile=0.9)
    # The engine's whole-flight phase answers for the whole flight.
    assert list(r.acceleration.index) == ["calm", "gusty", FLIGHT_PHASE]
    assert r.whole == FLIGHT_PHASE
    for phase in ("calm", "gusty"):
        x = per_realisation(mc, phase, "max_accel")
        row = r.acceleration.loc[phase]
        assert row["n"] == 40 and row["exceedances"] == int((x > limit).sum())
        assert row["probability"] == (x > limit).mean()
        assert row["ci_low"] <= row["probability"] <= row["ci_high"]
        assert row["worst"] == x.max()
        assert row["quantile"] == np.quantile(x, 0.9, method="inverted_cdf")
        t = r.tracking.loc[phase]
        y = per_realisation(mc, phase, "tracking_rms")
        assert t["tracking_rms_mean"] == pytest.approx(y.mean(), rel=1e-12)
        assert t["tracking_rms_ci_low"] <= y.mean() <= t["tracking_rms_ci_high"]
    # The whole flight: a realisation exceeds if it does in any phase; worst of the worsts.
    both = np.maximum(per_realisation(mc, "calm", "max_accel"),
                      per_realisation(mc, "gusty", "max_accel"))  # fmt: skip
    whole = r.acceleration.loc[FLIGHT_PHASE]
    assert whole["probability"] == (both > limit).mean()
    assert whole["worst"] == both.max()
    flown = per_realisation(mc, FLIGHT_PHASE, "tracking_rms")
    assert r.tracking.loc[FLIGHT_PHASE, "tracking_rms_mean"] == pytest.approx(flown.mean())
    assert r.payload.columns.empty or all(
        c.split("_")[0] in ("max", "min", "slack", "saturated") for c in r.payload.columns
    )
    assert all(len(line) <= 100 for line in r.to_text().splitlines())


def test_an_independent_batch_agrees_within_its_standard_error() -> None:
    # A threshold from a pilot batch (seed 7), then two independent batches: their estimates of
    # P(max_accel > t) in the gusty phase differ by less than 4 standard errors of the
    # difference (a false alarm about once in 16000 runs of this test).
    t = float(np.median(per_realisation(batch(40, seed=7), "gusty", "max_accel")))
    a = mission_report(batch(200, seed=1), t).acceleration.loc["gusty"]
    b = mission_report(batch(200, seed=2), t).acceleration.loc["gusty"]
    pooled = (a["exceedances"] + b["exceedances"]) / (a["n"] + b["n"])
    se = math.sqrt(pooled * (1 - pooled) * (1 / a["n"] + 1 / b["n"]))
    assert 0.05 < pooled < 0.95
    assert abs(a["probability"] - b["probability"]) < 4 * se
    # And each interval holds the other batch's estimate or is near it (two 95 % intervals).
    assert a["ci_low"] - 2 * se < b["probability"] < a["ci_high"] + 2 * se


def test_coming_columns_and_the_whole_flight_phase_are_used_when_present() -> None:
    mc = batch(30)
    # One column the results lack (whatever this engine's version gives), four they have.
    runs = mc.runs.drop(columns=["saturated_time"], errors="ignore")
    rng = np.random.default_rng(0)
    runs["max_swing"] = rng.uniform(0.0, 0.3, len(runs))
    runs["max_tension"] = rng.uniform(5.0, 9.0, len(runs))
    runs["min_tension"] = rng.uniform(0.0, 3.0, len(runs))
    runs["slack_time"] = rng.uniform(0.0, 0.1, len(runs))
    # The engine's whole-flight phase: here a copy of the gusty rows under its name.
    flight = runs[runs["phase"] == "gusty"].assign(phase=FLIGHT_PHASE)
    runs = pd.concat([runs, flight], ignore_index=True)
    fake = quadrs.MonteCarloResult(mc.scenario, mc.seed, mc.controllers, runs)
    r = mission_report(fake, 5.0, quantile=0.8)
    assert list(r.acceleration.index) == ["calm", "gusty", FLIGHT_PHASE] and r.whole == FLIGHT_PHASE
    sel = runs[runs["phase"] == FLIGHT_PHASE].sort_values("realisation")
    p = r.payload.loc[FLIGHT_PHASE]
    assert p["max_swing_worst"] == sel["max_swing"].max()
    assert p["max_tension_q"] == np.quantile(sel["max_tension"], 0.8, method="inverted_cdf")
    assert p["min_tension_worst"] == sel["min_tension"].min()
    assert p["slack_time_mean"] == pytest.approx(sel["slack_time"].mean(), rel=1e-12)
    assert "saturated_time_mean" not in r.payload  # absent from the results: left out
    text = r.to_text()
    assert "swing q80" in text and "tension lowest" in text and "saturated" not in text
    assert all(len(line) <= 100 for line in text.splitlines())
    assert ALL_PHASES not in text


def test_diverged_flights_count_as_exceeding_and_as_the_worst() -> None:
    mc = batch(20)
    runs = mc.runs.copy()
    gone = runs["realisation"].isin([3, 11])
    metrics = list(quadrs._core.METRIC_NAMES)
    # The engine leaves the phases open at the divergence NaN: gusty and the whole flight.
    runs.loc[gone & runs["phase"].isin(["gusty", FLIGHT_PHASE]), metrics] = np.nan
    runs.loc[gone, "diverged"] = True
    fake = quadrs.MonteCarloResult(mc.scenario, mc.seed, mc.controllers, runs)
    r = mission_report(fake, 1e9)
    assert r.acceleration.loc["calm", "exceedances"] == 0  # ended before the divergence
    assert r.acceleration.loc["gusty", "exceedances"] == 2
    assert r.acceleration.loc["gusty", "diverged"] == 2
    assert r.acceleration.loc[FLIGHT_PHASE, "worst"] == math.inf


def test_the_command_on_the_paper_preset_saves_draws_and_fits_100_columns(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "m.parquet"
    rc = main(["mission", "--preset", "paper", "--runs", "12", "--limit", "5", "--out", str(out),
               "--plots", str(tmp_path / "fig")])  # fmt: skip
    text = capsys.readouterr().out
    assert rc == 0
    assert all(len(line) <= 100 for line in text.splitlines())
    assert "P(max_accel > 5 m/s^2 (0.51 g))" in text and FLIGHT_PHASE in text
    saved = quadrs.MonteCarloResult.read_parquet(out)
    assert saved.controllers == ("pd",) and len(saved.realisations) == 12
    assert saved.scenario == quadrs.Scenario.preset("paper")
    # The printed P2 count is the saved runs' own count.
    x = per_realisation(saved, "P2", "max_accel")
    parcel = text[text.index("Parcel acceleration") :]  # after the route's table
    line = next(row for row in parcel.splitlines() if row.startswith("P2 "))
    assert line.split()[3] == str(int((x > 5).sum()))
    assert (tmp_path / "fig" / "mission_risk.png").stat().st_size > 0
    assert (tmp_path / "fig" / "exceedance_max_accel.svg").stat().st_size > 0


def test_the_command_on_a_scenario_of_ones_own_phases(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    src = tmp_path / "s.toml"
    src.write_text(two_phases().to_toml())
    rc = main(["mission", "--scenario", str(src), "--runs", "8", "--controller", "pd",
               "--seed", "3", "--quantile", "0.5"])  # fmt: skip
    text = capsys.readouterr().out
    assert rc == 0 and text.startswith("Route") and "Parcel: PD, 8 realisations" in text
    rows = [line.split()[0] for line in text.splitlines() if line[:5] in ("calm ", "gusty")]
    # One row per phase in each table (acceleration, tracking, attachment...).
    assert rows.count("calm") == rows.count("gusty") >= 2
    assert "q50" in text


def test_ctrl_c_keeps_what_finished_and_exits_130(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import quadrs.runs.montecarlo as montecarlo

    real = montecarlo.monte_carlo

    def interrupted(*args: object, **kwargs: object) -> quadrs.MonteCarloResult:
        if kwargs["runs"] != 50:  # the timing calibration before the batch
            return real(*args, **kwargs)  # type: ignore[arg-type]
        kwargs["runs"] = 5  # what finished before Ctrl-C (the calibration's flights not taken)
        kwargs["flown"] = None
        mc = real(*args, **kwargs)  # type: ignore[arg-type]
        mc.interrupted = True
        return mc

    monkeypatch.setattr(montecarlo, "monte_carlo", interrupted)
    out = tmp_path / "m.parquet"
    rc = main(["mission", "--preset", "paper", *TWO_PHASES, "--runs", "50", "--out", str(out)])
    assert rc == 130
    assert "5 of 50 realisations finished" in capsys.readouterr().out
    saved = quadrs.MonteCarloResult.read_parquet(out)
    assert saved.interrupted and len(saved.realisations) == 5


@pytest.mark.parametrize(
    ("args", "name"),
    [(["--limit", "-1"], "--limit"), (["--limit", "nan"], "--limit"),
     (["--quantile", "1"], "--quantile"), (["--out", "x.csv"], "--out"),
     (["--runs", "0"], "--runs")],
)  # fmt: skip
def test_bad_input_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], name: str
) -> None:
    rc = main(["mission", "--preset", "paper", *TWO_PHASES, *args])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and name in err


def test_repr_is_one_line_and_html_has_the_tables() -> None:
    r = mission_report(batch(6), 5.0)
    p = r.acceleration.loc[FLIGHT_PHASE, "probability"]
    assert "\n" not in repr(r) and f"{100 * p:.3g} %" in repr(r) and FLIGHT_PHASE in repr(r)
    html = r._repr_html_()
    # route, acceleration, tracking, and the payload's table when the engine gives its columns
    assert html.count("<table") == 3 + bool(len(r.payload.columns))


def test_an_acceleration_limit_is_taken_and_shown_in_standard_g() -> None:
    """Fragility is stated in g (ISTA, ASTM D4169): ``--limit max_specific_force=1.5g`` is
    1.5 standard gravities, and the parcel table shows the worst in g too;
    a g on an angle is refused naming the metric."""
    import argparse

    from quadrs.cli.common import limit_option
    from quadrs.present.labels import STANDARD_GRAVITY

    assert limit_option("max_specific_force=1.5g") == ("max_specific_force", 1.5 * 9.80665)
    assert limit_option("2 G") == ("max_accel", 2 * 9.80665)
    assert limit_option("max_accel=3") == ("max_accel", 3.0)
    with pytest.raises(argparse.ArgumentTypeError, match="max_swing"):
        limit_option("max_swing=2g")
    mc = batch(12)
    r = mission_report(mc, 1.5 * STANDARD_GRAVITY, metric="max_specific_force")
    text = r.to_text(width=200)
    assert "14.71 m/s^2 (1.5 g)" in text.replace("14.7099", "14.71")
    worst = r.acceleration["worst"].to_numpy(float)
    assert (worst > 9.0).all()  # |a - g| is about g at hover
    parcel = text[text.index("Parcel max_specific_force") :].splitlines()
    assert parcel[1].split()[-2:] == ["worst", "g"]
    calm = next(ln for ln in parcel if ln.startswith("calm"))
    assert calm.split()[-1] == f"{worst[0] / STANDARD_GRAVITY:.3g}"
    swing = mission_report(mc, 0.1, metric="max_swing").to_text(width=200)
    assert "worst g" not in swing


def test_a_new_angle_metric_is_in_degrees_in_the_table_and_in_limit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A metric the engine's registry adds with the unit "rad" (here a scratch registry: the
    engine's lists with one metric more) is typed in degrees in ``--limit`` and shown in
    degrees in the mission's table, with no Python list edited (issue 70): its unit travels
    with its one entry."""
    from quadrs import _core
    from quadrs.cli.common import limit_option

    mc = batch(12)
    name = "max_lean"
    assert name not in _core.METRIC_NAMES
    monkeypatch.setattr(_core, "METRIC_NAMES", [*_core.METRIC_NAMES, name])
    monkeypatch.setitem(_core.METRIC_UNITS, name, "rad")
    monkeypatch.setitem(_core.METRIC_LABELS, name, "largest lean")
    rng = np.random.default_rng(3)
    mc.runs[name] = rng.uniform(0.1, 0.8, len(mc.runs))  # in radians, as the results hold it
    metric, limit = limit_option(f"{name}=30")
    assert (metric, limit) == (name, pytest.approx(math.radians(30.0), rel=1e-15))
    assert limit_option(f"{name}=0.5rad")[1] == 0.5
    text = mission_report(mc, limit, metric=name).to_text(width=200)
    assert f"{name} (deg)" in text and "30 deg" in text
    report = mission_report(mc, limit, metric=name)
    parcel = text[text.index(f"Parcel {name}") :].splitlines()
    calm = next(ln for ln in parcel if ln.startswith("calm"))
    assert calm.split()[-1] == f"{math.degrees(report.acceleration['worst'].iloc[0]):.3g}"
