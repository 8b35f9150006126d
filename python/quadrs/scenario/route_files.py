"""Routes from the files operators already have: a QGroundControl ``.plan`` mission, or a CSV
of points (docs/delivery.md, "Your own route from a mission file").

A ``.plan`` is JSON; its ``mission.items`` are MAVLink mission items. Their positions become
the scenario's ``trajectory.route``, in the engine's local frame about the plan's
``plannedHomePosition``: x east and y north on the WGS-84 tangent plane at home
(``pymap3d.geodetic2enu``), z the item's altitude above home (what the vehicle holds over the
ground; the tangent plane's own "up" falls below it by d²/2R, 8 cm at 1 km). A point more than
MAX_DISTANCE (50 km) from home along the ground is refused: there the tangent plane is off
by more than half a metre and its vertical by 0.45° (at the antipode it folds a 20,000 km
leg into a short one). The flight starts at home at the base scenario's initial height (the
parcel hanging clear of the pad) and ends over the last point at that height. The items are
flown in mission order, ``DO_JUMP`` included; what each command becomes:

- ``NAV_WAYPOINT`` (16): a point, held ``param1`` s; ``NAV_LOITER_TIME`` (19): likewise.
- ``NAV_TAKEOFF`` (22): straight up to its altitude (over its position if it has one: a
  latitude and longitude of null, or NaN, mean "here"; 0 is a position).
- ``NAV_LAND`` (21): over its position (likewise) at the current altitude, then down to the
  start height; ``NAV_RETURN_TO_LAUNCH`` (20): back over home at the current altitude, then down.
- ``NAV_DELAY`` (93): a hold at the current point.
- ``DO_JUMP`` (177): back (or on) to the item whose sequence number is ``param1``
  (``doJumpId``; else its index + 1, home being 0), ``param2`` times, as the autopilot flies
  it (PX4 counts each jump over the whole mission); one that repeats forever is refused.
- ``DO_CHANGE_SPEED`` (178): speed type ``param1`` 0 (airspeed) or 1 (ground speed) sets the
  cruise speed (``trajectory.speed``; a multicopter flies both as its horizontal speed), -1 is
  no change, -2 the plan's default (``hoverSpeed``); the engine flies one speed, so different
  speeds in one plan are refused, as is a climb (2) or descent (3) speed, which the engine
  cannot fly apart from the cruise speed.
- ``DO_WINCH`` (42600) action 1 (relative length): the line ``param3`` m is paid out at the
  current point (``trajectory.lower``; on top of the line still out) at its own rate
  ``param4`` (m/s, ``trajectory.lower_speed``; the winch's top speed ``payload.winch_speed``
  the fastest rate, or the base scenario's where a lowering has none); action 4 (deliver:
  "drop, slow down, touch down, reel up, lock") the same lowering with the winch's final
  approach, which the scenario must have (``payload.approach_height``,
  ``payload.approach_speed``); action 6 (retract) before the release reels the parcel back
  in, in its order (``trajectory.retract``); after the release it is what the winch does
  anyway.
  ``DO_GRIPPER`` (211) action 0 (release) opens the hook where the mission reaches it: at the
  point of a lowering, once the parcel rests (``payload.release = "touchdown"``, read from the
  lowering's start on: ``payload.release_after``); anywhere else where the parcel stands, at
  the time the mission reaches the item (``payload.release`` that time: the reference's
  arrival at the point, after the point's lowering and retract): in flight, a drop; after a
  ``NAV_LAND`` (PX4's land-and-release) the landing sets the parcel down (the vehicle over
  its point at half the reeled-in line's hang above the ground, the line slack) and the hook
  opens once it rests; a ``NAV_TAKEOFF`` flies on. Action 1 (grab) before any release is the
  parcel hooked from the start.
  A plan decides the hook: without a ``DO_GRIPPER`` release it never opens (the base
  scenario's ``payload.release`` is dropped). A lowering before take-off or after landing, a
  release before take-off, is refused (it would be flown at the pad), as is any other winch or
  gripper action, naming its item (quadrs.scenario.plan_payload). At a point with payload
  items the holds before them (the waypoint's ``param1``, a ``NAV_DELAY``) are flown on
  arrival, before the items (``trajectory.arrival_hold``), as PX4 holds at a waypoint before
  it runs the items that follow; a ``NAV_DELAY`` after them holds after them
  (``trajectory.hold``).
- Commands that neither move the vehicle nor act on its payload (camera, gimbal, region of
  interest, video, ``CONDITION_DELAY``/``DISTANCE``/``YAW``, ``DO_LAND_START``): not flown,
  named in a warning.
- Everything else is refused naming its item: ``DO_SET_HOME`` (it would move home, and the
  altitudes above it, mid-flight), ``DO_REPOSITION``, servos and relays (they may release the
  payload), an unlimited loiter, a terrain-relative altitude, a survey pattern, any command
  quadrs does not know. docs/guarantees.md lists the same.

A CSV has a header row and one row per point: ``x, y, z`` in metres (the route as it is), or
``lat, lon, alt`` (degrees and metres, converted about the first row as above); an optional
``hold`` column (s) holds at each point.

Every file is read as quadrs reads every input file (quadrs.io.files.read_input_text): a
regular file of at most MAX_BYTES, UTF-8 (a byte-order mark is dropped).
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import io
import json
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TypeVar

from quadrs.scenario.plan_order import flown_order, item_command, whole_number
from quadrs.scenario.plan_payload import (
    PlanPayload,
    RouteFileError,
    _number,
    needs_a_final_approach,
    reached,
    set_down_height,
    winch_speeds,
)
from quadrs.scenario.route_timing import hold_time, lowering_time, time_bound

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
    "RouteFileWarning",
    "read_plan",
    "read_route_csv",
    "read_route_file",
]

Point = tuple[float, float, float]

# MAVLink MAV_CMD values (mavlink common.xml).
WAYPOINT, LOITER_UNLIM, LOITER_TURNS, LOITER_TIME, RTL, LAND, TAKEOFF = 16, 17, 18, 19, 20, 21, 22
DELAY, JUMP, CHANGE_SPEED, SET_HOME, REPOSITION = 93, 177, 178, 179, 192
# The winch and the gripper (MAV_CMD_DO_WINCH, MAV_CMD_DO_GRIPPER): quadrs.scenario.plan_payload.
WINCH, GRIPPER = 42600, 211
#: Commands below this navigate; from here on they are conditions and DO_ commands.
FIRST_NON_NAV = 100
#: Commands that neither move the vehicle nor act on its payload: not flown, named in a
#: warning (camera, gimbal, region of interest, video; conditions on the DO_ commands that
#: follow; the landing sequence's marker).
NOT_FLOWN = {
    112: "CONDITION_DELAY", 114: "CONDITION_DISTANCE", 115: "CONDITION_YAW",
    189: "DO_LAND_START", 195: "DO_SET_ROI_LOCATION", 196: "DO_SET_ROI_WPNEXT_OFFSET",
    197: "DO_SET_ROI_NONE", 200: "DO_CONTROL_VIDEO", 201: "DO_SET_ROI",
    202: "DO_DIGICAM_CONFIGURE", 203: "DO_DIGICAM_CONTROL", 204: "DO_MOUNT_CONFIGURE",
    205: "DO_MOUNT_CONTROL", 206: "DO_SET_CAM_TRIGG_DIST", 214: "DO_SET_CAM_TRIGG_INTERVAL",
    530: "SET_CAMERA_MODE", 531: "SET_CAMERA_ZOOM", 532: "SET_CAMERA_FOCUS",
    1000: "DO_GIMBAL_MANAGER_PITCHYAW", 2000: "IMAGE_START_CAPTURE",
    2001: "IMAGE_STOP_CAPTURE", 2500: "VIDEO_START_CAPTURE", 2501: "VIDEO_STOP_CAPTURE",
}  # fmt: skip
#: Commands refused with a reason of their own (any other unknown command is refused too).
REFUSED = {
    LOITER_UNLIM: "NAV_LOITER_UNLIM loiters forever: the flight would never end",
    LOITER_TURNS: "NAV_LOITER_TURNS circles a point: export the circle as waypoints",
    113: "CONDITION_CHANGE_ALT changes the altitude between waypoints: give it as a waypoint",
    SET_HOME: "DO_SET_HOME moves home (where a return goes, and the altitudes above it) "
    "mid-flight: not flown; plan it with one home",
    REPOSITION: "DO_REPOSITION sends the vehicle to a position outside the mission's legs: "
    "give it as a waypoint",
    181: "DO_SET_RELAY may release or move the payload, which quadrs cannot tell",
    182: "DO_REPEAT_RELAY may release or move the payload, which quadrs cannot tell",
    183: "DO_SET_SERVO may release or move the payload, which quadrs cannot tell",
    184: "DO_REPEAT_SERVO may release or move the payload, which quadrs cannot tell",
}
# MAV_FRAME values: altitudes above mean sea level, above home, above terrain.
AMSL_FRAMES, HOME_FRAMES, TERRAIN_FRAMES = (0, 5), (3, 6), (10, 11)
#: Points closer than this (m) are one point: the engine refuses a leg of zero length.
SAME_POINT = 1e-3
#: Farthest a point may be from home along the ground (m): beyond it the tangent plane's
#: distances are off by more than 0.5 m and its vertical by more than 0.45 degrees.
MAX_DISTANCE = 50e3
#: Mean Earth radius (m), for the distance along the ground that MAX_DISTANCE bounds.
EARTH_RADIUS = 6371008.8
#: Largest route file read (bytes).
MAX_BYTES = 16 << 20


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
    #: Whether the file decides the hook (a ``.plan``: ``release`` None then means never).
    decides_release: bool = False
    #: Scenario key -> the file's items that set it (a refused value names them).
    origins: tuple[tuple[str, str], ...] = ()
    #: The point the mission reaches the release at (``release``: "touchdown", "drop" where
    #: it stands, "land" after a landing); the DO_WINCH deliver items (lowerings with the
    #: winch's final approach, which the scenario needs).
    drop_point: int | None = None
    delivers: tuple[str, ...] = ()
    #: Per point: a lowering's own rate (m/s, None: the winch's), a retract after it; whether
    #: a lowering at an earlier point came before the release's (its rest must not open it).
    lower_rate: tuple[float | None, ...] = ()
    retract: tuple[bool, ...] = ()
    lowered_before: bool = False
    #: s, per point: the hold on arrival, before the point's items (a waypoint's hold, which
    #: PX4 flies before them); ``hold`` is then the hold after them (empty: none before).
    arrival_hold: tuple[float, ...] = ()

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
            "trajectory.arrival_hold": list(self.arrival_hold) if any(self.arrival_hold) else None,
            "trajectory.names": None,
            "initial.position": points[0],
        }
        if self.speed is not None:
            route["trajectory.speed"] = self.speed
        # The base's own lowerings went with its route.
        route["trajectory.lower"] = list(self.lower) if any(x > 0 for x in self.lower) else None
        route["trajectory.retract"] = list(self.retract) if any(self.retract) else None
        if self.release is None and self.decides_release:
            route["payload.release"] = None  # the hook never opens
        elif self.release in ("touchdown", "land"):
            route["payload.release"] = "touchdown"
        if self.release == "land":
            points[self.drop_point or 0][2] = set_down_height(base.to_dict(), extra)
        # A drop's time, and where a rest opens the hook from, come from the schedule below.
        given = {**base.to_dict().get("payload", {}),
                 **{k.removeprefix("payload."): v for k, v in extra.items()}}  # fmt: skip
        needs_a_final_approach(self.source, self.delivers, given)
        route.update(winch_speeds(self.lower, self.lower_rate, self.winch_speed, given))
        route.update(extra)
        data = base.to_dict()
        gust = data.get("gust", {})
        whole = gust.get("start", 0.0) == 0.0 and gust.get("end") == data["integrator"]["duration"]
        try:
            # The route's own time, from the engine's schedule of a flight surely long enough
            # for it (or of the duration given, which must then cover it).
            probe = float(extra.get("integrator.duration", self._time_bound(base, route)))
            # The base's gust window is kept as it is (a window past the flight is allowed),
            # except one over the whole flight, which follows the duration.
            timing = {"gust.end": probe} if whole else {}
            long = base.override({**route, "integrator.duration": probe, **timing})
            legs = long.route.legs if long.route is not None else []
            lowerings = long.route.lowerings if long.route is not None else []
            needed = (sum(g.arrival - g.start for g in legs) + hold_time(long.to_dict())
                      + sum(g.end - g.start for g in lowerings))  # fmt: skip
            dt = float(long["integrator.dt"])
            at = self.drop_point or 0
            # The mission reaches the point's items after its hold on arrival.
            held = self.arrival_hold[at] if at < len(self.arrival_hold) else 0.0
            arrival = (legs[at - 1].arrival if at > 0 else 0.0) + held
            if self.release == "drop" and "payload.release" not in extra:
                # The hook opens where the mission reaches the item (PX4 runs it there): the
                # reference's arrival at the point, after its lowering and retract; the
                # vehicle's lag behind it is the flight's.
                route["payload.release"] = reached(arrival, lowerings)
            elif self.release == "land" or (self.release == "touchdown" and self.lowered_before):
                # A rest before the mission reaches the point does not open it.
                route.setdefault("payload.release_after", arrival)
            duration = math.ceil(needed / dt - 1e-6) * dt
            route.setdefault("integrator.duration", duration)
            if whole:
                route.setdefault("gust.end", route["integrator.duration"])
            return base.override(route)
        except ValueError as e:
            raise RouteFileError(f"{self.source}: {self._blame(base, route, e)}") from None

    def _blame(self, base: RoutableScenario, route: Mapping[str, Any], e: ValueError) -> str:
        """The engine's refusal ``e`` of the route, led by what in the file caused it: the
        items that set the refused key, or the lowerings whose time made the flight too long
        for its step (a winch far too slow, or so fast that it cannot stop in time)."""
        from quadrs.scenario.plan_payload import origin_of

        key = getattr(e, "key", None)
        items = origin_of(self.origins, key)
        if items is None and key in ("integrator.dt", "integrator.duration"):
            items = self._lowering_time(base, route)
        return f"{items}: {e}" if items else str(e)

    def _lowering_time(self, base: RoutableScenario, route: Mapping[str, Any]) -> str | None:
        """What the lowerings take, when they take most of the route's time (or None)."""
        from quadrs.scenario.plan_payload import origin_of

        lower = [float(x) for x in route.get("trajectory.lower") or () if float(x) > 0]
        if not lower:
            return None
        v = float(route.get("payload.winch_speed", base["payload.winch_speed"]))
        a = float(route.get("payload.winch_acceleration", base["payload.winch_acceleration"]))
        t = sum(lowering_time(p, v, a) for p in lower)
        if not t > 0.5 * self._time_bound(base, route):
            return None
        rate = origin_of(self.origins, "payload.winch_speed")
        return (f"{rate + ': ' if rate else ''}the lowerings ({sum(lower):g} m of line) at "
                f"payload.winch_speed = {v:g} m/s and payload.winch_acceleration = {a:g} "
                f"m/s^2 take {t:.4g} s (each P / v + 2 v / a): not a winch that can fly this "
                "route")  # fmt: skip

    def _time_bound(self, base: RoutableScenario, route: Mapping[str, Any]) -> float:
        """Seconds the route surely takes less than (``route_timing.time_bound``: its legs,
        holds, lowerings and retracts at their bounds, and a margin) on ``base`` with the
        route's dotted keys; 1e5 where its values are not numbers (the scenario refuses the
        route below, naming the key)."""
        data = copy.deepcopy(base.to_dict())
        for key, value in route.items():
            *tables, last = key.split(".")
            node = data
            for table in tables:
                node = node.setdefault(table, {})
            node[last] = value
        bound = time_bound(data)
        return 1e5 if bound is None else bound


