"""A delivery engineer's first hour (issue 41): long commands that say what they cost, a
mission answer that leads with whether the route was flown, one unit per quantity, reports of
mission files, whole figures, a parcel below the ground, honest help and docs. One test (or
more) per item; each fails on the code before issue 41."""

from __future__ import annotations

import importlib
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

import quadrs
import quadrs.cli.cost
from quadrs.cli.main import main
from quadrs.design.mission import FLIGHT_PHASE, mission_report
from quadrs.scenario.scenario import presets

ROOT = Path(__file__).resolve().parents[2]
#: The short routes fly at dt = 2 ms, coarse for the payload's fastest mode (a StepSizeWarning
#: each batch): fine for what these tests check, which is the answer's form.
pytestmark = pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")
opt_module = importlib.import_module("quadrs.design.optimize")
#: The mission's joint row (quadrs.design.mission.ANY_PHASE).
ANY_PHASE = "any phase"

#: A short route (a 20 m dog-leg at 5 m), phases per leg, in about 12 s of flight.
SHORT_ROUTE = {
    "trajectory.route": [[0.0, 0.0, 2.0], [0.0, 0.0, 5.0], [20.0, 0.0, 5.0], [20.0, 10.0, 5.0]],
    "trajectory.hold": [0.5, 0.0, 0.0, 0.5],
    "trajectory.names": ["lift", "climb", "leg", "dog", "drop"],
    "gust.end": 30.0,
    "integrator.duration": 30.0,
    "integrator.dt": 0.002,
}


@pytest.fixture(scope="module")
def route() -> quadrs.Scenario:
    return quadrs.Scenario.preset("delivery").override(SHORT_ROUTE)


@pytest.fixture(scope="module")
def route_mc(route: quadrs.Scenario) -> quadrs.MonteCarloResult:
    return quadrs.monte_carlo(route, runs=12, seed=0, controllers=("pd",), progress=False,
                              spectra=False)  # fmt: skip


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def route_file(tmp_path: Path, scenario: quadrs.Scenario) -> str:
    path = tmp_path / "route.toml"
    path.write_text(scenario.to_toml())
    return str(path)


# -- 1. long commands say what they fly and how long; Ctrl-C keeps what finished ---------------
@pytest.fixture
def announce_all(monkeypatch: pytest.MonkeyPatch) -> None:
    """Announce every job (these are short: a long one is announced anyway)."""
    import quadrs.cli.cost

    monkeypatch.setattr(quadrs.cli.cost, "ANNOUNCE_AFTER", 0.0)


def test_a_short_job_is_not_announced(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], route: quadrs.Scenario
) -> None:
    code, _, err = cli(capsys, "mission", "--scenario", route_file(tmp_path, route),
                       "--runs", "2")  # fmt: skip
    assert code == 0 and "calibration" not in err


def test_mission_says_up_front_what_it_flies_and_how_long(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], route: quadrs.Scenario, announce_all: None
) -> None:
    code, _, err = cli(capsys, "mission", "--scenario", route_file(tmp_path, route),
                       "--runs", "4")  # fmt: skip
    assert code == 0
    first = err.splitlines()[0]
    assert re.match(r"quadrs mission: 4 realisations of a 30 s flight \(4 flights\): about \d+ s",
                    first)  # fmt: skip
    assert "calibration flights" in first and "Ctrl-C keeps what finished" in first


def test_rare_says_up_front_what_a_level_costs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short: quadrs.Scenario, announce_all: None
) -> None:
    path = tmp_path / "s.toml"
    path.write_text(short.to_toml())
    code, _, err = cli(capsys, "rare", "--scenario", str(path), "--metric", "max_accel",
                       "--phase", "P2", "--threshold", "1e6", "--per-level", "100",
                       "--max-levels", "2")  # fmt: skip
    assert code == 0
    first = err.splitlines()[0]
    assert first.startswith("quadrs rare: 100 flights a level, about ")
    assert "at most 2 (190 flights, about " in first and "Ctrl-C keeps the finished" in first


