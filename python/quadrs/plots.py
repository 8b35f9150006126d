"""Figures a reader of the paper will recognise (its Figs. 4-16), and their Monte Carlo versions.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (no global
figure state, rendered by Agg), and saves it as PNG and SVG when given ``path`` (a path
without suffix: ``path.png`` and ``path.svg`` are written). Line styles follow the paper: PD
dashed blue, SMC solid red, reference solid red, payload dashed black.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from quadrs.flight import Flight
from quadrs.parquet import atomic_write

#: Default frequency range of spectra (Hz): the payload modes of interest sit well below.
FMAX = 10.0
FORMATS = ("png", "svg")
STYLE: dict[str, dict[str, Any]] = {
    "pd": {"color": "tab:blue", "linestyle": "--", "marker": "*", "label": "PD"},
    "smc": {"color": "tab:red", "linestyle": "-", "marker": "+", "label": "SMC"},
}
#: Units of the metric columns and of common sweep keys, for axis labels.
UNITS = {
    "iae": "m s",
    "itae": "m s^2",
    "max_abs": "m",
    "rms": "m",
    "tracking_rms": "m",
    "peak_frequency": "Hz",
    "peak_amplitude": "m",
    "max_accel": "m/s^2",
    "rms_accel": "m/s^2",
    "payload.natural_frequency": "Hz",
    "payload.stiffness": "N/m",
    "payload.mass": "kg",
    "payload.damping": "N s/m",
    "gust.w20": "m/s",
    "gust.airspeed": "m/s",
    "gust.altitude": "m",
    "vehicle.mass": "kg",
    "integrator.dt": "s",
}
_CYCLE = ("tab:blue", "black", "goldenrod", "tab:green", "tab:purple", "tab:brown")

Flights = Flight | Sequence[Flight] | Mapping[str, Flight]


# -- helpers --------------------------------------------------------------------------------
def new_figure(nrows: int = 1, ncols: int = 1, width: float = 7.0, height: float = 3.0) -> Figure:
    """An Agg-backed figure of ``nrows x ncols`` panels, ``height`` inches per row."""
    fig = Figure(figsize=(width, height * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    fig.subplots(nrows, ncols, squeeze=False)
    return fig


def save(fig: Figure, path: str | Path, formats: Sequence[str] = FORMATS) -> list[Path]:
    """Write ``fig`` as ``path.<fmt>`` for each format (the directory is created); returns the
    files written. A suffix already on ``path`` is replaced."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    written = []
    with matplotlib.rc_context({"svg.hashsalt": "quadrs"}):
        for fmt in formats:
            target = path.with_suffix(f".{fmt}")
            meta = {"Date": None} if fmt == "svg" else None
            atomic_write(
                target,
                lambda f, fmt=fmt, meta=meta: fig.savefig(f, format=fmt, dpi=120, metadata=meta),  # type: ignore[misc]
            )
            written.append(target)
    return written


def _finish(fig: Figure, path: str | Path | None) -> Figure:
    if path is not None:
        save(fig, path)
    return fig


def _axes(fig: Figure) -> list[Axes]:
    return list(fig.axes)


def _named(flights: Flights) -> dict[str, Flight]:
    """Flights keyed by a label: the controller name, or the mapping's own keys."""
    if isinstance(flights, Flight):
        return {flights.controller: flights}
    if isinstance(flights, Mapping):
        return dict(flights)
    out: dict[str, Flight] = {}
    for f in flights:
        label = f.controller if f.controller not in out else f"{f.controller} #{len(out)}"
        out[label] = f
    return out


def _style(label: str, index: int, markers: bool = False) -> dict[str, Any]:
    """The paper's style for "pd"/"smc"; otherwise the ``index``-th colour and dash."""
    base = STYLE.get(label.lower())
    if base is not None:
        style = dict(base)
    else:
        style = {
            "color": _CYCLE[index % len(_CYCLE)],
            "linestyle": ("-", "--", "-.", ":")[index % 4],
            "marker": "o",
            "label": label,
        }
    if not markers:
        style.pop("marker")
    return style