def read_route_file(path: str | Path, start_height: float = 0.0) -> RouteFile:
    """A ``.plan`` (QGroundControl) or ``.csv`` route, by the file's suffix."""
    p = Path(path)
    if p.suffix.lower() == ".plan":
        return read_plan(p, start_height)
    if p.suffix.lower() == ".csv":
        return read_route_csv(p)
    raise RouteFileError(f"{p}: a route file is a QGroundControl .plan or a .csv of points")


def _read_text(p: Path) -> str:
    from quadrs.scenario.input_files import InputFileError, read_input_text

    try:
        return read_input_text(p, "route file", MAX_BYTES)
    except InputFileError as e:
        raise RouteFileError(str(e)) from None
    except OSError as e:
        raise RouteFileError(f"{p}: cannot read it ({e.strerror or e})") from None


def read_plan(path: str | Path, start_height: float = 0.0) -> RouteFile:
    """The route of a QGroundControl ``.plan`` mission (module docstring): home at
    ``start_height`` m, then the mission's items in the order they are flown."""
    p = Path(path)
    text = _read_text(p)
    try:
        doc = json.loads(text)
    except ValueError as e:  # JSONDecodeError, or an integer of more digits than Python reads
        raise RouteFileError(f"{p}: not JSON ({e})") from None
    except RecursionError:
        raise RouteFileError(f"{p}: not a QGroundControl plan (nested too deeply)") from None
    if not isinstance(doc, dict) or doc.get("fileType") != "Plan":
        raise RouteFileError(f'{p}: not a QGroundControl plan (no "fileType": "Plan")')
    mission = doc.get("mission")
    if not isinstance(mission, dict):
        raise RouteFileError(f"{p}: mission: missing (a plan's mission holds its items)")
    home = _lat_lon_alt(mission.get("plannedHomePosition"), f"{p}: mission.plannedHomePosition")
    items = mission.get("items")
    if not isinstance(items, list) or not items:
        raise RouteFileError(f"{p}: mission.items: no mission items")
    hover = _speed(mission.get("hoverSpeed"), f"{p}: mission.hoverSpeed")
    plan = _PlanRoute(home, start_height, str(p), hover)
    commands = [item_command(item, f"{p}: mission.items[{i}]") for i, item in enumerate(items)]
    for i in flown_order(items, commands, f"{p}: mission.items"):
        plan.item(commands[i], items[i]["params"], items[i], f"{p}: mission.items[{i}]")
    plan.end()
    route = plan.route(plan.cruise_speed())
    if plan.not_flown:
        warnings.warn(f"{p}: not flown (they do not move the vehicle): "
                      + ", ".join(plan.not_flown), RouteFileWarning, stacklevel=2)  # fmt: skip
    return route