def test_tune_says_up_front_how_many_candidates_and_how_long(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], announce_all: None
) -> None:
    from tests.cli.test_design import SHORT, TUNE

    code, _, err = cli(capsys, "tune", "--preset", "paper_stable_lateral", *SHORT, *TUNE,
                       "--out", str(tmp_path / "t.toml"))  # fmt: skip
    assert code == 0
    # --popsize 3 x 1 parameter x (--maxiter 2 + 1) = 9 candidates of 2 flights, 3 checks.
    assert "quadrs tune: up to 9 candidates of 2 flights, then 3 checks (24 flights): about" in err


def test_mc_and_paper_say_up_front_what_they_fly(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short: quadrs.Scenario, announce_all: None
) -> None:
    path = tmp_path / "s.toml"
    path.write_text(short.to_toml())
    code, _, err = cli(capsys, "mc", "--scenario", str(path), "--runs", "3")
    assert code == 0
    assert err.startswith("quadrs mc: 3 realisations x PD and SMC (6 flights): about ")
    # Bad input is refused before any calibration: one line, no announcement.
    code, _, err = cli(capsys, "mc", "--scenario", str(path), "--runs", str(10**12))
    assert code == 2 and len(err.strip().splitlines()) == 1 and "calibration" not in err
    code, _, err = cli(capsys, "paper", "--scenario", str(path), "--runs", "2", "--out",
                       str(tmp_path / "p"), "--frequencies", "-2")  # fmt: skip
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_the_calibration_flies_in_the_engine_not_the_batch(short: quadrs.Scenario) -> None:
    from quadrs.cli.cost import calibrate

    cal = calibrate(short, ("pd", "smc"), workers=1, flights=2)
    assert cal.flights == 4 and cal.workers == 1 and cal.per_flight > 0


def test_the_calibration_keeps_every_worker_busy(short: quadrs.Scenario) -> None:
    """By default one lane-set a worker (8 flights were one AVX-512 set, on one of two
    workers: the estimate doubled), never more than the batch flies."""
    from quadrs import _core
    from quadrs.cli.cost import calibrate

    lanes = _core.lanes_per_set()
    assert lanes == {"avx512": 8}.get(_core.simd_path(), 4)
    assert calibrate(short, ("pd",), workers=2).flights == 2 * lanes
    assert calibrate(short, ("pd", "smc"), workers=2, at_most=3).flights == 2 * 3


