"""A ``.plan``'s winch and gripper items as PX4 and MAVLink run them (docs/guarantees.md,
quadrs.scenario.plan_payload): a waypoint's hold flown before its items, each DO_WINCH rate
its own lowering's, a retract before the release in its order, a release opening where the
mission reaches it, and PX4's land-and-release delivery flown."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import quadrs
from quadrs.scenario.route_files import read_plan
from tests.engine.test_last_metres import HOME, _item, _plan, fly, lowering

LAT, LON = HOME[0], HOME[1]
TAKEOFF = _item(22, 0, 0, 0, None, None, None, 6.0)
OVER = _item(16, 2.0, 0, 0, None, LAT, LON, 6.0)
#: 3 m north of OVER, and 11 m.
NEAR = _item(16, 0, 0, 0, None, LAT + 3.0 / 111_195, LON, 6.0)
SECOND = _item(16, 2.0, 0, 0, None, LAT + 1e-4, LON, 6.0)
AWAY = _item(16, 0, 0, 0, None, LAT, LON, 7.0)
LAND = _item(21, 0, 0, 0, None, None, None, 0.0)
RELEASE = _item(211, 1, 0)
RETRACT = _item(42600, 1, 6)


def _delay(seconds: float) -> dict[str, Any]:
    return _item(93, seconds)


def _winch(length: float, rate: float | None = None) -> dict[str, Any]:
    return _item(42600, 1, 1, length, rate)


def _flown(tmp_path: Path, items: list[dict[str, Any]], **extra: Any) -> quadrs.Scenario:
    return read_plan(_plan(tmp_path, items), start_height=6.0).apply(lowering(5.0, **extra))


def _release(sc: quadrs.Scenario) -> float:
    return float(fly(sc).metrics.set_index("phase").loc["flight", "release_time"])


def test_a_waypoints_hold_is_flown_before_its_items(tmp_path: Path) -> None:
    """OVER holds 2 s, then lowers 2 m, then a NAV_DELAY of 3 s: PX4 holds at the waypoint
    first, runs the DO_WINCH, then the delay (before: the 2 s hold followed the lowering,
    merged with the delay). The line stays in while the vehicle holds on arrival."""
    sc = _flown(tmp_path, [TAKEOFF, OVER, _winch(2.0), _delay(3.0), AWAY])
    # The take-off and OVER are home at 6 m: the route's first point, then AWAY.
    assert sc["trajectory.arrival_hold"] == [2.0, 0.0] and sc["trajectory.hold"] == [3.0, 0.0]
    names = [g.name for g in sc.route.segments]
    assert names[:4] == ["arrive1", "lower1", "hold1", "leg1"]
    arrive, lower, hold, leg = sc.route.segments[:4]
    assert arrive.start == 0.0 and lower.start == arrive.end == 2.0
    assert hold.start == lower.end and hold.end == hold.start + 3.0 == leg.start
    tr = fly(sc, record_every=10).trace
    held = tr[(tr.index > arrive.start + 0.1) & (tr.index < arrive.end - 0.1)]
    assert held["line_rate"].abs().max() < 1e-9
    assert tr[(tr.index > lower.start) & (tr.index < lower.end)]["line_rate"].max() > 0.4
    # A drop from a waypoint that holds: the hook opens as the hold ends (the mission reaches
    # the release after it), not on arrival.
    drop = _flown(tmp_path, [TAKEOFF, OVER, RELEASE, AWAY])
    (arrive,) = [g for g in drop.route.segments if g.name.startswith("arrive")]
    assert drop["payload.release"] == arrive.end == arrive.start + 2.0
    # A point without items keeps its hold as before (after arrival, named hold).
    plain = _flown(tmp_path, [TAKEOFF, OVER, AWAY])
    assert "arrival_hold" not in plain.to_dict()["trajectory"]
    assert plain["trajectory.hold"] == [2.0, 0.0]


def test_each_winch_rate_is_its_own_lowerings(tmp_path: Path) -> None:
    """Two DO_WINCH items at two points, 0.3 and 0.5 m/s: the line pays out at each (before:
    refused, the engine flying one winch speed); the second relative length on top of the
    first's line still out."""
    sc = _flown(tmp_path, [TAKEOFF, OVER, _winch(2.0, 0.3), SECOND, _winch(1.5, 0.5), AWAY])
    assert sc["payload.winch_speed"] == 0.5
    assert [x for x in sc["trajectory.lower_speed"] if x] == [0.3, 0.5]
    assert [x for x in sc["trajectory.lower"] if x] == [2.0, 3.5]
    flight = fly(sc, record_every=10)
    tr = flight.trace
    for g, rate in zip(sc.route.lowerings, (0.3, 0.5), strict=True):
        paying = tr[(tr.index >= g.start) & (tr.index <= g.end)]["line_rate"]
        assert abs(paying.max() - rate) < 0.01 * rate, (g.name, paying.max())
    # A lowering without a rate flies the base scenario's winch speed (0.5 m/s) beside one.
    mixed = _flown(tmp_path, [TAKEOFF, OVER, _winch(2.0, 0.3), SECOND, _winch(1.5), AWAY])
    assert [x for x in mixed["trajectory.lower_speed"] if x] == [0.3, 0.5]


