"""Figures a reader of the paper will recognise (its Figs. 4-16), and their Monte Carlo versions.

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

import matplotlib
import numpy as np
import pandas as pd
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from quadrs.flight import Flight
from quadrs.parquet import atomic_write
from quadrs.psd import amplitude_to_psd as amplitude_to_psd  # re-exported: plots.amplitude_to_psd
from quadrs.psd import ensemble_psd_frame, phase_psd, phase_window, welch_psd
from quadrs.report import phase_diverged
from quadrs.units import UNITS as KEY_UNITS

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
    "itae": "m s²",
    "max_abs": "m",
    "rms": "m",
    "tracking_rms": "m",
    "peak_frequency": "Hz",
    "peak_amplitude": "m",
    "max_accel": "m/s²",
    "rms_accel": "m/s²",
    # every scenario key, from the package's one table of them (quadrs.units)
    **{key: unit.replace("^2", "²").replace("^3", "³") for key, unit in KEY_UNITS.items()},
}
#: Plain-English axis labels of metrics and common scenario keys, with units. Every figure
#: labels a metric or key through these (a key not listed shows as itself).
PLAIN_LABELS = {
    "max_accel": "Payload acceleration peak (m/s²)",
    "rms_accel": "Payload acceleration RMS (m/s²)",
    "max_abs": "Peak |payload relative displacement| (m)",
    "rms": "RMS payload relative displacement (m)",
    "iae": "Integrated absolute displacement, IAE (m s)",
    "itae": "Time-weighted IAE, ITAE (m s²)",
    "tracking_rms": "RMS altitude tracking error (m)",
    "peak_frequency": "Frequency of the displacement's spectral peak (Hz)",
    "peak_amplitude": "Amplitude of the displacement's spectral peak (m)",
    "payload.natural_frequency": "Attachment natural frequency (Hz)",
    "payload.stiffness": "Attachment stiffness (N/m)",
    "payload.mass": "Payload mass (kg)",
    "payload.damping": "Attachment damping (N s/m)",
    "payload.drag_area": "Payload drag area (m²)",
    "gust.w20": "Wind at 20 ft (m/s)",
    "gust.airspeed": "Airspeed (m/s)",
    "gust.altitude": "Altitude of the gust model (m)",
    "gust.air_density": "Air density (kg/m³)",
    "vehicle.mass": "Quadrotor mass (kg)",
    "vehicle.drag_area": "Quadrotor drag area (m²)",
    "integrator.dt": "Integration step (s)",
}
#: Short names for titles (the label without its unit, where that is long).
SHORT_NAMES = {
    "max_abs": "Peak |relative displacement|",
    "rms": "RMS relative displacement",
    "iae": "IAE",
    "itae": "ITAE",
    "tracking_rms": "RMS tracking error",
    "peak_frequency": "Spectral peak frequency",
    "peak_amplitude": "Spectral peak amplitude",
    "max_accel": "Peak payload acceleration",
    "rms_accel": "RMS payload acceleration",
}
#: What the trace's e_o = (zc - z) + d0 is called on a figure.
DISPLACEMENT = "payload relative displacement"
_CYCLE = ("tab:blue", "black", "goldenrod", "tab:green", "tab:purple", "tab:brown")

Flights = Flight | Sequence[Flight] | Mapping[str, Flight]
#: Where to draw: None (a new figure), one Axes, or one Axes per panel.
AxesArg = Axes | Sequence[Axes] | None


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


def _panels(
    ax: AxesArg, nrows: int, ncols: int = 1, width: float = 7.0, height: float = 3.0
) -> tuple[Figure, list[Axes]]:
    """The figure and its ``nrows x ncols`` panels (row-major): a new figure, or the caller's
    ``ax`` (one Axes for a one-panel figure, else a sequence of exactly that many Axes)."""
    n = nrows * ncols
    if ax is None:
        fig = new_figure(nrows, ncols, width, height)
        return fig, list(fig.axes)
    axes = [ax] if isinstance(ax, Axes) else list(ax)
    if len(axes) != n or not all(isinstance(a, Axes) for a in axes):
        raise ValueError(
            f"ax must be {'an Axes' if n == 1 else f'a sequence of {n} Axes'} (one per panel), "
            f"got {ax!r}"
        )
    root = axes[0].get_figure(root=True)
    if not isinstance(root, Figure):
        raise ValueError("ax must belong to a Figure")
    return root, axes


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


def _ctrl_name(ctrl: str) -> str:
    return str(STYLE.get(ctrl.lower(), {}).get("label", ctrl))


def _gust_window(flight: Flight) -> tuple[float, float] | None:
    s = flight.scenario
    return (float(s["gust.start"]), float(s["gust.end"])) if s["gust.enabled"] else None


def _unit(name: str) -> str:
    """The plain label of a metric or key with its unit; ``name (unit)`` if it has none."""
    if name in PLAIN_LABELS:
        return PLAIN_LABELS[name]
    return f"{name} ({UNITS[name]})" if name in UNITS else name


def _short(name: str) -> str:
    """A metric's or key's name for a title: short, without its unit."""
    return SHORT_NAMES.get(name) or _unit(name).split(" (")[0]


def _legend(ax: Axes, **kwargs: Any) -> None:
    """A legend of every labelled artist (call after drawing them all)."""
    ax.legend(loc="best", fontsize="small", **kwargs)


def _phases(flight: Flight, phases: Sequence[str] | None) -> list[str]:
    return list(phases) if phases is not None else flight.scenario.phase_names


# -- single flights -------------------------------------------------------------------------
def altitude(flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """Reference, quadrotor and payload altitude against time (paper Figs. 4 and 7), one panel
    per flight, from ``Flight.trace`` columns ``z_ref``, ``z`` and ``zc``."""
    named = _named(flights)
    fig, axes = _panels(ax, len(named))
    for a, (label, flight) in zip(axes, named.items(), strict=True):
        tr = flight.trace
        a.plot(tr.index, tr["z_ref"], color="tab:red", lw=1.2, label="reference")
        a.plot(tr.index, tr["z"], color="tab:blue", lw=1.0, label="quadrotor")
        a.plot(tr.index, tr["zc"], color="black", ls="--", lw=1.0, label="payload")
        _shade_gust(a, flight)
        a.set(xlabel="time (s)", ylabel="altitude (m)", title=_title(label, flight))
        _legend(a)
    return _finish(fig, path)


def _title(label: str, flight: Flight) -> str:
    return f"{_ctrl_name(label)}: seed {flight.seed}, realisation {flight.realisation}"


def _shade_gust(ax: Axes, flight: Flight) -> None:
    window = _gust_window(flight)
    if window is not None:
        ax.axvspan(*window, color="0.9", zorder=0, label="gust window")


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
    named = _named(flights)
    first = next(iter(named.values()))
    phases = _phases(first, phases)
    fig, axes = _panels(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        lo, hi = phase_window(first, phase)
        for i, (label, flight) in enumerate(named.items()):
            e = flight.trace["e_o"]
            part = e[(e.index >= lo) & (e.index <= hi)]
            a.plot(part.index, part.to_numpy(), lw=1.0, **_style(label, i))
        window = _gust_window(first)
        edges = [t for t in (window or ()) if lo <= t <= hi]
        for k, t in enumerate(edges):
            a.axvline(t, color="black", lw=1.0, label="gust start/end" if k == 0 else "_edge")
        a.set(
            xlabel="time (s)", ylabel=f"{DISPLACEMENT} (m)", title=f"relative oscillation, {phase}"
        )
        _legend(a)
    return _finish(fig, path)


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
    named = _named(flights)
    phases = _phases(next(iter(named.values())), phases)
    fig, axes = _panels(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        for i, (label, flight) in enumerate(named.items()):
            sp = flight.spectra[phase]
            sp = sp[sp["frequency"] <= fmax]
            a.plot(sp["frequency"], sp["amplitude"], lw=1.0, **_style(label, i))
        what = title or f"amplitude spectrum of the {DISPLACEMENT}"
        a.set(xlabel="frequency (Hz)", ylabel="amplitude (m)", title=f"{what}, {phase}")
        a.set_xlim(0, fmax)
        _legend(a)
    return _finish(fig, path)


def _loglog(a: Axes, fmax: float) -> None:
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlim(right=fmax)
    a.grid(True, which="both", alpha=0.3)


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
    named = _named(flights)
    phases = _phases(next(iter(named.values())), phases)
    fig, axes = _panels(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        for i, (label, flight) in enumerate(named.items()):
            f, p = phase_psd(flight, phase, method, resolution)
            keep = (f > 0) & (f <= fmax)
            a.plot(f[keep], p[keep], lw=1.0, **_style(label, i))
        how = "Welch" if method == "welch" else "periodogram"
        a.set(
            xlabel="frequency (Hz)",
            ylabel="PSD (m²/Hz)",
            title=f"power spectral density of the {DISPLACEMENT} ({how}), {phase}",
        )
        _loglog(a, fmax)
        _legend(a)
    return _finish(fig, path)


def gust_force(flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """The gust (paper Fig. 15): vertical wind velocity (m/s) and the vertical drag force it
    exerts on the quadrotor (N): the trace's ``drag_z``, the force the engine's dynamics use
    (docs/model.md section 1). Zoomed on the gust window when the gust is on."""
    named = _named(flights)
    fig, (ax_w, ax_f) = _panels(ax, 2)
    for i, (label, flight) in enumerate(named.items()):
        tr = _around_gust(flight)
        force = tr["drag_z"]
        if i == 0:
            ax_w.plot(tr.index, tr["wind_z"], color="black", lw=1.0, label="vertical wind")
        ax_f.plot(force.index, force.to_numpy(), lw=1.0, **_style(label, i))
    ax_w.set(xlabel="time (s)", ylabel="vertical wind (m/s)", title="vertical gust velocity")
    ax_f.set(xlabel="time (s)", ylabel="vertical drag force (N)",
             title="drag force on the quadrotor")  # fmt: skip
    _legend(ax_w)
    _legend(ax_f)
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
    fig, axes = _panels(ax, len(modes))
    for a, comp in zip(axes, modes, strict=True):
        chosen = sorted((m, f) for (c, m), f in flights.items() if c == comp)
        ref = chosen[0][1].trace
        a.plot(ref.index, ref["z_ref"], color="tab:red", lw=1.2, label="reference")
        for i, (mass, flight) in enumerate(chosen):
            tr = flight.trace
            style = _style(f"payload {mass:g} kg", i)
            a.plot(tr.index, tr["z"], lw=1.0, **style)
        what = (
            "compensated (vehicle + payload mass)" if comp else "conventional (vehicle mass only)"
        )
        a.set(
            xlabel="time (s)",
            ylabel="quadrotor altitude (m)",
            title=f"{_ctrl_name(chosen[0][1].controller)}, {what}",
        )
        _legend(a)
    return _finish(fig, path)


# -- Monte Carlo ----------------------------------------------------------------------------
Curve = tuple[pd.DataFrame, dict[str, Any], int]


def _ensemble_panels(
    df: pd.DataFrame, phases: Sequence[str] | None, ax: AxesArg
) -> tuple[Figure, list[tuple[Axes, str, list[Curve]]]]:
    """One panel per phase of a tidy ensemble frame, with each controller's rows, style and
    realisation count ``n``."""
    phases = list(phases) if phases is not None else [str(p) for p in pd.unique(df["phase"])]
    fig, axes = _panels(ax, len(phases))
    panels = []
    for a, phase in zip(axes, phases, strict=True):
        sel = df[df["phase"] == phase]
        curves = []
        for i, ctrl in enumerate(pd.unique(sel["controller"])):
            part = sel[sel["controller"] == ctrl]
            curves.append((part, _style(str(ctrl), i), int(part["n"].iloc[0])))
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
        _legend(a)
    return _finish(fig, path)


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
        _loglog(a, fmax)
        _legend(a)
    return _finish(fig, path)


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

    ``by``: the swept key(s) of a sweep's runs (:attr:`quadrs.sweep.SweepResult.keys`): one
    box or violin per grid point and controller, grouped by grid point along x, instead of
    pooling the points."""
    if kind not in ("box", "violin"):
        raise ValueError(f"kind must be 'box' or 'violin', got {kind!r}")
    keys = [by] if isinstance(by, str) else list(by or ())
    for key in keys:
        if key not in runs.columns:
            raise ValueError(f"by: {key!r} is not a column of the runs")
    ok = runs[~phase_diverged(runs)]
    phases = [str(p) for p in pd.unique(runs["phase"])]
    ctrls = [str(c) for c in pd.unique(runs["controller"])]
    colors = [_style(k, i)["color"] for i, k in enumerate(ctrls)]
    points = list(runs[keys].drop_duplicates().itertuples(index=False)) if keys else [()]
    width = max(3.2, 0.45 * len(points) * len(ctrls) + 1.0)
    fig, axes = _panels(ax, len(metrics), len(phases), width * len(phases), 2.8)
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
                a.set_xlabel(", ".join(_unit(k) for k in keys))
                handles = [Patch(color=col, alpha=0.5) for col in colors]
                a.legend(handles, [_ctrl_name(k) for k in ctrls], loc="best", fontsize="small")
            else:
                a.set_xticks(range(1, len(ctrls) + 1), [_ctrl_name(k) for k in ctrls])
            ylabel = textwrap.fill(_unit(metric), 30) if c == 0 else ""  # narrow panels
            a.set(title=f"{_short(metric)}, {phase}", ylabel=ylabel)
    return _finish(fig, path)