def test_tune_interrupted_keeps_the_candidates_flown_without_history(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.cli.test_design import SHORT, TUNE

    real = opt_module.monte_carlo
    calls: list[int] = []

    def interrupted_on_the_fourth(*args: object, **kwargs: object) -> object:
        calls.append(1)
        if len(calls) == 4:
            raise KeyboardInterrupt
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(opt_module, "monte_carlo", interrupted_on_the_fourth)
    out = tmp_path / "tuned.toml"
    code, _, err = cli(capsys, "tune", "--preset", "paper_stable_lateral", *SHORT, *TUNE,
                       "--out", str(out))  # fmt: skip
    assert code == 130
    history = tmp_path / "tuned-history.csv"
    assert f"the 3 candidates evaluated are in {history}" in err
    import pandas as pd

    assert len(pd.read_csv(history)) == 3


def test_tune_interrupted_in_its_first_candidate_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from tests.cli.test_design import SHORT, TUNE

    def interrupted(*args: object, **kwargs: object) -> object:
        raise KeyboardInterrupt

    monkeypatch.setattr(opt_module, "monte_carlo", interrupted)
    code, _, err = cli(capsys, "tune", "--preset", "paper_stable_lateral", *SHORT, *TUNE,
                       "--out", str(tmp_path / "t.toml"))  # fmt: skip
    assert code == 130 and "no candidate finished" in err


def test_the_eta_of_counted_pieces() -> None:
    from quadrs.cli.cost import Calibration, Eta, announce, duration

    assert [duration(s) for s in (0.2, 40, 420, 5.4 * 3600)] == ["1 s", "40 s", "7 min", "5.4 h"]
    line = announce("tune", "336 candidates", 67_200, Calibration(8, 2.32, 2))
    assert "(67,200 flights): about 5.4 h (0.29 s a flight on 2 threads" in line
    eta = Eta(4)
    assert eta.step().startswith("1 of 4 after ") and "left" in eta.step()


# -- 2. the mission's answer leads with whether the route was flown -----------------------------
def test_the_answer_leads_with_the_route_and_shows_the_time_near_the_tilt_limit(
    route_mc: quadrs.MonteCarloResult,
) -> None:
    r = mission_report(route_mc, 9.81)
    assert r.route is not None and r.route_flown
    text = r.to_text()
    assert text.startswith("Route: flown in all 12 flights")
    assert text.index("Route") < text.index("Parcel acceleration")
    # The engine measures the time near the tilt limit (near_tilt_time): the route's table
    # shows it, and nothing says it is not measured.
    assert "not measured" not in text
    assert "near the tilt limit" in text and "near tilt worst s" in text
    # The route's table: worst tracking and cross-track per phase, time at the thrust limit
    # and near the tilt limit.
    for m in ("max_tracking", "max_cross_track", "near_tilt_time"):
        sel = route_mc.runs[route_mc.runs["phase"] == "leg"][m]
        assert r.route.loc["leg", f"{m}_worst"] == pytest.approx(sel.max())
    assert "saturated_time_mean" in r.route and "near_tilt_time_mean" in r.route


def test_a_route_not_held_is_the_first_thing_said(route_mc: quadrs.MonteCarloResult) -> None:
    worst = float(route_mc.runs.loc[route_mc.runs["phase"] == FLIGHT_PHASE, "max_tracking"].max())
    limit = float(np.median(route_mc.runs.loc[route_mc.runs["phase"] == FLIGHT_PHASE,
                                              "max_tracking"]))  # fmt: skip
    r = mission_report(route_mc, 9.81, track_limit=limit, cross_track_limit=1e3)
    off = int((route_mc.runs.loc[route_mc.runs["phase"] == FLIGHT_PHASE, "max_tracking"]
               > limit).sum())  # fmt: skip
    assert not r.route_flown and r.route.loc[FLIGHT_PHASE, "off_route"] == off
    first = r.to_text().splitlines()[0]
    assert first.startswith(f"Route: NOT FLOWN in {off} of 12 flights")
    assert f"worst tracking {worst:.3g} m" in r.to_text().replace("\n", " ")


def test_mission_track_limit_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], route: quadrs.Scenario
) -> None:
    code, out, _ = cli(capsys, "mission", "--scenario", route_file(tmp_path, route), "--runs",
                       "3", "--track-limit", "0.001")  # fmt: skip
    assert code == 0 and out.startswith("Route: NOT FLOWN in 3 of 3 flights")
    code, _, err = cli(capsys, "mission", "--track-limit", "-1")
    assert code == 2 and "--track-limit" in err


def test_mission_fits_the_terminal_it_prints_to(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    route: quadrs.Scenario,
) -> None:
    """The tables and text at the terminal's width (COLUMNS, as the shell sets it), between 60
    and 100 columns; 100 when the output is not a terminal."""
    from quadrs.cli.common import report_width

    args = ("mission", "--scenario", route_file(tmp_path, route), "--runs", "3",
            "--controller", "pd,smc")  # fmt: skip
    widths = {}
    for columns in ("72", None):
        if columns is None:
            monkeypatch.delenv("COLUMNS", raising=False)
        else:
            monkeypatch.setenv("COLUMNS", columns)
        code, out, _ = cli(capsys, *args)
        assert code == 0
        widths[columns] = max(len(line) for line in out.splitlines())
    assert widths["72"] <= 72 < widths[None] <= 100
    for columns, width in (("30", 60), ("80", 80), ("500", 100)):
        monkeypatch.setenv("COLUMNS", columns)
        assert report_width() == width