def read_route_csv(path: str | Path) -> RouteFile:
    """The route of a CSV of points (module docstring): ``x, y, z`` (m) or ``lat, lon, alt``
    (degrees, m; about the first row), with an optional ``hold`` (s)."""
    p = Path(path)
    reader = csv.reader(io.StringIO(_read_text(p), newline=""), skipinitialspace=True)
    try:
        table = [row for row in reader if any(cell.strip() for cell in row)]
    except csv.Error as e:  # a cell beyond csv's field limit (128 KiB), a NUL
        raise RouteFileError(f"{p}: line {reader.line_num}: not CSV ({e})") from None
    if len(table) < 2:
        raise RouteFileError(f"{p}: no points (a header row, then one row per point)")
    header = [c.strip().lower() for c in table[0]]
    columns = set(header)
    geodetic = {"lat", "lon", "alt"} <= columns
    if not geodetic and not {"x", "y", "z"} <= columns:
        raise RouteFileError(f"{p}: the header must name x, y, z (m) or lat, lon, alt")
    names = ("lat", "lon", "alt") if geodetic else ("x", "y", "z")
    ranges = {"lat": (-90.0, 90.0), "lon": (-180.0, 180.0)}
    values = []
    for line, cells in enumerate(table[1:], start=2):
        row = dict(zip(header, cells, strict=False))
        values.append(
            [_number(row.get(n), f"{p}: line {line}, {n}", *ranges.get(n, ())) for n in names]
            + [_number(row.get("hold") or "0", f"{p}: line {line}, hold", minimum=0.0)]
        )
    if geodetic:
        home = tuple(values[0][:3])
        points = [_enu(v[0], v[1], v[2] - home[2], home, f"{p}: line {line}")
                  for line, v in enumerate(values, start=2)]  # fmt: skip
    else:
        points = [(v[0], v[1], v[2]) for v in values]
    route = _Builder(str(p))
    for point, v in zip(points, values, strict=True):
        route.to(point, v[3])
    return route.route(None)


