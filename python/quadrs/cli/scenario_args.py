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
    from quadrs.scenario.scenario import Scenario, ScenarioError, canonical_key, parse_value

    if args.scenario is not None and args.preset is not None:
        raise BadInput("--preset and --scenario: give one or the other")
    changes: dict[str, Any] = {}
    for item in args.overrides:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise BadInput(f"--set {item!r}: expected KEY=VALUE")
        changes[key] = parse_value(value.strip())
    if args.scenario is not None:
        # --set is laid on the file before the file is checked: a value the checks refuse
        # (the error's own advice: "set it to at least ...") can be fixed on the command line.
        try:
            base = Scenario.from_toml(args.scenario)
        except ScenarioError:
            if not changes:
                raise
            base = Scenario.from_toml(args.scenario, changes=changes)
    else:
        base = Scenario.preset(args.preset or "paper")
    if getattr(args, "px4_params", None) is not None:
        base = _with_px4_file(base, args)  # before --set: a key set explicitly wins
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


def _with_px4_file(base: Any, args: argparse.Namespace) -> Any:
    """``base`` with the parameters of ``--px4-params`` in ``[controller.px4]``, what was read
    said on stderr; refused (exit 2) when no law flown reads them."""
    import sys

    from quadrs.present.terminal import terminal_text
    from quadrs.scenario.px4_files import px4_changes, read_px4_parameters

    read = read_px4_parameters(args.px4_params)  # a file that is not PX4's: said first
    laws = tuple(getattr(args, "controller", ()) or ())
    if "px4" not in laws:
        raise BadInput(
            terminal_text(f"--px4-params {str(args.px4_params)!r}: its parameters go into "
                          f"[controller.px4], which only the px4 law reads; --controller "
                          f"{','.join(laws)} would fly without them: add px4 to --controller")
        )  # fmt: skip
    table = base.to_dict().get("controller", {}).get("px4", {})
    print(terminal_text(f"quadrs {args.command}: --px4-params {read.note()}"), file=sys.stderr)
    return base.override(px4_changes(read, table))


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
