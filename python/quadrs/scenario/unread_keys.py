"""Keys a scenario holds but does not read in its configuration: the rotors' aerodynamics on
ideal actuators, the paper body's drag areas on the rigid body. The engine keeps them (so
``--set actuator.model=ideal`` flies a rotor preset on ideal actuators, and a rigid body
inherits the paper's values from its base), but a value *given* to one of them, by
``override``/``--set``, a sweep, ``tune --param`` or a dispersion (``--disperse``,
``sensitivity``), would change nothing and read as "no effect": refused, naming the key and
what it would need.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["unread_reason"]


def _table(data: Mapping[str, Any], name: str) -> Mapping[str, Any]:
    table = data.get(name, {})
    return table if isinstance(table, Mapping) else {}


def _not_on_rotors(data: Mapping[str, Any]) -> str | None:
    model = _table(data, "actuator").get("model", "ideal")
    if model == "rotors":
        return None
    return (f'is read by actuator.model = "rotors" only (rotor aerodynamics), and this '
            f"scenario flies actuator.model = {model!r}: it would change nothing")  # fmt: skip


def _not_on_the_paper_body(data: Mapping[str, Any]) -> str | None:
    body = _table(data, "vehicle").get("body", "paper")
    if body != "rigid":
        return None
    return ('is read by vehicle.body = "paper" only; the rigid body this scenario flies takes '
            "its drag from vehicle.drag_coefficients: it would change nothing")  # fmt: skip


def _not_navigating(data: Mapping[str, Any]) -> str | None:
    mode = _table(data, "navigation").get("mode", "truth")
    if mode == "ekf":
        return None
    return (f'is read with navigation.mode = "ekf" only (the laws fly the estimate), and this '
            f"scenario flies navigation.mode = {mode!r}: it would change nothing")  # fmt: skip


#: Key prefix -> why no key under it is read in a scenario (None: they are).
PREFIX_RULES: dict[str, Callable[[Mapping[str, Any]], str | None]] = {
    "sensors.": _not_navigating,
    "navigation.": _not_navigating,
}

#: Key -> why it is not read in a scenario (None: it is).
RULES: dict[str, Callable[[Mapping[str, Any]], str | None]] = {
    "actuator.rotor_drag": _not_on_rotors,
    "actuator.flapping": _not_on_rotors,
    "actuator.translational_lift": _not_on_rotors,
    "vehicle.drag_area": _not_on_the_paper_body,
    "vehicle.lateral_drag_area": _not_on_the_paper_body,
}


def unread_reason(data: Mapping[str, Any], key: str) -> str | None:
    """The message refusing a value given to ``key`` (a canonical dotted key, an element
    ``[i]`` included) in the scenario ``data``, or None when the scenario reads it."""
    rule = RULES.get(re.sub(r"\[\d+\]$", "", key))
    if rule is None and key != "navigation.mode":
        rule = next((r for p, r in PREFIX_RULES.items() if key.startswith(p)), None)
    if rule is None:
        return None
    why = rule(data)
    return None if why is None else f"{key} {why}"
