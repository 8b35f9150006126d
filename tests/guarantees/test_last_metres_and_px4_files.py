"""The sixth round's guarantees on the last metres and PX4's files (docs/guarantees.md): a
``.plan``'s winch and gripper items flown where the plan puts them, or refused naming the
item; PX4 parameters and logs read as PX4 holds them, or refused or warned by name."""

from __future__ import annotations

import itertools
import re
from pathlib import Path
from typing import Any

import pytest

import quadrs
from quadrs.scenario.route_files import RouteFileError, read_plan
from tests.engine.test_last_metres import HOME, _item, _plan, lowering

LAT, LON = HOME[0], HOME[1]
TAKEOFF = _item(22, 0, 0, 0, None, None, None, 6.0)
OVER = _item(16, 2.0, 0, 0, None, LAT, LON, 6.0)
AWAY = _item(16, 0, 0, 0, None, LAT, LON, 7.0)
LAND = _item(21, 0, 0, 0, None, None, None, 0.0)


def _winch(length: float, rate: float | None = None) -> dict[str, Any]:
    return _item(42600, 1, 1, length, rate)


RELEASE = _item(211, 1, 0)


def _flown(tmp_path: Path, items: list[dict[str, Any]]) -> quadrs.Scenario:
    return read_plan(_plan(tmp_path, items), start_height=6.0).apply(lowering(5.0))


# -- a .plan's winch and gripper ----------------------------------------------------------------
def test_a_plan_that_never_opens_the_gripper_keeps_the_parcel(tmp_path: Path) -> None:
    """The base scenario releases at touchdown; the plan lowers and never opens: the hook
    stays shut. With the release item it opens at touchdown."""
    assert lowering(5.0)["payload.release"] == "touchdown"
    kept = _flown(tmp_path, [TAKEOFF, OVER, _winch(5.0), AWAY])
    assert "release" not in kept.to_dict()["payload"]
    opened = _flown(tmp_path, [TAKEOFF, OVER, _winch(5.0), RELEASE, AWAY])
    assert opened["payload.release"] == "touchdown"


@pytest.mark.parametrize(
    ("items", "where", "when"),
    [
        ([_winch(5.0), TAKEOFF, OVER, AWAY], "mission.items[0]: DO_WINCH", "before take-off"),
        ([RELEASE, TAKEOFF, OVER, AWAY], "mission.items[0]: DO_GRIPPER", "before take-off"),
        ([TAKEOFF, OVER, AWAY, LAND, _winch(2.0)], "mission.items[4]: DO_WINCH", "after landing"),
    ],
)  # fmt: skip
def test_payload_items_on_the_pad_are_refused(tmp_path: Path, items: list[Any], where: str,
                                              when: str) -> None:  # fmt: skip
    with pytest.raises(RouteFileError, match=re.escape(where) + ".*" + when):
        read_plan(_plan(tmp_path, items), start_height=6.0)


def test_one_winch_rate_given_twice_is_the_winchs_speed(tmp_path: Path) -> None:
    """Different rates are each lowering's own (tests/guarantees/test_plan_as_px4_runs_it.py);
    one rate given twice is the winch's speed, no speed per lowering."""
    second = _item(16, 2.0, 0, 0, None, LAT + 1e-4, LON, 6.0)
    same = _flown(tmp_path, [TAKEOFF, OVER, _winch(2.0, 0.5), second, _winch(2.0, 0.5), AWAY])
    assert same["payload.winch_speed"] == 0.5
    assert "lower_speed" not in same.to_dict()["trajectory"]


def test_a_winch_value_the_engine_refuses_names_the_plans_item(tmp_path: Path) -> None:
    """7 m of line on a drum that pays out at most 7 m (8 - 1) in two items: the engine's
    refusal of ``trajectory.lower[1]`` names the DO_WINCH items that asked for it."""
    with pytest.raises(
        RouteFileError,
        match=r"mission\.items\[2\] DO_WINCH params\[2\] "
        r"\(length, m\), mission\.items\[3\] DO_WINCH",
    ):
        _flown(tmp_path, [TAKEOFF, OVER, _winch(4.0), _winch(4.0), AWAY])
    with pytest.raises(
        RouteFileError,
        match=r"mission\.items\[2\] DO_WINCH params\[3\] "
        r"\(rate, m/s\).*payload\.winch_speed",
    ):
        _flown(tmp_path, [TAKEOFF, OVER, _winch(4.0, 1e9), AWAY])