class RouteFileWarning(UserWarning):
    """Mission items a route file holds that are not flown (they do not move the vehicle)."""


# -- internals ----------------------------------------------------------------------------


class _Builder:
    """Points with a hold at each; a point on top of the last one adds its hold to it. A hold
    before the point's first payload item is its hold on arrival (:meth:`items_here`)."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.points: list[Point] = []
        self.hold: list[float] = []
        self.arrival_hold: list[float] = []
        #: Per point: whether a payload item has been flown there (later holds follow it).
        self.itemised: list[bool] = []
        self.lower: list[float] = []
        self.lower_rate: list[float | None] = []
        self.retract: list[bool] = []

    def to(self, point: Point, hold: float = 0.0) -> None:
        if self.points and math.dist(point, self.points[-1]) < SAME_POINT:
            self.hold[-1] += hold
        else:
            self.points.append(point)
            self.hold.append(hold)
            self.arrival_hold.append(0.0)
            self.itemised.append(False)
            self.lower.append(0.0)
            self.lower_rate.append(None)
            self.retract.append(False)

    def items_here(self) -> None:
        """A payload item at the current point: the point's hold so far was flown on arrival,
        before it (PX4 holds at a waypoint, then runs the items that follow it)."""
        if not self.itemised[-1]:
            self.itemised[-1] = True
            self.arrival_hold[-1], self.hold[-1] = self.hold[-1], 0.0

    def route(self, speed: float | None) -> RouteFile:
        if len(self.points) < 2:
            raise RouteFileError(f"{self.source}: the route goes nowhere (one point)")
        lower = tuple(self.lower) if any(x > 0 for x in self.lower) else ()
        return RouteFile(tuple(self.points), tuple(self.hold), speed, self.source, lower,
                         arrival_hold=tuple(self.arrival_hold))  # fmt: skip


#: What flying one mission item does to the route: (route, params, item, where).
ItemHandler = Callable[["_PlanRoute", list[Any], dict[str, Any], str], None]


class _PlanRoute(_Builder):
    """A plan's route, built item by item in the order they are flown (:data:`HANDLERS`)."""

    def __init__(self, home: Point, start_height: float, source: str,
                 default_speed: float | None) -> None:  # fmt: skip
        super().__init__(source)
        self.home = home
        self.start_height = start_height
        self.default_speed = default_speed
        #: The cruise speeds DO_CHANGE_SPEED sets (None: the default).
        self.speeds: dict[float | None, str] = {}
        self.not_flown: list[str] = []
        self.payload = PlanPayload()
        #: Off the pad (after a take-off or a waypoint, until a landing); landed since, and
        #: the point of the last landing.
        self.airborne = self.landed = False
        self.landed_at: int | None = None
        self.to((0.0, 0.0, start_height))

    def route(self, speed: float | None) -> RouteFile:
        """The route with the payload's items: the plan decides the hook (module docstring)."""
        route = super().route(speed)
        p = self.payload
        rate = p.winch_speed()
        origins = tuple((k, ", ".join(v)) for k, v in p.origins.items())
        return dataclasses.replace(route, release=p.release, winch_speed=rate,
                                   decides_release=True, origins=origins,
                                   drop_point=p.drop_point, delivers=tuple(p.delivers),
                                   lower_rate=tuple(self.lower_rate),
                                   retract=tuple(self.retract),
                                   lowered_before=p.lowered_before)  # fmt: skip

    @property
    def here(self) -> Point:
        return self.points[-1]

    def item(self, command: int, params: list[Any], item: dict[str, Any], where: str) -> None:
        handler = HANDLERS.get(command)
        if handler is not None:
            handler(self, params, item, where)
        elif command in NOT_FLOWN:
            self.not_flown.append(f"{where.rsplit(': ', 1)[-1]} {NOT_FLOWN[command]}")
        else:
            kind = "navigation command" if command < FIRST_NON_NAV else "command"
            why = REFUSED.get(command, "quadrs flies waypoint 16, loiter-time 19, return 20, "
                              "land 21, take-off 22, delay 93, jump 177, change-speed 178, "
                              "gripper 211 and winch 42600, "
                              "and ignores commands that do not move the vehicle "
                              "(docs/guarantees.md)")  # fmt: skip
            raise RouteFileError(f"{where}: {kind} {command} is not supported: {why}")

    def cruise_speed(self) -> float | None:
        """The one cruise speed of the plan: DO_CHANGE_SPEED's, or the plan's default."""
        speeds = {self.default_speed if v is None else v: w for v, w in self.speeds.items()}
        if len(speeds) > 1:
            known = sorted(v for v in speeds if v is not None)
            default = " and the base scenario's (-2: the default)" if None in speeds else ""
            raise RouteFileError(
                f"{self.source}: DO_CHANGE_SPEED sets {known} m/s{default} "
                f"({', '.join(speeds.values())}): the engine flies one cruise speed "
                "(trajectory.speed); keep one"
            )
        return next(iter(speeds)) if speeds else self.default_speed

    def horizontal(self, params: list[Any], where: str, optional: bool) -> tuple[float, float]:
        lat, lon = params[4], params[5]
        absent = [v is None or (isinstance(v, float) and math.isnan(v)) for v in (lat, lon)]
        if optional and all(absent):
            return self.here[0], self.here[1]
        if optional and any(absent):
            raise RouteFileError(
                f"{where}: params[4] and params[5] (latitude, longitude): give both or neither "
                f"(null: here), got {lat!r}, {lon!r}"
            )
        lat = _number(lat, f"{where}: params[4] (latitude)", -90.0, 90.0)
        lon = _number(lon, f"{where}: params[5] (longitude)", -180.0, 180.0)
        e, n, _ = _enu(lat, lon, 0.0, self.home, where)
        return e, n

    def altitude(self, frame: Any, alt: Any, where: str) -> float:
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


