"""The validated scenario: presets, TOML in and out, dotted-key overrides.

A Scenario is an immutable nested mapping shaped exactly like its TOML file. Values are
checked by the engine itself (one set of rules, in Rust), so a Scenario that exists is one
the engine accepts; every error names the dotted key and the offending value.

The parts it is made of sit beside it: dotted keys and single values (``keys``), the nested
tables (``tables``), the presets and scenario files read (``preset_files``) and the TOML
written like a preset (``toml_layout``); their public names are offered here too.
"""

from __future__ import annotations

import contextvars
import copy
import json
import math
import sys
from collections.abc import Iterable, Iterator, Mapping
from functools import cached_property
from pathlib import Path
from typing import Any

import tomli_w

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover  (Python 3.10: the same parser, as a package)
    import tomli as tomllib

from quadrs import _core
from quadrs.scenario import plausibility
from quadrs.scenario.climate import climate_of, strip_climate
from quadrs.scenario.keys import (
    ScenarioError,
    _dotted,
    _split_key,
    canonical_key,
    canonical_keys,
    parse_value,
    scenario_error,
    toml_value,
)
from quadrs.scenario.overrides import (
    OPTIONAL_TABLES,
    _following,
    _leaf_keys,
    _route_drops_its_points,
    _set_key,
    _with_changes,
)
from quadrs.scenario.preset_files import (
    _BASE_KEY,
    MAX_FILE_BYTES,
    MAX_TEXT_CHARS,
    _preset_text,
    _read_text,
    _real,
    base_preset,
    presets,
)
from quadrs.scenario.route import FLIGHT_PHASE, Route
from quadrs.scenario.route_timing import Timing
from quadrs.scenario.tables import (
    MAX_DEPTH,
    _complete_controller_tables,
    _differences,
    _frozen,
    _merge,
    _plain,
    _route_drops_waypoints,
    _seed_controller_table,
    _seeded,
)
from quadrs.scenario.toml_layout import _layout_like

#: What this module offers; its keys, tables, preset files and TOML layout are made beside
#: it (keys, tables, preset_files, toml_layout).
__all__ = [
    "MAX_DEPTH",
    "MAX_FILE_BYTES",
    "MAX_TEXT_CHARS",
    "OPTIONAL_TABLES",
    "Scenario",
    "ScenarioError",
    "base_preset",
    "canonical_key",
    "canonical_keys",
    "design_keys",
    "key_value",
    "parse_value",
    "presets",
    "scenario_error",
    "start_height",
    "toml_value",
]


#: Files being read through ``base = "file.toml"`` chains (to refuse a cycle).
_BASE_CHAIN: contextvars.ContextVar[tuple[Path, ...]] = contextvars.ContextVar(
    "_BASE_CHAIN", default=()
)


def design_keys(scenario: Scenario, keys: Iterable[str], what: str) -> list[str]:
    """Keys a design-loop command sets on ``scenario`` (swept, tuned): canonical, each once
    (:func:`canonical_keys`), and not dispersed, since a dispersion would override every
    value set and the command would compare identical batches. ScenarioError naming the key
    and ``what`` (the option or argument) otherwise; checked before anything flies."""
    keys = canonical_keys(keys, what)
    dispersed = set(scenario.dispersions)
    for key in keys:
        if key in dispersed:
            raise scenario_error(
                f"{what}: {key} is also dispersed ([dispersions] or --disperse): its drawn "
                "values would replace every value set; remove one of the two",
                key,
            )
    return keys


def _resolve_base(data: dict[str, Any], chain: tuple[str, ...] = ()) -> dict[str, Any]:
    """``data`` on top of the preset its ``base`` names, which may itself have a base: the
    chain is followed to its end; a cycle is refused."""
    data = dict(data)
    base = data.pop(_BASE_KEY, None)
    if base is None:
        return data
    if not isinstance(base, str):
        raise scenario_error(f"base must name a preset, got {base!r}", "base")
    if base in chain:
        raise scenario_error(f"base: presets based on each other in a cycle: "
                             f"{' -> '.join((*chain, base))}", "base")  # fmt: skip
    text = _preset_text(base)
    try:
        parent = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:  # pragma: no cover - shipped presets parse
        raise scenario_error(f"base: preset {base!r} is not valid TOML: {e}", "base") from e
    return _merge(_resolve_base(parent, (*chain, base)), data)