# -- PX4 parameter files and logs ---------------------------------------------------------------
def _params(path: Path, rows: list[tuple[str, str]]) -> Path:
    text = "# Vehicle-Id Component-Id Name Value Type\n"
    path.write_text(text + "".join(f"1\t1\t{name}\t{value}\t9\n" for name, value in rows))
    return path


def _mission_scenario(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[Any, str]:
    """The scenario `quadrs mission ARGV` would fly (its parser and load_scenario), and
    what it said on stderr."""
    from quadrs.cli.main import build_parser
    from quadrs.cli.scenario_args import load_scenario

    args = build_parser("mission").parse_args(["mission", *argv])
    scenario = load_scenario(args)
    return scenario, capsys.readouterr().err


def test_px4_params_need_the_px4_law(tmp_path: Path, capsys) -> None:
    from tests.guarantees.test_design_loop_and_files import one_line, run_cli

    path = _params(tmp_path / "a.params", [("MPC_XY_P", "0.5")])
    code, _, err = run_cli("mission", "--runs", "1", "--controller", "pd", "--px4-params",
                           str(path), capsys=capsys)  # fmt: skip
    assert code == 2
    assert "only the px4 law reads" in one_line(err) and "--controller pd" in err


def test_an_explicit_set_beats_the_px4_file(tmp_path: Path, capsys) -> None:
    path = _params(tmp_path / "a.params", [("MC_ROLL_P", "7.0"), ("MPC_XY_P", "0.5")])
    scenario, err = _mission_scenario(capsys, "--controller", "px4", "--px4-params", str(path),
                                      "--set", "controller.px4.MC_ROLL_P=3.0")  # fmt: skip
    assert scenario["controller.px4.MC_ROLL_P"] == 3.0
    assert scenario["controller.px4.MPC_XY_P"] == 0.5
    assert "2 parameters read" in err


def _refused(path: Path, message: str) -> None:
    """Reading ``path`` is refused with ``message`` (a regular expression), and nothing else
    is said (no warning: numpy's overflow one was)."""
    import warnings

    from quadrs.scenario.px4_files import read_px4_parameters

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=message):
            read_px4_parameters(path)


def test_a_px4_parameter_named_twice_is_refused_naming_it(tmp_path: Path) -> None:
    path = _params(tmp_path / "a.params", [("MPC_XY_P", "0.5"), ("MC_ROLL_P", "6"),
                                           ("MPC_XY_P", "0.9")])  # fmt: skip
    _refused(path, r"line 4: 'MPC_XY_P' is given twice \(line 2: 0\.5; line 4: 0\.9\)")


def test_rate_k_multiplies_the_rate_gains_as_px4_does(tmp_path: Path) -> None:
    import json

    from quadrs import _core

    defaults = json.loads(_core.CONTROLLER_DEFAULTS["px4"])
    path = _params(tmp_path / "a.params", [("MC_ROLLRATE_K", "0.5"), ("MC_ROLLRATE_P", "0.2"),
                                           ("MC_YAWRATE_K", "2")])  # fmt: skip
    s = quadrs.Scenario.preset("delivery").with_px4_params(path)
    assert s["controller.px4.MC_ROLLRATE_P"] == pytest.approx(0.1)
    assert s["controller.px4.MC_ROLLRATE_I"] == pytest.approx(0.5 * defaults["MC_ROLLRATE_I"])
    assert s["controller.px4.MC_ROLLRATE_D"] == pytest.approx(0.5 * defaults["MC_ROLLRATE_D"])
    assert s["controller.px4.MC_YAWRATE_P"] == pytest.approx(2 * defaults["MC_YAWRATE_P"])
    assert s["controller.px4.MC_PITCHRATE_P"] == defaults["MC_PITCHRATE_P"]  # no K: as it was


