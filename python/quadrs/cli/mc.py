"""``quadrs mc``: a paired Monte Carlo batch (every controller through the same gusts) and its
Table-3 summary (a route's mission tables instead); the runs saved, checkpointed and resumed,
figures and exceedance tables on request."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from quadrs.cli import common

__all__ = ["add_mc", "cmd_mc"]


def add_mc(sub: Any, options: argparse.ArgumentParser) -> None:
    """Monte Carlo batch; prints the Table-3 summary

    Fly many gust realisations with every controller (paired: the same gust for each) and print the
    paper's Table 3 with 95% confidence intervals (IAE in m s, ITAE in m s^2; P = 100 SMC/PD in
    percent)."""
    p = common.command_parser(sub, add_mc, options)
    common.batch_options(p, 1000, "write the runs (one row per realisation, controller, phase)")
    common.table_options(p)
    common.plots_option(p, "write the batch's figures here")
    p.add_argument(
        "--checkpoint",
        type=Path,
        metavar="DIR",
        help="append each finished chunk of realisations to this Parquet dataset directory "
        "as it completes, so a killed run loses at most the chunks in flight",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --checkpoint DIR: fly only the realisations it lacks "
        "(same scenario, seed and controllers required)",
    )
    p.add_argument(
        "--chunk",
        type=int,
        metavar="N",
        help="realisations per chunk (default: about 1/20 of the runs when checkpointing, "
        "4 tasks per thread on Dask, else all at once)",
    )
    p.add_argument(
        "--fused",
        action="store_true",
        help="fused multiply-adds: faster, equal to the default to about 1e-12 but not bit for "
        "bit, and not across instruction sets (docs/performance.md); recorded in --out and "
        "--checkpoint",
    )
    common.limit_options(p)


def cmd_mc(args: argparse.Namespace) -> int:
    """A Monte Carlo batch: Table 3, optional Parquet and figures; 130 if interrupted."""
    from quadrs.cli.outputs import check_directories, check_outputs, check_suffix, save_runs
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.cli.tables import (
        is_mission,
        print_dispersions,
        print_limits,
        print_mission,
        print_table3,
    )
    from quadrs.runs.montecarlo import monte_carlo

    scenario = load_scenario(args)
    check_suffix(args.out, (".parquet",), "--out")
    common.check_positive("--runs", args.runs)
    common.check_positive("--workers", args.workers)
    common.check_positive("--chunk", args.chunk)
    if args.resume and args.checkpoint is None:
        raise common.BadInput("--resume needs --checkpoint DIR (the run to continue)")
    if args.checkpoint is not None and not args.resume and args.checkpoint.exists():
        if any(args.checkpoint.iterdir()):
            held = f"--checkpoint {args.checkpoint} already holds a run: add --resume"
            raise common.BadInput(held)
    check_outputs(args.out)
    check_directories(args.plots)
    if args.scheduler is None:  # a cluster's speed is not this machine's
        from quadrs.cli.cost import announce_batch

        announce_batch("mc", scenario, args.controllers, args.runs, args.workers, args.seed)
    with common.batch_scope(args.scheduler) as batch:
        mc = monte_carlo(
            scenario,
            controllers=args.controllers,
            out=args.checkpoint,
            **batch.keywords(args),
            **common.passed(args, "resume", "chunk", "sampling", "fused"),
        )
        batch.flown()
        saved = save_runs(mc, args.out)
    if not mc.runs.empty:
        print_dispersions(mc)
        if is_mission(mc):
            print_mission(mc, args)
        else:
            print_table3(mc, args)
        print_limits(mc, args)
    if args.plots is not None and not mc.runs.empty:
        from quadrs.cli.figures import mc_plots

        mc_plots(mc, args.plots, args.limit)
    return common.batch_status(mc, saved)