def _at(runs: pd.DataFrame, keys: list[str], point: tuple[Any, ...]) -> pd.DataFrame:
    mask = np.ones(len(runs), dtype=bool)
    for key, value in zip(keys, point, strict=True):
        mask &= (runs[key] == value).to_numpy()
    return runs[mask]


def _point_label(point: Sequence[Any]) -> str:
    return ", ".join(f"{v:g}" if isinstance(v, float) else str(v) for v in point)


def _finite(runs: pd.DataFrame, phase: str, ctrl: str, metric: str) -> np.ndarray:
    sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)][metric]
    values = sel.to_numpy(float)
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
    its 95% CI as error bars (from :meth:`quadrs.sweep.SweepResult.summary`). With a second
    swept key, one line per controller and value of that key."""
    keys = [n for n in summary.index.names if n not in ("metric", "phase")]
    part = summary.xs(metric, level="metric").reset_index()
    phases = list(phases) if phases is not None else [str(p) for p in pd.unique(part["phase"])]
    ctrls = [c.removesuffix("_mean") for c in part.columns if c.endswith("_mean")]
    fig, axes = _panels(ax, len(phases))
    for a, phase in zip(axes, phases, strict=True):
        sel = part[part["phase"] == phase]
        for j, (sub_label, sub) in enumerate(_by_second_key(sel, keys)):
            for i, ctrl in enumerate(ctrls):
                style = _style(ctrl, i, markers=True)
                if len(keys) > 1:
                    style["color"] = _CYCLE[j % len(_CYCLE)]
                _errorline(a, sub, keys[0], ctrl, style, sub_label)
        # The long label wrapped to fit beside one panel: unwrapped it overlaps its neighbours'.
        ylabel = textwrap.fill(_unit(metric), 28)
        a.set(xlabel=_unit(keys[0]), ylabel=ylabel, title=f"{_short(metric)}, {phase}")
        _legend(a, title="mean and 95% CI", title_fontsize="small")
    return _finish(fig, path)


def _by_second_key(sel: pd.DataFrame, keys: list[str]) -> list[tuple[str, pd.DataFrame]]:
    if len(keys) < 2:
        return [("", sel)]
    name = _short(keys[1]).lower()
    unit = f" {UNITS[keys[1]]}" if keys[1] in UNITS else ""
    return [
        (f", {name} {_point_label([v])}{unit}", sel[sel[keys[1]] == v])
        for v in pd.unique(sel[keys[1]])
    ]


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
    (:func:`quadrs.risk.survival_curve`; pointwise, not simultaneous). Diverged realisations
    count as exceeding every x. ``thresholds`` are marked as vertical lines."""
    from quadrs.risk import check_metric, survival_curve

    check_metric(metric)
    phases = list(phases) if phases is not None else [str(p) for p in pd.unique(runs["phase"])]
    ctrls = [str(c) for c in pd.unique(runs["controller"])]
    fig, axes = _panels(ax, len(phases))
    floor = 1.0
    for a, phase in zip(axes, phases, strict=True):
        for i, ctrl in enumerate(ctrls):
            sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)]
            div = phase_diverged(sel)
            curve = survival_curve(sel[metric].to_numpy(float), div, confidence)
            if curve.empty:
                continue
            style = _style(ctrl, i)
            n = int(curve["n"].iloc[0])
            note = f", {int(div.sum())} diverged (counted as exceeding)" if div.any() else ""
            style["label"] = f"{style['label']} (n = {n}{note})"
            x, p = curve["threshold"].to_numpy(float), curve["probability"].to_numpy(float)
            shown = p > 0
            a.step(x[shown], p[shown], where="post", lw=1.2, **style)
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
            a.axvline(float(t), color="black", lw=0.8, ls=":", label="limit" if k == 0 else "_")
        a.set_yscale("log")
        a.set_ylim(floor, 1.05)
        a.set(
            xlabel=_unit(metric),
            ylabel="Chance of exceeding",
            title=f"Exceedance, {phase} (bands: pointwise {confidence:.0%} exact intervals)",
        )
        _legend(a)
    return _finish(fig, path)


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
    phases = list(phases or mc.scenario.phase_names)
    runs = mc.runs
    fig, axes = _panels(ax, len(keys), len(phases), width=3.2 * len(phases), height=2.6)
    grid = np.asarray(axes, dtype=object).reshape(len(keys), len(phases))
    label = _unit(metric)
    for r, key in enumerate(keys):
        for c, phase in enumerate(phases):
            a = grid[r, c]
            for i, ctrl in enumerate(mc.controllers):
                sel = runs[(runs["phase"] == phase) & (runs["controller"] == ctrl)]
                ok = ~phase_diverged(sel)
                style = _style(ctrl, i)
                a.scatter(
                    sel.loc[ok, key],
                    sel.loc[ok, metric],
                    s=6,
                    alpha=0.5,
                    color=style["color"],
                    label=style["label"],
                )
                if (~ok).any():
                    top = np.nanmax(sel[metric]) if ok.any() else 1.0
                    a.scatter(
                        sel.loc[~ok, key],
                        np.full((~ok).sum(), top),
                        marker="x",
                        color=style["color"],
                        label=f"{style['label']} diverged",
                    )
            a.set(xlabel=_unit(key), title=f"{phase}")
            if c == 0:
                a.set_ylabel(label)
            if r == 0 and c == len(phases) - 1:
                _legend(a)
    return _finish(fig, path)


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
    phases = list(phases or pd.unique(idx["phase"]))
    params = list(sa.parameters)
    ctrls = [str(c) for c in pd.unique(idx["controller"])]
    height = 0.5 * len(params) + 1.6
    fig, axes = _panels(ax, 1, len(phases), width=3.4 * len(phases), height=height)
    width = 0.8 / (2 * len(ctrls))
    y = np.arange(len(params))
    for a, phase in zip(axes, phases, strict=True):
        for i, ctrl in enumerate(ctrls):
            sel = idx[(idx["phase"] == phase) & (idx["controller"] == ctrl)].set_index("parameter")
            sel = sel.reindex(params)
            style = _style(ctrl, i)
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
        names = [_short(p) for p in params]
        a.set_yticks(y, names if a is axes[0] else [""] * len(params))
        a.set_xlim(-0.05, 1.05)
        a.axvline(0, color="grey", lw=0.5)
        a.set(xlabel="Sobol' index (share of variance)", title=phase)
    axes[-1].legend(loc="lower right", fontsize="small")
    name = _unit(metric).split(" (")[0].split(",")[0]
    what = f"What drives the {name[0].lower() + name[1:]}"
    if ax is None:
        fig.suptitle(what)
    else:  # the caller's figure keeps its own title
        axes[0].set_title(f"{what}: {axes[0].get_title()}")
    return _finish(fig, path)


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
    :func:`quadrs.linear.equivalent_wind`, the gust's statistically equivalent wind)."""
    from quadrs.linear import equivalent_wind, linearize

    w0 = equivalent_wind(scenario) if wind is None else float(wind)
    f = np.logspace(-2, 1.5, 600) if freqs_hz is None else np.asarray(freqs_hz, dtype=float)
    fig, (a,) = _panels(ax, 1, height=3.6)
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
    return _finish(fig, path)