#: Keys a route file sets that a scenario file may also give (they then win over the file's).
_ROUTE_FILE_KEYS = ("trajectory.hold", "trajectory.arrival_hold", "trajectory.speed",
                    "trajectory.names", "initial.position", "integrator.duration",
                    "gust.end")  # fmt: skip


def start_height(position: Any) -> float:
    """The height (m) of an ``initial.position`` a route file's flight starts at: ScenarioError
    naming the key unless it is 3 numbers (it is read before the scenario checks it)."""
    if isinstance(position, list | tuple) and len(position) == 3:
        z = position[2]
        if isinstance(z, int | float) and not isinstance(z, bool) and math.isfinite(z):
            return float(z)
    raise scenario_error(f"initial.position must have 3 numbers (x, y, z in m), got "
                         f"{toml_value(position)[:80]}", "initial.position")  # fmt: skip


def _route_file_of(data: Mapping[str, Any]) -> Any:
    """The ``trajectory.route_file`` a scenario table names, or None."""
    trajectory = data.get("trajectory")
    return trajectory.get("route_file") if isinstance(trajectory, Mapping) else None


def _with_route_file(cls: type[Scenario], data: dict[str, Any], folder: Path,
                     build: Any) -> Scenario:  # fmt: skip
    """A scenario table with ``trajectory.route_file`` (a ``.plan`` or a CSV of points, relative
    to ``folder``): the rest of the table built by ``build``, then the file's route applied
    as ``Scenario.from_plan`` applies it; the route-dependent keys the table gives itself
    (holds, names, speed, start, duration) win over the file's. The scenario holds the points
    read, not the path: a saved run carries the route it flew."""
    from quadrs.scenario.route_files import read_route_file

    rest = copy.deepcopy(data)
    trajectory = rest["trajectory"]
    name = trajectory.pop("route_file")
    if not isinstance(name, str) or not name:
        raise scenario_error(
            f"trajectory.route_file must name a .plan or .csv file, got {name!r}",
            "trajectory.route_file",
        )
    given: dict[str, Any] = {}
    for key in _ROUTE_FILE_KEYS:
        section, leaf = key.split(".")
        table = rest.get(section)
        if isinstance(table, dict) and leaf in table:
            # checked with the file's route (holds and names count its points, the duration
            # covers it), not with the base's
            given[key] = table[leaf] if key == "initial.position" else table.pop(leaf)
    if "route" in trajectory:
        raise scenario_error(
            "trajectory.route and trajectory.route_file: give one or the other", "trajectory.route"
        )
    trajectory["interpolation"] = "route"
    speed_from_file = False
    try:
        base = build(rest)  # on its base's route (the file's replaces it, with its holds)
    except ScenarioError:
        # No route to stand on (a complete file, a waypoint base): a placeholder leg, at a
        # placeholder speed if none is given (then the file must give one).
        speed_from_file = "speed" not in trajectory and "trajectory.speed" not in given
        trajectory.update(route=[[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]], hold=[0.0, 0.0])
        trajectory.setdefault("speed", 1.0)
        base = build(rest)
    path = Path(name) if Path(name).is_absolute() else folder / name
    height = start_height(given.get("initial.position", base["initial.position"]))
    try:
        route = read_route_file(path, start_height=height)
        if speed_from_file and route.speed is None:
            raise ValueError("trajectory.speed must be given: the file and the base give none")
        return route.apply(base, given)
    except ValueError as e:
        raise scenario_error(f"trajectory.route_file = {name!r}: {e}",
                             "trajectory.route_file") from None  # fmt: skip


