"""Figures: those a reader of the paper will recognise (its Figs. 4-16) and their Monte Carlo
versions, and, from the modules beside this one, those of routes, rotors, wind, slung payloads
and missions.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (no global
figure state, rendered by Agg), and saves it as PNG and SVG when given ``path`` (a path
without suffix: ``path.png`` and ``path.svg`` are written). ``ax=`` draws into existing Axes
instead (one Axes, or a sequence with one per panel in row-major order; the function says
how many panels it draws) and returns their Figure. Line styles follow the paper: PD dashed
blue, SMC solid red, reference solid red, payload dashed black. Labels are plain English
(:data:`PLAIN_LABELS`), never the code's identifiers.

Spectral densities are one-sided, in units^2/Hz, and integrate over 0..fs/2 to the variance
of the (mean-removed) signal: :func:`welch_psd` for traces and generated gusts,
:func:`amplitude_to_psd` for the engine's amplitude spectra (docs/model.md section 5).
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from quadrs.plots import base as _base
from quadrs.plots.base import (
    CYCLE,
    DISPLACEMENT,
    STYLE,
    UNITS,
    AxesArg,
    Flights,
    add_legend,
    controller_label,
    finish_figure,
    flight_title,
    flights_by_label,
    gust_window,
    label_with_unit,
    line_style,
    loglog_axes,
    panel_axes,
    shade_gust,
    short_label,
)
from quadrs.present import labels as _labels
from quadrs.present.labels import display_scale
from quadrs.present.table3 import phase_diverged
from quadrs.runs import psd as _psd
from quadrs.runs.flight import Flight
from quadrs.runs.psd import phase_psd, phase_window
from quadrs.scenario.route import FLIGHT_PHASE

#: Display names of the gust models.
_MODEL_NAMES = {"dryden": "Dryden", "von_karman": "von Kármán"}


#: Public names re-exported from where they now live (the figure machinery in
#: quadrs.plots.base, the signal processing in quadrs.runs.psd): ``plots.save`` and the rest stay.
FMAX = _base.FMAX
FORMATS = _base.FORMATS
PLAIN_LABELS = _labels.PLAIN_LABELS
SHORT_NAMES = _base.SHORT_NAMES
new_figure = _base.new_figure
save = _base.save
amplitude_to_psd = _psd.amplitude_to_psd
ensemble_psd_frame = _psd.ensemble_psd_frame
gust_spectrum_frame = _psd.gust_spectrum_frame
welch_psd = _psd.welch_psd

# -- helpers --------------------------------------------------------------------------------


def _phases(flight: Flight, phases: Sequence[str] | None) -> list[str]:
    """The phases asked for; by default the scenario's own (the whole flight on request)."""
    return list(phases) if phases is not None else flight.scenario.scenario_phases


def _all_phases(df: pd.DataFrame) -> list[str]:
    """Every phase of a table, the whole-flight phase (if any) last."""
    own = _own_phases(df)
    return own + ([FLIGHT_PHASE] if (df["phase"] == FLIGHT_PHASE).any() else [])


def _own_phases(df: pd.DataFrame) -> list[str]:
    """The phases in a table's ``phase`` column, the whole-flight phase left out."""
    return [str(p) for p in pd.unique(df["phase"]) if p != FLIGHT_PHASE]


