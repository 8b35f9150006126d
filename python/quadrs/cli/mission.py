"""``quadrs mission``: will my parcel survive this route? One command over a Monte Carlo
batch: per phase (a route's legs and holds) and for the whole flight, the probability that
the payload's acceleration exceeds ``--limit``, the worst and a high quantile of swing and
tension, the tracking errors, with intervals (:mod:`quadrs.design.mission`; docs/delivery.md).

Kept apart from :mod:`quadrs.cli.main`, which registers the subcommand.
"""

from __future__ import annotations

import argparse
import copy
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from quadrs.cli.common import (
    EXIT_INTERRUPT,
    batch_scope,
    batch_status,
    command_parser,
    import_in_background,
    no_progress_option,
    note,
    parquet_out_option,
    plots_option,
    report_width,
    scheduler_option,
    seed_and_workers,
)
from quadrs.cli.safety_case import check_safety_case, safety_case_options, safety_outputs
from quadrs.engine.calls import CONTROLLERS

#: The parcel's default question: its peak specific force (what an accelerometer in the box
#: reads, packaging fragility's g: 1 g at rest) past 2 g (m/s^2, standard g), the 1 g of
#: kinematic acceleration this limit was before added to gravity's when vertical.
DEFAULT_METRIC = "max_specific_force"
DEFAULT_LIMIT = 2.0 * 9.80665
#: Default route tracking limit, m (quadrs.design.mission.TRACK_LIMIT).
TRACK_LIMIT = 10.0
#: The scenario mission flies without --preset or --scenario.
DEFAULT_PRESET = "delivery"


