"""Figures of Monte Carlo batches and sweeps: ensemble spectra and power spectral densities,
the distributions of the metrics over realisations, a metric against the swept keys (the
paper's Figs. 13 and 14).

Re-exported by :mod:`quadrs.plots`; save a figure with :func:`quadrs.plots.save`."""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from quadrs.plots.base import (
    CYCLE,
    DISPLACEMENT,
    FMAX,
    UNITS,
    AxesArg,
    add_legend,
    controller_label,
    finish_figure,
    label_with_unit,
    line_style,
    own_phases,
    panel_axes,
    psd_panel,
    require_drawn,
    short_label,
)
from quadrs.present.labels import display_scale
from quadrs.present.table3 import phase_diverged
from quadrs.runs.psd import ensemble_psd_frame

Curve = tuple[pd.DataFrame, dict[str, Any], int]


def _ensemble_panels(
    df: pd.DataFrame, phases: Sequence[str] | None, ax: AxesArg
) -> tuple[Figure, list[tuple[Axes, str, list[Curve]]]]:
    """One panel per phase of a tidy ensemble frame, with each controller's rows, style and
    realisation count ``n``."""
    phases = list(phases) if phases is not None else own_phases(df)
    fig, axes = panel_axes(ax, len(phases))
    panels = []
    for a, phase in zip(axes, phases, strict=True):
        sel = df[df["phase"] == phase]
        curves = []
        for i, ctrl in enumerate(pd.unique(sel["controller"])):
            part = sel[sel["controller"] == ctrl]
            curves.append((part, line_style(str(ctrl), i), int(part["n"].iloc[0])))
        panels.append((a, phase, curves))
    return fig, panels