def test_a_retract_before_the_release_reels_the_parcel_in_first(tmp_path: Path) -> None:
    """Lowered 2 m, reeled back in, released: the hook opens at the hook, in flight, as the
    retract ends (before: the retract was dropped and the release waited for a rest on the
    ground the 2 m line never reached)."""
    sc = _flown(tmp_path, [TAKEOFF, OVER, _winch(2.0), RETRACT, RELEASE, AWAY])
    lower, retract = sc.route.lowerings
    assert retract.payout == 0.0 and retract.start == lower.end
    assert sc["payload.release"] == retract.end
    flight = fly(sc, record_every=10)
    m, tr = flight.metrics.set_index("phase").loc["flight"], flight.trace
    assert abs(m["release_time"] - retract.end) <= sc["integrator.dt"]
    at = tr[tr.index <= m["release_time"]].iloc[-1]
    assert abs(at["line"] - sc["payload.length_min"]) < 0.02, at["line"]
    assert m["touchdown_speed"] > 5.0  # dropped from the hook, about 5 m


def test_a_release_opens_where_the_mission_reaches_it(tmp_path: Path) -> None:
    """Lowered to the ground at OVER, released 3 m on: the hook opens as the mission reaches
    the release (the reference's arrival there), not where the parcel first rested (before:
    at OVER, a waypoint early)."""
    sc = _flown(tmp_path, [TAKEOFF, OVER, _winch(5.5), NEAR, RELEASE, AWAY])
    (lowered,) = sc.route.lowerings
    arrival = next(g for g in sc.route.legs if abs(g.target[1] - 3.0) < 0.01).arrival
    assert sc["payload.release"] == arrival > lowered.end
    assert abs(_release(sc) - arrival) <= sc["integrator.dt"]
    # Lowered at OVER and again at NEAR, released there: the rest at OVER does not open it.
    twice = _flown(tmp_path, [TAKEOFF, OVER, _winch(5.5), RETRACT, NEAR, _winch(5.5), RELEASE,
                              AWAY])  # fmt: skip
    there = next(g for g in twice.route.legs if abs(g.target[1] - 3.0) < 0.01).arrival
    assert twice["payload.release"] == "touchdown"
    assert twice["payload.release_after"] == there
    assert _release(twice) > there


def test_land_and_release_sets_the_parcel_down_and_flies_on(tmp_path: Path) -> None:
    """PX4's land-and-release (NAV_LAND, DO_GRIPPER, NAV_TAKEOFF; before: refused, "after
    landing"): the vehicle descends over the point until the parcel rests on the ground with
    half its 1 m sling slack, the hook opens once it rests, and the vehicle climbs away."""
    sc = _flown(tmp_path, [TAKEOFF, NEAR, LAND, RELEASE, TAKEOFF, AWAY],
                **{"integrator.duration": 60.0})  # fmt: skip
    low = 0.5 * (sc["payload.length_min"] + sc["payload.attachment_offset"])
    assert [p[2] for p in sc["trajectory.route"]].count(low) == 1
    assert sc["payload.release"] == "touchdown"
    flight = fly(sc)
    m = flight.metrics.set_index("phase").loc["flight"]
    assert m["release_time"] > sc["payload.release_after"]
    assert m["touchdown_speed"] < 1.2 and m["touchdown_miss"] < 0.5, m
    assert flight.status == "ok"


def test_the_keys_a_plan_sets_are_checked_naming_them() -> None:
    """``trajectory.lower_speed`` (one per point, at most the winch's top speed),
    ``trajectory.retract`` (one per point) and ``payload.release_after`` (>= 0)."""
    for changes, message in (
        ({"trajectory.lower_speed": [0.6, 0.0]},
         r"trajectory\.lower_speed\[0\] must be 0 \(payload\.winch_speed\) or a pay-out speed "
         r"in \(0, payload\.winch_speed = 0\.5\] m/s, got 0\.6"),
        ({"trajectory.lower_speed": [0.3]},
         r"trajectory\.lower_speed needs one value per route point \(2\), got 1"),
        ({"trajectory.retract": [True]},
         r"trajectory\.retract needs one value per route point \(2\), got 1"),
        ({"payload.release_after": -1.0}, r"payload\.release_after must be >= 0, got -1\.0"),
    ):  # fmt: skip
        with pytest.raises(ValueError, match=message):
            lowering(5.0, **changes)
