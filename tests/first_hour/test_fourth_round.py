"""A delivery engineer's first hour, fourth round (issue 54, and issue 53's units): answers that
explain themselves, one unit per quantity on every input, the saved question kept, specific
force as the parcel's question, flights trimmed in the wind, one interval convention, PX4
files in, a first screen that says what quadrs is. One test (or more) per item, through the
command line where a user meets it; each fails on the code before issue 54."""

from __future__ import annotations

import io
import json
import math
import re
import struct
from pathlib import Path

import numpy as np
import pytest

import quadrs
from quadrs import _core
from quadrs.cli.main import build_parser, main

ROOT = Path(__file__).resolve().parents[2]
#: The short routes fly at dt = 2 ms, coarse for the payload's fastest mode (a StepSizeWarning
#: each batch): fine for what these tests check, which is the answer's form.
pytestmark = pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")

#: A short route (a 20 m dog-leg at 5 m), phases per leg, in about 12 s of flight.
SHORT_ROUTE = {
    "trajectory.route": [[0.0, 0.0, 2.0], [0.0, 0.0, 5.0], [20.0, 0.0, 5.0], [20.0, 10.0, 5.0]],
    "trajectory.hold": [0.5, 0.0, 0.0, 0.5],
    "trajectory.names": ["lift", "climb", "leg", "dog", "drop"],
    "gust.end": 30.0,
    "integrator.duration": 30.0,
    "integrator.dt": 0.002,
}

#: The user's variant: 1.5 kg on 3 m, 12 m/s, an 8 m/s crosswind.
VARIANT = [
    "--set", "payload.mass=1.5", "--set", "payload.cable_length=3", "--set",
    "trajectory.speed=12", "--set", "wind.speed=8",
]  # fmt: skip
#: PX4's own vertical speed limits (the delivery preset raises them to 5 and 4 m/s for its
#: route): the limits these tests check the route against.
PX4_DEFAULT_VERTICAL_LIMITS = {
    "controller.px4.MPC_Z_VEL_MAX_UP": 3.0,
    "controller.px4.MPC_Z_VEL_MAX_DN": 1.5,
}


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def route() -> quadrs.Scenario:
    return quadrs.Scenario.preset("delivery").override(SHORT_ROUTE)


def route_file(tmp_path: Path, scenario: quadrs.Scenario, name: str = "route.toml") -> str:
    path = tmp_path / name
    path.write_text(scenario.to_toml())
    return str(path)


@pytest.fixture
def quiet(monkeypatch: pytest.MonkeyPatch) -> None:
    """No calibration announcement (these are short jobs)."""
    import quadrs.cli.mission as cm

    monkeypatch.setattr(cm, "_announce", lambda *a: None)


