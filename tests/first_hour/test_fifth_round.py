"""A delivery engineer's first hour, fifth round (issue 72): a mission answer that parts the
touchdown from the flight, a preset whose duration follows its route, ``--set`` that can fix a
scenario file, a route override that keeps what depends on it, docs that agree with the
program, keys that say where they apply, impossible geometry refused, and the small things.
One test (or more) per item, through the command line where a user meets it; each fails on the
code before issue 72. (Every command the docs show runs: tests/test_docs_commands.py.)"""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import quadrs
from quadrs.cli.main import main
from quadrs.design.mission import mission_report
from quadrs.scenario.route_timing import covering, route_time

ROOT = Path(__file__).resolve().parents[2]

#: The delivery vehicle hovering at 5 m over its drop point, lowering 6 m of line (the parcel
#: touches down after about 4 m), holding 6 s (the hook opens), then climbing 1 m.
DROP_HERE = {
    "initial.position": [0.0, 0.0, 5.0],
    "trajectory.route": [[0.0, 0.0, 5.0], [0.0, 0.0, 6.0]],
    "trajectory.hold": [6.0, 0.0],
    "trajectory.lower": [6.0, 0.0],
}


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def delivery() -> quadrs.Scenario:
    return quadrs.Scenario.preset("delivery")


@pytest.fixture(scope="module")
def drop_mc(delivery: quadrs.Scenario) -> quadrs.MonteCarloResult:
    return quadrs.monte_carlo(delivery.override(DROP_HERE), runs=4, seed=0, controllers=("pd",),
                              progress=False, spectra=False)  # fmt: skip


# -- 1. the touchdown apart from the flight ---------------------------------------------------
def test_the_parcels_answer_parts_the_touchdown_from_the_flight(
    drop_mc: quadrs.MonteCarloResult,
) -> None:
    """The ground contact's jump (tens of g) is the phase of the touchdown's; in flight the
    parcel stays near 1 g: the answer gives both, and says the first is the contact law's."""
    r = mission_report(drop_mc, 2 * 9.80665, metric="max_specific_force")
    t = r.acceleration
    assert {"in flight", "touchdown"} <= set(t.index)
    assert int(t.loc["touchdown", "n"]) == 4  # every parcel touched down
    assert t.loc["touchdown", "worst"] > 5 * 9.80665  # the contact's peak
    assert t.loc["in flight", "worst"] < 2 * 9.80665  # the flight's
    assert int(t.loc["in flight", "exceedances"]) == 0
    # the whole flight's row is the touchdown's: the worst of both
    assert t.loc["flight", "worst"] == t.loc["touchdown", "worst"]
    line = r.parcel_line()
    assert "in flight 0 of 4 flights" in line and "at touchdown 4 of 4 flights" in line
    assert "contact law" in line and "ground.stiffness" in line
    text = r.to_text(width=80)
    assert line.split(":")[0] in text and max(len(s) for s in text.splitlines()) <= 100


def test_a_parcel_on_the_ground_twice_counts_both_contacts_as_touchdowns() -> None:
    """A parcel that bumps the pad at the lift (its first contact: ``touchdown_speed`` in
    ``climb``) and touches down at the drop point (``lower``: contact, ``touchdown_peak_force``,
    but no first contact) has both contacts' peaks under ``touchdown`` and neither ``in
    flight`` (before: the drop point's 8 g contact was counted in flight)."""
    from quadrs.design.mission_tables import IN_FLIGHT, TOUCHDOWN, contact_split

    nan = math.nan
    table = {  # two flights: the first bumps the pad, the second lowers as meant
        ("touchdown_speed", "climb"): [0.17, nan], ("touchdown_speed", "lower"): [nan, 0.4],
        ("touchdown_peak_force", "climb"): [43.0, nan],
        ("touchdown_peak_force", "lower"): [89.0, 60.0],
        ("max_accel", "climb"): [34.0, 2.5], ("max_accel", "transit"): [2.1, 2.2],
        ("max_accel", "lower"): [80.0, 55.0],
    }  # fmt: skip

    def values(metric: str, phase: str) -> np.ndarray:
        return np.asarray(table.get((metric, phase), [nan, nan]), float)

    present = {"touchdown_speed", "touchdown_peak_force", "max_accel"}
    split = contact_split(["climb", "transit", "lower"], values, present, "max_accel")
    assert split is not None
    np.testing.assert_array_equal(split[IN_FLIGHT], [2.1, 2.5])
    np.testing.assert_array_equal(split[TOUCHDOWN], [80.0, 55.0])


