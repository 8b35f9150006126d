"""A scenario's nested tables as plain values: checked on the way in (only tables, arrays,
strings, booleans and finite numbers, nested at most :data:`MAX_DEPTH` deep), merged (a file
over its base), compared leaf by leaf, and a control law's table completed from the engine's
defaults."""

from __future__ import annotations

import copy
import json
import math
from collections.abc import Mapping
from typing import Any

from quadrs import _core
from quadrs.scenario.keys import scenario_error

#: Deepest nesting of tables and arrays a scenario may have (the presets use 3).
MAX_DEPTH = 32


#: Integers in a scenario lie in [-2**63, 2**63).
_INT_LIMIT = 1 << 63


def _plain(value: Any, key: str = "") -> Any:
    """Tuples and numpy scalars -> plain TOML-able Python values, checked on the way: only
    tables, arrays, strings, booleans, finite numbers and integers within 64 bits, nested at
    most MAX_DEPTH deep (dates, times and other objects are refused, naming the key). Walks
    with an explicit stack, so no input can exhaust Python's recursion limit."""
    root: list[Any] = [None]
    stack: list[tuple[Any, str, Any, Any, int]] = [(value, key, root, 0, 0)]
    while stack:
        v, k, parent, slot, depth = stack.pop()
        where = k or "scenario"
        if depth > MAX_DEPTH:
            raise scenario_error(f"{where}: nested more than {MAX_DEPTH} levels deep", k or None)
        if isinstance(v, Mapping):
            table: dict[str, Any] = {}
            parent[slot] = table
            for kk, vv in v.items():
                kk = str(kk)
                table[kk] = None
                stack.append((vv, f"{k}.{kk}" if k else kk, table, kk, depth + 1))
            continue
        if isinstance(v, list | tuple):
            array: list[Any] = [None] * len(v)
            parent[slot] = array
            stack.extend((vv, f"{k}[{i}]", array, i, depth + 1) for i, vv in enumerate(v))
            continue
        if not isinstance(v, str | bytes) and hasattr(v, "item") and callable(v.item):
            v = v.item()  # numpy scalar
        if isinstance(v, float) and not math.isfinite(v):
            raise scenario_error(f"{where} must be a finite number, got {v!r}", k or None)
        if isinstance(v, int) and not isinstance(v, bool) and not -_INT_LIMIT <= v < _INT_LIMIT:
            raise scenario_error(f"{where} must be an integer within 64 bits, got {v}", k or None)
        if not isinstance(v, bool | int | float | str):
            raise scenario_error(
                f"{where}: a scenario holds numbers, booleans, strings, arrays and tables, "
                f"got {type(v).__name__} {v!r}",
                k or None,
            )
        parent[slot] = v
    return root[0]


def _seed_controller_table(controller: dict[str, Any], kind: Any) -> None:
    """A law's table the scenario leaves out flies the engine's defaults: setting one key of
    it (``controller.se3.kR``) starts from them (``_core.CONTROLLER_DEFAULTS``)."""
    defaults = _core.CONTROLLER_DEFAULTS.get(kind) if isinstance(kind, str) else None
    if defaults is not None and kind not in controller:
        controller[kind] = json.loads(defaults)


def _complete_controller_tables(data: dict[str, Any]) -> None:
    """A law's table that gives only some keys (``[controller.px4]`` with the few values a
    user's airframe changes) takes the rest from the engine's defaults, in place; a key the
    law does not know is still refused by the engine, naming it."""
    controller = data.get("controller")
    if not isinstance(controller, dict):
        return
    for kind, text in _core.CONTROLLER_DEFAULTS.items():
        table = controller.get(kind)
        if isinstance(table, dict):
            controller[kind] = {**json.loads(text), **table}


def _seeded(base: dict[str, Any], data: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with the engine's defaults for each law's table that ``data`` has and ``base``
    leaves out (what setting one key of it starts from, :func:`_seed_controller_table`): so
    that one ``--set controller.px4.X`` differs from the base in X alone."""
    mine, theirs = data.get("controller"), base.get("controller")
    if not isinstance(mine, Mapping) or not isinstance(theirs, dict):
        return base
    missing = [k for k in _core.CONTROLLER_DEFAULTS if k in mine and k not in theirs]
    if not missing:
        return base
    out = dict(base)
    out["controller"] = dict(theirs)
    for kind in missing:
        _seed_controller_table(out["controller"], kind)
    return out


def _frozen(value: Any) -> Any:
    """A hashable image of a plain value that is equal exactly when the values are equal
    (tables ignore key order; equal numbers hash equally, as Python guarantees)."""
    if isinstance(value, dict):
        return frozenset((k, _frozen(v)) for k, v in value.items())
    if isinstance(value, list):
        return tuple(_frozen(v) for v in value)
    return value


def _merge(base: dict[str, Any], extra: Mapping[str, Any]) -> dict[str, Any]:
    """Tables merge key by key; anything else (arrays, values) replaces. A file that turns
    its base into a route (``trajectory.interpolation = "route"``) drops the base's
    waypoints, as :meth:`Scenario.override` does."""
    out = copy.deepcopy(base)
    for k, v in extra.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), dict):
            out[k] = _merge(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    trajectory = extra.get("trajectory")
    if isinstance(trajectory, Mapping) and isinstance(out.get("trajectory"), dict):
        _route_drops_waypoints(out["trajectory"], trajectory)
    return out


def _route_drops_waypoints(merged: dict[str, Any], given: Mapping[str, Any]) -> None:
    """A scenario made a route on top of a waypoint base flies the route: the base's
    ``waypoints`` (which a route refuses) go, unless given alongside."""
    if given.get("interpolation") == "route" and "waypoints" not in given:
        merged.pop("waypoints", None)


def _leaves(data: Mapping[str, Any], path: tuple[str, ...] = ()) -> dict[tuple[str, ...], Any]:
    """Every value below nested tables by its path; arrays (of tables too) are one value."""
    out: dict[tuple[str, ...], Any] = {}
    for k, v in data.items():
        here = (*path, k)
        if isinstance(v, Mapping):
            out.update(_leaves(v, here))
        else:
            out[here] = v
    return out


def _differences(
    data: Mapping[str, Any], base: Mapping[str, Any]
) -> dict[tuple[str, ...], tuple[Any, Any]]:
    mine, theirs = _leaves(data), _leaves(base)
    return {
        path: (theirs.get(path), mine.get(path))
        for path in [*theirs, *(p for p in mine if p not in theirs)]
        if mine.get(path) != theirs.get(path)
    }
