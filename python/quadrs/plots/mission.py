"""Figures of ``quadrs mission``: per phase, the risk to the parcel with its intervals.

Re-exported by :mod:`quadrs.plots` (which therefore is not imported here); save a figure with
:func:`quadrs.plots.save`.
"""

from __future__ import annotations

import textwrap

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from quadrs.design.mission import MissionReport
from quadrs.present.terminal import terminal_text

__all__ = ["mission_risk"]


def mission_risk(report: MissionReport) -> Figure:
    """Two panels, one point per phase (the whole flight last): P(the parcel's metric >
    limit) in % with its exact interval, and the high quantile of the metric with its interval
    beside the worst realisation (diverged ones are left off the worst); both labelled by the
    report's metric, in the unit the tables show (degrees for swing)."""
    from quadrs.present.labels import PLAIN_LABELS, shown_unit, shown_value

    acc = report.acceleration
    metric = report.metric
    scale = shown_value(metric, 1.0)
    unit = shown_unit(metric)
    limit = f"{shown_value(metric, report.limit):.4g} {unit}".rstrip()
    fig = Figure(figsize=(7.0, 6.4), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1)
    x = np.arange(len(acc))
    names = [terminal_text(str(p)) for p in acc.index]
    p = 100 * acc["probability"].to_numpy(float)
    lo, hi = 100 * acc["ci_low"].to_numpy(float), 100 * acc["ci_high"].to_numpy(float)
    top.errorbar(x, p, yerr=[p - lo, hi - p], fmt="o", color="tab:red", capsize=4,
                 label=f"exact {report.confidence:.0%} interval")  # fmt: skip
    # Two lines each: a panel is about 2.5 in tall, the one-line labels ran into each other.
    top.set_ylabel(f"P({metric} > {limit})\nin %")
    top.set_ylim(bottom=0)
    top.set_title(f"{report.controller.upper()}, {report.runs} realisations")
    top.legend(loc="best", fontsize="small")
    q = scale * acc["quantile"].to_numpy(float)
    qlo = np.where(np.isfinite(acc["q_low"]), scale * acc["q_low"].to_numpy(float), q)
    qhi = np.where(np.isfinite(acc["q_high"]), scale * acc["q_high"].to_numpy(float), q)
    finite = np.isfinite(q)
    label = f"{report.quantile:g}-quantile (an open upper bound not drawn)"
    yerr = [(q - qlo)[finite], (qhi - q)[finite]]
    bottom.errorbar(x[finite], q[finite], yerr=yerr, fmt="s", color="tab:blue", capsize=4,
                    label=label)  # fmt: skip
    worst = scale * acc["worst"].to_numpy(float)
    ok = np.isfinite(worst)
    bottom.plot(x[ok], worst[ok], "k^", label="worst")
    bottom.axhline(scale * report.limit, color="gray", linestyle="--", label="limit")
    bottom.set_ylabel(textwrap.fill(PLAIN_LABELS.get(metric, f"{metric} ({unit})"), 32))
    bottom.legend(loc="best", fontsize="small")
    for a in (top, bottom):
        a.set_xticks(x, names)
        a.grid(True, alpha=0.3)
    return fig
