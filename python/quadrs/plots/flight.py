"""Figures of single flights: altitude, the payload's relative oscillation, its spectra and
power spectral densities, the gust's drag force (the paper's Figs. 4-12 and 15), and the
altitude with and without mass compensation (Fig. 16).

Re-exported by :mod:`quadrs.plots`; save a figure with :func:`quadrs.plots.save`."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import pandas as pd
from matplotlib.figure import Figure

from quadrs.plots.base import (
    DISPLACEMENT,
    FMAX,
    AxesArg,
    Flights,
    add_legend,
    controller_label,
    finish_figure,
    flight_title,
    flights_by_label,
    gust_window,
    line_style,
    panel_axes,
    psd_panel,
    require_drawn,
    shade_gust,
)
from quadrs.runs.flight import Flight
from quadrs.runs.psd import phase_psd, phase_window


def _phases(flight: Flight, phases: Sequence[str] | None) -> list[str]:
    """The phases asked for; by default the scenario's own (the whole flight on request)."""
    return list(phases) if phases is not None else flight.scenario.scenario_phases


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
    how = "Welch" if method == "welch" else "periodogram"
    drawn = []
    for a, phase in zip(axes, phases, strict=True):
        for i, (label, flight) in enumerate(named.items()):
            f, p = phase_psd(flight, phase, method, resolution)
            keep = (f > 0) & (f <= fmax)
            a.plot(f[keep], p[keep], lw=1.0, **line_style(label, i))
        drawn.append(psd_panel(a, fmax, f"spectral density of the {DISPLACEMENT} ({how}), {phase}"))
    require_drawn(drawn, f"power spectral density of the {DISPLACEMENT} ({how})")
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