def _number(text: str, ok: Callable[[float], bool], expected: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not ok(value):
        raise argparse.ArgumentTypeError(f"must be {expected}, got {text!r}")
    return value


def _positive(text: str) -> float:
    return _number(text, lambda v: math.isfinite(v) and v > 0, "finite and > 0")


def mission_limit(text: str) -> tuple[str, float]:
    """``--limit 5`` (max_accel, m/s^2), ``--limit 2g`` (in g: max_specific_force, the
    default's metric) or ``--limit METRIC=X``, as in ``quadrs report``: any metric the engine
    names, X in the unit every table shows (degrees for swing)."""
    from quadrs.cli.common import limit_option

    if "=" not in text and text.strip().lower().endswith("g"):
        # In g, the parcel's fragility is the specific force (what the default 2 g reads);
        # a bare number in m/s^2 stays max_accel, as in the other commands.
        text = f"{DEFAULT_METRIC}={text}"
    metric, value = limit_option(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return metric, value


def laws(text: str) -> tuple[str, ...]:
    """``pd`` or ``pd,smc,...``: control laws the engine has, each once."""
    names = tuple(n.strip() for n in text.split(","))
    for n in names:
        if n not in CONTROLLERS:
            raise argparse.ArgumentTypeError(
                f"{n!r} is not a control law: one of {', '.join(CONTROLLERS)}"
            )
    if len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(f"each law once, got {text!r}")
    return names


def _fraction(text: str) -> float:
    return _number(text, lambda v: 0 < v < 1, "in (0, 1)")


def add_mission(sub: Any, common: argparse.ArgumentParser) -> None:
    """will the parcel survive this route? per-leg risk of a Monte Carlo batch

    Fly --runs gust realisations of the scenario (default: --preset delivery) with one controller
    and print, first, whether the route was flown (tracking and cross-track error against
    --track-limit, divergence, time at the thrust limit), then per phase (a route's legs and holds
    under phases = "legs") and for the whole flight: the probability that the payload's peak
    acceleration exceeds --limit (exact 95% interval), the worst and the --quantile of the swing and
    the cable tension, slack and saturated time, and the tracking errors, with intervals (see
    docs/delivery.md). Diverged flights count as exceeding."""
    p = command_parser(sub, add_mission, common)
    _preset_help(p, f"start from a shipped preset (default: {DEFAULT_PRESET})")
    p.add_argument(
        "--runs",
        type=int,
        default=200,
        metavar="N",
        help="gust realisations (default: %(default)s)",
    )
    p.add_argument(
        "--limit",
        type=mission_limit,
        default=(DEFAULT_METRIC, DEFAULT_LIMIT),
        metavar="METRIC=X",
        help="the parcel's question, P(METRIC > X): any metric, X in the unit the tables show "
        "(degrees for swing; an acceleration in m/s^2 or g: max_specific_force=2g); a bare X "
        "in m/s^2 is max_accel=X, the kinematic acceleration (0 at rest), a bare Xg the "
        "specific force, as the default "
        f"(default: {DEFAULT_METRIC}=2g, the specific force an accelerometer in the box "
        "reads, 1 g at rest)",
    )
    p.add_argument(
        "--track-limit",
        type=_positive,
        default=TRACK_LIMIT,
        metavar="M",
        help="a flight whose tracking error (3-D distance from its reference) passes M metres "
        "in a phase is off its route there (default: %(default)s)",
    )
    p.add_argument(
        "--cross-track-limit",
        type=_positive,
        default=None,
        metavar="M",
        help="likewise for the cross-track error, m (default: the --track-limit)",
    )
    p.add_argument(
        "--touchdown-limit",
        type=_positive,
        default=1.0,
        metavar="V",
        help="a route that lowers its parcel leads with P(touchdown faster than V m/s) (default 1)",
    )
    p.add_argument(
        "--quantile",
        type=_fraction,
        default=0.95,
        metavar="Q",
        help="the high quantile shown beside the worst (default: %(default)s)",
    )
    p.add_argument(
        "--controller",
        type=laws,
        default=("pd",),
        metavar="LAW[,LAW...]",
        help=f"control law, one of {', '.join(CONTROLLERS)} (default: pd); several, "
        "comma-separated, fly the same gusts and are compared leg by leg against the first",
    )
    p.add_argument(
        "--plan",
        type=Path,
        metavar="FILE",
        help="fly the route of a QGroundControl .plan mission (waypoints about its planned "
        "home: x east, y north, z above home) or of a .csv of points (x,y,z or lat,lon,alt; "
        "optional hold), at the file's speed; docs/delivery.md",
    )
    p.add_argument(
        "--px4-params",
        type=Path,
        metavar="FILE",
        help="the airframe's PX4 parameters for the px4 law, from a QGroundControl .params file "
        "or a PX4 .ulg log: those [controller.px4] knows are read (PX4's names and units; "
        "--set controller.px4.* wins over the file), the others listed and ignored; needs the "
        'px4 law in --controller (docs/delivery.md, "PX4 files")',
    )
    seed_and_workers(p)
    scheduler_option(p)
    parquet_out_option(
        p, "write the runs with their run record (as quadrs mc --out; quadrs report reads it)"
    )
    plots_option(p, "write the figures here")
    safety_case_options(p)
    no_progress_option(p)


def _preset_help(p: argparse.ArgumentParser, text: str) -> None:
    """``--preset``'s help in this command alone: the scenario options are shared by every
    command (argparse's parents share their action objects), and mission's default differs."""
    for i, action in enumerate(p._actions):
        if action.dest == "preset":
            own = copy.copy(action)
            own.help = text
            p._actions[i] = own
            for group in p._action_groups:
                group._group_actions[:] = [own if a is action else a
                                           for a in group._group_actions]  # fmt: skip
            for option in action.option_strings:
                p._option_string_actions[option] = own


def cmd_mission(args: argparse.Namespace) -> int:
    from quadrs.cli.outputs import check_directories, check_outputs, save_runs
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.engine.calls import check_int
    from quadrs.runs.montecarlo import monte_carlo

    if args.preset is None and args.scenario is None:
        args.preset = DEFAULT_PRESET  # a mission is a route: the delivery preset's
    scenario = load_scenario(args)  # --px4-params read there, before --set (which wins)
    if args.out is not None and args.out.suffix.lower() != ".parquet":
        raise ValueError(f"--out {str(args.out)!r}: expected a file ending in .parquet")
    for name in ("runs", "workers"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise ValueError(f"--{name} must be >= 1, got {value}")
    check_int("--seed", args.seed)
    check_outputs(args.out)
    check_safety_case(args)
    check_directories(args.plots)
    # Calibrated here, not on a cluster (whose speed is not this machine's): the calibration's
    # flights are the batch's first, taken rather than flown again.
    flown = [] if args.scheduler is not None else _announce(scenario, args)
    # The report's statistics (scipy.stats, ~0.5 s to import) load while the batch flies: a
    # third-party package the batch itself never imports, so the two threads' imports do not
    # wait on each other.
    import_in_background("scipy.stats")

    with batch_scope(args.scheduler) as batch:
        mc = monte_carlo(scenario, controllers=args.controller, spectra=False, flown=flown,
                         **batch.keywords(args))  # fmt: skip
        batch.flown()
        metric, limit = args.limit
        mc.question = {  # saved with the runs: quadrs report asks it again
            "metric": metric,
            "limit": limit,
            "track_limit": args.track_limit,
            "cross_track_limit": args.cross_track_limit,
            "quantile": args.quantile,
            "touchdown_limit": args.touchdown_limit,
            "targets": dict(args.target),
        }
        saved = save_runs(mc, args.out)
    if mc.runs.empty:
        print("quadrs mission: interrupted before any flight finished", file=sys.stderr)
        return EXIT_INTERRUPT
    from quadrs.design.mission import mission_report

    if len(args.controller) > 1:
        from quadrs.design.mission_compare import compare_laws

        compared = compare_laws(mc, limit, args.controller, metric, args.quantile,
                                track_limit=args.track_limit,
                                cross_track_limit=args.cross_track_limit)  # fmt: skip
        reports = list(compared.reports.values())
        text = compared.to_text(width=report_width())
    else:
        reports = [mission_report(mc, limit, args.controller[0], args.quantile, metric=metric,
                                  track_limit=args.track_limit,
                                  cross_track_limit=args.cross_track_limit,
                                  touchdown_limit=args.touchdown_limit)]  # fmt: skip
        text = reports[0].to_text(width=report_width())
    if mc.interrupted:
        print(f"(interrupted: {reports[0].runs} of {args.runs} realisations finished)")
    print(text)
    saved = safety_outputs(mc, reports, args) and saved
    if args.plots is not None:
        from quadrs.cli.figures import mission_plots

        mission_plots(mc, reports, args.plots)
    return batch_status(mc, saved)


def _announce(scenario: Any, args: argparse.Namespace) -> list[Any]:
    """What the command flies and roughly how long, from a short calibration, on stderr;
    returns the calibration's flights (the batch's first realisations)."""
    from quadrs.cli.cost import announce, calibrate, precheck, say

    precheck(scenario, args.controller, args.runs, args.workers, args.seed)
    _say_clashes(scenario, args.controller)
    cal = calibrate(scenario, args.controller, args.workers, args.seed, at_most=args.runs)
    duration = float(scenario["integrator.duration"])
    what = f"{args.runs} realisations of a {duration:g} s flight"
    say(announce("mission", what, args.runs, cal), cal.estimate(args.runs))
    return [cal.chunk] if cal.chunk is not None else []


def _say_clashes(scenario: Any, controllers: tuple[str, ...]) -> None:
    """Before flying, on stderr: each leg whose reference asks as much as or more than a limit
    of the law (quadrs.design.route_limits): the flights will fall behind it there."""
    from quadrs.design.route_limits import route_clashes

    for law in controllers:
        for clash in route_clashes(scenario, law):
            note(f"quadrs mission: {law}: {clash} (the reference will be flown slower, off its "
                 "schedule)")  # fmt: skip
