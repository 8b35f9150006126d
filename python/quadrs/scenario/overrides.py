"""Dotted changes laid on a scenario's nested tables (``Scenario.override``, ``--set`` on a
scenario file before it is checked): one key set, the keys it excludes dropped, the keys
given per point of a route that a new route keeps or drops, and a file's duration that
follows its base's route (:mod:`quadrs.scenario.route_timing`)."""

from __future__ import annotations

import sys
from collections.abc import Iterable, Mapping
from typing import Any

import tomli_w

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover  (Python 3.10: the same parser, as a package)
    import tomli as tomllib

from quadrs import _core
from quadrs.scenario.keys import ScenarioError, _split_key, canonical_keys, scenario_error
from quadrs.scenario.route_timing import Timing, changes_timing
from quadrs.scenario.tables import _plain, _seed_controller_table

#: The scenario class (``quadrs.scenario.scenario.Scenario``, which imports this module: it is
#: handed in, not imported back).
Scenario = Any

#: Top-level tables the engine fills with defaults when a scenario omits them (so that
#: ``override({"ground.enabled": True})`` works on a preset without a ``[ground]`` table).
OPTIONAL_TABLES: frozenset[str] = frozenset(
    {"actuator", "ground", "volume", "wind", "navigation", "sensors"}
)

# Pairs of keys that give one thing two ways (the attachment's stiffness or natural frequency,
# the turbulence's W20 or level: each declared once, beside its owner in the engine; the wind
# table's file, which Python reads, or its rows): setting one replaces the other.
_ONE_OF = [*_core.ONE_OF_KEYS, ("wind.table.file", "wind.table.points")]
_EXCLUSIVE = {a: b for pair in _ONE_OF for a, b in (pair, pair[::-1])}
#: Optional tables below the top level that setting one of their keys creates.
_CREATED_TABLES = frozenset(
    {"wind.table", "wind.climate", "sensors.imu", "sensors.gnss", "sensors.baro", "sensors.heading"}
)


def _set_key(data: dict[str, Any], key: str, value: Any, changes: Mapping[str, Any],
             create: bool = False) -> None:  # fmt: skip
    """Set the dotted ``key`` of a scenario's nested mapping to ``value``, in place (None
    removes it): the key it excludes goes unless ``changes`` sets it too (a natural frequency
    replaces a stiffness). ``create``: tables on the way that ``data`` lacks are made (a file
    read before its base is merged under it). ScenarioError naming the key otherwise."""
    parts = _split_key(key)
    other = _EXCLUSIVE.get(key)
    if other is not None and other not in changes:
        *tables, name = other.split(".")
        node: Any = data
        for table in tables:
            node = node.get(table, {}) if isinstance(node, dict) else {}
        if isinstance(node, dict):
            node.pop(name, None)
    parent: Any = data
    for i, part in enumerate(parts[:-1]):
        made = create and isinstance(part, str) and isinstance(parts[i + 1], str)
        if ((i == 0 and part in OPTIONAL_TABLES) or made) and isinstance(
                parent, dict) and part not in parent:  # fmt: skip
            parent[part] = {}  # a table the scenario leaves at its defaults
        if ".".join(map(str, parts[: i + 1])) in _CREATED_TABLES and isinstance(
                parent, dict) and part not in parent:  # fmt: skip
            parent[part] = {}  # a table a key of it starts (wind.table.file)
        if i == 1 and parts[0] == "controller" and isinstance(parent, dict) and not create:
            _seed_controller_table(parent, part)
        try:
            parent = parent[part]
        except (KeyError, IndexError, TypeError):
            where = key if i == len(parts) - 2 else ".".join(map(str, parts[: i + 1]))
            raise scenario_error(f"{key}: unknown scenario key ({where})", key) from None
    last = parts[-1]
    if isinstance(parent, dict) and isinstance(last, str):
        if value is None:
            parent.pop(last, None)
        else:
            parent[last] = _plain(value, key)
    elif isinstance(parent, list) and isinstance(last, int) and last < len(parent):
        parent[last] = _plain(value, key)
    else:
        raise scenario_error(f"{key}: unknown scenario key", key)


def _route_drops_its_points(trajectory: dict[str, Any], changes: Mapping[str, Any]) -> None:
    """What a changed route (or interpolation) does to the keys given per point of the base's
    route, in place: a route of as many points keeps them (the lowering at its fourth point
    lowers at the new fourth point; the names still count its segments); another number of
    points, or no route, drops the base's lowerings (``trajectory.lower``: each at a point the
    new route does not have) and leg names (``trajectory.names``: the engine names the new
    legs), unless given again. ``trajectory.hold`` stays: the engine names its count."""
    new, old = changes.get("trajectory.route"), trajectory.get("route")
    same = (
        "trajectory.interpolation" not in changes
        and isinstance(new, list | tuple)
        and isinstance(old, list)
        and len(new) == len(old)
    )
    if same or not {"trajectory.route", "trajectory.interpolation"} & changes.keys():
        return
    if "trajectory.lower" not in changes:
        trajectory.pop("lower", None)
    if "trajectory.route" in changes and "trajectory.names" not in changes:
        trajectory.pop("names", None)


def _with_changes(text: str, source: str, changes: Mapping[str, Any]) -> str:
    """TOML ``text`` with the dotted ``changes`` laid on its own tables (those it cannot take,
    such as an index into an array its base holds, left for :meth:`Scenario.override`)."""
    try:
        data = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError):
        return text  # reading it again says why
    keys = canonical_keys(changes, "override")
    for key, value in zip(keys, changes.values(), strict=True):
        if value is None or key == "trajectory.route_file":
            continue
        try:
            _set_key(data, key, value, changes, create=True)
        except ScenarioError:
            pass  # set by the override that follows, which names a key nothing has
    return tomli_w.dumps(data)


def _following(cls: type[Scenario], data: dict[str, Any], timing: Timing | None,
               given: Iterable[str]) -> Scenario:  # fmt: skip
    """The scenario of ``data``: its base's (whose duration follows its route by ``timing``)
    with the dotted keys ``given`` set (a file's own, or an override's). Unless they set
    ``integrator.duration``, keys that move the route keep the base's margin past it (and
    its whole-flight turbulence, unless they set ``gust.end``)."""
    given = set(given)
    if timing is not None and "integrator.duration" not in given:
        if changes_timing(given):
            timing.apply(data, given)
        if "gust.end" in given:
            timing = Timing(timing.margin, whole_gust=False)
    else:
        timing = None
    scenario = cls(data)
    scenario._timing = timing
    return scenario


def _leaf_keys(node: Any, prefix: str = "") -> list[str]:
    """The dotted keys of a nested mapping's leaves (arrays whole)."""
    if not isinstance(node, Mapping):
        return [prefix] if prefix else []
    return [k for name, v in node.items()
            for k in _leaf_keys(v, f"{prefix}.{name}" if prefix else str(name))]  # fmt: skip