def _read_wind_table(data: dict[str, Any], folder: Path) -> None:
    """A ``[wind.table]`` that names a ``file`` (relative to ``folder``) gets the file's rows
    as its ``points`` instead (:mod:`quadrs.scenario.wind_table`), in place: the engine
    receives the numbers, and the scenario carries the wind it flies."""
    wind = data.get("wind")
    table = wind.get("table") if isinstance(wind, dict) else None
    if not isinstance(table, dict) or "file" not in table:
        return
    from quadrs.scenario.wind_table import read_wind_table

    name = table["file"]
    if "points" in table:
        raise scenario_error(
            "wind.table: give file or points, not both (the file's rows would replace the "
            "points given)",
            "wind.table.file",
        )
    if not isinstance(name, str) or not name:
        raise scenario_error(f"wind.table.file must name a CSV file or a PX4 .ulg log, got "
                             f"{name!r}",
                             "wind.table.file")  # fmt: skip
    path = Path(name) if Path(name).is_absolute() else folder / name
    try:
        points = read_wind_table(path, table.get("by", ""))
    except ValueError as e:
        raise scenario_error(f"wind.table.file = {name!r}: {e}", "wind.table.file") from None
    del table["file"]
    table["points"] = points


def _refuse_unread(data: dict[str, Any], given: Mapping[str, Any]) -> None:
    """ScenarioError naming the first key of ``given`` (values set, or dispersed) that the
    scenario ``data`` does not read (quadrs.scenario.unread_keys)."""
    from quadrs.scenario.unread_keys import unread_reason

    for key in given:
        why = unread_reason(data, key)
        if why is not None:
            raise scenario_error(why, key)


def key_value(scenario: Scenario, key: str) -> Any:
    """``scenario[key]``, or for a key of a law's table the scenario leaves out, the engine's
    default that setting the key starts from (``controller.px4.MPC_XY_P`` on a scenario with
    no ``[controller.px4]``): what a tuned or swept key is untuned. KeyError otherwise."""
    try:
        return scenario[key]
    except KeyError:
        parts = _split_key(key)
        if len(parts) < 3 or parts[0] != "controller":
            raise
        controller = scenario.get("controller")
        if not isinstance(controller, dict):
            raise
        _seed_controller_table(controller, parts[1])
        node: Any = controller
        for part in parts[1:]:
            try:
                node = node[part]
            except (KeyError, IndexError, TypeError):
                raise KeyError(key) from None
        return node


