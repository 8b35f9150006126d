"""Nothing lies, aborts or is lost, fifth round (issue 53): mission files, wind tables, the
px4 law's keys, the files quadrs reads, and the command line's refusals.

Each test goes through the command line where a user meets the case, and failed before the
fix it proves (docs/guarantees.md lists them beside their promise)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

import quadrs
from quadrs import Scenario
from quadrs.cli.main import main
from tests.guarantees.test_design_loop_and_files import TINY_CLI
from tests.scenario.test_route_files import HOME, east, item, north, plan, write

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

pytestmark = pytest.mark.filterwarnings(
    "ignore::quadrs.StabilityWarning",
    "ignore::quadrs.StepSizeWarning",
    "ignore:wind.table covers",  # the short tables these files give (said: tests/first_hour)
)


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def refused(capsys: pytest.CaptureFixture[str], *args: str) -> str:
    """The one line a refused command prints (exit 2, no traceback)."""
    code, _, err = cli(capsys, *args)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, (code, err)
    return lines[0]


def route_of(capsys: pytest.CaptureFixture[str], path: Path, *extra: str) -> dict[str, Any]:
    """The scenario ``scenario show`` prints for the delivery preset flying ``path``."""
    code, out, err = cli(capsys, "scenario", "show", "--preset", "delivery", "--set",
                         f'trajectory.route_file="{path}"', *extra)  # fmt: skip
    assert code == 0, err
    return tomllib.loads(out)


LAT, LON = HOME[0], HOME[1]


def legs(lat: float = LAT, lon: float = LON) -> list[dict[str, Any]]:
    """Take-off to 20 m, then out 100 m north and 100 m east of it (mission items 2 and 3)."""
    return [item(22, alt=20.0), item(16, lat + north(100.0), lon, 20.0),
            item(16, lat + north(100.0), lon + east(100.0), 20.0)]  # fmt: skip


# -- .plan semantics --------------------------------------------------------------------------
@pytest.mark.parametrize("repeat", [0, 1, 3])
def test_do_jump_repeats_its_legs(tmp_path: Path, capsys, repeat: int) -> None:
    """DO_JUMP to item 2 (sequence number 2, the first waypoint), ``repeat`` times: the legs
    between are flown 1 + repeat times (they were flown once, the jump skipped)."""
    doc = plan([*legs(), item(177, p0=2, p1=repeat), item(20)])
    data = route_of(capsys, write(tmp_path, doc))
    route = data["trajectory"]["route"]
    a = [0.0, 0.0, 20.0]
    north_point = route[2]
    east_point = route[3]
    assert math.dist(north_point, [0.0, 100.0, 20.0]) < 0.5
    assert math.dist(east_point, [100.0, 100.0, 20.0]) < 0.5
    loop = [north_point, east_point]
    expected = [route[0], a] + loop * (1 + repeat) + [a, route[0]]
    assert len(route) == len(expected)
    for got, want in zip(route, expected, strict=True):
        assert math.dist(got, want) < 1e-6


def test_do_jump_by_its_do_jump_id_and_refusals(tmp_path: Path, capsys) -> None:
    items = legs()
    for i, it in enumerate(items):
        it["doJumpId"] = 10 + i
    doc = plan([*items, item(177, p0=11, p1=2), item(20)])
    route = route_of(capsys, write(tmp_path, doc))["trajectory"]["route"]
    assert len(route) == 2 + 2 * 3 + 2  # home, up, (north, east) x 3, home above, home
    forever = write(tmp_path, plan([*legs(), item(177, p0=2, p1=-1)]), "forever.plan")
    line = refused(capsys, "mission", "--plan", str(forever))
    assert "forever.plan: mission.items[3]: DO_JUMP repeats forever" in line
    nowhere = write(tmp_path, plan([*legs(), item(177, p0=40, p1=1)]), "nowhere.plan")
    line = refused(capsys, "mission", "--plan", str(nowhere))
    assert "mission.items[3]: DO_JUMP params[0]: no mission item has sequence number 40" in line


@pytest.mark.parametrize(("command", "name"), [(179, "DO_SET_HOME"), (192, "DO_REPOSITION"),
                                               (183, "DO_SET_SERVO"), (31337, "")])  # fmt: skip
def test_items_not_flown_are_refused_naming_the_item(tmp_path: Path, capsys, command: int,
                                                     name: str) -> None:  # fmt: skip
    """Were skipped in silence: a DO_SET_HOME moved home (where the return goes) unseen."""
    doc = plan([*legs(), item(command, LAT, LON, 0.0, p0=0), item(20)])
    line = refused(capsys, "mission", "--plan", str(write(tmp_path, doc)))
    assert f"m.plan: mission.items[3]: command {command} is not supported" in line
    assert name in line


def test_harmless_items_are_named_in_a_warning(tmp_path: Path, capsys) -> None:
    doc = plan([*legs(), item(203), item(115, p0=90), item(20)])  # camera, yaw
    code, _, err = cli(capsys, "scenario", "show", "--preset", "delivery", "--set",
                       f'trajectory.route_file="{write(tmp_path, doc)}"')  # fmt: skip
    assert code == 0, err
    assert "mission.items[3] DO_DIGICAM_CONTROL" in err and "mission.items[4] CONDITION_YAW" in err


@pytest.mark.parametrize("kind", [2, 3])
def test_a_climb_or_descent_speed_is_not_the_cruise_speed(tmp_path: Path, capsys,
                                                          kind: int) -> None:  # fmt: skip
    doc = plan([item(178, p0=kind, p1=0.7), *legs(), item(20)])
    line = refused(capsys, "mission", "--plan", str(write(tmp_path, doc)))
    assert "mission.items[0]: DO_CHANGE_SPEED sets a" in line
    assert ("climb" if kind == 2 else "descent") in line


def test_change_speed_no_change_and_default_are_valid(tmp_path: Path, capsys) -> None:
    """-1 (no change) and -2 (back to the default) were refused as speeds <= 0."""
    doc = plan([item(178, p0=1, p1=-1), *legs(), item(178, p0=1, p1=-2), item(20)])
    data = route_of(capsys, write(tmp_path, doc))
    assert data["trajectory"]["speed"] == 5.0  # the plan's hoverSpeed: the default
    doc = plan([item(178, p0=0, p1=3.5), *legs(), item(178, p0=1, p1=-1), item(20)])
    assert route_of(capsys, write(tmp_path, doc))["trajectory"]["speed"] == 3.5
    doc = plan([item(178, p0=0, p1=3.5), *legs(), item(178, p0=1, p1=-2), item(20)])
    line = refused(capsys, "mission", "--plan", str(write(tmp_path, doc)))
    assert "DO_CHANGE_SPEED sets [3.5, 5.0] m/s" in line


@pytest.mark.parametrize("which", ["lat", "lon"])
def test_a_take_off_or_land_coordinate_of_zero_is_a_position(tmp_path: Path, capsys,
                                                            which: str) -> None:  # fmt: skip
    """Near the equator or Greenwich, 0 is a coordinate: it was read as "no position"."""
    home = [0.0005, 0.0005, 10.0] if which == "lat" else [51.4779, 0.0005, 10.0]
    lat, lon = home[0], home[1]
    zero_lat, zero_lon = (0.0, lon) if which == "lat" else (lat, 0.0)
    doc = plan([item(22, zero_lat, zero_lon, 20.0),
                item(16, lat + north(100.0, lat), lon, 20.0),
                item(21, zero_lat, zero_lon)], plannedHomePosition=home)  # fmt: skip
    route = route_of(capsys, write(tmp_path, doc))["trajectory"]["route"]
    offset = (0.0, -55.3) if which == "lat" else (-34.6, 0.0)  # 0.0005 degrees away
    up, land_above = route[2], route[-2]
    for point in (up, land_above):
        assert point[0] == pytest.approx(offset[0], abs=0.5)
        assert point[1] == pytest.approx(offset[1], abs=0.5)
    half = write(tmp_path, plan([item(22, None, 0.0, 20.0), *legs()[1:]]), "half.plan")
    assert "give both or neither" in refused(capsys, "mission", "--plan", str(half))


@pytest.mark.parametrize("where", [(-HOME[0], HOME[1] - 180.0), (HOME[0] + 1.0, HOME[1])])
def test_a_waypoint_far_from_home_is_refused(tmp_path: Path, capsys,
                                             where: tuple[float, float]) -> None:  # fmt: skip
    """The antipode became a 42.6 km leg on the tangent plane; 111 km north is beyond it too."""
    doc = plan([item(22, alt=20.0), item(16, where[0], where[1], 20.0)])
    line = refused(capsys, "mission", "--plan", str(write(tmp_path, doc)))
    assert "mission.items[1]" in line and "km from home" in line and "beyond 50 km" in line
    csv = write(tmp_path, f"lat,lon,alt\n{LAT},{LON},0\n{where[0]},{where[1]},0\n", "far.csv")
    assert "far.csv: line 3" in refused(capsys, "mission", "--plan", str(csv))


# -- the px4 law's keys -----------------------------------------------------------------------
@pytest.mark.parametrize("least", [0.5, 0.6, 0.9])
def test_a_least_thrust_at_or_above_hover_is_refused(capsys, least: float) -> None:
    """Flew: the vehicle climbed to 422 m on a 2 m step and the flight ended `ok`."""
    line = refused(capsys, "run", "--controller", "px4", "--set",
                   f"controller.px4.MPC_THR_MIN={least}")  # fmt: skip
    assert "controller.px4.MPC_THR_MIN must be below MPC_THR_HOVER (0.5)" in line
    line = refused(capsys, "scenario", "show", "--set", "controller.px4.MPC_THR_HOVER=0.1",
                   "--set", "controller.px4.MPC_THR_MIN=0.1")  # fmt: skip
    assert "MPC_THR_MIN must be below MPC_THR_HOVER (0.1)" in line


# -- wind tables ------------------------------------------------------------------------------
def test_a_wind_table_with_file_and_points_is_refused(tmp_path: Path, capsys) -> None:
    table = tmp_path / "w.csv"
    table.write_text("t,wind_x,wind_y,wind_z\n0,9,0,0\n10,9,0,0\n")
    s = tmp_path / "s.toml"
    s.write_text('base = "delivery"\n[wind.table]\nby = "time"\nfile = "w.csv"\n'
                 "points = [[0.0, 1.0, 0.0, 0.0], [10.0, 1.0, 0.0, 0.0]]\n")  # fmt: skip
    line = refused(capsys, "scenario", "show", "--scenario", str(s))
    assert "wind.table: give file or points, not both" in line


def test_set_names_a_wind_table_or_route_file(tmp_path: Path, capsys) -> None:
    """Were unknown keys to --set."""
    table = tmp_path / "w.csv"
    table.write_text("t,wind_x,wind_y,wind_z\n0,2,0,0\n10,3,0,0\n")
    code, out, err = cli(capsys, "scenario", "show", "--preset", "delivery", "--set",
                         f'wind.table.file="{table}"', "--set", 'wind.table.by="time"')  # fmt: skip
    assert code == 0, err
    assert tomllib.loads(out)["wind"]["table"]["points"] == [[0, 2, 0, 0], [10, 3, 0, 0]]
    # setting a file over a table's points replaces them
    s = Scenario.preset("delivery").override(
        {"wind.table": {"by": "time", "points": [[0.0, 1.0, 0.0, 0.0], [5.0, 1.0, 0.0, 0.0]]}}
    )
    s = s.override({"wind.table.file": str(table)})
    assert s["wind.table.points"] == [[0, 2, 0, 0], [10, 3, 0, 0]]
    route = write(tmp_path, "x,y,z\n0,0,2\n0,0,20\n50,0,20\n", "r.csv")
    data = route_of(capsys, route)
    assert data["trajectory"]["route"] == [[0, 0, 2], [0, 0, 20], [50, 0, 20]]
    line = refused(capsys, "mission", "--plan", str(route), "--set",
                   f'trajectory.route_file="{route}"')  # fmt: skip
    assert "--plan and --set trajectory.route_file" in line


# -- tracebacks become one line ---------------------------------------------------------------
def test_hostile_plans_and_start_positions_are_one_line(tmp_path: Path, capsys) -> None:
    deep = write(tmp_path, '{"fileType": "Plan", "mission": ' + "[" * 100_000 + "]" * 100_000
                 + "}", "deep.plan")  # fmt: skip
    assert "deep.plan" in refused(capsys, "mission", "--plan", str(deep))
    huge = json.dumps(plan(legs())).replace('"alt', '"x').replace("20.0", "1" + "0" * 400, 1)
    line = refused(capsys, "mission", "--plan", str(write(tmp_path, huge, "huge.plan")))
    assert "huge.plan: mission.items[0]: params[6] (altitude)" in line
    good = write(tmp_path, plan(legs()))
    for value in ("5", "[1,2]", '"up"', "[1,2,nan]"):
        line = refused(capsys, "mission", "--plan", str(good), "--set",
                       f"initial.position={value}")  # fmt: skip
        assert "initial.position must have 3 numbers" in line


def test_a_csv_cell_over_the_field_limit_is_one_line(tmp_path: Path, capsys) -> None:
    big = "1" * (200 << 10)
    route = write(tmp_path, f"x,y,z\n0,0,2\n{big},0,2\n", "big.csv")
    line = refused(capsys, "mission", "--plan", str(route))
    assert "big.csv" in line and "line 3" in line
    table = tmp_path / "w.csv"
    table.write_text(f"t,wind_x,wind_y,wind_z\n0,1,0,0\n{big},1,0,0\n")
    line = refused(capsys, "scenario", "show", "--preset", "delivery", "--set",
                   f'wind.table.file="{table}"', "--set", 'wind.table.by="time"')  # fmt: skip
    assert "w.csv" in line and "line 3" in line


def test_route_csv_coordinates_bom_and_encoding(tmp_path: Path, capsys) -> None:
    for lat, lon, says in [(95.0, LON, "line 3, lat: must be finite in [-90, 90], got '95.0'"),
                           (LAT, 368.5, "line 3, lon: must be finite in [-180, 180]")]:  # fmt: skip
        p = write(tmp_path, f"lat,lon,alt\n{LAT},{LON},0\n{lat},{lon},0\n", "c.csv")
        assert says in refused(capsys, "mission", "--plan", str(p))
    bom = tmp_path / "bom.csv"
    bom.write_bytes(b"\xef\xbb\xbfx,y,z\n0,0,2\n0,0,20\n")
    assert route_of(capsys, bom)["trajectory"]["route"] == [[0, 0, 2], [0, 0, 20]]
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"x,y,z\n0,0,2\n0,0,20 \xe9\n")
    line = refused(capsys, "mission", "--plan", str(latin))
    assert "latin.csv" in line and "not UTF-8" in line


# -- one reader for every input file ----------------------------------------------------------
def test_route_files_and_wind_tables_that_are_not_regular_files_are_refused(
    tmp_path: Path, capsys
) -> None:
    """Were read until memory ran out (/dev/zero) or blocked forever (a FIFO)."""
    zero_csv, zero_plan = tmp_path / "zero.csv", tmp_path / "zero.plan"
    zero_csv.symlink_to("/dev/zero")
    zero_plan.symlink_to("/dev/zero")
    fifo = tmp_path / "fifo.csv"
    os.mkfifo(fifo)
    commands = [("mission", "--plan", str(p)) for p in (zero_csv, zero_plan, fifo)]
    commands += [("scenario", "show", "--preset", "delivery", "--set",
                  f'trajectory.route_file="{p}"') for p in (zero_plan, fifo)]  # fmt: skip
    commands += [("scenario", "show", "--preset", "delivery", "--set", 'wind.table.by="time"',
                  "--set", f'wind.table.file="{p}"') for p in (zero_csv, fifo)]  # fmt: skip
    results: list[tuple[int, str]] = []

    def run(args: tuple[str, ...]) -> None:
        code = main(list(args))
        results.append((code, ""))

    for args in commands:
        worker = threading.Thread(target=run, args=(args,), daemon=True)
        worker.start()
        worker.join(timeout=20)
        assert not worker.is_alive(), f"{args} did not return"
        _, err = capsys.readouterr()
        assert results[-1][0] == 2 and "not a regular file" in err, (args, err)


# -- lost work --------------------------------------------------------------------------------
def test_a_large_wind_table_run_reads_back_everywhere(tmp_path: Path, capsys) -> None:
    """15,000 rows (about 0.4 MB as CSV, over 1 MiB as the scenario's TOML): the run was
    written, then refused by report, read_parquet, --resume's manifest and to_toml."""
    rows = "\n".join(f"{i * 0.01:.2f},{2 + math.sin(i):.6f},0.5,0" for i in range(15_000))
    (tmp_path / "w.csv").write_text("t,wind_x,wind_y,wind_z\n" + rows + "\n")
    s = tmp_path / "s.toml"
    s.write_text('base = "paper"\n[wind.table]\nby = "time"\nfile = "w.csv"\n')
    scenario = Scenario.from_toml(s)
    assert len(scenario.to_toml()) > 1 << 20
    assert Scenario.from_toml_string(scenario.to_toml()) == scenario
    out, ck = tmp_path / "runs.parquet", tmp_path / "ck"
    args = ["mc", "--scenario", str(s), *TINY_CLI, "--runs", "2", "--no-progress"]
    code, _, err = cli(capsys, *args, "--out", str(out), "--checkpoint", str(ck))
    assert code == 0, err
    code, report, err = cli(capsys, "report", str(out))
    assert code == 0 and "2 realisations" in report, err
    assert len(quadrs.MonteCarloResult.read_parquet(out).runs) > 0
    code, _, err = cli(capsys, *args, "--runs", "3", "--checkpoint", str(ck), "--resume")
    assert code == 0, err
    # and a route file beside it: the scenario re-read after the route was read in
    route = write(tmp_path, "x,y,z\n0,0,2\n0,0,6\n", "r.csv")
    s.write_text('base = "delivery"\n[trajectory]\nroute_file = "r.csv"\n'
                 '[wind.table]\nby = "time"\nfile = "w.csv"\n')  # fmt: skip
    assert Scenario.from_toml(s)["trajectory.route"] == [[0, 0, 2], [0, 0, 6]]
    del route


def test_ctrl_c_while_tune_prints_keeps_history_and_out(tmp_path: Path, capsys,
                                                        monkeypatch) -> None:  # fmt: skip
    import quadrs.cli.design as design

    def interrupted(*args: Any, **kwargs: Any) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(design, "_print_phase_effects", interrupted)
    out, history = tmp_path / "tuned.toml", tmp_path / "h.csv"
    code, _, err = cli(capsys, "tune", *TINY_CLI, "--controller", "pd", "--param",
                       "controller.pd.kp[2]=5:15", "--runs", "2", "--maxiter", "2",
                       "--method", "nelder-mead", "--out", str(out), "--history",
                       str(history))  # fmt: skip
    assert code == 130, err
    assert out.exists() and history.exists()


# -- refusals that say the right thing --------------------------------------------------------
def test_calibration_flies_realisations_of_the_batch(capsys, monkeypatch) -> None:
    """A dispersed draw refused in the calibration named realisation 10^12."""
    import quadrs.runs.chunk as chunk

    seen: list[tuple[int, int]] = []
    real = chunk.run_range

    def spy(scenario: Any, controllers: Any, seed: int, first: int, count: int,
            *args: Any, **kwargs: Any) -> Any:  # fmt: skip
        seen.append((first, count))
        return real(scenario, controllers, seed, first, count, *args, **kwargs)

    monkeypatch.setattr(chunk, "run_range", spy)
    code, _, err = cli(capsys, "mc", *TINY_CLI, "--runs", "3", "--controllers", "pd",
                       "--disperse", "payload.mass=uniform(0.2,0.3)")  # fmt: skip
    assert code == 0, err
    assert seen and all(first + count <= 3 for first, count in seen), seen


def test_tune_accepts_law_keys_and_checks_phases_before_calibrating(capsys, monkeypatch):
    import quadrs.cli.cost as cost

    calibrated: list[int] = []

    def stop(*args: Any, **kwargs: Any) -> Any:
        calibrated.append(1)
        raise KeyboardInterrupt

    monkeypatch.setattr(cost, "calibrate", stop)
    common = ["tune", "--preset", "delivery", "--runs", "2",
              "--out", "/tmp/never-written.toml"]  # fmt: skip
    line = refused(capsys, *common, "--controller", "px4", "--param",
                   "controller.px4.MPC_XY_P=0.5:1.5", "--phase", "nophase")  # fmt: skip
    assert "nophase" in line and not calibrated
    for law, key in (("px4", "controller.px4.MPC_XY_P=0.5:1.5"),
                     ("se3", "controller.se3.kx[0]=2:6")):  # fmt: skip
        code, _, err = cli(capsys, *common, "--controller", law, "--param", key)
        assert code == 130 and calibrated, err  # got as far as the calibration
        assert "unknown" not in err
    # One law's gain while another flies changes nothing: refused before calibrating.
    calibrated.clear()
    line = refused(capsys, *common, "--controller", "px4", "--param", "controller.se3.kx[0]=2:6")
    assert "gain of the se3 law" in line and not calibrated


def test_a_route_longer_than_the_probe_is_flown(tmp_path: Path, capsys) -> None:
    """Refused as "got 100000.0", an internal probe's duration; --set integrator.duration
    could not change it."""
    doc = plan([item(22, alt=20.0), item(16, LAT + north(50.0), LON, 20.0, hold=150_000.0)])
    p = write(tmp_path, doc)
    # A 20 ms step (a long route's quick look): the preset's 250 Hz attitude loop, 500 Hz inner
    # loop and 100 Hz wind are no whole number of its steps, so they run every step.
    coarse = ["--set", "integrator.dt=0.02", "--set", "controller.attitude_rate=0",
              "--set", "controller.inner_rate=0", "--set", "gust.rate=0"]  # fmt: skip
    data = route_of(capsys, p, *coarse)
    assert data["integrator"]["duration"] > 150_000
    line = refused(capsys, "scenario", "show", "--preset", "delivery", *coarse, "--set",
                   f'trajectory.route_file="{p}"', "--set",
                   "integrator.duration=120000")  # fmt: skip
    assert "must cover the route" in line and "got 120000" in line and "100000.0" not in line


def test_scenario_show_diff_after_one_law_key_lists_that_key(capsys) -> None:
    code, out, err = cli(capsys, "scenario", "show", "--diff", "--preset", "delivery", "--set",
                         "controller.px4.MPC_XY_P=1.2")  # fmt: skip
    assert code == 0, err
    assert out.splitlines()[0] == "# 1 key(s) differ from the preset 'delivery'"
    assert out.splitlines()[1].startswith("controller.px4.MPC_XY_P = 1.2")
    code, out, err = cli(capsys, "scenario", "show", "--preset", "delivery", "--set",
                         "controller.px4.MPC_XY_P=1.2")  # fmt: skip
    assert Scenario.from_toml_string(out) == Scenario.preset("delivery").override(
        {"controller.px4.MPC_XY_P": 1.2}
    )


def test_report_on_a_flight_trace_says_what_the_file_is(tmp_path: Path, capsys) -> None:
    trace = tmp_path / "t.parquet"
    assert main(["run", *TINY_CLI, "--trace", str(trace)]) == 0
    capsys.readouterr()
    line = refused(capsys, "report", str(trace))
    assert "is one flight's trace" in line and "Flight.read_parquet" in line
    assert "lacks" not in line


def test_mission_help_names_one_default_preset(capsys) -> None:
    with pytest.raises(SystemExit):
        build = __import__("quadrs.cli.main", fromlist=["build_parser"]).build_parser()
        build.parse_args(["mission", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "default: paper" not in text and "(default: delivery)" in text
    with pytest.raises(SystemExit):
        build.parse_args(["run", "--help"])
    assert "(default: paper)" in " ".join(capsys.readouterr().out.split())


# -- no abort at exit -------------------------------------------------------------------------
def test_no_abort_at_exit_after_a_refused_trace(tmp_path: Path, monkeypatch) -> None:
    """A refused read left an Arrow thread holding the Python bytes it was handed; releasing
    them needs the GIL, and during the interpreter's finalisation that ends the thread inside
    C++: SIGABRT at exit, "terminate called without an active exception" (about one run in
    25). Arrow must read memory of its own, and no process may abort."""
    import pyarrow as pa

    trace = tmp_path / "t.parquet"
    assert main(["run", *TINY_CLI, "--trace", str(trace)]) == 0
    import pyarrow.parquet as pq

    table = pq.read_table(trace)
    meta = dict(table.schema.metadata)
    doc = json.loads(meta[b"quadrs"])
    doc["seed"] = 7
    meta[b"quadrs"] = json.dumps(doc).encode()
    pq.write_table(table.replace_schema_metadata(meta), trace)
    handed: list[Any] = []
    real = pa.BufferReader

    def reader(source: Any) -> Any:
        handed.append(source)
        return real(source)

    import quadrs.io.parquet as parquet

    data = trace.read_bytes()
    monkeypatch.setattr(pa, "BufferReader", reader)
    monkeypatch.setattr(parquet, "read_regular", lambda path: data)  # these very bytes
    with pytest.raises(ValueError, match="run identity"):
        quadrs.Flight.read_parquet(trace)
    monkeypatch.undo()
    assert handed, "the trace was not read through a BufferReader"
    python_memory = pa.py_buffer(data).address
    for source in handed:
        assert isinstance(source, pa.Buffer) and source.address != python_memory
    code = ("import sys, quadrs\n"
            "try:\n    quadrs.Flight.read_parquet(sys.argv[1])\n"
            "except ValueError:\n    pass\nelse:\n    sys.exit(3)\n")  # fmt: skip
    for _ in range(10):
        proc = subprocess.run([sys.executable, "-c", code, str(trace)], capture_output=True,
                              text=True, timeout=120, check=False)  # fmt: skip
        assert proc.returncode == 0, (proc.returncode, proc.stderr)
        assert "terminate called" not in proc.stderr