def ensemble_spectra(
    spectra_frame: pd.DataFrame,
    phases: Sequence[str] | None = None,
    fmax: float = FMAX,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Monte Carlo version of Figs. 6/10/12: per phase the ensemble-mean amplitude spectrum
    of e_o per controller with a +-1 std band, from ``MonteCarloResult.spectra`` (columns
    controller, phase, frequency, mean, std, n)."""
    df = spectra_frame[spectra_frame["frequency"] <= fmax]
    fig, panels = _ensemble_panels(df, phases, ax)
    for a, phase, curves in panels:
        for part, style, n in curves:
            f, m, s = (part[c].to_numpy(float) for c in ("frequency", "mean", "std"))
            name = style["label"]
            style["label"] = f"{name}, mean (n = {n})"
            a.plot(f, m, lw=1.0, **style)
            a.fill_between(
                f, np.maximum(m - s, 0), m + s, color=style["color"], alpha=0.2,
                label=f"{name}, ±1 std",
            )  # fmt: skip
        a.set(
            xlabel="frequency (Hz)",
            ylabel="amplitude (m)",
            title=f"ensemble amplitude spectrum of the {DISPLACEMENT}, {phase}",
        )
        a.set_xlim(0, fmax)
        add_legend(a)
    return finish_figure(fig, path)


def ensemble_psd(
    spectra_frame: pd.DataFrame,
    phases: Sequence[str] | None = None,
    fmax: float = FMAX,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Monte Carlo one-sided PSD of e_o (m^2/Hz), log-log: per phase the ensemble-mean
    periodogram per controller (:func:`ensemble_psd_frame`), from ``MonteCarloResult.spectra``.
    Its integral is the ensemble-mean variance of e_o over the phase."""
    df = ensemble_psd_frame(spectra_frame)
    df = df[(df["frequency"] > 0) & (df["frequency"] <= fmax)]
    fig, panels = _ensemble_panels(df, phases, ax)
    drawn = []
    for a, phase, curves in panels:
        for part, style, n in curves:
            style["label"] = f"{style['label']}, mean periodogram (n = {n})"
            a.plot(part["frequency"], part["psd"], lw=1.0, **style)
        drawn.append(
            psd_panel(a, fmax, f"ensemble spectral density of the {DISPLACEMENT}, {phase}")
        )
    require_drawn(drawn, f"ensemble power spectral density of the {DISPLACEMENT}")
    return finish_figure(fig, path)


def distributions(
    runs: pd.DataFrame,
    metrics: Sequence[str] = ("iae", "itae"),
    kind: str = "box",
    path: str | Path | None = None,
    *,
    by: str | Sequence[str] | None = None,
    ax: AxesArg = None,
) -> Figure:
    """Distributions over gust realisations of each metric, per phase and controller (box or
    violin plots, from ``mc.runs``; diverged rows left out). Rows: metrics; columns: phases.

    ``by``: the swept key(s) of a sweep's runs (:attr:`quadrs.runs.sweep.SweepResult.keys`): one
    box or violin per grid point and controller, grouped by grid point along x, instead of
    pooling the points."""
    if kind not in ("box", "violin"):
        raise ValueError(f"kind must be 'box' or 'violin', got {kind!r}")
    keys = [by] if isinstance(by, str) else list(by or ())
    for key in keys:
        if key not in runs.columns:
            raise ValueError(f"by: {key!r} is not a column of the runs")
    ok = runs[~phase_diverged(runs)]
    phases = own_phases(runs)
    ctrls = [str(c) for c in pd.unique(runs["controller"])]
    colors = [line_style(k, i)["color"] for i, k in enumerate(ctrls)]
    points = list(runs[keys].drop_duplicates().itertuples(index=False)) if keys else [()]
    width = max(3.2, 0.45 * len(points) * len(ctrls) + 1.0)
    fig, axes = panel_axes(ax, len(metrics), len(phases), width * len(phases), 2.8)
    grid = np.asarray(axes, dtype=object).reshape(len(metrics), len(phases))
    step = 0.8 / len(ctrls)
    for r, metric in enumerate(metrics):
        for c, phase in enumerate(phases):
            a = grid[r, c]
            data, pos, cols = [], [], []
            for j, point in enumerate(points):
                here = _at(ok, keys, tuple(point))
                for i, ctrl in enumerate(ctrls):
                    data.append(_finite(here, phase, ctrl, metric))
                    # Grouped by grid point in a sweep; else one box per controller, on its tick.
                    pos.append(j + 1 + (i - (len(ctrls) - 1) / 2) * step if keys else i + 1)
                    cols.append(colors[i])
            _dist(a, data, kind, cols, pos, 0.85 * step if keys else 0.5)
            if keys:
                a.set_xticks(range(1, len(points) + 1), [_point_label(p) for p in points])
                a.set_xlabel(", ".join(label_with_unit(k) for k in keys))
                handles = [Patch(color=col, alpha=0.5) for col in colors]
                a.legend(
                    handles, [controller_label(k) for k in ctrls], loc="best", fontsize="small"
                )
            else:
                a.set_xticks(range(1, len(ctrls) + 1), [controller_label(k) for k in ctrls])
            ylabel = textwrap.fill(label_with_unit(metric), 30) if c == 0 else ""  # narrow panels
            a.set(title=f"{short_label(metric)}, {phase}", ylabel=ylabel)
    return finish_figure(fig, path)


def _at(runs: pd.DataFrame, keys: list[str], point: tuple[Any, ...]) -> pd.DataFrame:
    mask = np.ones(len(runs), dtype=bool)
    for key, value in zip(keys, point, strict=True):
        mask &= (runs[key] == value).to_numpy()
    return runs[mask]


def _point_label(point: Sequence[Any]) -> str:
    return ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in point)


def _finite(runs: pd.DataFrame, phase: str, ctrl: str, metric: str) -> np.ndarray:
    sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)][metric]
    values = sel.to_numpy(float) * display_scale(metric)
    return values[np.isfinite(values)]


