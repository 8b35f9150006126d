"""``quadrs sensitivity``: which uncertain parameter matters most. A Saltelli design over the
dispersed keys (and the gust realisation) and each key's Sobol' indices of one metric, largest
first."""

from __future__ import annotations

import argparse
import sys
import textwrap
from typing import TYPE_CHECKING, Any

from quadrs.cli.common import (
    EXIT_FAIL,
    EXIT_OK,
    BadInput,
    batch_scope,
    check_positive,
    command_parser,
    controllers_option,
    no_progress_option,
    parquet_out_option,
    plots_option,
    report_width,
    scheduler_option,
    seed_option,
    workers_option,
)

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = ["add_sensitivity", "cmd_sensitivity", "sensitivity_table"]


def add_sensitivity(sub: Any, common: argparse.ArgumentParser) -> None:
    """which uncertain parameter matters most: Sobol' indices

    Fly a Saltelli design over the scenario's dispersed keys (--disperse or a [dispersions] table)
    and the gust realisation, and print each key's first-order (S1) and total (ST) Sobol' index of
    one metric with 95% intervals, largest first."""
    p = command_parser(sub, add_sensitivity, common)
    p.add_argument(
        "--runs",
        type=int,
        default=256,
        metavar="N",
        help="base sample size, a power of two; flies N (k + 2) realisations per controller "
        "for k factors (default: %(default)s)",
    )
    seed_option(p)
    workers_option(p, help="worker threads (default: all)")
    controllers_option(p, "comma-separated controllers")
    p.add_argument(
        "--metric", default="iae", metavar="NAME", help="metric to rank by (default: iae)"
    )
    p.add_argument("--phase", metavar="NAME", help="only this phase (default: every phase)")
    p.add_argument(
        "--no-gust-factor",
        action="store_true",
        help="fly one gust for every row instead of treating the realisation as a factor",
    )
    scheduler_option(p)
    parquet_out_option(p, "write every index here")
    plots_option(p, "write index bar charts here")
    no_progress_option(p)


def cmd_sensitivity(args: argparse.Namespace) -> int:
    """Sobol' indices of the dispersed keys: a compact ranking, optional Parquet and bars."""
    from quadrs.cli.outputs import check_outputs, check_suffix, save
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.cli.tables import print_frame
    from quadrs.design.sensitivity import sensitivity
    from quadrs.engine.calls import MAX_WORKERS, check_int
    from quadrs.runs.flight import METRIC_COLUMNS

    scenario = load_scenario(args)
    check_suffix(args.out, (".parquet",), "--out")
    check_positive("--workers", args.workers)
    check_int("--seed", args.seed)
    if args.workers is not None:
        check_int("--workers", args.workers, 1, MAX_WORKERS)
    if args.metric not in METRIC_COLUMNS:
        raise BadInput(f"--metric {args.metric!r}: one of {', '.join(METRIC_COLUMNS)}")
    if args.phase is not None and args.phase not in scenario.phase_names:
        raise BadInput(f"--phase {args.phase!r}: one of {', '.join(scenario.phase_names)}")
    check_outputs(args.out)
    with batch_scope(args.scheduler) as batch:
        sa = sensitivity(scenario, controllers=args.controllers, gust=not args.no_gust_factor,
                         **batch.keywords(args))  # fmt: skip
        batch.flown()
        status = EXIT_OK
        if args.out is not None and not save(sa.to_parquet, args.out):  # first: Ctrl-C keeps it
            status = EXIT_FAIL
    heading = (
        f"Sobol' indices of {args.metric} (N = {sa.runs}, {len(sa.samples['row'].unique())} "
        f"flights per controller; ± half-width of the 95% interval)"
    )
    print(textwrap.fill(heading, report_width()))
    print_frame(sensitivity_table(sa, args.metric, args.phase), digits=2)
    if args.plots is not None:
        from quadrs import plots

        files = plots.save(plots.sobol_bars(sa, args.metric), args.plots / f"sobol_{args.metric}")
        print(f"wrote {len(files)} figure files to {args.plots}", file=sys.stderr)
    return status


def sensitivity_table(sa: Any, metric: str, phase: str | None) -> pd.DataFrame:
    """Phase, controller, parameter, S1 ± and ST ±: largest total index first, fits 100
    columns."""
    import pandas as pd

    t = sa.ranking(metric, phase)
    pm = lambda v, c: "" if pd.isna(v) else f"{v:5.2f} ± {c:4.2f}"  # noqa: E731
    out = pd.DataFrame(
        {
            "phase": t["phase"].to_numpy(),
            "controller": t["controller"].to_numpy(),
            "parameter": t["parameter"].to_numpy(),
            "S1": [pm(v, c) for v, c in zip(t["S1"], t["S1_conf"], strict=True)],
            "ST": [pm(v, c) for v, c in zip(t["ST"], t["ST_conf"], strict=True)],
        }
    )
    return out.set_index(["phase", "controller", "parameter"])
