"""A ``.plan``'s winch and gripper items (``DO_WINCH`` 42600, ``DO_GRIPPER`` 211) as the
route's lowerings, the hook's release and the winch's rate (quadrs.scenario.route_files).

A plan that holds them says what the payload does, so it decides the hook: it opens only
at a ``DO_GRIPPER`` release, never by the base scenario's ``payload.release``, and where the
mission reaches the item (as PX4 runs it): on the ground once the parcel rests, where it was
lowered at the item's point; else where it stands, at the time the mission reaches the item
(a drop, in flight). A ``DO_WINCH`` retract before the release reels the parcel in, in its
order. A release after a landing (``NAV_LAND``, PX4's land-and-release delivery) sets the
parcel down on the ground below the vehicle and opens there. Each ``DO_WINCH`` rate is its own
lowering's (``trajectory.lower_speed``; the winch's top speed the fastest of them). A lowering
or a release before take-off, or a lowering after landing, would be flown at the pad (the
parcel let go before lift-off): refused, naming the item. Each lowering and rate remembers its
item, so a value the engine refuses is named by the plan's item.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any, Protocol

from quadrs.scenario.keys import dotted_value

__all__ = ["PlanPayload", "RouteFileError"]


class RouteFileError(ValueError):
    """A route file the engine cannot fly, in one line naming the file and the item."""


# MAV_CMD_DO_WINCH, MAV_CMD_DO_GRIPPER and the actions read.
WINCH, GRIPPER = 42600, 211
WINCH_RELATIVE_LENGTH, WINCH_DELIVER, WINCH_RETRACT = 1, 4, 6
GRIPPER_RELEASE, GRIPPER_GRAB = 0, 1


class _Route(Protocol):
    """What the payload items read and change of the route being built."""

    source: str
    points: list[tuple[float, float, float]]
    lower: list[float]
    #: Per point: the lowering's rate (m/s, None: the winch's) and whether the line is reeled
    #: in after it (a retract before the release).
    lower_rate: list[float | None]
    retract: list[bool]
    #: Whether the vehicle is off the pad (after a take-off or waypoint, before a landing),
    #: and whether it has landed since.
    airborne: bool
    landed: bool
    landed_at: int | None

    def to(self, point: tuple[float, float, float], hold: float = 0.0) -> None: ...

    def items_here(self) -> None: ...


class PlanPayload:
    """The payload items of one plan, in the order they are flown."""

    def __init__(self) -> None:
        #: "touchdown" (at the point of a lowering, once the parcel rests), "drop" (where it
        #: stands: in flight, or on a line lowered at an earlier point), "land" (after a
        #: landing: set down below the vehicle) or None (never); the point the mission
        #: reaches it at.
        self.release: str | None = None
        self.drop_point: int | None = None
        #: The point whose lowering the line is still out from (None: reeled in), and whether
        #: a lowering came before it at another point (whose rest must not open the hook).
        self.lowered_at: int | None = None
        self.lowered_before = False
        #: The DO_WINCH deliver items (action 4): lowerings with the winch's final approach.
        self.delivers: list[str] = []
        #: The rates DO_WINCH items set (None: no rate, the base scenario's) -> their items.
        self.rates: dict[float | None, list[str]] = {}
        #: Scenario key -> the plan's items that set it.
        self.origins: dict[str, list[str]] = {}
        self.seen = False

    def item(self, route: _Route, command: int, params: list[Any], where: str) -> None:
        """A ``DO_WINCH`` or ``DO_GRIPPER`` item: a lowering at the current point, the hook's
        release after one, or refused naming the item."""
        self.seen = True
        action = params[1]
        label = where.rsplit(": ", 1)[-1]
        here = len(route.lower) - 1
        if command == WINCH:
            if action == WINCH_RETRACT:
                if self.lowered_at is not None and self.release is None:
                    # Before the release: the parcel reeled back in, in the plan's order (after
                    # it, what the winch does anyway).
                    route.items_here()
                    route.retract[here] = True
                    self.lowered_at = None
                return
            if action not in (WINCH_RELATIVE_LENGTH, WINCH_DELIVER):
                raise RouteFileError(
                    f"{where}: DO_WINCH action {action!r} is not supported (1, relative length: "
                    "pay out params[2] m; 4, deliver: the same with the winch's final "
                    "approach; 6, retract)"
                )
            if action == WINCH_DELIVER:
                self.delivers.append(label)
            _on_the_pad(route, where, "DO_WINCH lowers the parcel")
            route.items_here()
            length = _number(params[2], f"{where}: DO_WINCH params[2] (length, m)", 0.0)
            if length <= 0:
                raise RouteFileError(
                    f"{where}: DO_WINCH params[2] must pay out line (> 0 m), got {length!r}"
                )
            if route.retract[here]:
                raise RouteFileError(
                    f"{where}: DO_WINCH lowers again after a retract at the same point: the "
                    "engine flies one lowering and one retract per point; add a waypoint"
                )
            if self.lowered_at is not None and self.lowered_at != here and self.release is None:
                # A relative length: on top of the line still out from an earlier point.
                route.lower[here] = route.lower[self.lowered_at]
            route.lower[here] += length
            at = f"trajectory.lower[{here}]"
            self.origins.setdefault(at, []).append(f"{label} DO_WINCH params[2] (length, m)")
            rate = None
            if params[3] not in (None, 0):
                rate = _number(params[3], f"{where}: DO_WINCH params[3] (rate, m/s)")
            self.rates.setdefault(rate, []).append(label)
            # Two items at one point are one lowering: the later rate is its speed.
            route.lower_rate[here] = rate
            self.lowered_at = here
            return
        if action == GRIPPER_GRAB and self.release is None:
            return
        if action != GRIPPER_RELEASE or self.release is not None:
            raise RouteFileError(
                f"{where}: DO_GRIPPER action {action!r} is not supported here (0, release, "
                "once; 1, grab, before any release)"
            )
        if route.landed and not route.airborne and route.landed_at == here:
            # PX4's land-and-release: on the ground where the vehicle landed, a point of its
            # own (its height, the parcel's set-down, is the scenario's: RouteFile.apply).
            self.release = "land"
            x, y, _ = route.points[here]
            route.to((x, y, math.nan))
            here = len(route.lower) - 1
        else:
            _on_the_pad(route, where, "DO_GRIPPER releases the parcel")
            route.items_here()
            # Lowered here: once it rests; else where it stands (in flight: a drop).
            self.release = "touchdown" if self.lowered_at == here else "drop"
        self.drop_point = here
        self.lowered_before = any(x > 0 for i, x in enumerate(route.lower) if i != here)
        self.origins.setdefault("payload.release", []).append(f"{label} DO_GRIPPER")

    def winch_speed(self) -> float | None:
        """The winch's top speed the plan's rates ask for: the fastest of them (None: no rate,
        the base scenario's winch speed); each lowering's own rate is
        ``trajectory.lower_speed`` (:meth:`RouteFile.apply`)."""
        given = [r for r in self.rates if r is not None]
        if not given:
            return None
        rate = max(given)
        items = [f"{i} DO_WINCH params[3] (rate, m/s)" for i in self.rates[rate]]
        self.origins["payload.winch_speed"] = items
        # The servo's refusal names the acceleration: the rate set it too (4 a / v).
        self.origins["payload.winch_acceleration"] = items
        return rate


def winch_speeds(lower: Sequence[float], rates: Sequence[float | None], fastest: float | None,
                 given: Mapping[str, Any]) -> dict[str, Any]:  # fmt: skip
    """The winch's top speed and each lowering's own (``trajectory.lower_speed``, only where
    they differ): ``lower`` and ``rates`` per point, ``fastest`` the plan's fastest rate,
    ``given`` the scenario's payload table (a lowering without a rate flies its
    ``winch_speed``)."""
    lowered = [i for i, x in enumerate(lower) if x > 0]
    if fastest is None:
        return {}
    if len({rates[i] if i < len(rates) else None for i in lowered}) <= 1:
        return {"payload.winch_speed": fastest}
    own = given.get("winch_speed")
    speeds = [0.0] * len(lower)
    for i in lowered:
        rate = rates[i]
        speeds[i] = float(own) if rate is None and own is not None else (rate or 0.0)
    return {"payload.winch_speed": max(speeds), "trajectory.lower_speed": speeds}


def needs_a_final_approach(source: str, delivers: Sequence[str], given: Mapping[str, Any]) -> None:
    """A DO_WINCH deliver (action 4) slows for the last metres: refused, naming its items, on
    a scenario (its payload table ``given``) without the winch's final approach."""
    if delivers and given.get("approach_height") is None:
        raise RouteFileError(
            f"{source}: {', '.join(delivers)} DO_WINCH action 4 (deliver) slows "
            "for the last metres: the scenario needs the winch's final approach "
            "(payload.approach_height and payload.approach_speed), none given"
        )


