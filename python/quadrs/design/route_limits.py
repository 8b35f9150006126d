"""What a route asks of a control law, known before flying: each leg's reference speeds and
accelerations against the limits the law flies by (``quadrs mission`` says them before it flies
and beside a route it did not fly; docs/delivery.md, "Why a route is not flown").

A law cannot follow a reference faster than it lets itself go: PX4's cascade clips its
velocity setpoint at ``MPC_XY_VEL_MAX``, ``MPC_Z_VEL_MAX_UP`` and ``MPC_Z_VEL_MAX_DN`` and its
thrust's tilt at ``MPC_TILTMAX_AIR``; the PD and SMC laws clip their tilt at
``controller.tilt_limit``; every law is held by the rotors' largest thrust. A leg whose reference
asks more falls behind it, and a leg that asks exactly a velocity limit has no margin left to
correct a gust. Each such leg is a :class:`LimitClash`, with how much more it asks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

__all__ = ["LimitClash", "route_clashes"]

#: A leg asking at least this fraction of a velocity limit is flown at it, with no margin.
AT_LIMIT = 0.999


@dataclass(frozen=True)
class LimitClash:
    """One leg's reference against one of the law's limits."""

    #: The leg's name (its phase).
    leg: str
    #: The limit's key: a PX4 parameter's name or a scenario key.
    limit: str
    #: What is limited, in words ("descent speed").
    what: str
    #: The limit's value and what the leg's reference asks, in ``unit``.
    allowed: float
    asked: float
    unit: str

    def __str__(self) -> str:
        more = self.asked - self.allowed
        said = (
            f"{_g(more)} {self.unit} more ({self.asked / self.allowed:.2g} x)"
            if self.allowed > 0 and more > 0
            else "all of it, no margin to correct"
        )
        return (
            f"leg {self.leg}: a {self.what} of {_g(self.asked)} {self.unit} against "
            f"{self.limit} = {_g(self.allowed)} {self.unit}: {said}"
        )


def _g(x: float) -> str:
    return f"{x:.3g}"


def route_clashes(scenario: Any, controller: str) -> list[LimitClash]:
    """Every leg of ``scenario``'s route whose reference asks as much as, or more than, a limit
    of ``controller`` (its velocity limits, its tilt limit for the reference's acceleration,
    the rotors' thrust for a climb's), in route order; empty for a scenario without a route."""
    route = scenario.route
    if route is None:
        return []
    g = float(scenario["environment.gravity"])
    accel = float(scenario.get("trajectory.acceleration", math.nan))
    limits = _law_limits(scenario, controller)
    thrust = _climb_acceleration(scenario, g)
    out: list[LimitClash] = []
    for leg in route.legs:
        if leg.length <= 0:
            continue
        dx, dy, dz = (b - a for a, b in zip(leg.origin, leg.target, strict=True))
        across = math.hypot(dx, dy) / leg.length
        up = dz / leg.length
        asked = {
            "horizontal": leg.peak_speed * across,
            "climb": leg.peak_speed * max(up, 0.0),
            "descent": leg.peak_speed * max(-up, 0.0),
        }
        for key, what, allowed in limits["speed"]:
            v = asked[what]
            if v > 0 and v >= AT_LIMIT * allowed:
                out.append(LimitClash(leg.name, key, f"{what} speed", allowed, v, "m/s"))
        if leg.ramp > 0 and math.isfinite(accel):
            a = 2.0 * leg.peak_speed / leg.ramp  # the ramp's peak (a sin^2 pulse, legs.rs)
            a_h, a_up = a * across, a * max(up, 0.0)
            for key, tilt in limits["tilt"]:
                # The tilt the ramp needs, still air: tan(tilt) = a_h / (g + a_up).
                need = math.degrees(math.atan2(a_h, g + a_up))
                if need > tilt:
                    out.append(LimitClash(leg.name, key, "tilt", tilt, need, "deg"))
            if thrust is not None and a_up > thrust:
                out.append(LimitClash(leg.name, "actuator.thrust_max", "climb acceleration",
                                      thrust, a_up, "m/s^2"))  # fmt: skip
    return out


def _law_limits(scenario: Any, controller: str) -> dict[str, list[Any]]:
    """The law's velocity limits (key, which speed, m/s) and tilt limits (key, deg)."""
    if controller == "px4":
        px4 = _px4_table(scenario)
        return {
            "speed": [
                ("MPC_XY_VEL_MAX", "horizontal", float(px4["MPC_XY_VEL_MAX"])),
                ("MPC_Z_VEL_MAX_UP", "climb", float(px4["MPC_Z_VEL_MAX_UP"])),
                ("MPC_Z_VEL_MAX_DN", "descent", float(px4["MPC_Z_VEL_MAX_DN"])),
            ],
            "tilt": [("MPC_TILTMAX_AIR", float(px4["MPC_TILTMAX_AIR"]))],
        }
    tilt = scenario.get("controller.tilt_limit")
    tilts = [] if tilt is None else [("controller.tilt_limit", math.degrees(float(tilt)))]
    return {"speed": [], "tilt": tilts}


def _px4_table(scenario: Any) -> dict[str, Any]:
    """``[controller.px4]`` as flown: the scenario's values over the engine's defaults."""
    import json

    from quadrs import _core

    table = json.loads(_core.CONTROLLER_DEFAULTS["px4"])
    given = scenario.get("controller.px4")
    return {**table, **(given if isinstance(given, dict) else {})}


def _climb_acceleration(scenario: Any, g: float) -> float | None:
    """m/s^2, the largest upward acceleration the rotors give the vehicle and its payload at
    full thrust (None without a rotor model)."""
    if scenario.get("actuator.model") != "rotors":
        return None
    thrust_max = scenario.get("actuator.thrust_max")
    if thrust_max is None:
        return None
    mass = float(scenario["vehicle.mass"]) + float(scenario.get("payload.mass", 0.0))
    return 4 * float(thrust_max) / mass - g
