"""``quadrs report``: the summary of a saved Monte Carlo, mission or sweep file (or a
checkpoint directory) printed again, with its exceedance tables and figures on request."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from quadrs.cli.common import (
    EXIT_FAIL,
    EXIT_OK,
    BadInput,
    command_parser,
    limit_options,
    plots_option,
    table_options,
)
from quadrs.cli.safety_case import check_safety_case, safety_case_options, safety_outputs

__all__ = ["add_report", "cmd_report"]

#: Files quadrs writes that ``report`` does not read: their kind -> what to say instead.
_NOT_REPORTED = {
    "rare_event": "a rare-event result (quadrs rare --out): report reads Monte Carlo, mission "
    "and sweep files, and a rare-event result's safety case (--safety-case, --target); read "
    "it with RareEventResult.read_parquet",
    "flight": "one flight's trace (quadrs run --trace): report reads Monte Carlo, mission and "
    "sweep files; read it with quadrs.Flight.read_parquet",
    "sensitivity": "a sensitivity result (quadrs sensitivity --out): report reads Monte Carlo, "
    "mission and sweep files; read it with quadrs.SensitivityResult.read_parquet",
}


def add_report(sub: Any) -> None:
    """reprint the summary of a saved Monte Carlo, mission or sweep file

    Reprint the Table-3 summary (or a sweep's summary) from a Parquet file written by `quadrs mc
    --out` or `quadrs sweep --out`; for the flights of a route (`quadrs mission --out`), the
    mission's tables at the first --limit (default max_accel=9.81)."""
    p = command_parser(sub, add_report)
    p.add_argument(
        "file",
        type=Path,
        metavar="RUNS",
        help="the saved runs: a .parquet file (mc --out, sweep --out) or a --checkpoint directory",
    )
    plots_option(p, "write figures from the file here")
    limit_options(p)
    table_options(p)
    safety_case_options(p)


def saved_targets(mc: Any) -> dict[str, float]:
    """The targets the mission was saved with (``MonteCarloResult.question``)."""
    asked = getattr(mc, "question", None) or {}
    return {str(k): float(v) for k, v in (asked.get("targets") or {}).items()}


def _file_kind(path: Path) -> str | None:
    """The ``kind`` a quadrs Parquet file's metadata names (None if it names none); a
    sensitivity result's, which keeps its metadata under a key of its own, is "sensitivity"."""
    from quadrs.io.parquet import read_meta

    meta = read_meta(path, b"quadrs")
    kind = meta.get("kind") if isinstance(meta, dict) else None
    if kind is None and read_meta(path, b"quadrs_sensitivity") is not None:
        return "sensitivity"
    return kind if isinstance(kind, str) else None


def cmd_report(args: argparse.Namespace) -> int:
    """Reprint a saved batch's (or sweep's) summary; figures from it."""
    from quadrs.cli.figures import mc_plots, mission_plots, sweep_plots
    from quadrs.cli.tables import (
        is_mission,
        print_frame,
        print_limits,
        print_mission,
        print_table3,
    )
    from quadrs.runs.montecarlo import MonteCarloResult
    from quadrs.runs.sweep import SweepResult, is_sweep_file

    if args.file.is_dir():
        from quadrs.runs.store import RunStore

        if not RunStore(args.file).exists():
            raise BadInput(f"{str(args.file)!r}: not a quadrs run directory")
    elif not args.file.exists():
        raise BadInput(f"{str(args.file)!r}: no such file")
    check_safety_case(args)
    kind = None if args.file.is_dir() else _file_kind(args.file)
    if kind == "rare_event" and (args.safety_case is not None or args.target):
        return rare_page(args)
    if kind in _NOT_REPORTED:
        raise BadInput(f"{str(args.file)!r} is {_NOT_REPORTED[kind]}")
    if not args.file.is_dir() and is_sweep_file(args.file):
        result = SweepResult.read_parquet(args.file)
        print_frame(result.compact())
        print_limits(result, args)
        if args.plots is not None:
            sweep_plots(result, args.plots)
    else:
        mc = MonteCarloResult.read_parquet(args.file)
        note = " (interrupted batch)" if mc.interrupted else ""
        print(f"{args.file}: {len(mc.realisations)} realisations, seed {mc.seed}{note}")
        if mc.runs.empty:  # a run stopped before its first realisation finished
            return EXIT_OK
        mission = is_mission(mc)
        reports = print_mission(mc, args) if mission else []
        if not mission:
            print_table3(mc, args)
        print_limits(mc, args)
        if mission and not safety_outputs(mc, reports, args, saved_targets(mc)):
            return EXIT_FAIL
        if not mission and (args.safety_case is not None or args.target):
            raise BadInput(
                "--safety-case and --target read the flights of a mission "
                "(quadrs mission --out): this file holds none"
            )
        if args.plots is not None and mission:  # the mission's own figures
            mission_plots(mc, reports, args.plots)
        elif args.plots is not None:
            mc_plots(mc, args.plots, args.limit)
    return EXIT_OK


def rare_page(args: argparse.Namespace) -> int:
    """A saved rare-event result's answer again: its table's rows, the verdicts of the
    targets given and its ``--safety-case`` page (the one ``quadrs rare`` wrote, for one law)."""
    from quadrs.cli.rare import summary_rows, verdict_lines
    from quadrs.cli.safety_case import write_page
    from quadrs.rare.result import RareEventResult
    from quadrs.rare.safety import check_rare_targets, rare_safety_case

    result = RareEventResult.read_parquet(args.file)
    metric = getattr(result.model, "metric", None)
    if metric is None or result.interrupted:
        raise BadInput(f"{str(args.file)!r}: a rare-event result without a flight's estimate "
                       "(a limit-state function, or interrupted) has no safety case")  # fmt: skip
    targets = dict(args.target)
    check_rare_targets(metric, targets, "--target" if targets else "--safety-case")
    print(f"{args.file}: {result.value_name}, seed {result.seed}")
    for label, text in summary_rows(result):
        print(f"  {label:<34} {text}")
    for line in verdict_lines(result, targets):
        print(line)
    return (
        EXIT_OK if write_page([rare_safety_case(result, targets)], args.safety_case) else EXIT_FAIL
    )
