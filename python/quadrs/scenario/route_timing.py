"""A flight's duration and turbulence window that follow its route (docs/delivery.md,
"Make it yours"): a preset that flies a route (``delivery``) runs a fixed time past the end of
its route, with its turbulence over the whole flight; a scenario that changes the route's
timing (its points, holds, lowerings, speed, acceleration, the winch) without setting
``integrator.duration`` keeps that margin on the new route, and a turbulence window that
covered the whole flight keeps covering it, unless ``gust.end`` is set too.

The route's time is the engine's own schedule (``_core.describe``) of a probe flight long
enough for it, so it agrees with what the engine flies to the step.
"""

from __future__ import annotations

import copy
import itertools
import json
import math
from collections.abc import Iterable, Mapping
from typing import Any

from quadrs import _core
from quadrs.scenario.keys import dotted_value
from quadrs.scenario.route import Route

#: Keys whose change moves the route's schedule (the dotted keys a change may set).
TIMING_PREFIXES = (
    "trajectory.",
    "payload.winch_",
    "payload.length_min",
    "payload.approach_",
    "payload.attachment_offset",
    "ground.altitude",
)


def changes_timing(keys: Iterable[str]) -> bool:
    """Does setting ``keys`` (dotted) move a route's schedule?"""
    return any(k.startswith(TIMING_PREFIXES) for k in keys)


def lowering_time(
    payout: float, speed: float, acceleration: float, slowest: float | None = None
) -> float:
    """s, how long a lowering of ``payout`` m lasts at the winch's ``speed`` (m/s) and
    ``acceleration`` (m/s^2): the pay-out at its speed with a ramp ``speed / acceleration`` at
    each end. The engine's rule (``config::route::lowering_time``), which its schedule
    flies; Python's one copy until ``_core`` exports it. With a final approach (``slowest``,
    its speed, where slower than the winch's) an upper bound: the whole pay-out at it (the
    engine's schedule pays out at the winch's speed down to the approach height)."""
    paid = speed if slowest is None else min(speed, slowest)
    return payout / paid + 2 * speed / acceleration


def _numbers(values: Any) -> list[float]:
    if not isinstance(values, list | tuple):
        return []
    return [float(v) for v in values if isinstance(v, int | float) and not isinstance(v, bool)]


def lowering_speed(data: Mapping[str, Any], v: float) -> float:
    """m/s, the slowest speed a lowering pays out at: the winch's ``v``, or the final
    approach's (``payload.approach_speed``) where the scenario has one."""
    slow = dotted_value(data, "payload.approach_speed", None)
    return min(v, float(slow)) if slow is not None else v


def hold_time(data: Mapping[str, Any]) -> float:
    """s, the route's holds in all (``trajectory.hold`` and ``trajectory.arrival_hold``)."""
    keys = ("trajectory.hold", "trajectory.arrival_hold")
    return sum(sum(_numbers(dotted_value(data, k, None))) for k in keys)


def time_bound(data: Mapping[str, Any]) -> float | None:
    """Seconds the route of ``data`` (a scenario's nested mapping) surely takes less than: a
    leg of length L at cruise speed V and acceleration bound A takes less than L/V + 2V/A, a
    lowering of P m at the winch's speed v and acceleration a less than P/v + 2v/a (P at the
    final approach's speed where it is slower: docs/model.md, "Routes" and "The last
    metres"), plus the holds and a margin. None if the values are not
    numbers (the scenario's own checks then name the key)."""
    try:
        speed = float(dotted_value(data, "trajectory.speed"))
        accel = float(dotted_value(data, "trajectory.acceleration", 1.0))
        points = [tuple(float(x) for x in p) for p in dotted_value(data, "trajectory.route")]
        t = hold_time(data)
        lower = [p for p in _numbers(dotted_value(data, "trajectory.lower", [])) if p > 0]
        if lower:
            v = float(dotted_value(data, "payload.winch_speed", 1.0))
            a = float(dotted_value(data, "payload.winch_acceleration", 1.0))
            # Each at its own speed where it has one; a retract reels the longest line in.
            own = [p for p in _numbers(dotted_value(data, "trajectory.lower_speed", [])) if p > 0]
            least = min([lowering_speed(data, v), *own])
            t += sum(lowering_time(p, v, a, least) for p in lower)
            retracts = dotted_value(data, "trajectory.retract", [])
            if isinstance(retracts, list | tuple):
                t += sum(1 for r in retracts if r is True) * lowering_time(max(lower), v, a)
        t += sum(math.dist(p, q) / speed + 2 * speed / accel
                 for p, q in itertools.pairwise(points))  # fmt: skip
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return 1.01 * t + 1.0 if math.isfinite(t) and t >= 0 else None


def route_time(data: Mapping[str, Any]) -> float | None:
    """s, the time the route of ``data`` takes (its legs to rest, its holds and lowerings), from
    the engine's schedule; None if ``data`` flies no route or its route is refused (the
    scenario's own checks then say why)."""
    if dotted_value(data, "trajectory.interpolation") != "route":
        return None
    bound = time_bound(data)
    if bound is None:
        return None
    probe = copy.deepcopy(dict(data))
    probe.setdefault("integrator", {})["duration"] = bound
    try:
        rows = _core.describe(json.dumps(probe, allow_nan=False))["route"]
    except (ValueError, TypeError):
        return None
    route = Route.from_engine(rows)
    return (sum(s.arrival - s.start for s in route.legs) + hold_time(data)
            + sum(s.end - s.start for s in route.lowerings))  # fmt: skip


def covering(needed: float, dt: float) -> float:
    """``needed`` seconds rounded up to a whole number of steps ``dt``."""
    return math.ceil(needed / dt - 1e-6) * dt


class Timing:
    """How a scenario's duration follows its route: ``margin`` s past the route's end, and
    whether the turbulence blows over the whole flight (``whole_gust``)."""

    def __init__(self, margin: float, whole_gust: bool) -> None:
        self.margin = margin
        self.whole_gust = whole_gust

    @classmethod
    def of(cls, data: Mapping[str, Any]) -> Timing | None:
        """The timing of a scenario whose duration follows its route; None for one that flies
        no route (or whose route does not fit its duration)."""
        needed = route_time(data)
        duration = dotted_value(data, "integrator.duration")
        if needed is None or not isinstance(duration, int | float) or duration < needed:
            return None
        start, end = dotted_value(data, "gust.start", 0.0), dotted_value(data, "gust.end")
        return cls(float(duration) - needed, start == 0.0 and end == duration)

    def apply(self, data: dict[str, Any], given: Iterable[str]) -> None:
        """``data`` (changed by the keys ``given``, none of them ``integrator.duration``) with
        the duration that keeps this margin past its route, in place; the turbulence window
        follows if it covered the whole flight and ``gust.end`` is not given. Nothing changes
        if the route is refused (the scenario's checks then say why)."""
        given = set(given)
        needed = route_time(data)
        dt = dotted_value(data, "integrator.dt")
        if needed is None or not isinstance(dt, int | float) or dt <= 0:
            return
        duration = covering(needed + self.margin, float(dt))
        old = dotted_value(data, "integrator.duration")
        if isinstance(old, int | float) and math.isclose(duration, old, rel_tol=0, abs_tol=dt / 2):
            return  # the same schedule's length: keep the value as written
        data.setdefault("integrator", {})["duration"] = duration
        if self.whole_gust and "gust.end" not in given and isinstance(data.get("gust"), dict):
            data["gust"]["end"] = duration