def _phase_window(flight: Flight, phase: str) -> tuple[float, float]:
    for p in flight.scenario["phases"]:
        if p["name"] == phase:
            return float(p["start"]), float(p["end"])
    raise ValueError(f"phase must be one of {flight.scenario.phase_names}, got {phase!r}")


def _gust_window(flight: Flight) -> tuple[float, float] | None:
    s = flight.scenario
    return (float(s["gust.start"]), float(s["gust.end"])) if s["gust.enabled"] else None


def _unit(name: str) -> str:
    """``name (unit)`` when the unit is known."""
    return f"{name} ({UNITS[name]})" if name in UNITS else name


def _grid_shape(n: int) -> tuple[int, int]:
    return (n, 1) if n <= 3 else ((n + 1) // 2, 2)


# -- single flights -------------------------------------------------------------------------
def altitude(flights: Flights, path: str | Path | None = None) -> Figure:
    """Reference, quadrotor and payload altitude against time (paper Figs. 4 and 7), one panel
    per flight, from ``Flight.trace`` columns ``z_ref``, ``z`` and ``zc``."""
    named = _named(flights)
    fig = new_figure(len(named), 1)
    for ax, (label, flight) in zip(_axes(fig), named.items(), strict=True):
        tr = flight.trace
        ax.plot(tr.index, tr["z_ref"], color="tab:red", lw=1.2, label="reference")
        ax.plot(tr.index, tr["z"], color="tab:blue", lw=1.0, label="quadrotor z")
        ax.plot(tr.index, tr["zc"], color="black", ls="--", lw=1.0, label="payload zc")
        _shade_gust(ax, flight)
        ax.set(xlabel="t (s)", ylabel="altitude (m)", title=_title(label, flight))
        ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def _title(label: str, flight: Flight) -> str:
    name = STYLE.get(label.lower(), {}).get("label", label)
    return f"{name}: seed {flight.seed}, realisation {flight.realisation}"


def _shade_gust(ax: Axes, flight: Flight) -> None:
    window = _gust_window(flight)
    if window is not None:
        ax.axvspan(*window, color="0.9", zorder=0, label="gust window")


def oscillation(
    flights: Flights, phases: Sequence[str] | None = None, path: str | Path | None = None
) -> Figure:
    """Relative oscillation e_o = (zc - z) + d0 against time, one panel per phase, one line per
    flight (paper Figs. 5, 9 and 11: PD dashed blue against SMC solid red; fly both with the
    same seed for a paired comparison). The gust window is marked by black lines."""
    named = _named(flights)
    first = next(iter(named.values()))
    phases = list(phases) if phases is not None else first.scenario.phase_names
    fig = new_figure(len(phases), 1)
    for ax, phase in zip(_axes(fig), phases, strict=True):
        a, b = _phase_window(first, phase)
        for i, (label, flight) in enumerate(named.items()):
            e = flight.trace["e_o"]
            part = e[(e.index >= a) & (e.index <= b)]
            ax.plot(part.index, part.to_numpy(), lw=1.0, **_style(label, i))
        window = _gust_window(first)
        if window is not None:
            for t in window:
                if a <= t <= b:
                    ax.axvline(t, color="black", lw=1.0)
        ax.set(xlabel="t (s)", ylabel="e_o (m)", title=f"relative oscillation, {phase}")
        ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def spectra(
    flights: Flights,
    phases: Sequence[str] | None = None,
    fmax: float = FMAX,
    path: str | Path | None = None,
) -> Figure:
    """Amplitude spectrum |E_o(f)| of the relative oscillation per phase, one line per flight
    (paper Figs. 6, 10, 12; with a mapping such as ``{"gust": f1, "no gust": f0}``, Fig. 8),
    from ``Flight.spectra[phase]`` (``frequency`` Hz, ``amplitude`` m), 0 to ``fmax`` Hz."""
    named = _named(flights)
    first = next(iter(named.values()))
    phases = list(phases) if phases is not None else first.scenario.phase_names
    fig = new_figure(len(phases), 1)
    for ax, phase in zip(_axes(fig), phases, strict=True):
        for i, (label, flight) in enumerate(named.items()):
            sp = flight.spectra[phase]
            sp = sp[sp["frequency"] <= fmax]
            ax.plot(sp["frequency"], sp["amplitude"], lw=1.0, **_style(label, i))
        ax.set(xlabel="frequency (Hz)", ylabel="|E_o| (m)", title=f"spectrum of e_o, {phase}")
        ax.set_xlim(0, fmax)
        ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def drag_force(trace: pd.DataFrame, air_density: float, drag_area: float) -> pd.Series:
    """Vertical drag force on the quadrotor (N): Fdz = -1/2 rho CdA (vz - wind_z)|vz - wind_z|
    (MODEL.md section 1), from a flight trace."""
    rel = trace["vz"] - trace["wind_z"]
    return (-0.5 * air_density * drag_area * rel * rel.abs()).rename("Fdz")


def gust_force(flights: Flights, path: str | Path | None = None) -> Figure:
    """The gust (paper Fig. 15): vertical wind ``wind_z`` (m/s) and the drag force it exerts
    on the quadrotor, Fdz (N), with rho = ``gust.air_density`` and CdA = ``vehicle.drag_area``
    of each flight's scenario. Zoomed on the gust window when the gust is on."""
    named = _named(flights)
    fig = new_figure(2, 1)
    ax_w, ax_f = _axes(fig)
    for i, (label, flight) in enumerate(named.items()):
        s = flight.scenario
        tr = _around_gust(flight)
        force = drag_force(tr, float(s["gust.air_density"]), float(s["vehicle.drag_area"]))
        if i == 0:
            ax_w.plot(tr.index, tr["wind_z"], color="black", lw=1.0, label="wind_z")
        ax_f.plot(force.index, force.to_numpy(), lw=1.0, **_style(label, i))
    ax_w.set(xlabel="t (s)", ylabel="wind_z (m/s)", title="vertical gust velocity")
    ax_f.set(xlabel="t (s)", ylabel="Fdz (N)", title="drag force on the quadrotor")
    ax_f.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def _around_gust(flight: Flight) -> pd.DataFrame:
    window = _gust_window(flight)
    tr = flight.trace
    if window is None:
        return tr
    a, b = window
    pad = 0.1 * (b - a)
    return tr[(tr.index >= a - pad) & (tr.index <= b + pad)]


def mass_compensation(
    flights: Mapping[tuple[bool, float], Flight], path: str | Path | None = None
) -> Figure:
    """Altitude against time for several payload masses, without mass compensation (the
    conventional controller, m~ = m) and with it (m~ = m + mc): paper Fig. 16. ``flights`` maps
    ``(mass_compensation, payload_mass)`` to a flight."""
    modes = sorted({comp for comp, _ in flights})
    fig = new_figure(len(modes), 1)
    for ax, comp in zip(_axes(fig), modes, strict=True):
        chosen = sorted((m, f) for (c, m), f in flights.items() if c == comp)
        ref = chosen[0][1].trace
        ax.plot(ref.index, ref["z_ref"], color="tab:red", lw=1.2, label="reference")
        for i, (mass, flight) in enumerate(chosen):
            tr = flight.trace
            style = _style(f"mc = {mass:g} kg", i)
            ax.plot(tr.index, tr["z"], lw=1.0, **style)
        what = "with mass compensation (m + mc)" if comp else "conventional (m only)"
        ax.set(xlabel="t (s)", ylabel="z (m)", title=f"{_controller_of(chosen)}, {what}")
        ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def _controller_of(chosen: list[tuple[float, Flight]]) -> str:
    return str(STYLE.get(chosen[0][1].controller, {}).get("label", chosen[0][1].controller))


# -- Monte Carlo ----------------------------------------------------------------------------
def ensemble_spectra(
    spectra_frame: pd.DataFrame,
    phases: Sequence[str] | None = None,
    fmax: float = FMAX,
    path: str | Path | None = None,
) -> Figure:
    """Monte Carlo version of Figs. 6/10/12: per phase the ensemble-mean amplitude spectrum
    of e_o per controller with a +-1 std band, from ``MonteCarloResult.spectra`` (columns
    controller, phase, frequency, mean, std, n)."""
    df = spectra_frame[spectra_frame["frequency"] <= fmax]
    phases = list(phases) if phases is not None else list(pd.unique(df["phase"]))
    fig = new_figure(len(phases), 1)
    for ax, phase in zip(_axes(fig), phases, strict=True):
        sel = df[df["phase"] == phase]
        for i, ctrl in enumerate(pd.unique(sel["controller"])):
            part = sel[sel["controller"] == ctrl]
            style = _style(str(ctrl), i)
            f, m, s = (part[c].to_numpy(float) for c in ("frequency", "mean", "std"))
            n = int(part["n"].iloc[0]) if len(part) else 0
            style["label"] = f"{style['label']} (n = {n})"
            ax.plot(f, m, lw=1.0, **style)
            ax.fill_between(f, np.maximum(m - s, 0), m + s, color=style["color"], alpha=0.2)
        ax.set(xlabel="frequency (Hz)", ylabel="|E_o| (m)", title=f"ensemble spectrum, {phase}")
        ax.set_xlim(0, fmax)
        ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def distributions(
    runs: pd.DataFrame,
    metrics: Sequence[str] = ("iae", "itae"),
    kind: str = "box",
    path: str | Path | None = None,
) -> Figure:
    """Distributions over gust realisations of each metric, per phase and controller (box or
    violin plots, from ``mc.runs``; diverged rows left out). Rows: metrics; columns: phases."""
    if kind not in ("box", "violin"):
        raise ValueError(f"kind must be 'box' or 'violin', got {kind!r}")
    ok = runs[~runs["diverged"].astype(bool)]
    phases = list(pd.unique(runs["phase"]))
    ctrls = [str(c) for c in pd.unique(runs["controller"])]
    fig = new_figure(len(metrics), len(phases), width=3.2 * len(phases), height=2.8)
    grid = np.asarray(fig.axes).reshape(len(metrics), len(phases))
    for r, metric in enumerate(metrics):
        for c, phase in enumerate(phases):
            ax = grid[r, c]
            data = [_finite(ok, phase, ctrl, metric) for ctrl in ctrls]
            _dist(ax, data, kind, [_style(k, i)["color"] for i, k in enumerate(ctrls)])
            labels = [STYLE.get(k, {}).get("label", k) for k in ctrls]
            ax.set_xticks(range(1, len(ctrls) + 1), labels)
            ylabel = _unit(metric).replace(metric, metric.upper()) if c == 0 else ""
            ax.set(title=f"{metric.upper()}, {phase}", ylabel=ylabel)
    return _finish(fig, path)


def _finite(runs: pd.DataFrame, phase: str, ctrl: str, metric: str) -> np.ndarray:
    sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)][metric]
    values = sel.to_numpy(float)
    return values[np.isfinite(values)]


