"""A ``.plan``'s winch and gripper items (``DO_WINCH`` 42600, ``DO_GRIPPER`` 211) as the
route's lowerings, the hook's release and the winch's rate (quadrs.scenario.route_files).

A plan that holds them says what the payload does, so it decides the hook: it opens at
touchdown only after a ``DO_GRIPPER`` release, never by the base scenario's
``payload.release``. A lowering or a release before take-off or after landing would be
flown at the pad (the parcel let go before lift-off): refused, naming the item. The engine
flies one winch speed, so ``DO_WINCH`` items with different rates (or one with a rate and one
without, which flies the base scenario's) are refused, naming the items. Each lowering and
rate remembers its item, so a value the engine refuses is named by the plan's item.
"""

from __future__ import annotations

import math
from typing import Any, Protocol

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
    lower: list[float]
    #: Whether the vehicle is off the pad (after a take-off or waypoint, before a landing),
    #: and whether it has landed since.
    airborne: bool
    landed: bool


class PlanPayload:
    """The payload items of one plan, in the order they are flown."""

    def __init__(self) -> None:
        #: "touchdown" (after a lowering), "drop" (a release in flight, at ``drop_point``) or
        #: None (never).
        self.release: str | None = None
        self.drop_point: int | None = None
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
        if command == WINCH:
            if action == WINCH_RETRACT:
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
            length = _number(params[2], f"{where}: DO_WINCH params[2] (length, m)", 0.0)
            if length <= 0:
                raise RouteFileError(
                    f"{where}: DO_WINCH params[2] must pay out line (> 0 m), got {length!r}"
                )
            route.lower[-1] += length
            at = f"trajectory.lower[{len(route.lower) - 1}]"
            self.origins.setdefault(at, []).append(f"{label} DO_WINCH params[2] (length, m)")
            rate = None
            if params[3] not in (None, 0):
                rate = _number(params[3], f"{where}: DO_WINCH params[3] (rate, m/s)")
            self.rates.setdefault(rate, []).append(label)
            return
        if action == GRIPPER_GRAB and self.release is None:
            return
        if action != GRIPPER_RELEASE or self.release is not None:
            raise RouteFileError(
                f"{where}: DO_GRIPPER action {action!r} is not supported here (0, release, "
                "once; 1, grab, before any release)"
            )
        _on_the_pad(route, where, "DO_GRIPPER releases the parcel")
        if any(x > 0 for x in route.lower):
            self.release = "touchdown"
        else:  # in flight, no line lowered: a drop where the vehicle stands
            self.release, self.drop_point = "drop", len(route.lower) - 1
        self.origins.setdefault("payload.release", []).append(f"{label} DO_GRIPPER")

    def winch_speed(self, source: str) -> float | None:
        """The one rate of the plan's lowerings (None: the base scenario's winch speed);
        RouteFileError naming the items when they ask for different rates."""
        if len(self.rates) > 1:
            shown = "; ".join(f"{_rate(r)} at {', '.join(at)}" for r, at in self.rates.items())
            raise RouteFileError(
                f"{source}: DO_WINCH params[3] asks for different rates ({shown}): the engine "
                "flies one winch speed (payload.winch_speed); give every DO_WINCH the same rate"
            )
        rate = next(iter(self.rates), None)
        if rate is not None:
            items = [f"{i} DO_WINCH params[3] (rate, m/s)" for i in self.rates[rate]]
            self.origins["payload.winch_speed"] = items
            # The servo's refusal names the acceleration: the rate set it too (4 a / v).
            self.origins["payload.winch_acceleration"] = items
        return rate


def _rate(rate: float | None) -> str:
    return "no rate (the base scenario's winch_speed)" if rate is None else f"{rate:g} m/s"


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