def _px4_hover(sc: quadrs.Scenario) -> Any:
    """``sc``'s vehicle on the state, px4, 0.1 m below its reference, 6 s in still air."""
    from tests.engine import ON_THE_STATE

    still = sc.override({
        **ON_THE_STATE,
        "trajectory.interpolation": "step",
        "trajectory.waypoints": [[0.0, 0.0, 0.0, 2.1, 0.0], [6.0, 0.0, 0.0, 2.1, 0.0]],
        "trajectory.route": None, "trajectory.lower": None, "trajectory.hold": None,
        "trajectory.speed": None, "trajectory.acceleration": None,
        "trajectory.names": None, "phases": [{"name": "all", "start": 0.0, "end": 6.0}],
        "integrator.duration": 6.0, "gust.enabled": False, "wind.speed": 0.0,
        # From rest at 2 m (a trimmed start is the law's equilibrium: at its reference).
        "initial.trim": "rest",
    })  # fmt: skip
    return quadrs.simulate(still, "px4", record_every=1)


def test_the_files_hover_thrust_is_the_hover_feed_forward(tmp_path: Path) -> None:
    """``MPC_THR_HOVER`` is read into ``[controller.px4]`` (before: skipped with a warning,
    the law scaling its thrust by it: 53 N on the delivery's 48 N rotors) and flown as PX4
    flies it, the position loop's hover feed-forward, the thrust's scale the rotors' 4 x 12 N:
    a height error's thrust is MPC_THR_HOVER (a + g) / g x 48 N, so it scales with the
    parameter (before, with the scale weight / MPC_THR_HOVER, it did not); the vertical
    integrator, at its hover value from the start, takes up the rest of the weight."""
    import warnings

    base = quadrs.Scenario.preset("delivery")
    path = _params(tmp_path / "a.params", [("MPC_THR_HOVER", "0.42"), ("MPC_XY_P", "0.5")])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = base.with_px4_params(path)
    assert s["controller.px4.MPC_THR_HOVER"] == 0.42
    assert s["controller.px4.MPC_XY_P"] == 0.5
    g = base["environment.gravity"]
    weight = (base["vehicle.mass"] + base["payload.mass"]) * g
    full = 4 * base["actuator.thrust_max"]
    own, set_ = _px4_hover(base).trace, _px4_hover(s).trace
    # 0.1 m low: a = MPC_Z_VEL_P_ACC x MPC_Z_P x 0.1 = 0.4 m/s^2 asked of each.
    for trace, hover in [(own, weight / full), (set_, 0.42)]:
        assert trace["U1"].iloc[0] == pytest.approx(weight + hover * 0.4 / g * full, abs=1e-9)
        late = trace[trace.index > 5.0]
        assert late["U1"].mean() == pytest.approx(weight, rel=1e-3)
        assert (late["z"] - 2.1).abs().max() < 0.02


def test_px4_names_and_values_are_shown_safely(tmp_path: Path) -> None:
    from quadrs.scenario.px4_files import read_px4_parameters

    path = _params(tmp_path / "a.params", [("EVIL\x1b[2J", "1"), ("MPC_XY_P", "0.5")])
    note = read_px4_parameters(path).note()
    assert "\x1b" not in note and "EVIL\\x1b[2J" in note
    huge = _params(tmp_path / "b.params", [("MPC_XY_P", "1e39")])
    _refused(huge, r"line 2: MPC_XY_P = 1e\+39 is beyond a PX4 parameter's range")


def _two_wind_instances(path: Path) -> Path:
    import struct

    from tests.first_hour.test_fourth_round import ulog_file

    ulog_file(path, [(5_000_000, 1.0, 2.0), (6_000_000, 3.0, -1.0)])
    data = bytearray(path.read_bytes())

    def msg(kind: str, payload: bytes) -> bytes:
        return struct.pack("<HB", len(payload), ord(kind)) + payload

    data += msg("A", struct.pack("<BH", 1, 1) + b"wind")  # a second estimator's instance
    for t, north, east in [(5_000_000, 9.0, 9.0), (6_000_000, 9.0, 9.0)]:
        data += msg("D", struct.pack("<HQff", 1, t, north, east))
    path.write_bytes(bytes(data))
    return path


