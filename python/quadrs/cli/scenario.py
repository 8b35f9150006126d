"""``quadrs scenario``: inspect scenarios. ``show`` prints one as TOML laid out like its preset
(or only what differs from it), ``keys`` every dotted key with its value and unit, ``presets``
the shipped presets."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from quadrs.cli.common import EXIT_OK

__all__ = ["add_scenario", "cmd_scenario"]


def add_scenario(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "scenario",
        help="show a scenario, list its keys or the presets",
        description="Inspect scenarios: `show` prints the full TOML (SI units) laid out like "
        "its preset, with the preset's comments and units, `keys` every dotted key with its "
        "value and unit, `presets` the shipped presets.",
    )
    ssub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    show = ssub.add_parser("show", parents=[common], help="print the scenario as TOML")
    show.add_argument(
        "--diff",
        action="store_true",
        help="print only the keys that differ from the preset the scenario starts from "
        "(its `base`, else the --preset, else paper), as KEY = VALUE  # preset: OLD",
    )
    ssub.add_parser("keys", parents=[common], help="list every dotted key = current value  # unit")
    ssub.add_parser("presets", help="list the shipped presets")


def cmd_scenario(args: argparse.Namespace) -> int:
    """Show a scenario as TOML, list its keys, or list the presets."""
    from quadrs.cli.scenario_args import base_preset, load_scenario
    from quadrs.present.table3 import toml_value
    from quadrs.scenario.scenario import Scenario, presets

    if args.action == "presets":
        print("\n".join(presets()))
        return EXIT_OK
    scenario = load_scenario(args)
    if args.action == "show":
        base = base_preset(args)
        if not args.diff:
            sys.stdout.write(scenario.to_toml(like=base))
            return EXIT_OK
        changes = scenario.differences(Scenario.preset(base))
        print(f"# {len(changes)} key(s) differ from the preset {base!r}")
        for key, (old, new) in changes.items():
            was = f"{base}: {'not set' if old is None else toml_value(old)}"
            line = f"# {key} not set" if new is None else f"{key} = {toml_value(new)}"
            print(f"{line:<37} # {was}")
    else:
        from quadrs.scenario.units import unit

        lines = [(f"{key} = {toml_value(scenario[key])}", key) for key in scenario.keys()]
        width = min(max(len(line) for line, _ in lines), 60)
        for line, key in lines:
            try:
                print(f"{line:<{width}}  # {unit(key)}")
            except KeyError:  # a key the units table does not know (the engine refuses those)
                print(line)
        _print_unset_keys(scenario)
    return EXIT_OK


def _print_unset_keys(scenario: Any) -> None:
    """The keys this scenario does not set (optional tables such as ``wind.table``,
    ``actuator.faults``, other kinds' parameters), with their units and labels: every key the
    scenario may take, from the one table of them (``quadrs.scenario.units``)."""
    import re

    from quadrs.scenario.units import LABELS, UNITS

    index = re.compile(r"\[\d+\]")
    present = {index.sub("", k) for k in scenario.keys()}
    unset = [k for k in sorted(UNITS) if k not in present
             and not any(k.startswith(f"{p}.") for p in present)]  # fmt: skip
    if not unset:
        return
    print("\n# Not set here (optional tables and other kinds' keys; --set or a file may give "
          "them):")  # fmt: skip
    width = min(max(len(k) for k in unset), 48)
    for key in unset:
        print(f"# {key:<{width}}  {UNITS[key]:<8} {LABELS.get(key, '')}".rstrip())