def test_an_answer_without_touchdowns_has_no_touchdown_rows(delivery: quadrs.Scenario) -> None:
    calm = delivery.override({**DROP_HERE, "trajectory.lower": [0.0, 0.0]})
    mc = quadrs.monte_carlo(calm, runs=2, seed=0, controllers=("pd",), progress=False,
                            spectra=False)  # fmt: skip
    r = mission_report(mc, 2 * 9.80665, metric="max_specific_force")
    assert "touchdown" not in r.acceleration.index and r.parcel_line() == ""


# -- 3. a preset's duration and turbulence follow its route ------------------------------------
def test_a_slower_transit_lengthens_the_presets_flight_and_its_turbulence(
    delivery: quadrs.Scenario, capsys: pytest.CaptureFixture[str]
) -> None:
    margin = delivery["integrator.duration"] - route_time(delivery.to_dict())
    assert 0 <= margin < 5
    slow = delivery.override({"trajectory.speed": 7.0})
    need = route_time(slow.to_dict())
    assert need > delivery["integrator.duration"]  # the preset's 211 s no longer covers it
    assert slow["integrator.duration"] == pytest.approx(covering(need + margin, 0.001))
    assert slow["gust.end"] == slow["integrator.duration"]  # the turbulence blows throughout
    # set: kept as set
    kept = delivery.override({"trajectory.speed": 7.0, "integrator.duration": 300.0})
    assert kept["integrator.duration"] == 300.0 and kept["gust.end"] == delivery["gust.end"]
    window = delivery.override({"trajectory.speed": 7.0, "gust.end": 100.0})
    assert window["gust.end"] == 100.0 and window["integrator.duration"] > 211
    # a faster one shortens it; a change that does not move the route changes nothing
    assert delivery.override({"trajectory.speed": 9.0})["integrator.duration"] < 211
    assert delivery.override({"payload.mass": 0.6})["integrator.duration"] == 211.0
    code, out, err = cli(capsys, "scenario", "show", "--preset", "delivery", "--set",
                         "trajectory.speed=7", "--diff")  # fmt: skip
    assert code == 0, err
    assert "integrator.duration = 226.858" in out and "gust.end = 226.858" in out


def test_a_file_on_the_preset_that_moves_the_route_follows_it(tmp_path: Path) -> None:
    path = tmp_path / "slow.toml"
    path.write_text('base = "delivery"\n\n[trajectory]\nspeed = 7.0\n')
    s = quadrs.Scenario.from_toml(path)
    assert s["integrator.duration"] == pytest.approx(226.858)
    assert s["gust.end"] == s["integrator.duration"]
    path.write_text('base = "delivery"\n[trajectory]\nspeed = 7.0\n[integrator]\nduration = 230\n')
    assert quadrs.Scenario.from_toml(path)["gust.end"] == 211.0  # set: the file's own


# -- 4. --set fixes a scenario file the checks refuse ------------------------------------------
def test_set_can_follow_the_advice_of_a_refused_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "slow.toml"
    path.write_text('base = "delivery"\n\n[trajectory]\nspeed = 7.0\n[integrator]\n'
                    "duration = 211.0\n")  # fmt: skip
    code, _, err = cli(capsys, "scenario", "show", "--scenario", str(path), "--diff")
    found = re.search(r"set it to at least ([0-9.]+) s", err)
    assert code == 2 and found, err
    code, out, err = cli(capsys, "scenario", "show", "--scenario", str(path), "--diff", "--set",
                         f"integrator.duration={found.group(1)}")  # fmt: skip
    assert code == 0, err
    assert f"integrator.duration = {found.group(1)}" in out
    # a complete file (no base) likewise; a key the file's tables cannot take is still set
    complete = tmp_path / "complete.toml"
    whole = quadrs.Scenario.preset("delivery").to_dict()
    whole["trajectory"]["speed"] = 7.0
    import tomli_w

    complete.write_text(tomli_w.dumps(whole))
    code, _, err = cli(capsys, "scenario", "show", "--scenario", str(complete))
    assert code == 2 and "integrator.duration" in err
    code, out, err = cli(capsys, "scenario", "show", "--scenario", str(complete), "--set",
                         "integrator.duration=230", "--set", "gust.end=230", "--set",
                         "controller.pd.kp[0]=1.1")  # fmt: skip
    assert code == 0, err
    assert quadrs.Scenario.from_toml_string(out)["controller.pd.kp"][0] == 1.1