def _waypoint(r: _PlanRoute, params: list[Any], item: dict[str, Any], where: str) -> None:
    x, y = r.horizontal(params, where, optional=False)
    z = r.altitude(item.get("frame"), params[6], where)
    r.to((x, y, z), _number(params[0], f"{where}: params[0] (hold, s)", 0.0))
    r.airborne = True


def _takeoff(r: _PlanRoute, params: list[Any], item: dict[str, Any], where: str) -> None:
    x, y = r.horizontal(params, where, optional=True)
    z = r.altitude(item.get("frame"), params[6], where)
    r.to((r.here[0], r.here[1], z))
    r.to((x, y, z))
    r.airborne = True


def _land(r: _PlanRoute, params: list[Any], item: dict[str, Any], where: str) -> None:
    x, y = r.horizontal(params, where, optional=True)
    r.to((x, y, r.here[2]))
    r.to((x, y, r.start_height))
    r.airborne, r.landed = False, True
    r.landed_at = len(r.points) - 1


def _return(r: _PlanRoute, params: list[Any], item: dict[str, Any], where: str) -> None:
    r.to((0.0, 0.0, r.here[2]))
    r.to((0.0, 0.0, r.start_height))
    r.airborne, r.landed = False, True


def _delay(r: _PlanRoute, params: list[Any], item: dict[str, Any], where: str) -> None:
    r.to(r.here, _number(params[0], f"{where}: NAV_DELAY params[0]", 0.0))