def _dist(ax: Axes, data: list[np.ndarray], kind: str, colors: list[str]) -> None:
    keep = [i for i, d in enumerate(data) if len(d)]
    if not keep:
        return
    vals = [data[i] for i in keep]
    pos = [i + 1 for i in keep]
    if kind == "violin" and all(np.ptp(v) > 0 for v in vals):
        parts = ax.violinplot(vals, positions=pos, showmedians=True)
        bodies: list[Any] = list(parts["bodies"])  # type: ignore[call-overload]
        for body, i in zip(bodies, keep, strict=True):
            body.set_facecolor(colors[i])
    else:
        box = ax.boxplot(vals, positions=pos, widths=0.5, patch_artist=True)
        for patch, i in zip(box["boxes"], keep, strict=True):
            patch.set(facecolor=colors[i], alpha=0.35)


def sweep_metric(
    summary: pd.DataFrame,
    metric: str = "max_abs",
    phases: Sequence[str] | None = None,
    path: str | Path | None = None,
) -> Figure:
    """Mean of ``metric`` against the first swept key, one panel per phase, per controller with
    its 95% CI as error bars (from :meth:`quadrs.sweep.SweepResult.summary`). With a second
    swept key, one line per controller and value of that key."""
    keys = [n for n in summary.index.names if n not in ("metric", "phase")]
    part = summary.xs(metric, level="metric").reset_index()
    phases = list(phases) if phases is not None else list(pd.unique(part["phase"]))
    ctrls = [c.removesuffix("_mean") for c in part.columns if c.endswith("_mean")]
    fig = new_figure(len(phases), 1)
    for ax, phase in zip(_axes(fig), phases, strict=True):
        sel = part[part["phase"] == phase]
        for j, (sub_label, sub) in enumerate(_by_second_key(sel, keys)):
            for i, ctrl in enumerate(ctrls):
                style = _style(ctrl, i, markers=True)
                if len(keys) > 1:
                    style["color"] = _CYCLE[j % len(_CYCLE)]
                _errorline(ax, sub, keys[0], ctrl, style, sub_label)
        ylabel = f"{_unit(metric)}, mean and 95% CI"
        ax.set(xlabel=_unit(keys[0]), ylabel=ylabel, title=f"{metric}, {phase}")
        ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def _by_second_key(sel: pd.DataFrame, keys: list[str]) -> list[tuple[str, pd.DataFrame]]:
    if len(keys) < 2:
        return [("", sel)]
    return [(f", {keys[1]} = {v}", sel[sel[keys[1]] == v]) for v in pd.unique(sel[keys[1]])]


