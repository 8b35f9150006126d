"""Figures of risk: the chance of exceeding a value of a metric, with its intervals.

Re-exported by :mod:`quadrs.plots`; save a figure with :func:`quadrs.plots.save`."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from quadrs.plots.base import (
    AxesArg,
    add_legend,
    all_phases,
    controller_label,
    finish_figure,
    label_with_unit,
    line_style,
    panel_axes,
)
from quadrs.present.labels import display_scale, shown_unit
from quadrs.present.table3 import phase_diverged


def exceedance_curves(
    runs: pd.DataFrame,
    metric: str = "max_accel",
    thresholds: Sequence[float] = (),
    phases: Sequence[str] | None = None,
    confidence: float = 0.95,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Empirical exceedance curves P(metric > x) = 1 - CDF, log y, one panel per phase, one line
    per controller, with a band of pointwise exact (Clopper-Pearson) ``confidence`` intervals
    (:func:`quadrs.stats.risk.survival_curve`; pointwise, not simultaneous). Diverged realisations
    count as exceeding every x. ``thresholds`` (in the metric's stored unit) are marked as
    vertical lines. Default ``phases``: every phase, the whole flight's last. Each curve runs
    to the largest value flown (marked), where its chance of being exceeded falls to 0.
    Angles (swing) are drawn in degrees."""
    from quadrs.stats.risk import check_metric, survival_curve

    check_metric(metric)
    scale = display_scale(metric)
    phases = list(phases) if phases is not None else all_phases(runs)
    ctrls = [str(c) for c in pd.unique(runs["controller"])]
    fig, axes = panel_axes(ax, len(phases))
    floor = 1.0
    drawn = []
    for a, phase in zip(axes, phases, strict=True):
        # A metric every flight gives the same value in this phase (a released parcel's swing:
        # 0) has no curve to draw: the panel says so, rather than a step 1e-12 wide.
        same: list[str] = []
        valued = False  # some flight has a value here, or diverged (which exceeds)
        for i, ctrl in enumerate(ctrls):
            sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)]
            div = phase_diverged(sel)
            values = sel[metric].to_numpy(float)[~div]
            values = values[np.isfinite(values)]
            valued = valued or bool(div.any()) or bool(values.size)
            if len(values) > 1 and not div.any() and values.min() == values.max():
                same.append(f"{controller_label(ctrl)}: {scale * values[0]:g} {shown_unit(metric)} "
                            f"in every one of its {len(values)} flights")  # fmt: skip
                continue
            curve = survival_curve(sel[metric].to_numpy(float), div, confidence)
            if curve.empty:
                continue
            style = line_style(ctrl, i)
            n = int(curve["n"].iloc[0])
            note = f", {int(div.sum())} diverged (counted as exceeding)" if div.any() else ""
            style["label"] = f"{style['label']} (n = {n}{note})"
            x = scale * curve["threshold"].to_numpy(float)
            p = curve["probability"].to_numpy(float)
            shown = p > 0
            # P(value > x) stays at its last non-zero value up to the largest value flown.
            xs, ps = np.r_[x[shown], x[-1]], np.r_[p[shown], p[shown][-1:]]
            a.step(xs, ps, where="post", lw=1.2, **style)
            a.plot(x[-1:], ps[-1:], marker="|", ms=10, color=style["color"],
                   ls=style.get("linestyle", "-"), label="_worst")  # fmt: skip
            a.fill_between(
                x,
                curve["ci_low"].to_numpy(float),
                curve["ci_high"].to_numpy(float),
                step="post",
                color=style["color"],
                alpha=0.2,
                label=f"{style['label'].split(' (')[0]}, {confidence:.0%} interval",
            )
            floor = min(floor, 0.5 / max(n, 1))
        drawn.append(valued)
        if not drawn[-1]:
            # No flight has a value here (an event's metric where the event never happened):
            # the panel says so, without a limit line to legend.
            a.text(0.5, 0.5, _no_values(metric), transform=a.transAxes, ha="center",
                   va="center", color="0.4", fontsize="small", wrap=True)  # fmt: skip
            a.set(title=f"Exceedance, {phase}", xticks=[], yticks=[])
            continue
        for k, t in enumerate(thresholds):
            a.axvline(scale * float(t), color="black", lw=0.8, ls=":",
                      label="limit" if k == 0 else "_")  # fmt: skip
        a.set_yscale("log")
        a.set_ylim(floor, 1.05)
        a.set(
            xlabel=label_with_unit(metric),
            ylabel="Chance of exceeding",
            title=f"Exceedance, {phase} (bands: pointwise {confidence:.0%} exact intervals)",
        )
        if same:
            a.text(0.5, 0.5, "\n".join(same), transform=a.transAxes, ha="center", va="center",
                   color="0.3", fontsize="small")  # fmt: skip
            if not a.get_legend_handles_labels()[0]:
                continue
        add_legend(a)
    if not any(drawn):
        raise ValueError(f"exceedance of {metric}: {_no_values(metric)} in any phase")
    return finish_figure(fig, path)


def _no_values(metric: str) -> str:
    """What a panel (or a figure) without a value of ``metric`` says."""
    from quadrs import _core

    event = ""
    if metric in _core.EVENT_METRICS:
        event = " (an event's metric: the event never happened)"
    return f"no flight has a value of {metric}{event}"
