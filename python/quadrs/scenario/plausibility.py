"""Plausibility of a scenario the engine accepts: refuse what cannot fly, warn on unit slips.

The engine checks that every value is legal (positive masses, increasing times, ...). Legal
is not plausible: a thrust limit below the weight lets the vehicle fall for the whole flight,
and a payload typed in grams (220 kg) flies without complaint. :func:`check` runs wherever a
:class:`~quadrs.scenario.scenario.Scenario` is validated:

- what cannot fly raises :class:`~quadrs.ScenarioError` naming the keys and the numbers;
- what is implausible issues one :class:`PlausibilityWarning` per finding, naming the key,
  its value and unit and the likely slip. Python shows each distinct warning once per
  session (the command line once per run); silence them with
  ``warnings.simplefilter("ignore", quadrs.PlausibilityWarning)``.

The thresholds are deliberately loose (docs/model.md, "Plausibility"): they catch a factor of
1000 or of 57, not an unusual design.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

from quadrs._core import ScenarioError
from quadrs.scenario.keys import dotted_value
from quadrs.scenario.units import unit


class PlausibilityWarning(UserWarning):
    """A scenario value is legal but implausible, most likely a unit slip (grams for kg,
    rad/s for Hz, degrees for rad)."""


#: Largest plausible vehicle mass (kg): a heavier "vehicle" was most likely typed in grams.
MAX_VEHICLE_MASS = 100.0
#: A payload this many times the vehicle's mass was most likely typed in grams: a heavy-lift
#: multirotor carries about its own mass (a 2.5 kg parcel under a 2.2 kg vehicle is a real
#: question; a 500 "kg" parcel, 0.5 kg in grams, is a slip of 1000).
GRAMS_RATIO = 10.0
#: Largest plausible payload natural frequency (Hz) on a spring below a multirotor.
MAX_NATURAL_FREQUENCY = 50.0
#: Largest plausible w20 (m/s): MIL-F-8785C's "severe" is 45 kt (23 m/s) at 20 ft.
MAX_W20 = 30.0
#: Upper end of the Dryden low-altitude model (m): 1000 ft.
MAX_GUST_ALTITUDE = 304.8


def _value(data: dict[str, Any], key: str) -> Any:
    return dotted_value(data, key)


def _fmt(key: str, value: float) -> str:
    return f"{key} = {value:g} {unit(key)}"


def refusals(data: dict[str, Any]) -> list[tuple[str, str]]:
    """(key, message) for each thing in ``data`` (a scenario's nested mapping) that cannot
    fly."""
    out = []
    thrust_max = _value(data, "controller.thrust_max")
    m, mc, g = (_value(data, k) for k in ("vehicle.mass", "payload.mass", "environment.gravity"))
    if thrust_max is not None and None not in (m, mc, g):
        weight = (m + mc) * g
        if thrust_max < weight:
            out.append((
                "controller.thrust_max",
                f"controller.thrust_max = {thrust_max:g} N is below the weight "
                f"(vehicle.mass + payload.mass) * environment.gravity = ({m:g} + {mc:g}) kg * "
                f"{g:g} m/s^2 = {weight:.4g} N: the vehicle cannot hover",
            ))  # fmt: skip
    out.extend(_route_below_ground(data))
    return out


def _ground(data: dict[str, Any]) -> float | None:
    """The ground's altitude (m) when the scenario has one, else None."""
    if _value(data, "ground.enabled") is not True:
        return None
    altitude = _value(data, "ground.altitude")
    return float(altitude) if isinstance(altitude, int | float) else 0.0


def _route_points(data: dict[str, Any]) -> list[tuple[float, float, float]]:
    """The route's points when the scenario flies one (the engine has checked their form)."""
    route = _value(data, "trajectory.route")
    if _value(data, "trajectory.interpolation") != "route" or not isinstance(route, list):
        return []
    return [(float(p[0]), float(p[1]), float(p[2])) for p in route
            if isinstance(p, list) and len(p) == 3]  # fmt: skip


def _route_below_ground(data: dict[str, Any]) -> list[tuple[str, str]]:
    """A route point below the ground: every flight would end in it (status "ground")."""
    ground = _ground(data)
    if ground is None:
        return []
    return [(f"trajectory.route[{i}]",
             f"trajectory.route[{i}] = [{x:g}, {y:g}, {z:g}] m is below the ground "
             f"(ground.altitude = {ground:g} m): every flight would end in it; raise the "
             "point (a drop point is where the vehicle hovers, the winch lowers the parcel "
             "from there: trajectory.lower)")
            for i, (x, y, z) in enumerate(_route_points(data)) if z < ground]  # fmt: skip


def _lowering_short_of_ground(data: dict[str, Any]) -> list[str]:
    """A lowering that stops with the parcel hanging above the ground: it never touches down
    (and a hook that opens at touchdown never opens)."""
    ground = _ground(data)
    lower = _value(data, "trajectory.lower")
    if ground is None or not isinstance(lower, list) or _value(data, "payload.model") != "cable":
        return []
    reeled = _value(data, "payload.length_min")
    if reeled is None:
        reeled = _value(data, "payload.cable_length")
    offset = _value(data, "payload.attachment_offset") or 0.0
    if not isinstance(reeled, int | float):
        return []
    out = []
    for i, ((_, _, z), paid) in enumerate(zip(_route_points(data), lower, strict=False)):
        if not isinstance(paid, int | float) or paid <= 0:
            continue
        above = z - offset - reeled - paid - ground  # the parcel's bottom at rest on the line
        if above > 0:
            out.append(
                f"trajectory.lower[{i}] = {paid:g} m leaves the parcel {above:.3g} m above the "
                f"ground (trajectory.route[{i}] at {z:g} m - payload.attachment_offset "
                f"{offset:g} m - the reeled-in line {reeled:g} m - {paid:g} m): it never "
                f"touches down; lower at least {paid + above:.3g} m or hover lower"
            )
    return out


def findings(data: dict[str, Any]) -> list[str]:
    """One short message per implausible value in ``data``, each naming the key, the value
    with its unit and the likely slip."""
    out = []
    m, mc = _value(data, "vehicle.mass"), _value(data, "payload.mass")
    if m is not None and m > MAX_VEHICLE_MASS:
        out.append(f"{_fmt('vehicle.mass', m)} (> {MAX_VEHICLE_MASS:g}): typed in grams?")
    if m is not None and mc is not None and mc > GRAMS_RATIO * m:
        out.append(f"{_fmt('payload.mass', mc)} is over {GRAMS_RATIO:g} times vehicle.mass = "
                   f"{m:g} kg: typed in grams?")  # fmt: skip
    fn = _value(data, "payload.natural_frequency")
    if fn is not None and fn > MAX_NATURAL_FREQUENCY:
        out.append(
            f"{_fmt('payload.natural_frequency', fn)} (> {MAX_NATURAL_FREQUENCY:g}): the key is "
            "in Hz; rad/s or wrong unit?"
        )
    attitude = _value(data, "initial.attitude")  # roll and pitch: the engine bounds them
    if isinstance(attitude, list) and len(attitude) == 3 and abs(attitude[2]) > 2 * math.pi:
        out.append(f"initial.attitude[2] (yaw) = {attitude[2]:g} rad (> 2 pi): degrees?")
    w20 = _value(data, "gust.w20")
    if w20 is not None and w20 > MAX_W20:
        out.append(
            f"{_fmt('gust.w20', w20)} is beyond severe turbulence (45 kt = 23 m/s): knots or ft/s?"
        )
    altitude = _value(data, "gust.altitude")  # or "vehicle": clamped by the engine
    if isinstance(altitude, int | float) and altitude > MAX_GUST_ALTITUDE:
        out.append(
            f"{_fmt('gust.altitude', altitude)} is above the low-altitude Dryden model's "
            "1000 ft (305 m): feet?"
        )
    below = _parcel_below_ground(data)
    if below:
        out.append(below)
    out.extend(_lowering_short_of_ground(data))
    short = _wind_table_short(data)
    if short:
        out.append(short)
    return out


def _wind_table_short(data: dict[str, Any]) -> str:
    """A wind table by time that covers only part of the flight (a log of a shorter flight):
    outside its rows the end rows' wind holds, which the user should know."""
    points = _value(data, "wind.table.points")
    duration, dt = _value(data, "integrator.duration"), _value(data, "integrator.dt")
    numbers = isinstance(duration, int | float) and isinstance(dt, int | float)
    if _value(data, "wind.table.by") != "time" or not isinstance(points, list) or len(points) < 2:
        return ""  # one row is a constant wind, not a series that ends
    if not numbers:
        return ""
    first, last = float(points[0][0]), float(points[-1][0])
    if first <= dt and last >= duration - dt:
        return ""
    return (
        f"wind.table covers t = {first:g} to {last:g} s of a {duration:g} s flight "
        "(integrator.duration): outside its rows the wind of its first or last row holds"
    )


def _parcel_below_ground(data: dict[str, Any]) -> str:
    """A cable payload hanging below the ground at the start (an empty string if not)."""
    if _value(data, "payload.model") != "cable" or _value(data, "ground.enabled") is not True:
        return ""
    position = _value(data, "initial.position")
    # With a winch the line starts reeled in (payload.length_min).
    reeled = _value(data, "payload.length_min")
    key = "payload.length_min" if reeled is not None else "payload.cable_length"
    length = reeled if reeled is not None else _value(data, "payload.cable_length")
    offset = _value(data, "payload.attachment_offset") or 0.0
    ground = _value(data, "ground.altitude") or 0.0
    if not isinstance(position, list) or len(position) != 3 or length is None:
        return ""
    bottom = position[2] - offset - length
    if bottom >= ground:
        return ""
    return (
        f"the parcel starts below the ground: initial.position[2] = {position[2]:g} m - "
        f"payload.attachment_offset = {offset:g} m - {key} = {length:g} m = "
        f"{bottom:.3g} m < ground.altitude = {ground:g} m: start higher or shorten the line"
    )


def check(data: dict[str, Any]) -> None:
    """Refuse what cannot fly (:class:`~quadrs.ScenarioError` naming the keys, with the
    numbers); warn once per implausible value (:class:`PlausibilityWarning`)."""
    refused = refusals(data)
    if refused:
        error = ScenarioError("; ".join(m for _, m in refused))
        error.key = ", ".join(k for k, _ in refused)  # as the engine's errors name theirs
        raise error
    for message in findings(data):
        # Attributed to this line, not the caller's: Python's default filter then shows each
        # message once per session, however many scenarios (a sweep's points) repeat it.
        warnings.warn(message, PlausibilityWarning, stacklevel=1)