def _errorline(
    ax: Axes, sub: pd.DataFrame, key: str, ctrl: str, style: dict[str, Any], suffix: str
) -> None:
    x = sub[key].to_numpy()
    mean = sub[f"{ctrl}_mean"].to_numpy(float)
    lo = mean - sub[f"{ctrl}_ci_low"].to_numpy(float)
    hi = sub[f"{ctrl}_ci_high"].to_numpy(float) - mean
    err = np.nan_to_num(np.vstack([lo, hi]))
    style = {**style, "label": f"{style['label']}{suffix}"}
    ax.errorbar(x, mean, yerr=err, capsize=3, lw=1.0, **style)


def max_amplitude(
    summary: pd.DataFrame,
    phases: Sequence[str] = ("P1", "P3"),
    path: str | Path | None = None,
) -> Figure:
    """Maximum relative-oscillation amplitude against the swept key (paper Figs. 13 and 14,
    over ``payload.natural_frequency``: take-off P1 and landing P3), PD -* and SMC --+ with
    95% CIs, from a sweep's summary."""
    present = set(summary.index.get_level_values("phase"))
    return sweep_metric(summary, "max_abs", [p for p in phases if p in present] or None, path)


# -- risk -----------------------------------------------------------------------------------
#: Plain-English axis labels of metrics, with units.
PLAIN_LABELS = {
    "max_accel": "Payload acceleration peak (m/s²)",
    "rms_accel": "Payload acceleration RMS (m/s²)",
    "max_abs": "Peak payload bounce |e_o| (m)",
    "rms": "RMS payload bounce e_o (m)",
    "iae": "Integrated absolute bounce, IAE (m s)",
    "itae": "Time-weighted IAE, ITAE (m s²)",
    "tracking_rms": "RMS altitude tracking error (m)",
    "peak_frequency": "Frequency of the bounce's spectral peak (Hz)",
    "peak_amplitude": "Amplitude of the bounce's spectral peak (m)",
}