# -- 5. a route override keeps what depends on the route ---------------------------------------
def test_setting_the_presets_own_route_changes_nothing(delivery: quadrs.Scenario) -> None:
    again = delivery.override({"trajectory.route": delivery["trajectory.route"]})
    assert again == delivery and again["trajectory.lower"] == [0.0, 0.0, 0.0, 6.0, 0.0]
    moved = [[x + 10.0, y, z] for x, y, z in delivery["trajectory.route"]]
    there = delivery.override({"trajectory.route": moved})  # as many points: the same lowering
    assert there["trajectory.lower"] == delivery["trajectory.lower"]
    assert there.scenario_phases == delivery.scenario_phases


def test_a_route_of_other_points_drops_the_names_it_cannot_have(delivery: quadrs.Scenario) -> None:
    """Four points where the preset has five: the preset's lowering (at its fourth point) and
    leg names go with its route; the holds are per point and must be given (the error names
    the key and the count)."""
    route = [[0.0, 0.0, 2.0], [0.0, 0.0, 30.0], [300.0, 0.0, 30.0], [300.0, 0.0, 5.0]]
    with pytest.raises(quadrs.ScenarioError, match=r"trajectory.hold.*\(4\)"):
        delivery.override({"trajectory.route": route})
    s = delivery.override({"trajectory.route": route, "trajectory.hold": [2.0, 0, 0, 15.0]})
    assert "lower" not in s.to_dict()["trajectory"] and "names" not in s.to_dict()["trajectory"]
    assert s["integrator.duration"] < 150  # the shorter route's, with the preset's margin


# -- 7. docs that agree with the program -------------------------------------------------------
def test_the_model_docs_preset_table_is_the_presets(delivery: quadrs.Scenario) -> None:
    """docs/model.md's delivery table names the route's every point, the lowering, the winch
    and the line as the preset has them."""
    text = (ROOT / "docs" / "model.md").read_text()
    table = text[text.index("## The delivery preset") :]
    table = table[: table.index("**Findings.**")]
    route = " -> ".join(f"({x:g},{y:g},{z:g})" for x, y, z in delivery["trajectory.route"])
    assert route in table, route
    for key in ("trajectory.lower", "payload.winch_speed", "payload.length_min",
                "payload.release", "ground.stiffness"):  # fmt: skip
        assert key.split(".")[1] in table, key
    assert f"{delivery['payload.cable_length']:g} m" in table


def test_the_docs_do_not_promise_minutes_for_seconds_of_work() -> None:
    """README and docs/delivery.md: a 200-run delivery mission takes seconds on two cores
    (docs/performance.md measures 4-13 s), not "1.5 min"."""
    for page in (ROOT / "README.md", ROOT / "docs" / "delivery.md"):
        for line in page.read_text().splitlines():
            if "quadrs mission" in line and "--runs 200" in line:
                assert "1.5 min" not in line, (page.name, line)


