"""Routes from the files operators already have: a QGroundControl ``.plan`` mission, or a CSV
of points (docs/delivery.md, "Your own route from a mission file").

A ``.plan`` is JSON; its ``mission.items`` are MAVLink mission items. Their positions become
the scenario's ``trajectory.route``, in the engine's local frame about the plan's
``plannedHomePosition``: x east and y north on the WGS-84 tangent plane at home
(``pymap3d.geodetic2enu``), z the item's altitude above home (what the vehicle holds over the
ground; the tangent plane's own "up" falls below it by d²/2R, 8 cm at 1 km). The flight
starts at home at the base scenario's initial height (the parcel hanging clear of the pad)
and ends over the last point at that height. What each command becomes:

- ``NAV_WAYPOINT`` (16): a point, held ``param1`` s; ``NAV_LOITER_TIME`` (19): likewise.
- ``NAV_TAKEOFF`` (22): straight up to its altitude (over its position if it has one).
- ``NAV_LAND`` (21): over its position at the current altitude, then down to the start
  height; ``NAV_RETURN_TO_LAUNCH`` (20): back over home at the current altitude, then down.
- ``NAV_DELAY`` (93): a hold at the current point.
- ``DO_CHANGE_SPEED`` (178): the cruise speed (``trajectory.speed``); the engine flies one
  speed, so different speeds in one plan are refused.
- ``DO_WINCH`` (42600) action 1 (relative length): the line ``param3`` m is paid out at the
  current point (``trajectory.lower``; ``param4``, a rate in m/s, sets
  ``payload.winch_speed``); action 6 (retract) is what the winch does after the release
  anyway. ``DO_GRIPPER`` (211) action 0 (release) after a lowering opens the hook once the
  parcel rests (``payload.release = "touchdown"``); action 1 (grab) before any release is
  the parcel hooked from the start. Any other winch or gripper action is refused naming
  its item. At a point with a lowering the point's hold follows the lowering.
- Other ``DO_*`` and condition commands (camera, servo, ...) do not move the
  vehicle and are skipped. Any other navigation command (an unlimited loiter, a terrain-
  relative altitude, a survey pattern) is refused naming its item.

A CSV has a header row and one row per point: ``x, y, z`` in metres (the route as it is), or
``lat, lon, alt`` (degrees and metres, converted about the first row as above); an optional
``hold`` column (s) holds at each point.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TypeVar

_S = TypeVar("_S", bound="RoutableScenario")


class RoutableScenario(Protocol):
    """What :meth:`RouteFile.apply` reads of a scenario. A
    :class:`~quadrs.scenario.scenario.Scenario` is one; typed by what is read so that the
    scenario module, which reads route files through this one, is not imported back."""

    def to_dict(self) -> dict[str, Any]: ...
    def override(self: _S, changes: Mapping[str, Any]) -> _S: ...
    def __getitem__(self, key: str) -> Any: ...
    @property
    def route(self) -> Any: ...


__all__ = [
    "RoutableScenario",
    "RouteFile",
    "RouteFileError",
    "read_plan",
    "read_route_csv",
    "read_route_file",
]

Point = tuple[float, float, float]

# MAVLink MAV_CMD values (mavlink common.xml).
WAYPOINT, LOITER_UNLIM, LOITER_TURNS, LOITER_TIME, RTL, LAND, TAKEOFF = 16, 17, 18, 19, 20, 21, 22
DELAY, CHANGE_SPEED = 93, 178
# The winch and the gripper (MAV_CMD_DO_WINCH, MAV_CMD_DO_GRIPPER) and the actions read.
WINCH, GRIPPER = 42600, 211
WINCH_RELATIVE_LENGTH, WINCH_RETRACT = 1, 6
GRIPPER_RELEASE, GRIPPER_GRAB = 0, 1
#: Commands below this navigate; from here on they are conditions and DO_ commands (camera,
#: gripper, servo, region of interest, ...), which do not move the vehicle.
FIRST_NON_NAV = 100
# MAV_FRAME values: altitudes above mean sea level, above home, above terrain.
AMSL_FRAMES, HOME_FRAMES, TERRAIN_FRAMES = (0, 5), (3, 6), (10, 11)
#: Points closer than this (m) are one point: the engine refuses a leg of zero length.
SAME_POINT = 1e-3


class RouteFileError(ValueError):
    """A route file the engine cannot fly, in one line naming the file and the item."""


@dataclass(frozen=True)
class RouteFile:
    """A route read from a file: points in the engine's frame (m; x east, y north, z up from
    home), a hold at each (s), and the cruise speed the file asks for (m/s, or None)."""

    points: tuple[Point, ...]
    hold: tuple[float, ...]
    speed: float | None
    source: str
    #: m of line lowered at each point (all 0 without a winch item), the hook's release
    #: (``"touchdown"`` or None) and the winch's rate (m/s, or None).
    lower: tuple[float, ...] = ()
    release: str | None = None
    winch_speed: float | None = None

    @property
    def length(self) -> float:
        """The route's length along its straight legs (m)."""
        return sum(math.dist(a, b) for a, b in zip(self.points, self.points[1:], strict=False))

    def apply(self, base: _S, changes: Mapping[str, Any] | None = None) -> _S:
        """``base`` flying this route: ``trajectory.route``, ``.hold`` and (if the file sets
        it) ``.speed``, the start at the route's first point, and ``integrator.duration`` just
        long enough for it. The base's leg names go (they named its own legs); a turbulence
        that blew over the base's whole flight blows over the whole route. ``changes``
        (dotted keys, as ``--set`` gives them) are applied with the route and win over it:
        a speed given there sets the route's time."""
        extra = dict(changes or {})
        points = [list(p) for p in self.points]
        route: dict[str, Any] = {
            "trajectory.interpolation": "route",
            "trajectory.route": points,
            "trajectory.hold": list(self.hold),
            "trajectory.names": None,
            "initial.position": points[0],
        }
        if self.speed is not None:
            route["trajectory.speed"] = self.speed
        # The base's own lowerings went with its route.
        route["trajectory.lower"] = list(self.lower) if any(x > 0 for x in self.lower) else None
        if self.release is not None:
            route["payload.release"] = self.release
        if self.winch_speed is not None:
            route["payload.winch_speed"] = self.winch_speed
        route.update(extra)
        data = base.to_dict()
        gust = data.get("gust", {})
        whole = gust.get("start", 0.0) == 0.0 and gust.get("end") == data["integrator"]["duration"]
        try:
            # The route's own time, from the engine's schedule of a flight long enough for it.
            long = base.override({**route, "integrator.duration": 1e5, "gust.end": 1e5})
            legs = long.route.legs if long.route is not None else []
            lowerings = long.route.lowerings if long.route is not None else []
            needed = (sum(g.arrival - g.start for g in legs) + sum(long["trajectory.hold"])
                      + sum(g.end - g.start for g in lowerings))  # fmt: skip
            dt = float(long["integrator.dt"])
            duration = math.ceil(needed / dt - 1e-6) * dt
            route.setdefault("integrator.duration", duration)
            if whole:
                route.setdefault("gust.end", route["integrator.duration"])
            return base.override(route)
        except ValueError as e:
            raise RouteFileError(f"{self.source}: {e}") from None


