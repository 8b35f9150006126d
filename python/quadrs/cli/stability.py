"""``quadrs stability``: the closed loop linearised at hover, its poles and a verdict for each
controller (exit 1 when one is unstable)."""

from __future__ import annotations

import argparse
from typing import Any

from quadrs.cli import common

__all__ = ["add_stability", "cmd_stability"]


def add_stability(sub: Any, options: argparse.ArgumentParser) -> None:
    """closed-loop poles at hover and a verdict

    Linearise the closed loop at hover and print its poles (1/s) and a stability verdict for each
    controller."""
    p = common.command_parser(sub, add_stability, options)
    common.controller_option(p, both=True)
    p.add_argument(
        "--poles",
        action="store_true",
        help="also print every pole (real and imaginary part in 1/s, frequency in Hz)",
    )


def cmd_stability(args: argparse.Namespace) -> int:
    """Closed-loop poles at hover, per controller."""
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.cli.tables import print_frame
    from quadrs.hover.stability import stability as check

    scenario = load_scenario(args)
    controllers = common.paper_controllers() if args.controller == "both" else (args.controller,)
    unstable = False
    for controller in controllers:
        report = check(scenario, controller=controller)
        print(f"== {controller.upper()} ==")
        print(str(report))
        if args.poles:
            print_frame(report.poles)
        unstable |= report.verdict == "unstable"
    return common.EXIT_FAIL if unstable else common.EXIT_OK