def reached(arrival: float, lowerings: Sequence[Any]) -> float:
    """s, when the mission reaches an item at a point the reference arrives at ``arrival``:
    after the point's lowering and retract (the schedule's lowerings that follow on)."""
    t = arrival
    for g in lowerings:
        if abs(g.start - t) < 1e-9:
            t = g.end
    return t


def set_down_height(data: Mapping[str, Any], extra: Mapping[str, Any]) -> float:
    """m, the vehicle's height over a land-and-release's point: the parcel set down on the
    ground with half its reeled-in line slack (``ground.altitude`` plus half of
    ``payload.length_min`` and ``payload.attachment_offset``, of the scenario ``data`` with
    the dotted ``extra``): the vehicle stays a point in the air, its landing gear not
    modelled."""

    def value(key: str, default: float) -> float:
        return float(extra.get(key, dotted_value(data, key, default)))

    line = value("payload.length_min", value("payload.cable_length", 0.0))
    return value("ground.altitude", 0.0) + 0.5 * (line + value("payload.attachment_offset", 0.0))


def _on_the_pad(route: _Route, where: str, what: str) -> None:
    """Refuses a payload action while the vehicle stands on the pad: flown there, the parcel
    would leave before lift-off (or after the landing, where the route no longer is)."""
    if route.airborne:
        return
    when = "after landing" if route.landed else "before take-off"
    raise RouteFileError(
        f"{where}: {what} {when}, with the vehicle on the ground: it would be flown at the "
        "pad; put it between the take-off and the landing, where the parcel is to go"
    )


def origin_of(origins: tuple[tuple[str, str], ...], key: str | None) -> str | None:
    """The plan's items that set ``key`` (a scenario key the engine refused), or None."""
    if key is None:
        return None
    found = [items for k, items in origins if k == key]
    return found[0] if found else None


def _number(value: Any, where: str, minimum: float = -math.inf, maximum: float = math.inf) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):  # OverflowError: a 400-digit integer
        shown = repr(value) if len(repr(value)) <= 40 else f"{repr(value)[:40]}..."
        raise RouteFileError(f"{where}: not a number within range: {shown}") from None
    if isinstance(value, bool) or not (math.isfinite(v) and minimum <= v <= maximum):
        span = f" in [{minimum:g}, {maximum:g}]" if math.isfinite(minimum) else ""
        raise RouteFileError(f"{where}: must be finite{span}, got {value!r}")
    return v
