"""Routes from mission files (quadrs.scenario.route_files): a QGroundControl ``.plan`` becomes the
route it describes, in metres about its home (checked against WGS-84's radii of curvature,
computed here independently of pymap3d); a CSV of points likewise; a malformed file gets one
line naming what is wrong; ``quadrs mission --plan`` flies it."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

import pytest

import quadrs
from quadrs.cli.main import main
from quadrs.scenario.route_files import RouteFileError, read_plan, read_route_csv, read_route_file

#: The plan most tests read has a camera item, which is not flown and warns so (checked by
#: its own test with pytest.warns).
pytestmark = pytest.mark.filterwarnings("ignore:.*not flown \\(they do not move the vehicle\\)")

HOME = (47.3977419, 8.5455938, 488.0)
A, E2 = 6378137.0, 6.69437999014e-3  # WGS-84


def north(metres: float, lat: float = HOME[0]) -> float:
    """Degrees of latitude for `metres` north: the meridian radius of curvature M."""
    s = math.sin(math.radians(lat))
    m = A * (1 - E2) / (1 - E2 * s * s) ** 1.5
    return math.degrees(metres / m)


def east(metres: float, lat: float = HOME[0]) -> float:
    """Degrees of longitude for `metres` east: the prime vertical's N cos(lat)."""
    s = math.sin(math.radians(lat))
    n = A / math.sqrt(1 - E2 * s * s)
    return math.degrees(metres / (n * math.cos(math.radians(lat))))


def item(command: int, lat: Any = None, lon: Any = None, alt: Any = 0, hold: Any = 0,
         frame: int = 3, **params: Any) -> dict[str, Any]:  # fmt: skip
    p = [hold, 0, 0, None, lat, lon, alt]
    for i, v in params.items():
        p[int(i.removeprefix("p"))] = v
    return {"type": "SimpleItem", "command": command, "frame": frame, "params": p,
            "autoContinue": True}  # fmt: skip


def plan(items: list[dict[str, Any]], **mission: Any) -> dict[str, Any]:
    return {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "mission": {"version": 2, "firmwareType": 12, "vehicleType": 2, "cruiseSpeed": 15,
                    "hoverSpeed": 5, "plannedHomePosition": list(HOME), "items": items,
                    **mission},
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
    }  # fmt: skip


def write(tmp_path: Path, doc: Any, name: str = "m.plan") -> Path:
    p = tmp_path / name
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return p


def hundred_metres_north() -> dict[str, Any]:
    lat, lon = HOME[0], HOME[1]
    return plan([
        item(22, alt=30.0),
        item(16, lat, lon, 30.0),
        item(16, lat + north(100.0), lon, 30.0, hold=4.0),
        item(203, frame=2),  # DO_DIGICAM_CONTROL: does not move (not flown, named in a warning)
        item(21, lat + north(100.0), lon),
    ])  # fmt: skip


def test_an_item_that_does_not_move_the_vehicle_is_named_in_a_warning(tmp_path: Path) -> None:
    from quadrs.scenario.route_files import RouteFileWarning

    with pytest.warns(RouteFileWarning, match=r"not flown .*mission.items\[3\] DO_DIGICAM_CONTROL"):
        read_plan(write(tmp_path, hundred_metres_north()), start_height=2.0)


def test_two_waypoints_100_m_apart_north_become_a_100_m_leg(tmp_path: Path) -> None:
    r = read_plan(write(tmp_path, hundred_metres_north()), start_height=2.0)
    # home at 2 m, up to 30 m (take-off and the first waypoint are one point), 100 m north,
    # hold 4 s, land: down to 2 m.
    assert len(r.points) == 4 and r.hold == (0.0, 0.0, 4.0, 0.0)
    (x0, y0, z0), (x1, y1, z1), (x2, y2, z2), (x3, y3, z3) = r.points
    assert (x0, y0, z0) == (0.0, 0.0, 2.0) and (x1, y1, z1) == (0.0, 0.0, 30.0)
    assert math.dist(r.points[1], r.points[2]) == pytest.approx(100.0, rel=1e-3)
    assert abs(x2) < 1e-6 and y2 == pytest.approx(100.0, rel=1e-3) and z2 == 30.0
    assert (x3, y3, z3) == (x2, y2, 2.0)
    assert r.length == pytest.approx(28 + 100 + 28, rel=1e-3)
    assert r.speed == 5.0  # the plan's hoverSpeed


def test_east_and_above_mean_sea_level(tmp_path: Path) -> None:
    lat, lon = HOME[0], HOME[1]
    doc = plan([item(16, lat, lon + east(250.0), HOME[2] + 40.0, frame=0)])
    r = read_plan(write(tmp_path, doc))
    x, y, z = r.points[-1]
    assert x == pytest.approx(250.0, rel=1e-3) and abs(y) < 0.1 and z == pytest.approx(40.0)


