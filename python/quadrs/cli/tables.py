"""The tables the commands print: a frame as text, the paper's Table 3, the exceedance tables
of ``--limit``, a dispersed batch's varied keys, and a route's mission tables (``mc`` and
``report`` of a route)."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING, Any, TextIO

from quadrs.cli.common import report_width
from quadrs.present.terminal import fit_columns, terminal_text

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = [
    "is_mission",
    "print_dispersions",
    "print_frame",
    "print_limits",
    "print_mission",
    "print_table3",
    "shown_limit",
    "thresholds_shown",
]


def print_frame(frame: pd.DataFrame, out: TextIO | None = None, digits: int = 4) -> None:
    """``frame`` as text on ``out`` (stdout), numbers to ``digits`` significant digits, in
    blocks of columns as wide as the terminal (``report_width``)."""
    import pandas as pd

    with pd.option_context(
        "display.max_rows", 500, "display.float_format", lambda v: f"{v:.{digits}g}"
    ):
        print(fit_columns(frame, report_width()), file=out or sys.stdout)


def print_table3(mc: Any, args: argparse.Namespace) -> None:
    """The paper's Table 3 of a batch, as ``--wide`` and ``--no-paper`` ask."""
    from quadrs.present.table3 import format_table3, shows_paper

    paper = not args.no_paper and shows_paper(mc.scenario)  # the paper's P: its own problem only
    print(terminal_text(format_table3(mc.summary(), wide=args.wide, paper=paper)))


def print_limits(result: Any, args: argparse.Namespace) -> None:
    """The exceedance tables of ``--limit`` (and the paired PD/SMC difference)."""
    from quadrs.stats.risk import limits_difference_table, limits_table

    if not args.limit:
        return
    import textwrap

    def heading(text: str) -> None:
        print("\n" + textwrap.fill(text, report_width()))

    heading("P(metric > threshold), exact 95% Clopper-Pearson intervals; a diverged run counts "
            "as exceeding from the phase it diverged in:")  # fmt: skip
    print_frame(thresholds_shown(limits_table(result, args.limit, args.half_width / 100)))
    if {"pd", "smc"} <= set(result.controllers):
        heading("SMC - PD, paired on the same gusts (Newcombe interval, exact McNemar p):")
        print_frame(thresholds_shown(limits_difference_table(result, args.limit)))


def thresholds_shown(table: Any) -> Any:
    """A limits table's ``threshold`` column in the unit the tables show (degrees for swing),
    with that unit beside it: every table of limits the same way."""
    from quadrs.present.labels import shown_unit, shown_value

    if "threshold" in table:
        metrics = [str(m) for m in table.index]
        table["threshold"] = [shown_value(m, float(v)) for m, v in zip(metrics, table["threshold"],
                                                                         strict=True)]  # fmt: skip
        table.insert(list(table.columns).index("threshold") + 1, "unit",
                     [shown_unit(m) for m in metrics])  # fmt: skip
    return table


def print_dispersions(mc: Any) -> None:
    """A dispersed batch says what varied before its table."""
    from quadrs.scenario.dispersion import describe

    lines = describe(mc.scenario)
    if lines:
        print(f"Dispersed ({mc.sampling} sampling, values per realisation in the runs table):")
        for line in lines:
            print(f"  {line}")


def is_mission(mc: Any) -> bool:
    """A batch of a route (``quadrs mission``, or ``mc`` of a routed scenario): its answer is
    the mission's tables, not the paper's Table 3 of the spring's displacement."""
    return str(mc.scenario["trajectory.interpolation"]) == "route"


def print_mission(mc: Any, args: argparse.Namespace) -> list[Any]:
    """The mission's tables of each controller, at the first --limit; without one, the question
    the mission was asked when it was saved (``MonteCarloResult.question``), else the
    mission's default (max_specific_force at 2 g). Returns the reports printed."""
    from quadrs.cli.mission import DEFAULT_LIMIT, DEFAULT_METRIC
    from quadrs.design.mission import mission_report

    asked = dict(getattr(mc, "question", None) or {})
    if args.limit:
        asked["metric"], asked["limit"] = args.limit[0]
    metric = asked.get("metric", DEFAULT_METRIC)
    limit = asked.get("limit", DEFAULT_LIMIT)
    extra = {k: asked[k] for k in ("track_limit", "cross_track_limit", "quantile",
                                   "touchdown_limit") if asked.get(k) is not None}  # fmt: skip
    if asked and not args.limit:
        print(f"(the question this mission was saved with: P({metric} > "
              f"{shown_limit(metric, limit)}))")  # fmt: skip
    reports = [mission_report(mc, limit, ctrl, metric=metric, **extra) for ctrl in mc.controllers]
    for report in reports:
        print(report.to_text(width=report_width()))
    return reports


def shown_limit(metric: str, limit: float) -> str:
    """A limit in the unit the tables show, with that unit: ``30 deg``."""
    from quadrs.present.labels import shown_unit, shown_value

    return f"{shown_value(metric, limit):g} {shown_unit(metric)}".rstrip()