# -- the gust alone -------------------------------------------------------------------------
def gust_spectrum_frame(
    component: str = "vertical",
    sigma: float = 1.0,
    length_scale: float = 2.0,
    airspeed: float = 10.0,
    dt: float = 0.01,
    steps: int = 8192,
    realisations: int = 64,
    seed: int = 0,
    *,
    models: Sequence[str] = ("dryden", "von_karman"),
    resolution: float | None = None,
    workers: int | None = None,
) -> pd.DataFrame:
    """The generated gust's spectrum against the formula, per model: the Welch PSD
    (:func:`welch_psd`, ``(m/s)^2/Hz``) of each of ``realisations`` series of
    :func:`quadrs.gust.gust_series` (``steps`` samples every ``dt`` s), averaged (column
    ``welch``, with its standard error ``welch_se`` over realisations), beside
    :func:`quadrs.gust.gust_psd` at the same frequencies: ``filter`` (the forming filter the
    series discretises) and ``formula`` (the Dryden or exact von Karman PSD). ``resolution``
    defaults to 1 / (1024 dt) Hz. The sampled series' PSD is the aliased filter PSD: compare
    well below the Nyquist frequency 1 / (2 dt)."""
    from quadrs.gust import gust_psd, gust_series

    if not dt > 0:
        raise ValueError(f"dt must be positive (s), got {dt!r}")
    resolution = 1.0 / (min(1024, steps) * dt) if resolution is None else resolution
    parts = []
    for model in models:
        x = gust_series(
            component, sigma, length_scale, airspeed, dt, steps, realisations, seed,
            model=model, workers=workers,
        )  # fmt: skip
        f, p = welch_psd(x, 1.0 / dt, resolution)
        p = np.atleast_2d(p)
        realised, target = gust_psd(f, component, sigma, length_scale, airspeed, dt, model=model)
        se = p.std(axis=0, ddof=1) / np.sqrt(len(p)) if len(p) > 1 else np.full(len(f), np.nan)
        parts.append(
            pd.DataFrame(
                {
                    "model": model,
                    "frequency": f,
                    "welch": p.mean(axis=0),
                    "welch_se": se,
                    "filter": realised,
                    "formula": target,
                }
            )
        )
    out = pd.concat(parts, ignore_index=True)
    out.attrs = {
        "component": component, "sigma": sigma, "length_scale": length_scale,
        "airspeed": airspeed, "dt": dt, "realisations": realisations,
    }  # fmt: skip
    return out


_MODEL_NAMES = {"dryden": "Dryden", "von_karman": "von Kármán"}


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
    fig, axes = _panels(ax, len(models))
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
        _loglog(a, top)
        _legend(a)
    return _finish(fig, path)


from quadrs.plots_mission import mission_risk  # noqa: E402, F401  (re-exported)
from quadrs.plots_wind import gust_spectra, gust_spectra_frame, wind_met  # noqa: E402, F401
from quadrs.plots_payload import payload_path, swing_tension  # noqa: E402,F401  (re-exported)
from quadrs.plots_rotors import rotors  # noqa: E402, F401  (re-exported)