def read_route_file(path: str | Path, start_height: float = 0.0) -> RouteFile:
    """A ``.plan`` (QGroundControl) or ``.csv`` route, by the file's suffix."""
    p = Path(path)
    if p.suffix.lower() == ".plan":
        return read_plan(p, start_height)
    if p.suffix.lower() == ".csv":
        return read_route_csv(p)
    raise RouteFileError(f"{p}: a route file is a QGroundControl .plan or a .csv of points")


def read_plan(path: str | Path, start_height: float = 0.0) -> RouteFile:
    """The route of a QGroundControl ``.plan`` mission (module docstring): home at
    ``start_height`` m, then the mission's items."""
    p = Path(path)
    try:
        doc = json.loads(p.read_text())
    except OSError as e:
        raise RouteFileError(f"{p}: cannot read it ({e.strerror})") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as e:
        raise RouteFileError(f"{p}: not JSON ({e})") from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise RouteFileError(f'{p}: not a QGroundControl plan (no "fileType": "Plan")')
    mission = doc.get("mission")
    if not isinstance(mission, dict):
        raise RouteFileError(f"{p}: mission: missing (a plan's mission holds its items)")
    home = _lat_lon_alt(mission.get("plannedHomePosition"), f"{p}: mission.plannedHomePosition")
    items = mission.get("items")
    if not isinstance(items, list) or not items:
        raise RouteFileError(f"{p}: mission.items: no mission items")
    plan = _PlanRoute(home, start_height, str(p))
    speeds: set[float] = set()
    hover = mission.get("hoverSpeed")
    for i, item in enumerate(items):
        plan.item(item, f"{p}: mission.items[{i}]", speeds)
    plan.end()
    if len(speeds) > 1:
        raise RouteFileError(
            f"{p}: DO_CHANGE_SPEED sets {sorted(speeds)} m/s: the engine flies one cruise "
            "speed (trajectory.speed); keep one"
        )
    speed = speeds.pop() if speeds else _speed(hover, f"{p}: mission.hoverSpeed")
    return plan.route(speed)