# -- single flights -------------------------------------------------------------------------
def altitude(flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """Reference, quadrotor and payload altitude against time (paper Figs. 4 and 7), one panel
    per flight, from ``Flight.trace`` columns ``z_ref``, ``z`` and ``zc``."""
    named = flights_by_label(flights)
    fig, axes = panel_axes(ax, len(named))
    for a, (label, flight) in zip(axes, named.items(), strict=True):
        tr = flight.trace
        a.plot(tr.index, tr["z_ref"], color="tab:red", lw=1.2, label="reference")
        a.plot(tr.index, tr["z"], color="tab:blue", lw=1.0, label="quadrotor")
        a.plot(tr.index, tr["zc"], color="black", ls="--", lw=1.0, label="payload")
        shade_gust(a, flight)
        a.set(xlabel="time (s)", ylabel="altitude (m)", title=flight_title(label, flight))
        add_legend(a)
    return finish_figure(fig, path)


def oscillation(
    flights: Flights,
    phases: Sequence[str] | None = None,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Payload relative displacement e_o = (zc - z) + d0 against time, one panel per phase, one
    line per flight (paper Figs. 5, 9 and 11: PD dashed blue against SMC solid red; fly both
    with the same seed for a paired comparison). Black lines mark the gust's start and end."""
    named = flights_by_label(flights)
    first = next(iter(named.values()))
    phases = _phases(first, phases)
    fig, axes = panel_axes(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        lo, hi = phase_window(first, phase)
        for i, (label, flight) in enumerate(named.items()):
            e = flight.trace["e_o"]
            part = e[(e.index >= lo) & (e.index <= hi)]
            a.plot(part.index, part.to_numpy(), lw=1.0, **line_style(label, i))
        window = gust_window(first)
        edges = [t for t in (window or ()) if lo <= t <= hi]
        for k, t in enumerate(edges):
            a.axvline(t, color="black", lw=1.0, label="gust start/end" if k == 0 else "_edge")
        a.set(
            xlabel="time (s)", ylabel=f"{DISPLACEMENT} (m)", title=f"relative oscillation, {phase}"
        )
        add_legend(a)
    return finish_figure(fig, path)


def spectra(
    flights: Flights,
    phases: Sequence[str] | None = None,
    fmax: float = FMAX,
    path: str | Path | None = None,
    *,
    title: str | None = None,
    ax: AxesArg = None,
) -> Figure:
    """Amplitude spectrum of the payload relative displacement e_o per phase, one line per
    flight (paper Figs. 6, 10, 12; with a mapping such as ``{"gust": f1, "no gust": f0}``,
    Fig. 8), from ``Flight.spectra[phase]`` (``frequency`` Hz, ``amplitude`` m), 0 to ``fmax``
    Hz. ``title`` (default: what is shown) is followed by the phase."""
    named = flights_by_label(flights)
    phases = _phases(next(iter(named.values())), phases)
    fig, axes = panel_axes(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        for i, (label, flight) in enumerate(named.items()):
            sp = flight.spectra[phase]
            sp = sp[sp["frequency"] <= fmax]
            a.plot(sp["frequency"], sp["amplitude"], lw=1.0, **line_style(label, i))
        what = title or f"amplitude spectrum of the {DISPLACEMENT}"
        a.set(xlabel="frequency (Hz)", ylabel="amplitude (m)", title=f"{what}, {phase}")
        a.set_xlim(0, fmax)
        add_legend(a)
    return finish_figure(fig, path)


def psd(
    flights: Flights,
    phases: Sequence[str] | None = None,
    fmax: float = FMAX,
    path: str | Path | None = None,
    *,
    method: str = "welch",
    resolution: float | None = 0.2,
    ax: AxesArg = None,
) -> Figure:
    """One-sided power spectral density of the payload relative displacement e_o (m^2/Hz),
    log-log, one panel per phase, one line per flight, up to ``fmax`` Hz.

    ``method="welch"`` (default): :func:`welch_psd` of the trace's e_o over the phase, Hann
    segments of ``1 / resolution`` s. ``"periodogram"``: :func:`amplitude_to_psd` of the
    engine's spectrum (``Flight.spectra``, rectangular window over the whole phase, the
    estimator :func:`ensemble_psd` averages). Either integrates to e_o's variance."""
    if method not in ("welch", "periodogram"):
        raise ValueError(f"method must be 'welch' or 'periodogram', got {method!r}")
    named = flights_by_label(flights)
    phases = _phases(next(iter(named.values())), phases)
    fig, axes = panel_axes(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        for i, (label, flight) in enumerate(named.items()):
            f, p = phase_psd(flight, phase, method, resolution)
            keep = (f > 0) & (f <= fmax)
            a.plot(f[keep], p[keep], lw=1.0, **line_style(label, i))
        how = "Welch" if method == "welch" else "periodogram"
        a.set(
            xlabel="frequency (Hz)",
            ylabel="PSD (m²/Hz)",
            title=f"power spectral density of the {DISPLACEMENT} ({how}), {phase}",
        )
        loglog_axes(a, fmax)
        add_legend(a)
    return finish_figure(fig, path)


def gust_force(flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """The gust (paper Fig. 15): vertical wind velocity (m/s) and the vertical drag force it
    exerts on the quadrotor (N): the trace's ``drag_z``, the force the engine's dynamics use
    (docs/model.md section 1). Zoomed on the gust window when the gust is on."""
    named = flights_by_label(flights)
    fig, (ax_w, ax_f) = panel_axes(ax, 2)
    for i, (label, flight) in enumerate(named.items()):
        tr = _around_gust(flight)
        force = tr["drag_z"]
        if i == 0:
            ax_w.plot(tr.index, tr["wind_z"], color="black", lw=1.0, label="vertical wind")
        ax_f.plot(force.index, force.to_numpy(), lw=1.0, **line_style(label, i))
    ax_w.set(xlabel="time (s)", ylabel="vertical wind (m/s)", title="vertical gust velocity")
    ax_f.set(xlabel="time (s)", ylabel="vertical drag force (N)",
             title="drag force on the quadrotor")  # fmt: skip
    add_legend(ax_w)
    add_legend(ax_f)
    return finish_figure(fig, path)


def _around_gust(flight: Flight) -> pd.DataFrame:
    window = gust_window(flight)
    tr = flight.trace
    if window is None:
        return tr
    a, b = window
    pad = 0.1 * (b - a)
    return tr[(tr.index >= a - pad) & (tr.index <= b + pad)]


def mass_compensation(
    flights: Mapping[tuple[bool, float], Flight],
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Quadrotor altitude against time for several payload masses, without mass compensation
    (the conventional controller, m~ = m; first panel) and with it (m~ = m + mc): paper
    Fig. 16. ``flights`` maps ``(mass_compensation, payload_mass)`` to a flight of one
    controller (for both controllers, draw each into its own column of ``ax``)."""
    modes = sorted({comp for comp, _ in flights})
    fig, axes = panel_axes(ax, len(modes))
    for a, comp in zip(axes, modes, strict=True):
        chosen = sorted((m, f) for (c, m), f in flights.items() if c == comp)
        ref = chosen[0][1].trace
        a.plot(ref.index, ref["z_ref"], color="tab:red", lw=1.2, label="reference")
        for i, (mass, flight) in enumerate(chosen):
            tr = flight.trace
            style = line_style(f"payload {mass:g} kg", i)
            a.plot(tr.index, tr["z"], lw=1.0, **style)
        what = (
            "compensated (vehicle + payload mass)" if comp else "conventional (vehicle mass only)"
        )
        a.set(
            xlabel="time (s)",
            ylabel="quadrotor altitude (m)",
            title=f"{controller_label(chosen[0][1].controller)}, {what}",
        )
        add_legend(a)
    return finish_figure(fig, path)


# -- Monte Carlo ----------------------------------------------------------------------------
Curve = tuple[pd.DataFrame, dict[str, Any], int]


def _ensemble_panels(
    df: pd.DataFrame, phases: Sequence[str] | None, ax: AxesArg
) -> tuple[Figure, list[tuple[Axes, str, list[Curve]]]]:
    """One panel per phase of a tidy ensemble frame, with each controller's rows, style and
    realisation count ``n``."""
    phases = list(phases) if phases is not None else _own_phases(df)
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
    for a, phase, curves in panels:
        for part, style, n in curves:
            style["label"] = f"{style['label']}, mean periodogram (n = {n})"
            a.plot(part["frequency"], part["psd"], lw=1.0, **style)
        a.set(
            xlabel="frequency (Hz)",
            ylabel="PSD (m²/Hz)",
            title=f"ensemble power spectral density of the {DISPLACEMENT}, {phase}",
        )
        loglog_axes(a, fmax)
        add_legend(a)
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
    phases = _own_phases(runs)
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
    phases = list(phases) if phases is not None else _own_phases(part)
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


# -- risk ---------------------------------------------------------------------------------
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
    phases = list(phases) if phases is not None else _all_phases(runs)
    ctrls = [str(c) for c in pd.unique(runs["controller"])]
    fig, axes = panel_axes(ax, len(phases))
    floor = 1.0
    for a, phase in zip(axes, phases, strict=True):
        for i, ctrl in enumerate(ctrls):
            sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)]
            div = phase_diverged(sel)
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
        add_legend(a)
    return finish_figure(fig, path)


# -- uncertain parameters -------------------------------------------------------------------
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
    phases = list(phases or _own_phases(idx))
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


def gust_transmissibility(
    scenario: Any,
    controllers: Sequence[str] = ("pd", "smc"),
    wind: float | None = None,
    freqs_hz: Any = None,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
) -> Figure:
    """Gust-to-e_o transmissibility |e_o / w_z|(f) of the closed loop linearised at hover
    (:func:`quadrs.linearize`) about a steady vertical wind ``wind`` (m/s; default
    :func:`quadrs.hover.linear.equivalent_wind`, the gust's statistically equivalent wind)."""
    from quadrs.hover.linear import equivalent_wind, linearize

    w0 = equivalent_wind(scenario) if wind is None else float(wind)
    f = np.logspace(-2, 1.5, 600) if freqs_hz is None else np.asarray(freqs_hz, dtype=float)
    fig, (a,) = panel_axes(ax, 1, height=3.6)
    for c in controllers:
        lin = linearize(scenario, c, inputs=("wind_z",), outputs=("e_o",), wind=(0.0, 0.0, w0))
        mag = np.abs(lin.frequency_response(f)[:, 0, 0])
        style = {k: v for k, v in STYLE[c].items() if k != "marker"}
        a.loglog(f, mag, **style)
    a.set_xlabel("Gust frequency (Hz)")
    a.set_ylabel("Payload relative displacement\nper unit vertical gust (m per m/s)")
    a.set_title(f"Vertical gust to payload oscillation, linearised about {w0:.2g} m/s updraft")
    a.grid(True, which="both", alpha=0.3)
    a.legend()
    return finish_figure(fig, path)


# -- the gust alone -------------------------------------------------------------------------


def gust_spectrum(
    frame: pd.DataFrame | None = None,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
    **params: Any,
) -> Figure:
    """The generated gust's one-sided PSD against its formula, log-log, one panel per model:
    the ensemble-mean Welch PSD with a +-2 standard-error band, the formula, and (von Kármán)
    the rational filter that approximates it, from the lowest Welch bin to a fifth of the
    Nyquist frequency. ``frame``: from :func:`gust_spectrum_frame`, which is called with
    ``params`` (its arguments) when ``frame`` is None."""
    frame = gust_spectrum_frame(**params) if frame is None else frame
    p = frame.attrs  # what the frame was made with
    models = [str(m) for m in pd.unique(frame["model"])]
    fig, axes = panel_axes(ax, len(models))
    top = 0.1 / p["dt"]
    for a, model in zip(axes, models, strict=True):
        sel = frame[(frame["model"] == model) & (frame["frequency"] > 0)]
        sel = sel[sel["frequency"] <= top]
        f = sel["frequency"].to_numpy(float)
        mean, se = sel["welch"].to_numpy(float), sel["welch_se"].to_numpy(float)
        name = _MODEL_NAMES.get(model, model)
        label = f"generated, Welch mean of {p['realisations']}"
        a.plot(f, mean, color="tab:blue", lw=1.2, label=label)
        a.fill_between(
            f, np.maximum(mean - 2 * se, 0), mean + 2 * se, color="tab:blue", alpha=0.2,
            label="±2 standard errors",
        )  # fmt: skip
        a.plot(f, sel["formula"], color="black", ls="--", lw=1.2, label=f"{name} formula")
        if model != "dryden":  # Dryden's filter is its formula
            a.plot(f, sel["filter"], color="tab:red", ls=":", lw=1.2, label="rational filter")
        a.set(
            xlabel="frequency (Hz)",
            ylabel="PSD ((m/s)²/Hz)",
            title=(
                f"{name} {p['component']} gust: sigma = {p['sigma']:g} m/s, "
                f"L = {p['length_scale']:g} m, V = {p['airspeed']:g} m/s"
            ),
        )
        loglog_axes(a, top)
        add_legend(a)
    return finish_figure(fig, path)


from quadrs.plots.mission import mission_risk  # noqa: E402, F401  (re-exported)
from quadrs.plots.payload import (  # noqa: E402,F401  (re-exported)
    lowering_path,
    payload_path,
    swing_tension,
)
from quadrs.plots.rotors import rotors  # noqa: E402, F401  (re-exported)
from quadrs.plots.route import altitude_profile, ground_track  # noqa: E402, F401
from quadrs.plots.wind import gust_spectra, gust_spectra_frame, wind_met  # noqa: E402, F401
