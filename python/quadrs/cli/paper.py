"""``quadrs paper``: every table and figure of the paper remade into a directory, with
report.md setting our Table 3 beside the paper's."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from quadrs.cli import common

__all__ = ["add_paper", "cmd_paper"]


def add_paper(sub: Any, options: argparse.ArgumentParser) -> None:
    """every table and figure of the paper, and report.md

    Remake the paper's Figs. 4-16 and Table 3 with quadrs (with Monte Carlo versions) into DIR, with
    report.md setting our Table 3 beside the paper's. The numbers are not the paper's (see
    docs/paper-calibration.md)."""
    from quadrs.paper.grid import FREQUENCIES, MASSES

    p = common.command_parser(sub, add_paper, options)
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument(
        "--runs",
        type=int,
        default=200,
        metavar="N",
        help="Monte Carlo realisations for Table 3 (default: %(default)s; raise for tighter "
        "intervals)",
    )
    p.add_argument(
        "--sweep-runs",
        type=int,
        default=None,
        metavar="N",
        help="realisations per natural frequency for Figs. 13/14 (default: runs/10, >= 2)",
    )
    p.add_argument(
        "--frequencies",
        type=common._values,
        default=list(FREQUENCIES),
        metavar="F1,F2,...",
        help=f"payload natural frequencies in Hz for Figs. 13/14 (default: "
        f"{','.join(map(str, FREQUENCIES))})",
    )
    p.add_argument(
        "--masses",
        type=common._values,
        default=list(MASSES),
        metavar="M1,M2,...",
        help=f"payload masses in kg for Fig. 16 (default: {','.join(map(str, MASSES))})",
    )
    common.seed_option(p)
    common.workers_option(p, help="worker threads (default: all)")
    common.table_options(p)
    common.no_progress_option(p)


def cmd_paper(args: argparse.Namespace) -> int:
    """Every table and figure of the paper, and report.md."""
    from quadrs.cli.cost import announce_batch
    from quadrs.cli.outputs import check_directories
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.cli.tables import print_table3
    from quadrs.paper.pipeline import paper

    scenario = load_scenario(args)
    common.check_positive("--runs", args.runs, 2)
    common.check_positive("--sweep-runs", args.sweep_runs, 2)
    common.check_positive("--workers", args.workers)
    sweep_runs = max(2, args.runs // 10) if args.sweep_runs is None else args.sweep_runs
    from quadrs.paper.pipeline import _check as check_paper

    check_paper(args.runs, sweep_runs, args.seed, args.frequencies, args.masses, scenario)
    check_directories(args.out, option="--out")  # refused before the estimate, not after
    extra = 2 * sweep_runs * len(args.frequencies)
    what = (f"{args.runs} realisations x PD and SMC, a sweep of {len(args.frequencies)} "
            f"frequencies x {sweep_runs}")  # fmt: skip
    announce_batch("paper", scenario, ("pd", "smc"), args.runs, args.workers, args.seed,
                   extra, what)  # fmt: skip
    result = paper(
        args.out,
        scenario,
        args.runs,
        args.seed,
        args.workers,
        common.progress(args),
        sweep_runs=args.sweep_runs,
        frequencies=args.frequencies,
        masses=args.masses,
    )
    if result.mc is not None and not result.mc.runs.empty:
        print_table3(result.mc, args)
    print(f"wrote {len(result.files)} files to {result.out}", file=sys.stderr)
    return common.EXIT_INTERRUPT if result.interrupted else common.EXIT_OK
