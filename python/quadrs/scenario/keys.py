"""Dotted keys and single values of a scenario: the one spelling of a key
(``controller.pd.kp[02]`` is ``controller.pd.kp[2]``), a value given on the command line
(TOML syntax, else a bare string) and a value written back on one line, and the
:class:`ScenarioError` that names the key at fault."""

from __future__ import annotations

import json
import re
import sys
from collections.abc import Iterable, Mapping
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover  (Python 3.10: the same parser, as a package)
    import tomli as tomllib

from quadrs import _core

ScenarioError = _core.ScenarioError


def scenario_error(message: str, key: str | None) -> ScenarioError:
    """A :class:`ScenarioError` whose ``key`` attribute names the dotted key at fault (as
    the engine's own do), None when no single key is."""
    error = ScenarioError(message)
    error.key = key
    return error


_SEGMENT = re.compile(r"^(?P<name>[A-Za-z_][A-Za-z0-9_]*)(?P<index>(\[\d+\])*)$")


def parse_value(text: str) -> Any:
    """A command-line value: TOML syntax (numbers, booleans, arrays, quoted strings), else a
    bare string. ``"2"`` -> 2, ``"[1, 2]"`` -> [1, 2], ``"min_jerk"`` -> "min_jerk"."""
    try:
        value = tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:
        raise scenario_error(f"{text[:40]!r}...: a value nested too deeply", None) from None
    return value


def _split_key(key: str) -> list[str | int]:
    """``"phases[1].end"`` -> ["phases", 1, "end"]."""
    if not isinstance(key, str) or not key:
        raise scenario_error(f"scenario keys are dotted strings, got {key!r}", None)
    parts: list[str | int] = []
    for segment in key.split("."):
        m = _SEGMENT.match(segment)
        if m is None:
            raise scenario_error(f"{key}: not a valid dotted key (segment {segment!r})", key)
        parts.append(m["name"])
        parts.extend(int(i) for i in re.findall(r"\[(\d+)\]", m["index"]))
    return parts


def canonical_key(key: str) -> str:
    """The one spelling of a dotted key: ``"controller.pd.kp[02]"`` -> ``"controller.pd.kp[2]"``
    (indices without leading zeros). Every key a user gives (dispersions, ``override``,
    sweeps, optimised parameters) goes through it, so two spellings never name two keys."""
    out = ""
    for part in _split_key(key):
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else part)
    return out


def canonical_keys(keys: Iterable[str], what: str) -> list[str]:
    """``keys`` in their canonical spelling; ScenarioError naming both spellings if two of
    them are one key (``what``: where they were given, for the message)."""
    seen: dict[str, str] = {}
    out = []
    for key in keys:
        canon = canonical_key(key)
        if canon in seen:
            raise scenario_error(
                f"{what}: {seen[canon]!r} and {key!r} are the same key ({canon}); give it once",
                canon,
            )
        seen[canon] = key
        out.append(canon)
    return out


def _dotted(path: tuple[str, ...]) -> str:
    """A path as a dotted key, quoting parts that hold a dot (``dispersions."payload.mass"``)."""
    return ".".join(json.dumps(p) if not _SEGMENT.match(p) else p for p in path)


def toml_value(value: Any) -> str:
    """``value`` in TOML syntax on one line (what ``quadrs --set KEY=VALUE`` accepts back)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, list | tuple):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    return json.dumps(str(value))


def dotted_value(data: Mapping[str, Any], key: str, default: Any = None) -> Any:
    """The value of a plain dotted ``key`` (no indices) in a scenario's nested mapping, or
    ``default`` where a table on the way or the key is missing (read before the scenario is
    checked)."""
    node: Any = data
    for part in key.split("."):
        if not isinstance(node, Mapping) or part not in node:
            return default
        node = node[part]
    return node
