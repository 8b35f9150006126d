"""``quadrs sweep``: a Monte Carlo batch at every point of a grid of one or two scenario keys,
with the same seed at every point, and its compact summary."""

from __future__ import annotations

import argparse
from typing import Any

from quadrs.cli import common

__all__ = ["add_sweep", "cmd_sweep"]


def add_sweep(sub: Any, options: argparse.ArgumentParser) -> None:
    """Monte Carlo at every point of a one- or two-key grid

    Run a Monte Carlo batch at every grid point of one or two scenario keys, with the same seed at
    every point (common random numbers: differences between points are not gust noise). Prints mean
    IAE (m s) and ITAE (m s^2) per controller and P = 100 SMC/PD (%) per point and phase."""
    p = common.command_parser(sub, add_sweep, options)
    p.add_argument(
        "--param",
        required=True,
        metavar="KEY",
        help="dotted scenario key to sweep, e.g. payload.natural_frequency (Hz)",
    )
    p.add_argument(
        "--values",
        required=True,
        type=common._values,
        metavar="V1,V2,...",
        help="its values in the key's unit, comma-separated (or a TOML array)",
    )
    p.add_argument("--param2", metavar="KEY", help="optional second key (full grid)")
    p.add_argument("--values2", type=common._values, metavar="V1,V2,...", help="values of --param2")
    common.batch_options(p, 100, "write the tidy runs table of every point (swept keys as columns)")
    common.plots_option(p, "write the sweep's figures here")
    common.limit_options(p)


def cmd_sweep(args: argparse.Namespace) -> int:
    """A one- or two-key sweep: compact summary, optional Parquet and figures."""
    from quadrs.cli.outputs import check_outputs, check_suffix, save_runs
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.cli.tables import print_frame, print_limits
    from quadrs.runs.sweep import sweep

    scenario = load_scenario(args)
    grid = {args.param: args.values}
    if (args.param2 is None) != (args.values2 is None):
        raise common.BadInput("--param2 and --values2 go together")
    if args.param2 is not None:
        if args.param2 == args.param:
            raise common.BadInput(f"--param2 {args.param2}: the same key as --param")
        grid[args.param2] = args.values2
    check_suffix(args.out, (".parquet",), "--out")
    common.check_positive("--runs", args.runs)
    common.check_positive("--workers", args.workers)
    check_outputs(args.out)
    with common.batch_scope(args.scheduler) as batch:
        result = sweep(scenario, grid, controllers=args.controllers, **batch.keywords(args))
        batch.flown()
        saved = save_runs(result, args.out)
    if not result.runs.empty:
        print_frame(result.compact())
        print_limits(result, args)
    if args.plots is not None and not result.runs.empty:
        from quadrs.cli.figures import sweep_plots

        sweep_plots(result, args.plots)
    return common.batch_status(result, saved)