def read_route_csv(path: str | Path) -> RouteFile:
    """The route of a CSV of points (module docstring): ``x, y, z`` (m) or ``lat, lon, alt``
    (degrees, m; about the first row), with an optional ``hold`` (s)."""
    p = Path(path)
    try:
        with p.open(newline="") as f:
            rows = list(csv.DictReader(f, skipinitialspace=True))
    except OSError as e:
        raise RouteFileError(f"{p}: cannot read it ({e.strerror})") from None
    if not rows:
        raise RouteFileError(f"{p}: no points (a header row, then one row per point)")
    columns = {c.strip().lower() for c in rows[0] if c is not None}
    geodetic = {"lat", "lon", "alt"} <= columns
    if not geodetic and not {"x", "y", "z"} <= columns:
        raise RouteFileError(f"{p}: the header must name x, y, z (m) or lat, lon, alt")
    names = ("lat", "lon", "alt") if geodetic else ("x", "y", "z")
    values = []
    for line, row in enumerate(rows, start=2):
        row = {k.strip().lower(): v for k, v in row.items() if k is not None}
        values.append(
            [_number(row.get(n), f"{p}: line {line}, {n}") for n in names]
            + [_number(row.get("hold") or "0", f"{p}: line {line}, hold", minimum=0.0)]
        )
    if geodetic:
        home = tuple(values[0][:3])
        points = [_enu(v[0], v[1], v[2] - home[2], home) for v in values]
    else:
        points = [(v[0], v[1], v[2]) for v in values]
    route = _Builder(str(p))
    for point, v in zip(points, values, strict=True):
        route.to(point, v[3])
    return route.route(None)


# -- internals ----------------------------------------------------------------------------


