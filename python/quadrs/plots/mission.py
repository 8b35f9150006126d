"""Figures of ``quadrs mission``: per phase, the risk to the parcel with its intervals.

Re-exported by :mod:`quadrs.plots` (which therefore is not imported here); save a figure with
:func:`quadrs.plots.save`.
"""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from quadrs.design.mission import MissionReport
from quadrs.present.terminal import terminal_text

__all__ = ["mission_risk"]


def mission_risk(report: MissionReport) -> Figure:
    """Two panels, one point per phase (the whole flight last): P(payload acceleration peak >
    limit) in % with its exact interval, and the high quantile of the peak with its interval
    beside the worst realisation (diverged ones are left off the worst)."""
    acc = report.acceleration
    fig = Figure(figsize=(7.0, 5.2), layout="constrained")
    FigureCanvasAgg(fig)
    top, bottom = fig.subplots(2, 1)
    x = np.arange(len(acc))
    names = [terminal_text(str(p)) for p in acc.index]
    p = 100 * acc["probability"].to_numpy(float)
    lo, hi = 100 * acc["ci_low"].to_numpy(float), 100 * acc["ci_high"].to_numpy(float)
    top.errorbar(x, p, yerr=[p - lo, hi - p], fmt="o", color="tab:red", capsize=4,
                 label=f"exact {report.confidence:.0%} interval")  # fmt: skip
    top.set_ylabel(f"P(peak > {report.limit:g} m/s²) (%)")
    top.set_ylim(bottom=0)
    top.set_title(f"{report.controller.upper()}, {report.runs} realisations")
    top.legend(loc="best", fontsize="small")
    q = acc["quantile"].to_numpy(float)
    qlo = np.where(np.isfinite(acc["q_low"]), acc["q_low"], q)
    qhi = np.where(np.isfinite(acc["q_high"]), acc["q_high"], q)
    finite = np.isfinite(q)
    label = f"{report.quantile:g}-quantile (an open upper bound not drawn)"
    yerr = [(q - qlo)[finite], (qhi - q)[finite]]
    bottom.errorbar(x[finite], q[finite], yerr=yerr, fmt="s", color="tab:blue", capsize=4,
                    label=label)  # fmt: skip
    worst = acc["worst"].to_numpy(float)
    ok = np.isfinite(worst)
    bottom.plot(x[ok], worst[ok], "k^", label="worst")
    bottom.axhline(report.limit, color="gray", linestyle="--", label="limit")
    bottom.set_ylabel("Payload acceleration peak (m/s²)")
    bottom.legend(loc="best", fontsize="small")
    for a in (top, bottom):
        a.set_xticks(x, names)
        a.grid(True, alpha=0.3)
    return fig