def test_the_scenario_flies_exactly_the_route(tmp_path: Path) -> None:
    base = quadrs.Scenario.preset("delivery")
    r = read_plan(write(tmp_path, hundred_metres_north()), start_height=2.0)
    s = r.apply(base)
    assert s["trajectory.route"] == [list(p) for p in r.points]
    assert s["initial.position"] == list(r.points[0])
    assert s["trajectory.speed"] == 5.0
    route = s.route
    assert route is not None and len(route.legs) == 3
    needed = sum(g.arrival - g.start for g in route.legs) + sum(r.hold)
    dt = s["integrator.dt"]
    assert needed <= s["integrator.duration"] < needed + dt + 1e-9
    assert s["gust.end"] == s["integrator.duration"]  # the preset's wind blows throughout
    with pytest.raises(ValueError, match="must cover the route"):
        s.override({"integrator.duration": s["integrator.duration"] - 2 * dt})


def test_a_route_longer_than_the_flight_says_how_long_to_fly() -> None:
    """The delivery route flown slower than a duration that is set (not the preset's, which
    follows its route) needs a longer flight: the message gives a duration that does cover
    it (rounded up to 0.1 s), not only the shortfall."""
    slow = {"trajectory.speed": 6.0}
    fixed = quadrs.Scenario.preset("delivery").override({"integrator.duration": 211.0})
    with pytest.raises(ValueError, match="must cover the route") as caught:
        fixed.override(slow)
    found = re.search(r"set it to at least ([0-9.]+) s", str(caught.value))
    assert found, str(caught.value)
    enough = float(found.group(1))
    s = fixed.override({**slow, "integrator.duration": enough})
    assert s["integrator.duration"] == enough
    with pytest.raises(ValueError, match="must cover the route"):
        fixed.override({**slow, "integrator.duration": enough - 0.1})


def test_return_to_launch_comes_home(tmp_path: Path) -> None:
    lat, lon = HOME[0], HOME[1]
    doc = plan([item(22, alt=20.0), item(16, lat + north(60.0), lon + east(80.0), 25.0),
                item(20)])  # fmt: skip
    r = read_plan(write(tmp_path, doc), start_height=1.5)
    assert r.points[-2] == (0.0, 0.0, 25.0) and r.points[-1] == (0.0, 0.0, 1.5)
    assert math.dist(r.points[2][:2], (80.0, 60.0)) == pytest.approx(0.0, abs=0.1)


@pytest.mark.parametrize(
    ("doc", "says"),
    [
        ("{not json", "not JSON"),
        ({"fileType": "Mission"}, "not a QGroundControl plan"),
        ({"fileType": "Plan"}, "mission: missing"),
        (plan([]), "mission.items: no mission items"),
        (plan([item(16, None, HOME[1], 30.0)]), "mission.items[0]: params[4] (latitude)"),
        (plan([item(16, 91.0, HOME[1], 30.0)]), "params[4] (latitude): must be finite in"),
        (plan([item(17, HOME[0], HOME[1], 30.0)]), "mission.items[0]: navigation command 17"),
        (plan([item(16, HOME[0], HOME[1], 30.0, frame=10)]), "above terrain"),
        (plan([{"type": "ComplexItem", "complexItemType": "survey"}]), "'survey' item"),
        (plan([item(178, p1=7.0), item(16, HOME[0] + 1e-3, HOME[1], 9.0), item(178, p1=9.0)]),
         "DO_CHANGE_SPEED sets [7.0, 9.0]"),
        (plan([item(16, HOME[0] + 1e-3, HOME[1], 9.0)], plannedHomePosition=[1, 2]),
         "plannedHomePosition: expected [latitude, longitude, altitude]"),
        (plan([item(178, p1=5.0)]), "no waypoint to fly to"),
    ],
)  # fmt: skip
def test_a_malformed_plan_gets_one_line_naming_what_is_wrong(
    tmp_path: Path, doc: Any, says: str
) -> None:
    with pytest.raises(RouteFileError) as e:
        read_plan(write(tmp_path, doc))
    message = str(e.value)
    assert says in message and "\n" not in message and "m.plan" in message