def exceedance_curves(
    runs: pd.DataFrame,
    metric: str = "max_accel",
    thresholds: Sequence[float] = (),
    phases: Sequence[str] | None = None,
    confidence: float = 0.95,
    path: str | Path | None = None,
) -> Figure:
    """Empirical exceedance curves P(metric > x) = 1 - CDF, log y, one panel per phase, one line
    per controller, with a band of pointwise exact (Clopper-Pearson) ``confidence`` intervals
    (:func:`quadrs.risk.survival_curve`; pointwise, not simultaneous). Diverged realisations
    count as exceeding every x. ``thresholds`` are marked as vertical lines."""
    from quadrs.risk import check_metric, survival_curve

    check_metric(metric)
    phases = list(phases) if phases is not None else [str(p) for p in pd.unique(runs["phase"])]
    ctrls = [str(c) for c in pd.unique(runs["controller"])]
    fig = new_figure(len(phases), 1)
    floor = 1.0
    for ax, phase in zip(_axes(fig), phases, strict=True):
        for i, ctrl in enumerate(ctrls):
            sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)]
            div = sel["diverged"].to_numpy(bool)
            curve = survival_curve(sel[metric].to_numpy(float), div, confidence)
            if curve.empty:
                continue
            style = _style(ctrl, i)
            n = int(curve["n"].iloc[0])
            note = f", {int(div.sum())} diverged (counted as exceeding)" if div.any() else ""
            style["label"] = f"{style['label']} (n = {n}{note})"
            x, p = curve["threshold"].to_numpy(float), curve["probability"].to_numpy(float)
            shown = p > 0
            ax.step(x[shown], p[shown], where="post", lw=1.2, **style)
            ax.fill_between(
                x,
                curve["ci_low"].to_numpy(float),
                curve["ci_high"].to_numpy(float),
                step="post",
                color=style["color"],
                alpha=0.2,
            )
            floor = min(floor, 0.5 / max(n, 1))
        for t in thresholds:
            ax.axvline(float(t), color="black", lw=0.8, ls=":")
        ax.set_yscale("log")
        ax.set_ylim(floor, 1.05)
        ax.set(
            xlabel=PLAIN_LABELS.get(metric, _unit(metric)),
            ylabel="Chance of exceeding",
            title=f"Exceedance, {phase} (bands: pointwise {confidence:.0%} exact intervals)",
        )
        ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