def _dist(
    ax: Axes,
    data: list[np.ndarray],
    kind: str,
    colors: list[str],
    positions: Sequence[float],
    width: float,
) -> None:
    """One box or violin per non-empty data set, at its position, in its colour (boxes for all
    when any set has no spread: a violin needs one)."""
    keep = [i for i, d in enumerate(data) if len(d)]
    if not keep:
        return
    vals = [data[i] for i in keep]
    pos = [positions[i] for i in keep]
    if kind == "violin" and all(np.ptp(v) > 0 for v in vals):
        parts = ax.violinplot(vals, positions=pos, widths=width, showmedians=True)
        bodies: list[Any] = list(parts["bodies"])  # type: ignore[call-overload]
        for body, i in zip(bodies, keep, strict=True):
            body.set_facecolor(colors[i])
    else:
        box = ax.boxplot(vals, positions=pos, widths=width, patch_artist=True, manage_ticks=False)
        for patch, i in zip(box["boxes"], keep, strict=True):
            patch.set(facecolor=colors[i], alpha=0.35)


def sweep_metric(
    summary: pd.DataFrame,
    metric: str = "max_abs",
    phases: Sequence[str] | None = None,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Mean of ``metric`` against the first swept key, one panel per phase, per controller with
    its 95% CI as error bars (from :meth:`quadrs.runs.sweep.SweepResult.summary`). With a second
    swept key, one line per controller and value of that key."""
    keys = [n for n in summary.index.names if n not in ("metric", "phase")]
    part = summary.xs(metric, level="metric").reset_index()
    phases = list(phases) if phases is not None else own_phases(part)
    ctrls = [c.removesuffix("_mean") for c in part.columns if c.endswith("_mean")]
    fig, axes = panel_axes(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        sel = part[part["phase"] == phase]
        for j, (sub_label, sub) in enumerate(_by_second_key(sel, keys)):
            for i, ctrl in enumerate(ctrls):
                style = line_style(ctrl, i, markers=True)
                if len(keys) > 1:
                    style["color"] = CYCLE[j % len(CYCLE)]
                sub.attrs["scale"] = display_scale(metric)
                _errorline(a, sub, keys[0], ctrl, style, sub_label)
        # The long label wrapped to fit beside one panel: unwrapped it overlaps its neighbours'.
        ylabel = textwrap.fill(label_with_unit(metric), 28)
        a.set(
            xlabel=label_with_unit(keys[0]), ylabel=ylabel, title=f"{short_label(metric)}, {phase}"
        )
        add_legend(a, title="mean and 95% CI", title_fontsize="small")
    return finish_figure(fig, path)


def _by_second_key(sel: pd.DataFrame, keys: list[str]) -> list[tuple[str, pd.DataFrame]]:
    if len(keys) < 2:
        return [("", sel)]
    name = short_label(keys[1]).lower()
    unit = f" {UNITS[keys[1]]}" if keys[1] in UNITS else ""
    return [
        (f", {name} {_point_label([v])}{unit}", sel[sel[keys[1]] == v])
        for v in pd.unique(sel[keys[1]])
    ]


def _errorline(
    ax: Axes, sub: pd.DataFrame, key: str, ctrl: str, style: dict[str, Any], suffix: str
) -> None:
    x = sub[key].to_numpy()
    k = float(sub.attrs.get("scale", 1.0))
    mean = k * sub[f"{ctrl}_mean"].to_numpy(float)
    lo = mean - k * sub[f"{ctrl}_ci_low"].to_numpy(float)
    hi = k * sub[f"{ctrl}_ci_high"].to_numpy(float) - mean
    err = np.nan_to_num(np.vstack([lo, hi]))
    style = {**style, "label": f"{style['label']}{suffix}"}
    ax.errorbar(x, mean, yerr=err, capsize=3, lw=1.0, **style)


def max_amplitude(
    summary: pd.DataFrame,
    phases: Sequence[str] = ("P1", "P3"),
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Maximum relative-oscillation amplitude against the swept key (paper Figs. 13 and 14,
    over ``payload.natural_frequency``: take-off P1 and landing P3), PD -* and SMC --+ with
    95% CIs, from a sweep's summary."""
    present = set(summary.index.get_level_values("phase"))
    shown = [p for p in phases if p in present] or None
    return sweep_metric(summary, "max_abs", shown, path, ax=ax)