# -- 8. discoverability -------------------------------------------------------------------------
def test_scenario_keys_says_which_preset_and_shows_the_delivery_keys(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, out, _ = cli(capsys, "scenario", "keys")
    assert code == 0
    which = next(line for line in out.splitlines() if "These are the keys" in line)
    assert "preset 'paper'" in which and "--preset delivery" in which
    winch = next(line for line in out.splitlines() if "payload.winch_speed" in line)
    assert "delivery: 1.0" in winch  # an unset key a preset sets, with its value there
    code, out, _ = cli(capsys, "scenario", "keys", "--preset", "delivery")
    wind = next(line for line in out.splitlines() if line.startswith("wind.speed = 5.0"))
    said = r"# m/s at 20 ft \(6\.1 m\); 6\.6\d? m/s at the route's 30 m \(wind.shear = \"log\"\)"
    assert re.search(said, wind), wind


def test_rare_names_its_default_preset_and_the_one_with_the_phase(
    capsys: pytest.CaptureFixture[str],
) -> None:
    code, _, err = cli(capsys, "rare", "--metric", "max_accel", "--phase", "transit",
                       "--threshold", "8")  # fmt: skip
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert "preset 'paper' (rare's default" in err and "--preset delivery has 'transit'" in err


# -- 9. impossible geometry ---------------------------------------------------------------------
def test_a_drop_point_below_the_ground_is_refused(delivery: quadrs.Scenario) -> None:
    route = delivery["trajectory.route"]
    route[3][2] = -5.0
    with pytest.raises(quadrs.ScenarioError, match=r"trajectory.route\[3\].*below the ground"):
        delivery.override({"trajectory.route": route})


def test_a_lowering_that_stops_short_of_the_ground_warns(delivery: quadrs.Scenario) -> None:
    with pytest.warns(quadrs.PlausibilityWarning, match=r"trajectory.lower\[3\] = 2 m leaves "
                      r"the parcel 1.95 m above the ground.*at least 3.95 m"):  # fmt: skip
        delivery.override({"trajectory.lower": [0.0, 0.0, 0.0, 2.0, 0.0]})
    with warnings.catch_warnings():
        warnings.simplefilter("error", quadrs.PlausibilityWarning)
        delivery.override({"trajectory.lower": [0.0, 0.0, 0.0, 4.0, 0.0]})  # reaches it


def test_a_route_not_flown_judges_no_touchdown(drop_mc: quadrs.MonteCarloResult) -> None:
    """Every flight off its route (a tracking limit no flight meets): the last metres are not
    judged as if the parcel had been lowered at its drop point."""
    r = mission_report(drop_mc, 20.0, track_limit=1e-3)
    assert "NOT FLOWN" in r.verdict()
    assert r.last_metres_line().startswith("Last metres: not judged: the route was NOT FLOWN")
    flown = mission_report(drop_mc, 20.0)
    assert "(4 touchdowns)" in flown.last_metres_line()


# -- 10. the small things ----------------------------------------------------------------------
def test_a_wind_table_shorter_than_the_flight_is_noted(delivery: quadrs.Scenario) -> None:
    rows = [[0.0, 0.0, 1.0, 0.0], [6.0, 0.0, 2.0, 0.0]]
    with pytest.warns(quadrs.PlausibilityWarning, match=r"wind.table covers t = 0 to 6 s of a "
                      r"211 s flight"):  # fmt: skip
        delivery.override({"wind.table.by": "time", "wind.table.points": rows})


def test_a_time_spent_has_no_negative_bound() -> None:
    from quadrs.design.mission_tables import _mean_columns

    runs = pd_frame([0.0, 0.0, 0.0, 0.3])
    cols = _mean_columns("saturated_time", "p", {"p": runs}, 0.95)
    assert cols["saturated_time_ci_low"] == 0.0 and cols["saturated_time_ci_high"] > 0.075


def pd_frame(values: list[float]) -> Any:
    import pandas as pd

    return pd.DataFrame({"saturated_time": values, "diverged": [False] * len(values)})


def test_a_seconds_column_shows_seconds(drop_mc: quadrs.MonteCarloResult) -> None:
    text = mission_report(drop_mc, 20.0).to_text(width=100)
    block = text[text.index("at thrust limit s") :]
    block = block[: block.index("any phase")]
    assert "P <=" not in block and "0 in all 4" in block


def test_a_limit_in_g_is_the_parcels_specific_force() -> None:
    from quadrs.cli.mission import DEFAULT_LIMIT, DEFAULT_METRIC, mission_limit

    assert mission_limit("2g") == (DEFAULT_METRIC, pytest.approx(DEFAULT_LIMIT))
    assert mission_limit("9.81") == ("max_accel", 9.81)


def test_a_long_note_is_wrapped_to_the_report_width(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """On a terminal a note is wrapped to its width; into a file it stays one line."""
    import sys

    from quadrs.cli.common import note

    monkeypatch.setenv("COLUMNS", "80")
    text = "quadrs mission: " + " ".join(["a-long-word"] * 30)
    note(text)
    assert capsys.readouterr().err == text + "\n"
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    note(text)
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) > 1 and max(map(len, lines)) <= 80
    assert lines[0].startswith("quadrs mission:") and all(s.startswith("  ") for s in lines[1:])


def test_the_readme_says_the_test_time_in_a_sentence() -> None:
    text = (ROOT / "README.md").read_text()
    paragraph = next(p for p in text.split("\n\n") if p.startswith("The second runs every"))
    assert len(paragraph) < 400 and "docs/performance.md" in paragraph
    assert "(+300s)" not in text  # the measurements are in docs/performance.md


def test_the_route_time_is_the_engines(delivery: quadrs.Scenario) -> None:
    need = route_time(delivery.to_dict())
    # 209.2509 s before the sixth round's final approach (from 2 m as the vehicle knows its
    # height: its lowering about 9.5 s longer, the hold after it 9.5 s shorter).
    assert need is not None and math.isclose(need, 209.2009, abs_tol=1e-3)
    with pytest.raises(quadrs.ScenarioError, match=r"at least 209\.3 s"):
        delivery.override({"integrator.duration": 200.0})
    assert np.isfinite(need)