def test_a_csv_of_points(tmp_path: Path) -> None:
    p = write(tmp_path, "x, y, z, hold\n0, 0, 2, 1\n0, 0, 20, 0\n300, 40, 20, 5\n", "r.csv")
    r = read_route_file(p)
    assert r.points == ((0, 0, 2), (0, 0, 20), (300, 40, 20)) and r.hold == (1, 0, 5)
    lat, lon = HOME[0], HOME[1]
    g = write(tmp_path, f"lat,lon,alt\n{lat},{lon},{HOME[2] + 2}\n"
                        f"{lat + north(100.0)},{lon},{HOME[2] + 2}\n", "g.csv")  # fmt: skip
    r = read_route_csv(g)
    assert r.points[0] == (0.0, 0.0, 0.0)
    assert r.points[1][1] == pytest.approx(100.0, rel=1e-3) and r.points[1][2] == 0.0
    bad = [
        ("a,b\n1,2\n", "must name x, y, z"),
        ("x,y,z\n0,0,1\n0,0,nan\n", "line 3, z"),
        ("x,y,z\n1,1,1\n", "one point"),
        ("x,y,z,hold\n0,0,1,-2\n0,1,1,0\n", "line 2, hold"),
    ]
    for text, says in bad:
        with pytest.raises(RouteFileError, match=r".*r\.csv: .*" + says.replace("(", ".")):
            read_route_csv(write(tmp_path, text, "r.csv"))
    with pytest.raises(RouteFileError, match=r"a route file is a QGroundControl \.plan or a \.csv"):
        read_route_file(write(tmp_path, "x", "r.txt"))


def test_mission_flies_a_plan_and_refuses_a_bad_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = write(tmp_path, hundred_metres_north())
    common = ["mission", "--runs", "2", "--set", "integrator.dt=0.002", "--plan"]
    assert main([*common, str(good), "--set", "trajectory.speed=4.0"]) == 0
    out = capsys.readouterr().out
    for leg in ("leg1", "leg2", "hold3", "leg3", "flight"):
        assert f"\n{leg} " in out
    bad = write(tmp_path, plan([item(16, "north", HOME[1], 30.0)]), "bad.plan")
    assert main([*common, str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.plan: mission.items[0]: params[4]" in err


def test_from_plan_is_the_file_applied_to_its_base(tmp_path: Path) -> None:
    p = write(tmp_path, hundred_metres_north())
    base = quadrs.Scenario.preset("delivery")
    expected = read_plan(p, start_height=base["initial.position"][2]).apply(base)
    assert quadrs.Scenario.from_plan(p) == expected  # base="delivery" by default
    assert quadrs.Scenario.from_plan(p, base=base) == expected
    slow = quadrs.Scenario.from_plan(p, base="delivery", changes={"trajectory.speed": 2.0})
    assert slow["trajectory.speed"] == 2.0
    assert slow["integrator.duration"] > expected["integrator.duration"]
    toml = tmp_path / "mine.toml"
    toml.write_text('base = "delivery"\n[payload]\nmass = 0.4\n')
    mine = quadrs.Scenario.from_plan(p, base=toml)
    assert mine["payload.mass"] == 0.4 and mine["trajectory.route"] == expected["trajectory.route"]


def test_a_scenario_file_names_its_route_file(tmp_path: Path) -> None:
    """``trajectory.route_file`` in a scenario file (relative to the file) or a mapping: the
    scenario holds the file's points, as from_plan gives them; keys the file sets win."""
    (tmp_path / "routes").mkdir()
    csv = write(tmp_path / "routes", "x, y, z, hold\n0, 0, 2, 1\n0, 0, 20, 0\n300, 40, 20, 5\n",
                "r.csv")  # fmt: skip
    scenario = tmp_path / "s.toml"
    scenario.write_text('base = "delivery"\n[trajectory]\nroute_file = "routes/r.csv"\n')
    s = quadrs.Scenario.from_toml(scenario)
    assert s == quadrs.Scenario.from_plan(csv, base="delivery")
    assert s["trajectory.route"] == [[0, 0, 2], [0, 0, 20], [300, 40, 20]]
    assert s["trajectory.hold"] == [1, 0, 5] and s["initial.position"] == [0, 0, 2]
    assert "route_file" not in s.to_dict()["trajectory"]  # the points, not a path that can change
    assert quadrs.Scenario.from_toml_string(s.to_toml()) == s
    given = quadrs.Scenario.from_dict({
        "base": "delivery",
        "trajectory": {"route_file": str(csv), "hold": [0, 0, 9], "names": ["up", "out", "drop"]},
        "integrator": {"duration": 100.0},
    })  # fmt: skip
    assert given["trajectory.hold"] == [0, 0, 9] and given["integrator.duration"] == 100.0
    assert given["trajectory.names"] == ["up", "out", "drop"]
    for table, says in [
        ({"route_file": "missing.csv"}, r"trajectory\.route_file = 'missing\.csv': .*cannot read"),
        ({"route_file": 3}, r"trajectory\.route_file must name a \.plan or \.csv file, got 3"),
    ]:
        with pytest.raises(ValueError, match=says):
            quadrs.Scenario.from_dict({"base": "delivery", "trajectory": table})
