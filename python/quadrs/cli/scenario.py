"""``quadrs scenario``: inspect scenarios. ``show`` prints one as TOML laid out like its preset
(or only what differs from it), ``keys`` every dotted key with its value and unit, ``presets``
the shipped presets."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from quadrs.cli.common import EXIT_OK, command_parser

__all__ = ["add_scenario", "cmd_scenario"]


def add_scenario(sub: Any, common: argparse.ArgumentParser) -> None:
    """show a scenario, list its keys or the presets

    Inspect scenarios: `show` prints the full TOML (SI units) laid out like its preset, with the
    preset's comments and units, `keys` every dotted key with its value and unit, `presets` the
    shipped presets."""
    p = command_parser(sub, add_scenario)
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
        _print_keys(scenario, base_preset(args), args.scenario is not None)
    return EXIT_OK


def _print_keys(scenario: Any, preset: str, from_file: bool) -> None:
    """Every key the scenario sets with its value and unit (``wind.speed`` with where it
    blows at that speed and what it becomes at the route's height); then which preset that
    is and the others; then the keys it leaves unset."""
    from quadrs.present.table3 import toml_value
    from quadrs.scenario.scenario import presets
    from quadrs.scenario.units import unit

    lines = [(f"{key} = {toml_value(scenario[key])}", key) for key in scenario.keys()]
    width = min(max(len(line) for line, _ in lines), 60)
    for line, key in lines:
        try:
            said = unit(key) + (_wind_heights(scenario) if key == "wind.speed" else "")
            print(f"{line:<{width}}  # {said}")
        except KeyError:  # a key the units table does not know (the engine refuses those)
            print(line)
    others = ", ".join(f"--preset {p}" for p in presets() if p != preset)
    what = f"a scenario file based on the preset {preset!r}" if from_file else (
        f"the preset {preset!r}")  # fmt: skip
    print(f"\n# These are the keys of {what}; another's: {others} (delivery flies a route with "
          "a winch, a sheared wind and the ground)")  # fmt: skip
    _print_unset_keys(scenario)


def _wind_heights(scenario: Any) -> str:
    """Where ``wind.speed`` blows at that speed (20 ft) and, through ``wind.shear``, the mean
    wind at the route's highest point."""
    import numpy as np

    from quadrs import _core

    said = " at 20 ft (6.1 m)"
    route = scenario.get("trajectory.route")
    if scenario.get("trajectory.interpolation") != "route" or not route:
        return said
    height = max(float(p[2]) for p in route)
    w = _core.mean_wind(scenario.to_json(), np.array([height]))[0]
    shear = scenario.get("wind.shear")
    return (
        f"{said}; {float(np.hypot(w[0], w[1])):.3g} m/s at the route's {height:g} m "
        f'(wind.shear = "{shear}")'
    )


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
    print("# Not set here (optional tables and other kinds' keys; --set or a file may give "
          "them):")  # fmt: skip
    width = min(max(len(k) for k in unset), 48)
    elsewhere = _set_by_presets()
    for key in unset:
        where = elsewhere.get(key, "")
        print(f"# {key:<{width}}  {UNITS[key]:<8} {LABELS.get(key, '')}{where}".rstrip())


def _set_by_presets() -> dict[str, str]:
    """Per key (indices dropped) a preset sets: `` (delivery: 1.0)``, the presets' values."""
    import re

    from quadrs.present.table3 import toml_value
    from quadrs.scenario.scenario import Scenario, presets

    index = re.compile(r"\[\d+\]")
    found: dict[str, list[str]] = {}
    for name in presets():
        s = Scenario.preset(name)
        for key in s.keys():
            if not index.search(key):
                found.setdefault(key, []).append(f"{name}: {toml_value(s[key])[:24]}")
    return {k: f" ({'; '.join(v)})" for k, v in found.items()}