# -- uncertain parameters -------------------------------------------------------------------
def dispersion_scatter(
    mc: Any,
    metric: str = "iae",
    phases: Sequence[str] | None = None,
    path: str | Path | None = None,
) -> Figure:
    """A metric against each dispersed key, one point per realisation and controller (rows:
    keys; columns: phases). Diverged realisations are drawn as crosses at the top."""
    keys = list(mc.dispersed_keys)
    if not keys:
        raise ValueError("dispersion_scatter needs a batch with dispersed keys")
    phases = list(phases or mc.scenario.phase_names)
    runs = mc.runs
    fig = new_figure(len(keys), len(phases), width=3.2 * len(phases), height=2.6)
    grid = np.asarray(fig.axes).reshape(len(keys), len(phases))
    label = PLAIN_LABELS.get(metric, _unit(metric))
    for r, key in enumerate(keys):
        for c, phase in enumerate(phases):
            ax = grid[r, c]
            for i, ctrl in enumerate(mc.controllers):
                sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)]
                ok = ~sel["diverged"].astype(bool)
                style = _style(ctrl, i)
                ax.scatter(
                    sel.loc[ok, key],
                    sel.loc[ok, metric],
                    s=6,
                    alpha=0.5,
                    color=style["color"],
                    label=style["label"],
                )
                if (~ok).any():
                    top = np.nanmax(sel[metric]) if ok.any() else 1.0
                    ax.scatter(
                        sel.loc[~ok, key],
                        np.full((~ok).sum(), top),
                        marker="x",
                        color=style["color"],
                        label=f"{style['label']} diverged",
                    )
            ax.set(xlabel=_unit(key), title=f"{phase}")
            if c == 0:
                ax.set_ylabel(label)
            if r == 0 and c == len(phases) - 1:
                ax.legend(loc="best", fontsize="small")
    return _finish(fig, path)