class _Builder:
    """Points with a hold at each; a point on top of the last one adds its hold to it."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.points: list[Point] = []
        self.hold: list[float] = []
        self.lower: list[float] = []
        self.release: str | None = None
        self.winch_speed: float | None = None

    def to(self, point: Point, hold: float = 0.0) -> None:
        if self.points and math.dist(point, self.points[-1]) < SAME_POINT:
            self.hold[-1] += hold
        else:
            self.points.append(point)
            self.hold.append(hold)
            self.lower.append(0.0)

    def route(self, speed: float | None) -> RouteFile:
        if len(self.points) < 2:
            raise RouteFileError(f"{self.source}: the route goes nowhere (one point)")
        lower = tuple(self.lower) if any(x > 0 for x in self.lower) else ()
        return RouteFile(tuple(self.points), tuple(self.hold), speed, self.source, lower,
                         self.release, self.winch_speed)  # fmt: skip


class _PlanRoute(_Builder):
    def __init__(self, home: Point, start_height: float, source: str) -> None:
        super().__init__(source)
        self.home = home
        self.start_height = start_height
        self.to((0.0, 0.0, start_height))

    @property
    def here(self) -> Point:
        return self.points[-1]

    def item(self, item: Any, where: str, speeds: set[float]) -> None:
        if not isinstance(item, dict):
            raise RouteFileError(f"{where}: not a mission item (a JSON object)")
        if item.get("type") != "SimpleItem":
            kind = item.get("complexItemType", item.get("type"))
            raise RouteFileError(
                f"{where}: a {kind!r} item is not supported: export the pattern as waypoints"
            )
        command = item.get("command")
        params = item.get("params")
        if not isinstance(command, int) or not isinstance(params, list) or len(params) != 7:
            raise RouteFileError(f"{where}: a mission item needs a command and 7 params")
        if command == CHANGE_SPEED:
            speed = _speed(params[1], f"{where}: DO_CHANGE_SPEED params[1]")
            if speed is not None:
                speeds.add(speed)
            return
        if command in (WINCH, GRIPPER):
            self._winch_or_gripper(command, params, where)
            return
        if command >= FIRST_NON_NAV:
            return
        if command == DELAY:
            self.to(self.here, _number(params[0], f"{where}: NAV_DELAY params[0]", 0.0))
            return
        if command == RTL:
            self.to((0.0, 0.0, self.here[2]))
            self.to((0.0, 0.0, self.start_height))
            return
        if command not in (WAYPOINT, LOITER_TIME, LAND, TAKEOFF):
            raise RouteFileError(
                f"{where}: navigation command {command} is not supported (waypoint 16, "
                "loiter-time 19, return 20, land 21, take-off 22, delay 93)"
            )
        x, y = self._horizontal(params, where, optional=command in (TAKEOFF, LAND))
        if command == LAND:
            self.to((x, y, self.here[2]))
            self.to((x, y, self.start_height))
            return
        z = self._altitude(item.get("frame"), params[6], where)
        if command == TAKEOFF:
            self.to((self.here[0], self.here[1], z))
            self.to((x, y, z))
            return
        self.to((x, y, z), _number(params[0], f"{where}: params[0] (hold, s)", 0.0))

    def _winch_or_gripper(self, command: int, params: list[Any], where: str) -> None:
        """A ``DO_WINCH`` or ``DO_GRIPPER`` item (module docstring): a lowering at the current
        point, or the hook's release after one; any other action refused naming the item."""
        action = params[1]
        if command == WINCH:
            if action == WINCH_RETRACT:
                return
            if action != WINCH_RELATIVE_LENGTH:
                raise RouteFileError(
                    f"{where}: DO_WINCH action {action!r} is not supported (1, relative length: "
                    "pay out params[2] m; 6, retract)"
                )
            length = _number(params[2], f"{where}: DO_WINCH params[2] (length, m)", 0.0)
            if length <= 0:
                raise RouteFileError(
                    f"{where}: DO_WINCH params[2] must pay out line (> 0 m), got {length!r}"
                )
            self.lower[-1] += length
            if params[3] not in (None, 0):
                self.winch_speed = _number(params[3], f"{where}: DO_WINCH params[3] (rate, m/s)")
            return
        if action == GRIPPER_GRAB and self.release is None:
            return
        if action != GRIPPER_RELEASE or not any(x > 0 for x in self.lower):
            raise RouteFileError(
                f"{where}: DO_GRIPPER action {action!r} is not supported here (0, release, "
                "after a DO_WINCH lowering; 1, grab, before any release)"
            )
        self.release = "touchdown"

    def _horizontal(self, params: list[Any], where: str, optional: bool) -> tuple[float, float]:
        lat, lon = params[4], params[5]
        if optional and (lat in (None, 0) or lon in (None, 0)):
            return self.here[0], self.here[1]
        lat = _number(lat, f"{where}: params[4] (latitude)", -90.0, 90.0)
        lon = _number(lon, f"{where}: params[5] (longitude)", -180.0, 180.0)
        e, n, _ = _enu(lat, lon, 0.0, self.home)
        return e, n

    def _altitude(self, frame: Any, alt: Any, where: str) -> float:
        a = _number(alt, f"{where}: params[6] (altitude)")
        if frame in HOME_FRAMES:
            return a
        if frame in AMSL_FRAMES:
            return a - self.home[2]
        if frame in TERRAIN_FRAMES:
            raise RouteFileError(
                f"{where}: frame {frame} (altitude above terrain) needs terrain data; "
                "use altitudes above home (frame 3)"
            )
        raise RouteFileError(f"{where}: frame {frame!r} is not a global frame (0, 3, 5, 6)")

    def end(self) -> None:
        if len(self.points) < 2:
            raise RouteFileError(f"{self.source}: mission.items: no waypoint to fly to")


def _enu(lat: float, lon: float, height: float, home: Sequence[float]) -> Point:
    """East and north (m) of (lat, lon) on the tangent plane at home; ``height`` as given."""
    import pymap3d

    e, n, _ = pymap3d.geodetic2enu(lat, lon, home[2], home[0], home[1], home[2])
    return float(e), float(n), float(height)


def _lat_lon_alt(value: Any, where: str) -> Point:
    if not isinstance(value, list) or len(value) != 3:
        raise RouteFileError(f"{where}: expected [latitude, longitude, altitude], got {value!r}")
    return (
        _number(value[0], f"{where}[0] (latitude)", -90.0, 90.0),
        _number(value[1], f"{where}[1] (longitude)", -180.0, 180.0),
        _number(value[2], f"{where}[2] (altitude)"),
    )


def _speed(value: Any, where: str) -> float | None:
    if value is None:
        return None
    v = _number(value, where)
    if not v > 0:
        raise RouteFileError(f"{where}: a speed must be > 0 m/s, got {value!r}")
    return v


def _number(value: Any, where: str, minimum: float = -math.inf, maximum: float = math.inf) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RouteFileError(f"{where}: not a number: {value!r}") from None
    if not (math.isfinite(v) and minimum <= v <= maximum):
        span = f" in [{minimum:g}, {maximum:g}]" if math.isfinite(minimum) else ""
        raise RouteFileError(f"{where}: must be finite{span}, got {value!r}")
    return v