def test_run_prints_its_metrics_at_the_terminals_width(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A single flight's 26 metrics by phase, in blocks of columns that fit the terminal
    (the table was one line of nearly 400 characters a phase), every metric still shown."""
    from quadrs.runs.flight import METRIC_COLUMNS

    monkeypatch.setenv("COLUMNS", "72")
    code, out, _ = cli(capsys, "run", "--preset", "delivery")
    assert code == 0
    assert max(len(line) for line in out.splitlines()) <= 72
    shown = set(out.split())
    assert set(METRIC_COLUMNS) <= shown
    assert {"lift", "climb", "flight"} <= shown


# -- 3. mission flies a route by default ---------------------------------------------------------
def test_mission_defaults_to_the_delivery_preset(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import quadrs.cli.mission as cm
    import quadrs.runs.montecarlo as montecarlo

    seen: list[quadrs.Scenario] = []
    real = montecarlo.monte_carlo

    def spy(scenario: quadrs.Scenario, *args: object, **kwargs: object) -> object:
        seen.append(scenario)
        kwargs["runs"] = 1
        return real(scenario.override(SHORT_ROUTE), *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(montecarlo, "monte_carlo", spy)
    monkeypatch.setattr(cm, "_announce", lambda *a: None)
    code, _, _ = cli(capsys, "mission", "--runs", "1")
    assert code == 0 and seen[0] == quadrs.Scenario.preset("delivery")


# -- issue 42's mission items: zeros are not intervals; per-phase intervals are not joint -------
def test_a_count_that_never_happened_is_a_bound_not_an_interval(
    route_mc: quadrs.MonteCarloResult,
) -> None:
    r = mission_report(route_mc, 1e3)
    # Clopper-Pearson, k = 0: the two-sided interval's upper end (issue 54: one convention)
    bound = 100 * (1 - 0.025 ** (1 / 12))
    text = r.to_text()
    assert f"0 of 12 flights, P <= {bound:.3g}" in text
    assert "0 [0, 0]" not in text
    from quadrs.design.mission import one_sided_upper

    assert one_sided_upper(0, 200) == pytest.approx(1 - 0.05 ** (1 / 200), rel=1e-12)
    assert one_sided_upper(3, 200) > one_sided_upper(0, 200)


def test_any_phase_is_the_joint_count_and_the_rows_say_they_are_not_joint(
    route_mc: quadrs.MonteCarloResult,
) -> None:
    legs = ["lift", "climb", "leg", "dog", "drop"]
    runs = route_mc.runs[route_mc.runs["phase"].isin(legs)]
    limit = float(np.quantile(runs["max_accel"], 0.9))
    r = mission_report(route_mc, limit)
    wide = runs.pivot(index="realisation", columns="phase", values="max_accel")
    joint = int((wide > limit).any(axis=1).sum())
    assert r.joint is not None and int(r.joint.loc["acceleration", "count"]) == joint
    from quadrs.stats.risk import exceedance_interval

    _, lo, hi = exceedance_interval(joint, 12)
    assert r.joint.loc["acceleration", "ci_low"] == pytest.approx(lo)
    assert r.joint.loc["acceleration", "ci_high"] == pytest.approx(hi)
    text = r.to_text().replace("\n", " ")
    assert f"{ANY_PHASE}: {joint} of 12 flights" in text
    assert "for that phase alone, not joint over the phases" in text


# -- 13. --limit in both forms in both commands ------------------------------------------------
def test_limit_in_both_forms_in_mission_and_report(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], route: quadrs.Scenario
) -> None:
    src = route_file(tmp_path, route)
    out = tmp_path / "m.parquet"
    code, a, _ = cli(capsys, "mission", "--scenario", src, "--runs", "3", "--limit",
                     "max_accel=1.2", "--out", str(out))  # fmt: skip
    assert code == 0 and "P(max_accel > 1.2 m/s^2" in a
    code, b, _ = cli(capsys, "mission", "--scenario", src, "--runs", "3", "--limit", "1.2")
    assert code == 0 and "P(max_accel > 1.2 m/s^2" in b
    code, _, err = cli(capsys, "mission", "--limit", "no_such_metric=3")
    assert code == 2 and "no_such_metric" in err and len(err.strip().splitlines()) == 1
    # Another metric, in the unit the tables show (degrees for swing).
    code, e, _ = cli(capsys, "mission", "--scenario", src, "--runs", "3", "--limit",
                     "max_swing=30")  # fmt: skip
    assert code == 0 and "Parcel max_swing (deg): P(max_swing > 30 deg)" in e
    code, c, _ = cli(capsys, "report", str(out), "--limit", "1.2")
    assert code == 0 and "P(max_accel > 1.2 m/s^2" in c
    code, d, _ = cli(capsys, "report", str(out), "--limit", "max_accel=1.2")
    assert code == 0 and "P(max_accel > 1.2 m/s^2" in d


def test_limit_parsing_is_general_over_metric_names() -> None:
    from quadrs.cli.main import _limit

    assert _limit("2.5") == ("max_accel", 2.5)
    assert _limit("max_tension=7") == ("max_tension", 7.0)
    # Any metric the engine names is accepted (a new one too, with no change here).
    for name in quadrs._core.METRIC_NAMES:
        assert _limit(f"{name}=1")[0] == name
    assert math.isfinite(_limit("max_swing=30")[1])


# -- 4. one unit per quantity: swing in degrees wherever a person reads it ----------------------
def test_swing_is_degrees_in_figures_and_limits(
    route_mc: quadrs.MonteCarloResult, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from quadrs import plots
    from quadrs.plots.base import label_with_unit

    assert label_with_unit("max_swing").endswith("(deg)")
    fig = plots.exceedance_curves(route_mc.runs, "max_swing")
    worst = math.degrees(float(route_mc.runs.loc[route_mc.runs["phase"] == "leg",
                                                 "max_swing"].max()))  # fmt: skip
    ax = fig.axes[2]  # lift, climb, leg: the leg's panel
    right = max(max(line.get_xdata()) for line in ax.get_lines() if len(line.get_xdata()))
    assert right == pytest.approx(worst)
    out = tmp_path / "m.parquet"
    route_mc.to_parquet(out)
    code, text, _ = cli(capsys, "report", str(out), "--limit", "max_swing=30")
    table = text[text.index("P(metric > threshold)") :]
    assert code == 0 and " 30 " in table and "deg" in table


# -- 5. report on a mission file prints the mission's tables -------------------------------------
def test_report_on_a_mission_file_prints_the_mission(
    route_mc: quadrs.MonteCarloResult, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "m.parquet"
    route_mc.to_parquet(out)
    code, text, _ = cli(capsys, "report", str(out))
    assert code == 0
    assert "Route: flown in all 12 flights" in text and "Swing (deg) and tension (N)" in text
    assert "Table 3" not in text and "IAE" not in text
    # Its figures are the mission's (they were a batch's: distributions and max_accel only).
    figs = tmp_path / "figs"
    code, _, _ = cli(capsys, "report", str(out), "--plots", str(figs))
    assert code == 0
    names = {p.stem for p in figs.glob("*.png")}
    assert {"exceedance_max_specific_force", "exceedance_max_swing"} <= names
    assert {n for n in names if n.startswith("mission_risk")} and "distributions" not in names


# -- 6. exceedance figures: the whole flight's panel, curves to the worst value ----------------
def test_exceedance_figure_has_the_flight_panel_and_reaches_the_worst(
    route_mc: quadrs.MonteCarloResult,
) -> None:
    from quadrs import plots

    fig = plots.exceedance_curves(route_mc.runs, "max_accel")
    titles = [a.get_title() for a in fig.axes]
    assert any(t.startswith(f"Exceedance, {FLIGHT_PHASE} ") for t in titles)
    ax = next(a for a in fig.axes if a.get_title().startswith(f"Exceedance, {FLIGHT_PHASE} "))
    worst = float(route_mc.runs.loc[route_mc.runs["phase"] == FLIGHT_PHASE, "max_accel"].max())
    right = max(max(line.get_xdata()) for line in ax.get_lines() if len(line.get_xdata()))
    assert right == pytest.approx(worst)
    # The tail is drawn one flight at a time: the last step is 1 of n, whatever n.
    from quadrs.stats.risk import survival_curve

    x = np.random.default_rng(0).normal(size=1000)
    curve = survival_curve(x)
    shown = curve[curve["probability"] > 0]
    assert shown["probability"].iloc[-1] == pytest.approx(1 / 1000)
    assert curve["threshold"].iloc[-1] == x.max()


# -- 7. a parcel that starts below the ground warns --------------------------------------------
def test_a_parcel_below_the_ground_warns() -> None:
    """A line that hangs the parcel below the ground at the start: a warning where the ground
    only ends the vehicle's flight (no contact for the parcel), a refusal where the parcel meets
    the ground (ground.stiffness, the delivery preset), whose winch starts the line reeled in
    (payload.length_min)."""
    slung = quadrs.Scenario.preset("slung")
    # The vehicle at 0 m, the parcel about 1.05 m below it (attachment offset + line).
    with pytest.warns(quadrs.PlausibilityWarning, match="parcel starts below the ground"):
        slung.override({"ground.enabled": True, "ground.altitude": -0.5})
    with warnings.catch_warnings():
        warnings.simplefilter("error", quadrs.PlausibilityWarning)
        slung.override({"ground.enabled": True, "ground.altitude": -1.5})  # clear: no warning
    base = quadrs.Scenario.preset("delivery")
    reeled = base["initial.position"][2] + 0.5  # reeled in, the line is longer than the start
    lower = list(base["trajectory.lower"])
    lower[3] = base["payload.cable_length"] - reeled  # the most a lowering may pay out
    with pytest.raises(quadrs.ScenarioError, match="must hang the parcel above the ground"):
        base.override({"payload.length_min": reeled, "trajectory.lower": lower})
    base.override({"payload.length_min": reeled - 1.0, "trajectory.lower": lower})  # clear


# -- 9. the paper command and report do not claim to reproduce ----------------------------------
def test_paper_help_and_report_do_not_claim_to_reproduce(
    capsys: pytest.CaptureFixture[str], short: quadrs.Scenario
) -> None:
    from quadrs.paper.pipeline import _head, _ordering_lines, paper_phases

    code, out, _ = cli(capsys, "paper", "--help")
    assert code == 0 and "Reproduce" not in out and "not the paper's" in out
    assert "reproduced" not in "\n".join(_head(10, 10, 0))
    mc = quadrs.monte_carlo(short, runs=3, progress=False)
    summ = paper_phases(mc.summary())
    assert FLIGHT_PHASE not in summ.index.get_level_values("phase")
    text = "\n".join(_ordering_lines(mc.summary()))
    assert "nan" not in text


# -- 10. marginal modes, notebooks, API roles, re-flown failures ---------------------------------
def test_a_marginal_mode_never_reads_plus_zero() -> None:
    from quadrs.hover.stability import _pole

    assert _pole(3.1e-4, 2.0) == "+3.1e-04 ± 2.00j"
    assert _pole(0.04, 2.98) == "+0.04 ± 2.98j"


def test_no_ipywidgets_means_the_text_bar(monkeypatch: pytest.MonkeyPatch) -> None:
    import sys

    from quadrs.present.terminal import tqdm_class

    monkeypatch.setitem(sys.modules, "ipywidgets", None)  # not installed
    import tqdm.std

    assert tqdm_class() is tqdm.std.tqdm


def test_the_docs_site_shows_roles_as_code() -> None:
    import importlib.util

    spec = importlib.util.spec_from_file_location("hooks", ROOT / "scripts/mkdocs_hooks.py")
    assert spec is not None and spec.loader is not None
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    assert hooks.strip_roles("see :func:<code>quadrs.simulate</code>") == (
        "see <code>quadrs.simulate</code>"
    )
    assert "scripts/mkdocs_hooks.py" in (ROOT / "mkdocs.yml").read_text()


def test_a_reflown_failure_is_not_called_realisation_0(short: quadrs.Scenario) -> None:
    r = quadrs.rare_event(short, controller="pd", metric="max_accel", phase="P2",
                          threshold=0.0, per_level=100, p0=0.1, max_levels=1)  # fmt: skip
    flight = r.flight(0)
    assert "realisation 0" not in repr(flight) and "failure sample 0" in repr(flight)


# -- 13. a preset turned into a route --------------------------------------------------------------
def test_a_preset_overridden_into_a_route_drops_its_waypoints(tmp_path: Path) -> None:
    route = {"trajectory.interpolation": "route", "trajectory.route": [[0, 0, 0], [0, 0, 2]],
             "trajectory.speed": 1.0, "trajectory.acceleration": 1.0,
             "trajectory.hold": [1.0, 0.0], "phases": "legs"}  # fmt: skip
    s = quadrs.Scenario.paper().override(route)
    assert str(s["trajectory.interpolation"]) == "route"
    path = tmp_path / "r.toml"
    path.write_text('base = "paper"\nphases = "legs"\n[trajectory]\ninterpolation = "route"\n'
                    "route = [[0.0, 0.0, 0.0], [0.0, 0.0, 2.0]]\nspeed = 1.0\n"
                    "acceleration = 1.0\nhold = [1.0, 0.0]\n")  # fmt: skip
    assert quadrs.Scenario.from_toml(path) == s


# -- 15. the whole-flight row: documented, and the phases alone -----------------------------------
def test_the_phases_alone(short: quadrs.Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=2, controllers=("pd",), progress=False)
    assert FLIGHT_PHASE in set(mc.runs["phase"])
    alone = mc.phases_only()
    assert list(pd_unique(alone["phase"])) == ["P1", "P2", "P3"]
    f = quadrs.simulate(short, "pd", seed=0)
    assert list(f.phases_only()["phase"]) == ["P1", "P2", "P3"]
    # Documented where the API reference (docs/api/runs.md) and README show it.
    for text in (quadrs.MonteCarloResult.__doc__, quadrs.Flight.__doc__,
                 (ROOT / "README.md").read_text()):  # fmt: skip
        flat = " ".join(str(text).split())
        assert "phases_only" in flat and "counts the flight twice" in flat


def pd_unique(values: object) -> list[object]:
    import pandas as pd

    return list(pd.unique(values))  # type: ignore[call-overload]


# -- must show: every documented command runs as written, or its cost is stated ----------------
DOC_FILES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: Inline mentions that name a command or an option, not a command to run.
FRAGMENTS = re.compile(r"^quadrs (\w+|\w+ --[\w-]+|mc --sampling \.\.\.|mc --plots DIR|"
                       r"linearize --wind|run --trace FILE\.parquet|rare --controller pd,smc|"
                       r"scenario show --preset|rare: .*|report|"
                       r"tune --preset delivery --controller smc)$")  # fmt: skip
#: A time stated beside a command: "about 7 min", "(1 min)", "5-12 h", "30 s".
COST = re.compile(r"\b\d+(?:[.,]\d+)?(?:-\d+)? ?(?:s|min|minutes|h|hours?)\b")
#: Commands that take long enough that the docs must say how long (a subcommand, or a size).
LONG_SUBCOMMANDS = {"rare", "tune", "paper", "sensitivity"}


def documented_commands() -> list[tuple[str, str, str]]:
    """(file, command, its context) for every ``quadrs`` command in README.md and docs/*.md:
    each line of a code block (continuations joined, ``# comments`` and ``[optional]`` parts
    dropped) and each inline code span that is a whole command; the context is the command's
    own line with its comments (and, for a block of one command, the text just before it and
    the paragraph after it), or the inline span's paragraph."""
    out = []
    for path in DOC_FILES:
        text = path.read_text()
        for m in re.finditer(r"^```[a-z]*\n(.*?)^```", text, re.S | re.M):
            before = text[max(0, m.start() - 300) : m.start()].split("```")[-1]
            after = text[m.end() : m.end() + 900].split("\n\n```")[0]
            # Each command with its own comment lines (continuations joined).
            found: list[tuple[str, str]] = []
            for raw in m.group(1).replace("\\\n", " ").splitlines():
                line = raw.strip().removeprefix("$ ")
                hit = re.search(r"(?:^|&& )(?:\.venv/bin/)?(quadrs .*)", line)
                if hit:
                    cmd = re.sub(r"\s+#.*$", "", hit.group(1))
                    cmd = re.sub(r"\s*\[--[^\]]*\]", "", cmd)
                    found.append((" ".join(cmd.split()), line))
                elif line.startswith("#") and found:
                    found[-1] = (found[-1][0], found[-1][1] + " " + line)
            for cmd, own in found:
                # The text around the block speaks for it when it holds one command.
                context = own + (before + after if len(found) == 1 else "")
                out.append((path.name, cmd, context))
        prose = re.sub(r"^```.*?^```", "", text, flags=re.S | re.M)
        for para in prose.split("\n\n"):
            for span in re.findall(r"`((?:\.venv/bin/)?quadrs [^`]+)`", para):
                cmd = " ".join(span.removeprefix(".venv/bin/").split())
                if not FRAGMENTS.match(cmd):
                    out.append((path.name, cmd, para))
    return out


def test_every_documented_command_parses_as_written() -> None:
    import shlex

    from quadrs.cli.main import build_parser

    commands = documented_commands()
    assert len(commands) > 40
    bad = []
    for name, cmd, _ in commands:
        try:
            build_parser().parse_args(shlex.split(cmd)[1:])
        except SystemExit:
            bad.append((name, cmd))
    assert bad == []


def test_every_long_documented_command_states_its_cost() -> None:
    import shlex

    missing = []
    for name, cmd, context in documented_commands():
        argv = shlex.split(cmd)
        runs = int(argv[argv.index("--runs") + 1]) if "--runs" in argv else 0
        long = argv[1] in LONG_SUBCOMMANDS or runs >= 2000 or (
            argv[1] == "mission" and runs >= 200 and "--preset paper" not in cmd)  # fmt: skip
        if long and not COST.search(context):
            missing.append((name, cmd))
    assert missing == []


def test_the_notebook_shows_swing_in_degrees(route_mc: quadrs.MonteCarloResult) -> None:
    r = mission_report(route_mc, 9.81)
    html = r._repr_html_()
    assert "swing (deg)" in html and "(rad" not in html
    worst = math.degrees(float(r.payload.loc["leg", "max_swing_worst"]))
    assert f"{worst:.3g}" in html


# -- 11. the docs say what the code does today ---------------------------------------------------
def test_delivery_md_paper_example_is_what_the_command_prints() -> None:
    """docs/delivery.md's paper-preset table: 200 flights, limit 5 m/s^2 (a few seconds)."""
    mc = quadrs.monte_carlo(quadrs.Scenario.paper(), runs=200, seed=0, controllers=("pd",),
                            progress=False, spectra=False)  # fmt: skip
    text = mission_report(mc, 5.0).to_text()
    doc = (ROOT / "docs/delivery.md").read_text()
    table = text[text.index("Parcel acceleration") :]
    for phase in ("P1", "P2", "P3", FLIGHT_PHASE):
        printed = next(line for line in table.splitlines() if line.startswith(f"{phase} "))
        assert printed in doc, printed
    assert "every flight (about 5.77" not in doc


def test_gust_md_says_the_wind_follows_the_vehicle() -> None:
    text = " ".join((ROOT / "docs/gust.md").read_text().split())
    assert "built for one airspeed and one altitude" not in text
    assert "it follows both every step" in text


# -- 12. README: the scope as it is, the presets as shipped ---------------------------------------
def test_readme_describes_the_scope_and_every_preset() -> None:
    readme = (ROOT / "README.md").read_text()
    what = readme[readme.index("## What it is") : readme.index("```python")]
    for word in ("cable", "route", "mission", "rare", "rotors"):
        assert word in what, word
    listed = readme[readme.index("Presets:") :]
    for name in presets():
        assert f"`{name}`" in listed, name
    assert "takes about 14 s" not in readme and "about 30 s" in readme


# -- 14. the slung preset says why its PD is unstable, with the engine's numbers ------------------
def test_the_slung_preset_says_why_its_pd_is_unstable() -> None:
    report = quadrs.stability(quadrs.Scenario.preset("slung"), "pd")
    assert not report.stable
    pole = report.excited_unstable_modes()[0].split(" ", 2)[-1]  # "+0.04 ± 2.98j"
    text = (ROOT / "python/quadrs/presets/slung.toml").read_text()
    assert "UNSTABLE" in text and pole.replace("±", "+/-") in text