class Scenario:
    """A complete, validated scenario. Build one from a preset, a TOML file or a mapping;
    derive variants with :meth:`override`. Instances are immutable and compare by value."""

    #: How the duration follows the route (a preset's, and what derives from it without
    #: setting ``integrator.duration``); None: the duration is as set.
    _timing: Timing | None = None

    def __init__(self, data: Mapping[str, Any]) -> None:
        data = _plain(data)
        if not isinstance(data, dict):
            raise ScenarioError(f"a scenario is a table of tables, got {type(data).__name__}")
        table = data.get("dispersions")
        if isinstance(table, dict) and table:
            keys = canonical_keys(table, "dispersions")
            data["dispersions"] = dict(zip(keys, table.values(), strict=True))
        _read_wind_table(data, Path.cwd())
        _complete_controller_tables(data)
        climate_of(data)  # a bad [wind.climate] names its key (Python alone reads it)
        self._data: dict[str, Any] = data
        _ = self._derived  # validate now: a Scenario that exists is one the engine accepts
        _refuse_unread(data, data.get("dispersions") or {})  # a draw that changes nothing
        plausibility.check(data)  # and one that can fly; implausible values warn

    # -- construction -------------------------------------------------------------------
    @classmethod
    def paper(cls) -> Scenario:
        """The paper preset of docs/model.md (vertical flight, vertical Dryden gust, Table 2
        gains)."""
        return cls.preset("paper")

    @classmethod
    def preset(cls, name: str) -> Scenario:
        """A shipped preset by name (see :func:`quadrs.scenario.scenario.presets`). A preset
        that flies a route keeps its duration's margin past the route's end when a change
        moves the route (:mod:`quadrs.scenario.route_timing`) unless the duration is set."""
        scenario = cls.from_toml_string(_preset_text(name))
        scenario._timing = Timing.of(scenario._data)
        return scenario

    @classmethod
    def from_toml(cls, path: str | Path, changes: Mapping[str, Any] | None = None) -> Scenario:
        """Read a scenario file. A file may start from a preset with ``base = "paper"`` and
        give only what differs; otherwise it must be complete. Unknown keys are rejected.
        ``changes`` (dotted keys, as ``--set`` gives them) are laid on the file's own tables
        before it is checked, so that they may fix a file the checks refuse (a duration too
        short for its route); a key the file's tables cannot take is set afterwards, as
        :meth:`override` sets it."""
        text = _read_text(Path(path))
        return cls.from_toml_string(text, source=str(path), changes=changes)

    @classmethod
    def from_toml_string(cls, text: str, source: str = "<string>",
                         changes: Mapping[str, Any] | None = None) -> Scenario:  # fmt: skip
        """Parse TOML text. ``base`` may name a preset or, unlike in :meth:`from_dict`, another
        scenario file (``base = "tuned.toml"``, relative to ``source``'s directory).
        ``changes``: as :meth:`from_toml`'s."""
        if changes:
            return cls.from_toml_string(_with_changes(text, source, changes), source
                                        ).override(changes)  # fmt: skip
        if len(text) > MAX_TEXT_CHARS:
            raise ScenarioError(f"{source} is larger than {MAX_TEXT_CHARS} characters")
        if len(text) > MAX_FILE_BYTES:  # parsing takes several times the text's size
            from quadrs.engine.calls import check_memory

            check_memory(f"parsing the scenario {source}", 16 * len(text))
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as e:
            raise ScenarioError(f"{source} is not valid TOML: {e}") from e
        except RecursionError:
            raise ScenarioError(f"{source}: values nested too deeply") from None
        _read_wind_table(data, Path(source).parent if source != "<string>" else Path.cwd())
        if _route_file_of(data) is not None:
            folder = Path(source).parent if source != "<string>" else Path.cwd()
            return _with_route_file(cls, data, folder, lambda rest: cls.from_toml_string(
                tomli_w.dumps(rest), source))  # fmt: skip
        base = data.get(_BASE_KEY)
        if isinstance(base, str) and base.endswith(".toml") and base not in presets():
            path = Path(base)
            if not path.is_absolute() and source != "<string>":
                path = Path(source).parent / path
            chain = _BASE_CHAIN.get()
            if _real(path) in chain:
                raise scenario_error(
                    f"base = {base!r} in {source}: a scenario file bases on itself", "base"
                )
            token = _BASE_CHAIN.set((*chain, _real(path)))
            try:
                parent = cls.from_toml(path)
            finally:
                _BASE_CHAIN.reset(token)
            del data[_BASE_KEY]
            merged = _merge(parent._data, _plain(data))
            return _following(cls, merged, parent._timing, _leaf_keys(data))
        return cls.from_dict(data)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Scenario:
        """From a nested mapping shaped like the TOML file (``base`` allowed)."""
        data = _plain(data)
        if not isinstance(data, dict):
            raise ScenarioError(f"a scenario is a table of tables, got {type(data).__name__}")
        if _route_file_of(data) is not None:
            return _with_route_file(cls, data, Path.cwd(), cls.from_dict)
        base = data.get(_BASE_KEY)
        timing = None
        if isinstance(base, str) and base in presets():
            timing = Scenario.preset(base)._timing
        return _following(cls, _resolve_base(data), timing, _leaf_keys(data))

    @classmethod
    def from_plan(
        cls,
        path: str | Path,
        base: str | Path | Scenario = "delivery",
        changes: Mapping[str, Any] | None = None,
    ) -> Scenario:
        """``base`` (a preset name, a scenario file or a Scenario) flying the route of a
        QGroundControl ``.plan`` mission or a CSV of points (quadrs.scenario.route_files):
        the route, its holds and speed, the start at home at the base's initial height, and a
        duration just long enough. ``changes`` (dotted keys) are applied with it and win."""
        from quadrs.scenario.route_files import read_route_file

        if isinstance(base, Scenario):
            start = base
        elif str(base) in presets():
            start = cls.preset(str(base))
        else:
            start = cls.from_toml(base)
        extra = dict(changes or {})
        height = start_height(extra.get("initial.position", start["initial.position"]))
        return read_route_file(path, start_height=height).apply(start, extra)

    # -- output -------------------------------------------------------------------------
    def to_toml(self, like: str | None = None) -> str:
        """The complete scenario as TOML; ``Scenario.from_toml_string(s.to_toml()) == s``.

        ``like``: a preset name whose layout, compact arrays, units and comments to keep;
        values that differ from it carry the preset's value in their comment
        (``mass = 0.3  # kg ...; paper: 0.22``). The result parses back to this scenario.
        """
        if like is None:
            return tomli_w.dumps(self._data)
        return _layout_like(self._data, Scenario.preset(like)._data, like)

    def differences(self, base: Scenario) -> dict[str, tuple[Any, Any]]:
        """Dotted keys whose value differs from ``base``: key -> (base value, this value),
        ``None`` where a side does not set the key. Arrays (and ``phases``) compare whole."""
        theirs = _seeded(base._data, self._data)
        return {_dotted(p): change for p, change in _differences(self._data, theirs).items()}

    def to_dict(self) -> dict[str, Any]:
        """A deep copy of the nested mapping."""
        return copy.deepcopy(self._data)

    def to_json(self) -> str:
        """The engine's form (what is handed to Rust): without ``[wind.climate]``, which
        Python draws (the engine sees each realisation's wind.heading and wind.speed)."""
        data = self._data
        if "climate" in (data.get("wind") or {}):
            data = strip_climate(copy.deepcopy(data))
        return json.dumps(data, allow_nan=False)

    # -- variants -----------------------------------------------------------------------
    def with_px4_params(self, path: str | Path) -> Scenario:
        """A new Scenario whose ``[controller.px4]`` takes the airframe's parameters from a
        QGroundControl ``.params`` file or a PX4 ``.ulg`` log: the parameters the table knows
        (PX4's names and units; each axis's ``MC_*RATE_K`` multiplies its rate P, I and D, as
        PX4 does; ``MPC_THR_HOVER`` is the position loop's hover feed-forward, as in PX4, the
        thrust's scale staying the vehicle's full thrust), the rest of
        the file ignored (:func:`quadrs.scenario.px4_files.read_px4_parameters` lists them).
        ScenarioError naming the file for one that is neither."""
        from quadrs.scenario.px4_files import px4_changes, read_px4_parameters

        read = read_px4_parameters(path)
        table = self.to_dict().get("controller", {}).get("px4", {})
        return self.override(px4_changes(read, table))

    def override(self, changes: Mapping[str, Any]) -> Scenario:
        """A new Scenario with dotted keys replaced, e.g. ``{"gust.w20": 15.0,
        "payload.mass": 0.44, "phases[2].end": 65.0}``. Setting ``payload.stiffness``
        drops ``payload.natural_frequency`` and vice versa (likewise ``gust.w20`` and
        ``gust.intensity``); a value of None removes an
        optional key (``controller.thrust_max``). Setting ``trajectory.interpolation`` to
        "route" drops the base's ``trajectory.waypoints`` unless they are given too; a
        ``trajectory.route`` of another number of points (or another interpolation) drops the
        base's ``trajectory.lower`` and ``trajectory.names`` (given per point and segment of
        the base's route) unless given too; one of as many points keeps them. A change that
        moves a preset's route (its points, holds, speed, the winch) without setting
        ``integrator.duration`` keeps the preset's margin past the route's end, and its
        whole-flight turbulence unless ``gust.end`` is set (:mod:`quadrs.scenario.route_timing`)."""
        keys = canonical_keys(changes, "override")
        changes = dict(zip(keys, changes.values(), strict=True))
        if "trajectory.route_file" in changes:
            # The route of a file, read now (relative to the working directory), as
            # ``from_plan`` flies it; the other changes are applied with it and win.
            rest = dict(changes)
            name = rest.pop("trajectory.route_file")
            if not isinstance(name, str) or not name:
                raise scenario_error(f"trajectory.route_file must name a .plan or .csv file, "
                                     f"got {name!r}", "trajectory.route_file")  # fmt: skip
            if "trajectory.route" in rest:
                raise scenario_error("trajectory.route and trajectory.route_file: give one or "
                                     "the other", "trajectory.route")  # fmt: skip
            try:
                return Scenario.from_plan(name, base=self, changes=rest)
            except ScenarioError:
                raise
            except ValueError as e:
                raise scenario_error(f"trajectory.route_file = {name!r}: {e}",
                                     "trajectory.route_file") from None  # fmt: skip
        data = copy.deepcopy(self._data)
        if changes.get("trajectory.interpolation") == "route":
            given = {k.removeprefix("trajectory."): v for k, v in changes.items()
                     if k.startswith("trajectory.")}  # fmt: skip
            _route_drops_waypoints(data.get("trajectory", {}), given)
        _route_drops_its_points(data.get("trajectory", {}), changes)
        for key, value in changes.items():
            _set_key(data, key, value, changes)
        new = _following(Scenario, data, self._timing, changes)
        _refuse_unread(new._data, {k: v for k, v in changes.items() if v is not None})
        return new

    # -- uncertain parameters -----------------------------------------------------------
    @property
    def dispersions(self) -> dict[str, dict[str, Any]]:
        """The ``[dispersions]`` table: dotted key -> distribution (empty when fixed)."""
        return copy.deepcopy(self._data.get("dispersions", {}))

    @property
    def dispersed(self) -> bool:
        """True if some key carries a distribution (or a wind climate draws the wind)."""
        return bool(self._data.get("dispersions")) or "climate" in (self._data.get("wind") or {})

    def fixed(self, values: Mapping[str, float] | None = None) -> Scenario:
        """This scenario without its ``[dispersions]`` table, with ``values`` (e.g. the ones a
        realisation drew) set: the scenario one realisation of a dispersed batch flies. Where
        the values move the route's schedule (a drawn winch times its own lowering) its phases
        stay this scenario's windows (``phases = "legs"`` as the nominal schedule gives them),
        as the batch's rows have them: the realisation flies its own schedule in them."""
        data = strip_climate(copy.deepcopy(self._data))
        data.pop("dispersions", None)
        fixed = Scenario(data)
        if not values:
            return fixed
        drawn = fixed.override(dict(values))
        if drawn.phase_windows == fixed.phase_windows:
            return drawn
        windows = [{"name": name, "start": start, "end": end}
                   for name, (start, end) in fixed.phase_windows.items()][:-1]  # fmt: skip
        return drawn.override({"phases": windows})

    def realisation(self, seed: int, realisation: int) -> Scenario:
        """The fixed scenario realisation ``realisation`` of master ``seed`` flies under
        ``sampling="random"`` (its draws depend only on (seed, realisation)); itself when
        nothing is dispersed. For a design (lhs, sobol) use ``MonteCarloResult.scenario_of``."""
        if not self.dispersed:
            return self
        from quadrs.scenario.dispersion import draw

        row = draw(self, seed, realisation, 1).iloc[0]
        return self.fixed({k: float(v) for k, v in row.items()})

    # -- reading ------------------------------------------------------------------------
    def __getitem__(self, key: str) -> Any:
        """A value by dotted key: ``s["gust.w20"]``, ``s["phases[0].name"]``."""
        node: Any = self._data
        for part in _split_key(key):
            try:
                node = node[part]
            except (KeyError, IndexError, TypeError):
                raise KeyError(key) from None
        return copy.deepcopy(node)

    def __contains__(self, key: object) -> bool:
        """``"gust.w20" in s``: whether the scenario holds that dotted key; False for anything
        that is not a valid dotted key (a number, None, a malformed key)."""
        if not isinstance(key, str):
            return False
        try:
            self[key]
        except (KeyError, ValueError):
            return False
        return True

    def get(self, key: str, default: Any = None) -> Any:
        try:
            return self[key]
        except KeyError:
            return default

    def keys(self) -> Iterator[str]:
        """Every leaf as a dotted key (arrays of tables indexed: ``phases[0].end``)."""

        def walk(node: Any, prefix: str) -> Iterator[str]:
            if isinstance(node, dict):
                for k, v in node.items():
                    yield from walk(v, f"{prefix}.{k}" if prefix else k)
            elif isinstance(node, list) and node and all(isinstance(v, dict) for v in node):
                for i, v in enumerate(node):
                    yield from walk(v, f"{prefix}[{i}]")
            else:
                yield prefix

        return walk(self._data, "")

    @cached_property
    def _derived(self) -> _core.Description:
        # Validation and derived numbers only: no engine, no gust filters.
        derived = _core.describe(self.to_json())
        # Shared by every flight and batch of this scenario: nobody may change them in place.
        for frequencies in derived["spectrum_frequencies"]:
            frequencies.flags.writeable = False
        return derived

    @property
    def engine(self) -> _core.Engine:
        """The compiled engine (:mod:`quadrs.engine.compiled`): built on first use, then shared by
        every flight, batch, stability analysis and linearisation of this scenario."""
        engine = self.__dict__.get("_engine")
        if engine is None:
            from quadrs.engine.compiled import compiled

            engine = self.__dict__["_engine"] = compiled(self.to_json())
        return engine

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without its engine (rebuilt, or found in the cache, where it is used)."""
        state = self.__dict__.copy()
        state.pop("_engine", None)
        return state

    @property
    def stiffness(self) -> float:
        """Attachment stiffness kc (N/m), whichever way it was given."""
        return float(self._derived["stiffness"])

    @property
    def hover_offset(self) -> float:
        """Static stretch d0 = mc g / kc (m): the payload hangs this far below at hover."""
        return float(self._derived["hover_offset"])

    @property
    def turbulence_w20(self) -> float:
        """W20 of the turbulence (m/s): ``gust.w20``, or the level ``gust.intensity`` names."""
        return float(self._derived["turbulence_w20"])

    @property
    def steps(self) -> int:
        """RK4 steps of one flight."""
        return int(self._derived["steps"])

    @property
    def state_names(self) -> list[str]:
        """The states of this scenario's vehicle, in the engine's order."""
        return list(self._derived["state_names"])

    @property
    def trace_columns(self) -> list[str]:
        """The columns of a flight's trace (after the time index)."""
        return list(self._derived["trace_columns"])

    @property
    def phase_names(self) -> list[str]:
        """The phases every result has a row for: the scenario's own (``scenario_phases``),
        then ``"flight"``, the whole flight (docs/model.md, "Routes")."""
        return list(self._derived["phases"])

    @property
    def scenario_phases(self) -> list[str]:
        """The phases the scenario itself names (``phases``, or a route's legs and holds under
        ``phases = "legs"``), without the whole-flight phase."""
        return [p for p in self.phase_names if p != FLIGHT_PHASE]

    @property
    def phase_windows(self) -> dict[str, tuple[float, float]]:
        """Each phase's time window (s, both ends included), ``"flight"`` last."""
        return {str(n): (float(a), float(b)) for n, a, b in self._derived["phase_windows"]}

    @property
    def route(self) -> Route | None:
        """The schedule of a route (``trajectory.interpolation = "route"``): its legs and
        holds with their times, lengths and arrival; None for waypoint trajectories."""
        segments = self._derived["route"]
        return Route.from_engine(segments) if segments else None

    @property
    def spectrum_frequencies(self) -> list[Any]:
        """Per phase, the frequencies (Hz) of its amplitude-spectrum bins (read-only arrays,
        shared by every flight of this scenario: ``np.array(f)`` for a copy to change)."""
        return list(self._derived["spectrum_frequencies"])

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scenario) and self._data == other._data

    def __hash__(self) -> int:
        # Agrees with __eq__: equal mappings give equal frozen images, whatever their key
        # order or number types (1 == 1.0).
        return hash(_frozen(self._data))

    def __repr__(self) -> str:
        p, g = self._data["payload"], self._data["gust"]
        attach = (
            f"fn={p['natural_frequency']} Hz"
            if "natural_frequency" in p
            else f"kc={p['stiffness']} N/m"
        )
        if p.get("model") == "cable":
            attach = f"on a {p['cable_length']} m cable, {attach}"
        level = f"w20={g['w20']} m/s" if "w20" in g else f"{g.get('intensity')}"
        gust = f"{g['model']} {level}" if g["enabled"] else "off"
        dt = self["integrator.dt"]
        n = len(self._data.get("dispersions", {}))
        spread = f", {n} dispersed key{'s' if n > 1 else ''}" if n else ""
        return f"<Scenario payload {p['mass']} kg {attach}, gust {gust}, dt={dt}{spread}>"