#: DO_CHANGE_SPEED's speed types (param1) and what the engine does with each.
SPEED_TYPES = {0: "airspeed", 1: "ground speed", 2: "climb speed", 3: "descent speed"}


def _change_speed(r: _PlanRoute, params: list[Any], item: dict[str, Any], where: str) -> None:
    here = f"{where}: DO_CHANGE_SPEED"
    kind = whole_number(0 if params[0] is None else params[0], f"{here} params[0] (speed type)", 0)
    if kind not in SPEED_TYPES:
        raise RouteFileError(f"{here} params[0] (speed type) must be 0 (airspeed), 1 (ground "
                             f"speed), 2 (climb) or 3 (descent), got {params[0]!r}")  # fmt: skip
    value = params[1]
    if value is None or _number(value, f"{here} params[1] (speed)") == -1:
        return  # no change
    if kind >= 2:
        raise RouteFileError(
            f"{here} sets a {SPEED_TYPES[kind]} (params[0] = {kind}): the engine flies every "
            "leg at one speed (trajectory.speed), not a vertical speed apart; remove the item"
        )
    label = where.rsplit(": ", 1)[-1]
    if _number(value, f"{here} params[1] (speed)") == -2:  # back to the default
        r.speeds.setdefault(None, label)
        return
    speed = _speed(value, f"{here} params[1]")
    r.speeds.setdefault(speed, label)