# -- 1. "NOT FLOWN" says why, before flying where it can be known ------------------------------
def test_the_users_px4_variant_names_the_vertical_speed_limit_and_the_leg(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    short = quadrs.Scenario.preset("delivery").override(
        {
            "initial.position": [0.0, 0.0, 5.0],
            "trajectory.route": [
                [0.0, 0.0, 5.0],
                [0.0, 0.0, 25.0],
                [60.0, 0.0, 25.0],
                [60.0, 0.0, 5.0],
            ],
            # Four points, no lowering (the variant's 3 m line): a hold at each end.
            "trajectory.hold": [2.0, 0.0, 0.0, 15.0],
            "trajectory.names": ["lift", "climb", "transit", "descent", "drop"],
            "integrator.duration": 70.0,
            "gust.end": 70.0,
        }
        | PX4_DEFAULT_VERTICAL_LIMITS
    )
    code, out, err = cli(capsys, "mission", "--scenario", route_file(tmp_path, short),
                         "--controller", "px4", "--runs", "2", *VARIANT)  # fmt: skip
    assert code == 0
    # Before flying (stderr), and beside the verdict: the leg, the limit, how much more.
    said = [line for line in err.splitlines() if "MPC_Z_VEL_MAX_DN" in line]
    assert said and "leg descent" in said[0] and "1.5 m/s" in said[0], err
    assert "MPC_Z_VEL_MAX_UP" in err and "leg climb" in err
    verdict = " ".join(out.split("\n\n")[0].split())
    assert verdict.startswith("Route")
    if "NOT FLOWN" in verdict:
        assert "MPC_Z_VEL_MAX_DN" in verdict and "leg descent" in verdict


def test_each_leg_is_checked_against_the_laws_limits_by_its_own_numbers() -> None:
    """An independent count: a leg of length L under a sin^2 acceleration pulse of peak a
    peaks at min(v, sqrt(a L / 2)); its vertical share against MPC_Z_VEL_MAX_*; its horizontal
    against MPC_XY_VEL_MAX (equal is no margin: flagged)."""
    from quadrs.design.route_limits import route_clashes

    s = quadrs.Scenario.preset("delivery").override(
        {"trajectory.speed": 12.0} | PX4_DEFAULT_VERTICAL_LIMITS
    )
    clashes = {(c.leg, c.limit): c for c in route_clashes(s, "px4")}
    a = float(s["trajectory.acceleration"])
    climb = min(12.0, math.sqrt(a * 28.0 / 2))  # 2 m -> 30 m
    descent = min(12.0, math.sqrt(a * 25.0 / 2))  # 30 m -> 5 m
    assert clashes[("climb", "MPC_Z_VEL_MAX_UP")].asked == pytest.approx(climb)
    assert clashes[("descent", "MPC_Z_VEL_MAX_DN")].asked == pytest.approx(descent)
    assert clashes[("descent", "MPC_Z_VEL_MAX_DN")].allowed == 1.5
    assert clashes[("transit", "MPC_XY_VEL_MAX")].asked == pytest.approx(12.0)
    assert "no margin" in str(clashes[("transit", "MPC_XY_VEL_MAX")])
    # Raised limits: nothing left to say; the PD law has no velocity limits.
    raised = s.override({"controller.px4.MPC_Z_VEL_MAX_DN": 6.0,
                         "controller.px4.MPC_Z_VEL_MAX_UP": 6.0,
                         "controller.px4.MPC_XY_VEL_MAX": 15.0})  # fmt: skip
    assert route_clashes(raised, "px4") == []
    assert all("VEL" not in c.limit for c in route_clashes(s, "pd"))


def test_a_route_past_the_tilt_limit_is_said_before_flying() -> None:
    from quadrs.design.route_limits import route_clashes

    # The preset's tilt limit is 45 deg (PX4's MPC_TILTMAX_AIR): 12 m/s^2 asks 50.7.
    s = quadrs.Scenario.preset("delivery").override({"trajectory.acceleration": 12.0})
    tilt = [c for c in route_clashes(s, "pd") if c.limit == "controller.tilt_limit"]
    assert tilt and tilt[0].leg == "transit"
    assert tilt[0].asked == pytest.approx(math.degrees(math.atan(12.0 / 9.81)), rel=1e-3)


# -- 2. one unit per quantity on every input ---------------------------------------------------
def test_tune_reads_a_swing_constraint_in_degrees_as_mission_does() -> None:
    args = build_parser().parse_args(
        ["tune", "--out", "t.toml", "--param", "controller.pd.kp[0]=0.5:2", "--constraint",
         "max_swing@transit<=30",
         "--constraint", "P(max_swing>10)<=0.05", "--constraint", "max_specific_force<=1.5g"]
    )  # fmt: skip
    mean, chance, force = args.constraint
    assert mean.bound == pytest.approx(math.radians(30.0))
    assert chance.level == pytest.approx(math.radians(10.0)) and chance.bound == 0.05
    assert force.bound == pytest.approx(1.5 * 9.80665)
    assert str(mean) == "max_swing@transit<=30deg"  # printed back in the unit it was typed in
    mission = build_parser().parse_args(["mission", "--limit", "max_swing=30"])
    assert mission.limit == ("max_swing", pytest.approx(mean.bound))


def test_rare_reads_a_swing_threshold_in_degrees(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import quadrs.rare

    seen: list[float] = []

    class Seen(Exception):
        pass

    def fake(*args: object, **kwargs: object) -> None:
        seen.append(float(kwargs["threshold"]))  # type: ignore[arg-type]
        raise Seen

    monkeypatch.setattr(quadrs.rare, "rare_event", fake)
    with pytest.raises(Seen):
        main(["rare", "--preset", "delivery", "--metric", "max_swing", "--phase", "transit",
              "--threshold", "30", "--no-progress"])  # fmt: skip
    assert seen == [pytest.approx(math.radians(30.0))]


@pytest.mark.parametrize("command", ["tune", "rare", "mission"])
def test_each_input_says_its_unit_in_its_help(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = cli(capsys, command, "--help")
    text = " ".join(out.split())
    assert code == 0 and "degrees for swing" in text


def test_a_unit_that_does_not_fit_the_metric_is_refused(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, _, err = cli(capsys, "mission", "--limit", "max_tension=2g")
    assert code == 2 and "not an acceleration" in err


# -- issue 53's units: the mission's tables and figure under a swing limit ---------------------
@pytest.fixture(scope="module")
def route_mc(route: quadrs.Scenario) -> quadrs.MonteCarloResult:
    return quadrs.monte_carlo(route, runs=12, seed=0, controllers=("pd", "smc"), progress=False,
                              spectra=False)  # fmt: skip


@pytest.fixture(scope="module")
def saved_mc(route_mc: quadrs.MonteCarloResult, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("mc") / "route.parquet"
    route_mc.to_parquet(path)
    return path


def test_a_swing_limit_shows_q95_and_worst_in_degrees(
    saved_mc: Path, route_mc: quadrs.MonteCarloResult, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = cli(capsys, "report", str(saved_mc), "--limit", "max_swing=8")
    assert code == 0
    runs = route_mc.runs[(route_mc.runs["controller"] == "pd") & (route_mc.runs["phase"] == "leg")]
    worst_deg = math.degrees(float(runs["max_swing"].max()))
    block = out[out.index("Parcel max_swing (deg)") :]
    row = next(line for line in block.splitlines() if line.startswith("leg "))
    assert f"{worst_deg:.3g}" in row.split()  # degrees, not radians
    assert f"{math.radians(worst_deg):.3g}" not in row.split()


def test_the_mission_figure_is_labelled_by_its_metric(route_mc: quadrs.MonteCarloResult) -> None:
    from quadrs.design.mission import mission_report
    from quadrs.plots.mission import mission_risk

    fig = mission_risk(mission_report(route_mc, math.radians(8), metric="max_swing"))
    top, bottom = fig.axes
    assert "max_swing" in top.get_ylabel() and "8 deg" in top.get_ylabel()
    assert "m/s²" not in top.get_ylabel() + bottom.get_ylabel()
    assert "deg" in bottom.get_ylabel()
    limit_line = next(ln for ln in bottom.get_lines() if ln.get_label() == "limit")
    assert limit_line.get_ydata()[0] == pytest.approx(8.0)


def test_the_mission_figures_labels_stay_apart_and_inside(
    route_mc: quadrs.MonteCarloResult,
) -> None:
    """The longest labels (the specific force's, a limit in m/s²) fit their panels: each axis
    label inside the figure and clear of the other panel's."""
    from quadrs.design.mission import mission_report
    from quadrs.plots.mission import mission_risk

    fig = mission_risk(mission_report(route_mc, 19.6133, metric="max_specific_force"))
    renderer = fig.canvas.get_renderer()
    fig.draw(renderer)
    top, bottom = (a.yaxis.label.get_window_extent(renderer) for a in fig.axes)
    whole = fig.bbox
    for box in (top, bottom):
        assert whole.x0 <= box.x0 and box.x1 <= whole.x1
        assert whole.y0 <= box.y0 and box.y1 <= whole.y1
    assert top.y0 > bottom.y1  # the top panel's label above the bottom one's


def test_the_paired_difference_table_gives_a_swing_threshold_in_degrees(
    saved_mc: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The mc's paired SMC - PD table (a routed batch prints the mission's tables as well).
    from quadrs.cli import main as cli_main

    args = build_parser().parse_args(["report", str(saved_mc), "--limit", "max_swing=8"])
    cli_main._print_limits(quadrs.MonteCarloResult.read_parquet(saved_mc), args)
    out = capsys.readouterr().out
    paired = out[out.index("SMC - PD") :]
    assert re.search(r"max_swing\s.*\b8\s+deg\b", paired), paired
    assert "0.14" not in paired


# -- 3. report remembers the saved question ----------------------------------------------------
def test_report_asks_the_question_the_mission_was_saved_with(
    tmp_path: Path, route: quadrs.Scenario, capsys: pytest.CaptureFixture[str], quiet: None
) -> None:
    out_file = tmp_path / "m.parquet"
    code, first, _ = cli(capsys, "mission", "--scenario", route_file(tmp_path, route), "--runs",
                         "3", "--limit", "max_specific_force=1.5g", "--track-limit", "4",
                         "--out", str(out_file))  # fmt: skip
    assert code == 0
    code, again, _ = cli(capsys, "report", str(out_file))
    assert code == 0
    assert "P(max_specific_force > 14.71" in again and "max_accel >" not in again
    assert "past 4 m" in again  # the tracking limit too
    # The tables themselves are the mission's own.
    assert first[first.index("Parcel") :] in again
    # An explicit --limit still wins.
    _, other, _ = cli(capsys, "report", str(out_file), "--limit", "max_accel=3")
    assert "P(max_accel > 3" in other


def test_the_saved_question_survives_read_parquet(
    tmp_path: Path, route_mc: quadrs.MonteCarloResult
) -> None:
    import copy

    mc = copy.copy(route_mc)
    mc.question = {"metric": "max_swing", "limit": 0.2, "track_limit": 5.0,
                   "cross_track_limit": None, "quantile": 0.9}  # fmt: skip
    mc.to_parquet(tmp_path / "q.parquet")
    assert quadrs.MonteCarloResult.read_parquet(tmp_path / "q.parquet").question == mc.question


# -- 4. fragility is specific force ------------------------------------------------------------
def test_the_parcels_default_question_is_specific_force(
    tmp_path: Path, route: quadrs.Scenario, capsys: pytest.CaptureFixture[str], quiet: None
) -> None:
    code, out, _ = cli(capsys, "mission", "--scenario", route_file(tmp_path, route), "--runs", "2")
    assert code == 0
    assert "P(max_specific_force > 19.6133 m/s^2 (2 g))" in out
    _, help_text, _ = cli(capsys, "mission", "--help")
    help_text = " ".join(help_text.split())
    assert "default: max_specific_force=2g" in help_text and "1 g at rest" in help_text


def test_the_change_is_said_where_it_changed() -> None:
    delivery = " ".join((ROOT / "docs" / "delivery.md").read_text().split())
    said = delivery.index("Its default is `max_specific_force=2g`")
    assert said < delivery.index("## 2")  # in the first section, where --limit is explained
    changes = (ROOT / "CHANGELOG.md").read_text()
    assert "max_specific_force" in changes and "default" in changes


# -- 5. flights start trimmed in the wind ------------------------------------------------------
@pytest.fixture(scope="module")
def windy() -> quadrs.Scenario:
    return quadrs.Scenario.preset("delivery").override(
        {"wind.speed": 8.0, "wind.shear": "none", "gust.enabled": False}
    )


def steady_swing(s: quadrs.Scenario, wind: float) -> float:
    """The parcel's balance in a steady wind, drag on weight: atan(1/2 rho CdA w^2 / (m g))."""
    drag = 0.5 * s["gust.air_density"] * s["payload.drag_area"] * wind**2
    return math.atan(drag / (s["payload.mass"] * s["environment.gravity"]))


def test_the_first_legs_swing_starts_at_its_steady_value(windy: quadrs.Scenario) -> None:
    """The start is the plant's balance in the wind (docs/model.md, "The start"): the parcel
    hangs at its steady angle and stays there until the law, which has no wind feed-forward,
    levels the vehicle (a tenth of a second); from rest it starts straight below and swings
    out at once. What follows over the lift hold is the law's doing, not the start's."""
    for law in ("pd", "px4"):
        flight = quadrs.simulate(windy, law, record_every=1)
        swing = flight.trace["swing"].to_numpy()
        assert swing[0] == pytest.approx(steady_swing(windy, 8.0), rel=1e-6), law
        # Trimmed, the first 0.1 s stay within 0.3 degrees of it, the vehicle at rest; from
        # rest the parcel is a whole steady angle away and moving.
        early = flight.trace[flight.trace.index < 0.1]
        rest = quadrs.simulate(windy.override({"initial.trim": "rest"}), law, record_every=1)
        early_rest = rest.trace[rest.trace.index < 0.1]["swing"].to_numpy()
        assert rest.trace["swing"].to_numpy()[0] == 0.0
        off = np.max(np.abs(early["swing"].to_numpy() - swing[0]))
        assert off < math.radians(0.3) < np.min(np.abs(early_rest - swing[0])), law
        # In balance, one step in the vehicle and the parcel have barely moved (under 0.1 m/s^2
        # over the preset's 2 ms step: px4's first update of its 50 Hz loop); from rest the
        # wind's drag has already sped them up (about 3 m/s^2 on the vehicle).
        for start, most, least in ((flight, 0.0, 2e-4), (rest, 1e-3, math.inf)):
            step = start.trace.iloc[1]
            moved = max(math.hypot(step.vx, step.vy, step.vz),
                        math.hypot(step.vxc, step.vyc, step.vzc))  # fmt: skip
            assert most <= moved < least, (law, moved)


def test_the_trim_key_is_refused_by_name_and_documented(capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = cli(capsys, "run", "--preset", "delivery", "--set", 'initial.trim="level"')
    assert code == 2 and "initial.trim" in err
    model = (ROOT / "docs" / "model.md").read_text()
    assert "initial.trim" in model and '"rest"' in model


# -- 6. one interval convention ----------------------------------------------------------------
def test_none_seen_is_the_upper_end_of_the_same_two_sided_interval(
    route_mc: quadrs.MonteCarloResult,
) -> None:
    from quadrs.design.mission import mission_report
    from quadrs.stats.risk import exceedance_interval

    r = mission_report(route_mc, 1e3)
    _, _, hi = exceedance_interval(0, 12)
    text = r.to_text()
    assert f"0 of 12 flights, P <= {100 * hi:.3g}" in text
    assert float(r.acceleration.loc["flight", "ci_high"]) == pytest.approx(hi)
    assert hi == pytest.approx(1 - 0.025 ** (1 / 12), rel=1e-9)
    assert "one-sided" not in text
    risk = (ROOT / "docs" / "risk.md").read_text()
    assert "two-sided" in risk and "one interval convention" in risk.lower()


# -- 7. PX4 files in ---------------------------------------------------------------------------
#: A few of the airframe's parameters, [controller.px4]'s and others.
AIRFRAME = {
    "MPC_XY_VEL_MAX": 8.0,
    "MPC_Z_VEL_MAX_DN": 2.5,
    "MPC_TILTMAX_AIR": 35.0,
    "MC_ROLLRATE_P": 0.95,
    "MPC_XY_P": 0.95,
    "SYS_AUTOSTART": 4001,
    "BAT1_N_CELLS": 4,
}


def params_file(path: Path) -> Path:
    """A QGroundControl .params file as it writes one (float32 values printed to 18 places)."""
    rows = ["# Onboard parameters for Vehicle 1", "#", "# Vehicle-Id Component-Id Name Value Type"]
    for name, v in AIRFRAME.items():
        if isinstance(v, int):
            rows.append(f"1\t1\t{name}\t{v}\t6")
        else:
            rows.append(f"1\t1\t{name}\t{float(np.float32(v)):.18f}\t9")
    path.write_text("\n".join(rows) + "\n")
    return path


def ulog_file(path: Path, wind: list[tuple[int, float, float]] | None = None) -> Path:
    """A .ulg made with pyulog's own writer (its parameters), and a ``wind`` topic appended
    as ULog messages (format, subscription, data), which pyulog reads back."""
    from pyulog import ULog  # type: ignore[import-untyped]

    log = ULog(None)
    log._initial_parameters = dict(AIRFRAME)
    buf = io.BytesIO()
    log.write_ulog(buf)
    data = bytearray(buf.getvalue())

    def msg(kind: str, payload: bytes) -> bytes:
        return struct.pack("<HB", len(payload), ord(kind)) + payload

    if wind:
        data += msg("F", b"wind:uint64_t timestamp;float windspeed_north;float windspeed_east;")
        data += msg("A", struct.pack("<BH", 0, 0) + b"wind")
        for t, north, east in wind:
            data += msg("D", struct.pack("<HQff", 0, t, north, east))
    path.write_bytes(bytes(data))
    return path


def test_a_params_file_and_a_ulg_give_the_same_px4_table(tmp_path: Path) -> None:
    base = quadrs.Scenario.preset("delivery")
    a = base.with_px4_params(params_file(tmp_path / "airframe.params"))
    b = base.with_px4_params(ulog_file(tmp_path / "flight.ulg"))
    assert a["controller.px4"] == b["controller.px4"]
    assert a["controller.px4.MPC_XY_VEL_MAX"] == 8.0
    assert a["controller.px4.MC_ROLLRATE_P"] == 0.95  # the float32's shortest decimal
    assert "SYS_AUTOSTART" not in a["controller.px4"]
    defaults = json.loads(_core.CONTROLLER_DEFAULTS["px4"])
    assert a["controller.px4.MPC_Z_P"] == defaults["MPC_Z_P"]  # not in the file: PX4's default


def test_mission_takes_px4_params_and_lists_what_it_ignored(
    tmp_path: Path, route: quadrs.Scenario, capsys: pytest.CaptureFixture[str], quiet: None
) -> None:
    path = params_file(tmp_path / "airframe.params")
    code, _, err = cli(capsys, "mission", "--scenario", route_file(tmp_path, route),
                       "--controller", "px4", "--runs", "1", "--px4-params", str(path))  # fmt: skip
    assert code == 0
    assert "5 parameters read into [controller.px4]" in err
    assert "2 others ignored (BAT1_N_CELLS, SYS_AUTOSTART)" in err


def test_a_file_that_is_not_px4s_is_refused_naming_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.ulg"
    bad.write_bytes(b"not a log at all")
    code, _, err = cli(capsys, "mission", "--runs", "1", "--px4-params", str(bad))
    assert code == 2 and "bad.ulg" in err and "not a PX4 .ulg log" in err
    text = tmp_path / "bad.params"
    text.write_text("1\t1\tMPC_XY_VEL_MAX\tfast\t9\n")
    code, _, err = cli(capsys, "mission", "--runs", "1", "--px4-params", str(text))
    assert code == 2 and "line 1" in err and "MPC_XY_VEL_MAX" in err


def test_a_ulg_wind_estimate_is_a_wind_table_by_time(tmp_path: Path) -> None:
    ulog_file(tmp_path / "w.ulg", [(5_000_000, 1.0, 2.0), (6_000_000, 3.0, -1.0)])
    scenario_path = tmp_path / "s.toml"
    scenario_path.write_text('base = "delivery"\n[wind.table]\nfile = "w.ulg"\nby = "time"\n')
    # a log of 1 s under a 211 s flight: said (issue 72), its last row holding after it
    with pytest.warns(quadrs.PlausibilityWarning, match=r"wind.table covers t = 0 to 1 s of a "
                      r"211 s flight"):  # fmt: skip
        s = quadrs.Scenario.from_toml(scenario_path)
    # x east, y north (a .plan route's axes), t from the topic's first sample.
    assert s["wind.table.points"] == [[0.0, 2.0, 1.0, 0.0], [1.0, -1.0, 3.0, 0.0]]


# -- 8. the first screen -----------------------------------------------------------------------
def test_the_readmes_first_screen_says_what_quadrs_is() -> None:
    text = (ROOT / "README.md").read_text()
    first = "\n".join(text.splitlines()[:40])
    blocks = re.findall(r"```(?:sh|bash|console)?\n(.*?)```", text, re.S)
    assert blocks and first.find(blocks[0].strip().splitlines()[0]) >= 0
    for word in ("cable", "route", "mission", "risk"):
        assert word in first.lower(), word
    paragraphs = [p for p in text.split("\n\n") if p.strip()]
    what = next(i for i, p in enumerate(paragraphs) if "cable" in p.lower())
    script = next(i for i, p in enumerate(paragraphs) if "test.sh" in p and "```" not in p)
    assert what < script


def test_the_docs_home_describes_the_current_package() -> None:
    index = (ROOT / "docs" / "index.md").read_text()
    assert "delivery.md" in index and "rare-events.md" in index
    assert "cable" in index and "px4" in index.lower()


def test_the_model_page_credits_the_transit_swing_truthfully() -> None:
    model = (ROOT / "docs" / "model.md").read_text()
    assert "2.6 N on 4.9 N" not in model or "28 degrees" in model


# -- 10. small ones ----------------------------------------------------------------------------
def test_mission_help_names_one_default_preset(capsys: pytest.CaptureFixture[str]) -> None:
    _, out, _ = cli(capsys, "mission", "--help")
    text = " ".join(out.split())
    assert "default: paper" not in text and "(default: delivery)" in text


def test_the_top_help_says_units_defaults_and_exit_status_1(
    capsys: pytest.CaptureFixture[str],
) -> None:
    _, out, _ = cli(capsys, "--help")
    text = " ".join(out.split())
    assert "degrees for headings" in text and "swing" in text and "PX4" in text
    assert "1 an output could not be written" in text and "stability" in text and "tune" in text
    assert "run and tune fly smc" in text and "mission and rare pd" in text


def test_monte_carlo_draws_no_bar_into_a_pipe(
    route: quadrs.Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``progress`` left at its default (True) and stderr not a terminal (pytest's capture, as
    a pipe): the bar is made disabled, so nothing is drawn however long the batch."""
    import quadrs.present.terminal as terminal

    made: list[object] = []
    real = terminal.tqdm_class()

    class Recording(real):  # type: ignore[misc, valid-type]
        def __init__(self, *args: object, **kwargs: object) -> None:
            made.append(kwargs.get("disable"))
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(terminal, "tqdm_class", lambda: Recording)
    quadrs.monte_carlo(route, runs=2, controllers=("pd",), spectra=False)
    assert made == [True]


def test_dir_shows_the_public_names_only() -> None:
    names = dir(quadrs)
    for helper in ("Any", "TYPE_CHECKING", "annotations", "importlib"):
        assert helper not in names
    assert "Scenario" in names and "monte_carlo" in names and "runs" in names


def test_in_with_a_non_string_is_false() -> None:
    s = quadrs.Scenario.preset("delivery")
    assert 0 not in s and None not in s and "gust.w20" in s and "no.such" not in s


def test_scenario_keys_lists_the_keys_of_optional_tables(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, _ = cli(capsys, "scenario", "keys", "--preset", "delivery")
    assert code == 0
    for key in ("wind.table.file", "wind.table.by", "actuator.faults"):
        assert re.search(rf"^# {re.escape(key)}\b", out, re.M), key


def test_a_heavy_parcel_is_not_called_grams() -> None:
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        quadrs.Scenario.preset("delivery").override({"payload.mass": 2.5})
