"""Figures of uncertain parameters: a metric against each dispersed key, and the Sobol'
indices of a sensitivity analysis.

Re-exported by :mod:`quadrs.plots`; save a figure with :func:`quadrs.plots.save`."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from quadrs.plots.base import (
    AxesArg,
    add_legend,
    finish_figure,
    label_with_unit,
    line_style,
    own_phases,
    panel_axes,
    short_label,
)
from quadrs.present.labels import display_scale
from quadrs.present.table3 import phase_diverged


def dispersion_scatter(
    mc: Any,
    metric: str = "iae",
    phases: Sequence[str] | None = None,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """A metric against each dispersed key, one point per realisation and controller (rows:
    keys; columns: phases). Diverged realisations are drawn as crosses at the top."""
    keys = list(mc.dispersed_keys)
    if not keys:
        raise ValueError("dispersion_scatter needs a batch with dispersed keys")
    phases = list(phases or mc.scenario.scenario_phases)
    runs = mc.runs
    fig, axes = panel_axes(ax, len(keys), len(phases), width=3.2 * len(phases), height=2.6)
    grid = np.asarray(axes, dtype=object).reshape(len(keys), len(phases))
    label = label_with_unit(metric)
    for r, key in enumerate(keys):
        for c, phase in enumerate(phases):
            a = grid[r, c]
            for i, ctrl in enumerate(mc.controllers):
                sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)]
                ok = ~phase_diverged(sel)
                style = line_style(ctrl, i)
                a.scatter(
                    sel.loc[ok, key],
                    sel.loc[ok, metric] * display_scale(metric),
                    s=6,
                    alpha=0.5,
                    color=style["color"],
                    label=style["label"],
                )
                if (~ok).any():
                    top = np.nanmax(sel[metric]) * display_scale(metric) if ok.any() else 1.0
                    a.scatter(
                        sel.loc[~ok, key],
                        np.full((~ok).sum(), top),
                        marker="x",
                        color=style["color"],
                        label=f"{style['label']} diverged",
                    )
            a.set(xlabel=label_with_unit(key), title=f"{phase}")
            if c == 0:
                a.set_ylabel(label)
            if r == 0 and c == len(phases) - 1:
                add_legend(a)
    return finish_figure(fig, path)


def sobol_bars(
    sa: Any,
    metric: str = "iae",
    phases: Sequence[str] | None = None,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """First-order (S1, solid) and total (ST, hatched) Sobol' indices of one metric with
    their 95 % intervals, per phase (columns) and controller (bar colours)."""
    idx = sa.indices[sa.indices["metric"] == metric]
    phases = list(phases or own_phases(idx))
    params = list(sa.parameters)
    ctrls = [str(c) for c in pd.unique(idx["controller"])]
    height = 0.5 * len(params) + 1.6
    fig, axes = panel_axes(ax, 1, len(phases), width=3.4 * len(phases), height=height)
    width = 0.8 / (2 * len(ctrls))
    y = np.arange(len(params))
    for a, phase in zip(axes, phases, strict=True):
        for i, ctrl in enumerate(ctrls):
            sel = idx[(idx["phase"] == phase) & (idx["controller"] == ctrl)].set_index("parameter")
            sel = sel.reindex(params)
            style = line_style(ctrl, i)
            for j, (col, hatch) in enumerate((("S1", None), ("ST", "//"))):
                pos = y - 0.4 + width * (2 * i + j + 0.5)
                a.barh(
                    pos,
                    sel[col],
                    height=width,
                    xerr=sel[f"{col}_conf"],
                    color=style["color"],
                    alpha=0.45 if hatch else 0.85,
                    hatch=hatch,
                    label=f"{style['label']} {'total' if hatch else 'first-order'}",
                )
        names = [short_label(p) for p in params]
        a.set_yticks(y, names if a is axes[0] else [""] * len(params))
        a.set_xlim(-0.05, 1.05)
        a.axvline(0, color="grey", lw=0.5)
        a.set(xlabel="Sobol' index (share of variance)", title=phase)
    axes[-1].legend(loc="lower right", fontsize="small")
    name = label_with_unit(metric).split(" (")[0].split(",")[0]
    what = f"What drives the {name[0].lower() + name[1:]}"
    if ax is None:
        fig.suptitle(what)
    else:  # the caller's figure keeps its own title
        axes[0].set_title(f"{what}: {axes[0].get_title()}")
    return finish_figure(fig, path)