#: What each flown command does (module docstring). A command absent here is ignored with a
#: warning (NOT_FLOWN) or refused, naming its item.
HANDLERS: dict[int, ItemHandler] = {
    WAYPOINT: _waypoint,
    LOITER_TIME: _waypoint,
    TAKEOFF: _takeoff,
    LAND: _land,
    RTL: _return,
    DELAY: _delay,
    CHANGE_SPEED: _change_speed,
    WINCH: lambda r, params, item, where: r.payload.item(r, WINCH, params, where),
    GRIPPER: lambda r, params, item, where: r.payload.item(r, GRIPPER, params, where),
}


def _enu(lat: float, lon: float, height: float, home: Sequence[float], where: str) -> Point:
    """East and north (m) of (lat, lon) on the tangent plane at home; ``height`` as given.
    RouteFileError naming ``where`` if the point is farther than MAX_DISTANCE from home."""
    import pymap3d

    p1, p2 = math.radians(home[0]), math.radians(lat)
    dlon = math.radians(lon - home[1])
    h = math.sin((p2 - p1) / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dlon / 2) ** 2
    ground = 2 * EARTH_RADIUS * math.asin(min(1.0, math.sqrt(h)))
    if ground > MAX_DISTANCE:
        raise RouteFileError(
            f"{where}: ({lat:g}, {lon:g}) is {ground / 1e3:.4g} km from home "
            f"({home[0]:g}, {home[1]:g}): beyond {MAX_DISTANCE / 1e3:g} km the local tangent "
            "plane the route is flown on is wrong; split the mission"
        )
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