def test_a_log_with_two_wind_instances_says_which_is_read(tmp_path: Path) -> None:
    from quadrs.scenario.px4_files import Px4FileWarning, read_ulog_wind

    path = _two_wind_instances(tmp_path / "w.ulg")
    with pytest.warns(
        Px4FileWarning,
        match=r"2 instances of topic 'wind' \(multi_id 0, 1\): "
        r"the first, multi_id 0, is read",
    ):
        rows = read_ulog_wind(path)
    assert rows == [[0.0, 2.0, 1.0, 0.0], [1.0, -1.0, 3.0, 0.0]]


def test_a_logs_wind_is_thinned_and_px4_files_are_capped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import quadrs.scenario.px4_files as px4
    from tests.first_hour.test_fourth_round import ulog_file

    # 100 Hz for 30 s: rows 0.1 s apart at most, and at most WIND_ROWS of them.
    samples = [(1_000_000 + 10_000 * i, 1.0, float(i)) for i in range(3000)]
    path = ulog_file(tmp_path / "w.ulg", samples)
    rows = px4.read_ulog_wind(path)
    assert len(rows) == 300
    assert all(b[0] - a[0] >= 0.1 - 1e-9 for a, b in itertools.pairwise(rows))
    monkeypatch.setattr(px4, "WIND_ROWS", 50)
    assert len(px4.read_ulog_wind(path)) <= 51
    monkeypatch.setattr(px4, "MAX_LOG_BYTES", 100)
    with pytest.raises(ValueError, match=r"w\.ulg.*larger than"):
        px4.read_ulog_wind(path)
    big = _params(tmp_path / "big.params", [(f"P{i}", "1") for i in range(100_000)])
    with pytest.raises(ValueError, match=r"big\.params.*larger than 1 MiB"):
        px4.read_px4_parameters(big)


# -- a dispersed winch's schedule ---------------------------------------------------------------
def test_a_dispersed_winch_flies_its_own_schedule_in_a_batch() -> None:
    """Each realisation's winch times its own lowering and every segment after it: batch row
    ``i`` is ``simulate(realisation=i)`` bit for bit (before, the batch flew the nominal
    schedule with each realisation's winch, and its rows differed). A draw whose schedule
    does not fit the flight is refused naming the realisation."""
    import numpy as np

    from quadrs.runs.flight import METRIC_COLUMNS

    base = lowering(6.0, **{"integrator.dt": 0.001})
    dispersed = base.override({"dispersions": {
        "payload.winch_speed": {"dist": "uniform", "low": 0.5, "high": 1.0},
    }})  # fmt: skip
    runs = 6
    mc = quadrs.monte_carlo(dispersed, runs=runs, seed=3, controllers=["pd"], progress=False,
                            spectra=False)  # fmt: skip
    metrics = list(METRIC_COLUMNS)
    for i in (0, 2, 5):
        alone = quadrs.simulate(dispersed, "pd", seed=3, realisation=i)
        row = mc.runs[mc.runs["realisation"] == i][metrics].to_numpy()
        np.testing.assert_array_equal(alone.metrics[metrics].to_numpy(), row, err_msg=f"row {i}")
    # The realisations' lowerings did differ: the touchdowns fall at their own times.
    lowered = mc.runs[mc.runs["phase"] == "lower1"]["touchdown_speed"]
    assert lowered.nunique() == runs, lowered
    too_slow = base.override({"dispersions": {
        "payload.winch_speed": {"dist": "uniform", "low": 0.1, "high": 0.2},
    }})  # fmt: skip
    with pytest.raises(quadrs.ScenarioError, match=r"realisation \d+ drew .*integrator\.duration"):
        quadrs.monte_carlo(too_slow, runs=2, seed=3, controllers=["pd"], progress=False)