def sobol_bars(
    sa: Any,
    metric: str = "iae",
    phases: Sequence[str] | None = None,
    path: str | Path | None = None,
) -> Figure:
    """First-order (S1, solid) and total (ST, hatched) Sobol' indices of one metric with
    their 95 % intervals, per phase (columns) and controller (bar colours)."""
    idx = sa.indices[sa.indices["metric"] == metric]
    phases = list(phases or pd.unique(idx["phase"]))
    params = list(sa.parameters)
    ctrls = [str(c) for c in pd.unique(idx["controller"])]
    fig = new_figure(1, len(phases), width=3.4 * len(phases), height=0.5 * len(params) + 1.6)
    width = 0.8 / (2 * len(ctrls))
    y = np.arange(len(params))
    for ax, phase in zip(fig.axes, phases, strict=True):
        for i, ctrl in enumerate(ctrls):
            sel = idx[(idx["phase"] == phase) & (idx["controller"] == ctrl)].set_index("parameter")
            sel = sel.reindex(params)
            style = _style(ctrl, i)
            for j, (col, hatch) in enumerate((("S1", None), ("ST", "//"))):
                pos = y - 0.4 + width * (2 * i + j + 0.5)
                ax.barh(
                    pos,
                    sel[col],
                    height=width,
                    xerr=sel[f"{col}_conf"],
                    color=style["color"],
                    alpha=0.45 if hatch else 0.85,
                    hatch=hatch,
                    label=f"{style['label']} {'total' if hatch else 'first-order'}",
                )
        ax.set_yticks(y, params if ax is fig.axes[0] else [""] * len(params))
        ax.set_xlim(-0.05, 1.05)
        ax.axvline(0, color="grey", lw=0.5)
        ax.set(xlabel="Sobol' index (share of variance)", title=phase)
    fig.axes[-1].legend(loc="lower right", fontsize="small")
    name = PLAIN_LABELS.get(metric, metric).split(" (")[0].split(",")[0]
    fig.suptitle(f"What drives the {name[0].lower() + name[1:]}")
    return _finish(fig, path)


def gust_transmissibility(
    scenario: Any,
    controllers: Sequence[str] = ("pd", "smc"),
    wind: float | None = None,
    freqs_hz: Any = None,
    path: str | Path | None = None,
) -> Figure:
    """Gust-to-e_o transmissibility |e_o / w_z|(f) of the closed loop linearised at hover
    (:func:`quadrs.linearize`) about a steady vertical wind ``wind`` (m/s; default
    :func:`quadrs.linear.equivalent_wind`, the gust's statistically equivalent wind)."""
    from quadrs.linear import equivalent_wind, linearize

    w0 = equivalent_wind(scenario) if wind is None else float(wind)
    f = np.logspace(-2, 1.5, 600) if freqs_hz is None else np.asarray(freqs_hz, dtype=float)
    fig = new_figure(height=3.6)
    ax = _axes(fig)[0]
    for c in controllers:
        lin = linearize(scenario, c, inputs=("wind_z",), outputs=("e_o",), wind=(0.0, 0.0, w0))
        mag = np.abs(lin.frequency_response(f)[:, 0, 0])
        style = {k: v for k, v in STYLE[c].items() if k != "marker"}
        ax.loglog(f, mag, **style)
    ax.set_xlabel("Gust frequency (Hz)")
    ax.set_ylabel("Payload oscillation per unit gust\n|e_o / vertical wind| (m per m/s)")
    ax.set_title(f"Vertical gust to payload oscillation, linearised about {w0:.2g} m/s updraft")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return _finish(fig, path)
