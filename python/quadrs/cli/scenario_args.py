"""The scenario a command's options give: ``--preset`` or ``--scenario``, every ``--set`` and
``--disperse`` applied at once, and the route of ``--plan`` for the commands that have it
(the options themselves: :func:`quadrs.cli.common.scenario_options`)."""

from __future__ import annotations

import argparse
from typing import Any

from quadrs.cli.common import BadInput

__all__ = ["base_preset", "load_scenario", "parse_distribution"]


def base_preset(args: argparse.Namespace) -> str:
    """The preset the scenario starts from: its file's ``base``, else --preset, else paper."""
    from quadrs.scenario.scenario import base_preset as file_base

    found = file_base(args.scenario) if args.scenario is not None else None
    return found or args.preset or "paper"


def load_scenario(args: argparse.Namespace) -> Any:
    """The scenario of ``--preset``/``--scenario`` with every ``--set`` applied at once, then
    flying the route of ``--plan`` if the command has it (quadrs.scenario.route_files)."""
    from quadrs.scenario.scenario import Scenario, canonical_key, parse_value

    if args.scenario is not None and args.preset is not None:
        raise BadInput("--preset and --scenario: give one or the other")
    if args.scenario is not None:
        base = Scenario.from_toml(args.scenario)
    else:
        base = Scenario.preset(args.preset or "paper")
    changes: dict[str, Any] = {}
    for item in args.overrides:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise BadInput(f"--set {item!r}: expected KEY=VALUE")
        changes[key] = parse_value(value.strip())
    if args.dispersions:
        table = dict(base.dispersions)
        if isinstance(changes.get("dispersions"), dict):
            table.update(changes.pop("dispersions"))
        for item in args.dispersions:
            key, sep, spec = item.partition("=")
            if not sep or not key.strip():
                raise BadInput(f"--disperse {item!r}: expected KEY=DIST(ARGS)")
            table[canonical_key(key.strip())] = parse_distribution(spec)  # replaces the base's
        changes["dispersions"] = table
    plan = getattr(args, "plan", None)
    if plan is None:
        return base.override(changes) if changes else base
    if "trajectory.route_file" in changes:
        raise BadInput("--plan and --set trajectory.route_file: give one route file")
    return Scenario.from_plan(plan, base, changes)


def _top_level_split(text: str) -> list[str]:
    """``text`` split at the commas outside brackets (``choice``'s lists stay whole)."""
    parts, depth, start = [], 0, 0
    for i, c in enumerate(text):
        depth += (c == "[") - (c == "]")
        if c == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    return [*parts, text[start:]]


def parse_distribution(text: str) -> dict[str, Any]:
    """``"uniform(0.1, 0.4)"`` or ``"normal(mean=2, std=0.2)"`` -> a dispersion entry."""
    from quadrs.scenario.dispersion import DISTRIBUTIONS
    from quadrs.scenario.scenario import parse_value

    name, sep, rest = text.strip().partition("(")
    name = name.strip()
    if not sep or not rest.endswith(")") or name not in DISTRIBUTIONS:
        raise BadInput(
            f"--disperse: {text!r} is not DIST(ARGS) with DIST one of {', '.join(DISTRIBUTIONS)}"
        )
    order = DISTRIBUTIONS[name]
    spec: dict[str, Any] = {"dist": name}
    args = [a.strip() for a in _top_level_split(rest[:-1]) if a.strip()]
    for i, arg in enumerate(args):
        pname, eq, value = arg.partition("=")
        if not eq:
            if i >= len(order):
                raise BadInput(f"--disperse: {name} takes {len(order)} values ({', '.join(order)})")
            pname, value = order[i], arg
        spec[pname.strip()] = parse_value(value.strip())
    return spec
