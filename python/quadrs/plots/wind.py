"""Figures of the wind over the whole flight (docs/model.md, "Wind over the whole flight"): the
wind a flight met, and the turbulence's spectrum per component against the MIL-F-8785C
formulas. Conventions as in :mod:`quadrs.plots` (Agg, PNG and SVG with ``path``, ``ax=``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from quadrs import _core
from quadrs.plots.base import (
    AxesArg,
    add_legend,
    finish_figure,
    panel_axes,
    panel_rows,
    psd_panel,
    require_drawn,
    welch_band,
)
from quadrs.runs.flight import Flight
from quadrs.runs.gust import COMPONENTS, gust_scales
from quadrs.runs.psd import gust_spectrum_frame
from quadrs.scenario.scenario import Scenario

_AXES = ("x", "y", "z")


def mean_wind(scenario: Scenario, altitude: Any) -> np.ndarray:
    """The scenario's ``[wind]`` mean wind (m/s, inertial x, y, z) at each altitude (m), shape
    (n, 3): W20 f(h) (cos chi, sin chi, 0), computed by the engine."""
    h = np.ascontiguousarray(np.atleast_1d(altitude), dtype=np.float64)
    return _core.mean_wind(scenario.to_json(), h)


def wind_met(flight: Flight, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """The wind the quadrotor met (m/s, inertial, held over each step: the trace's
    ``wind_x``, ``wind_y``, ``wind_z``) against time, one panel per component (three
    panels), with the ``[wind]`` mean wind at the quadrotor's altitude dashed: what the
    turbulence and the discrete gusts ride on."""
    trace = flight.trace
    t = trace.index.to_numpy(float)
    mean = mean_wind(flight.scenario, trace["z"].to_numpy(float))
    fig, axes = panel_axes(ax, 3)
    for i, (a, name) in enumerate(zip(axes, _AXES, strict=True)):
        a.plot(t, trace[f"wind_{name}"], color="tab:blue", lw=0.8, label="wind met")
        a.plot(t, mean[:, i], color="black", ls="--", lw=1.2, label="mean wind at z")
        a.set(xlabel="time (s)", ylabel=f"wind {name} (m/s)")
        a.grid(True, alpha=0.3)
        add_legend(a)
    what = flight.label or f"realisation {flight.realisation}"
    axes[0].set_title(f"Wind met ({flight.controller.upper()}, {what})")
    return finish_figure(fig, path)


def _scale(scenario: Scenario, key: str, given: float | None, word: str) -> float:
    value = scenario[key]
    if given is not None:
        return float(given)
    if value == word:
        raise ValueError(
            f"{key} = {word!r} follows the vehicle: give the {key.split('.')[1]} to draw at"
        )
    return float(value)


def gust_spectra_frame(
    scenario: Scenario,
    altitude: float | None = None,
    airspeed: float | None = None,
    *,
    dt: float = 0.01,
    steps: int = 8192,
    realisations: int = 64,
    seed: int = 0,
) -> pd.DataFrame:
    """The scenario's turbulence per component at one altitude (m) and airspeed (m/s) (the
    scenario's own unless given; required where they follow the vehicle): for each of
    longitudinal, lateral, vertical, :func:`quadrs.plots.gust_spectrum_frame` with that
    component's MIL-F-8785C sigma and L (column ``component``)."""
    h = _scale(scenario, "gust.altitude", altitude, "vehicle")
    v = _scale(scenario, "gust.airspeed", airspeed, "relative")
    scales = gust_scales(h, scenario.turbulence_w20)
    model = str(scenario["gust.model"])
    parts = []
    for c in COMPONENTS:
        sigma, length = scales[c]
        part = gust_spectrum_frame(
            c, sigma, length, v, dt, steps, realisations, seed, models=(model,)
        )
        parts.append(part.assign(component=c, sigma=sigma, length_scale=length))
    out = pd.concat(parts, ignore_index=True)
    out.attrs = {"altitude": h, "airspeed": v, "dt": dt, "realisations": realisations,
                 "model": model}  # fmt: skip
    return out


def gust_spectra(
    frame: pd.DataFrame | None = None,
    path: str | Path | None = None,
    *,
    ax: AxesArg = None,
    **params: Any,
) -> Figure:
    """The turbulence's one-sided PSD per component (three panels) against the MIL-F-8785C
    formula at that component's sigma and L: the ensemble-mean Welch PSD with a +-2
    standard-error band and the formula, log-log up to a fifth of the Nyquist frequency.
    ``frame``: from :func:`gust_spectra_frame`, called with ``params`` when None."""
    frame = gust_spectra_frame(**params) if frame is None else frame
    p = frame.attrs
    fig, axes = panel_axes(ax, len(COMPONENTS))
    top = 0.1 / p["dt"]
    drawn = []
    for a, c in zip(axes, COMPONENTS, strict=True):
        sel = panel_rows(frame, "component", c, top)
        f = welch_band(a, sel, f"Welch mean of {p['realisations']}")
        a.plot(f, sel["formula"], color="black", ls="--", lw=1.2, label="MIL-F-8785C formula")
        sigma, length = float(sel["sigma"].iloc[0]), float(sel["length_scale"].iloc[0])
        title = f"{c}: sigma = {sigma:.3g} m/s, L = {length:.3g} m"
        drawn.append(psd_panel(a, top, title, ylabel="PSD ((m/s)²/Hz)"))
    axes[0].figure.suptitle(
        f"{p['model']} turbulence at h = {p['altitude']:g} m, V = {p['airspeed']:g} m/s"
    )
    require_drawn(drawn, "turbulence spectra")
    return finish_figure(fig, path)
