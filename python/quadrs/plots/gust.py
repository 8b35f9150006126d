"""Figures of the gust: what the closed loop at hover passes of it to the payload
(transmissibility), and the generated gust's spectrum against its formula.

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
    finish_figure,
    line_style,
    panel_axes,
    panel_rows,
    psd_panel,
    require_drawn,
    welch_band,
)
from quadrs.runs.psd import gust_spectrum_frame

#: Display names of the gust models.
_MODEL_NAMES = {"dryden": "Dryden", "von_karman": "von Kármán"}


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
    for i, c in enumerate(controllers):
        lin = linearize(scenario, c, inputs=("wind_z",), outputs=("e_o",), wind=(0.0, 0.0, w0))
        mag = np.abs(lin.frequency_response(f)[:, 0, 0])
        style = line_style(c, i)
        a.loglog(f, mag, **style)
    a.set_xlabel("Gust frequency (Hz)")
    a.set_ylabel("Payload relative displacement\nper unit vertical gust (m per m/s)")
    a.set_title(f"Vertical gust to payload oscillation, linearised about {w0:.2g} m/s updraft")
    a.grid(True, which="both", alpha=0.3)
    a.legend()
    return finish_figure(fig, path)


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
    drawn = []
    for a, model in zip(axes, models, strict=True):
        sel = panel_rows(frame, "model", model, top)
        name = _MODEL_NAMES.get(model, model)
        f = welch_band(a, sel, f"generated, Welch mean of {p['realisations']}")
        a.plot(f, sel["formula"], color="black", ls="--", lw=1.2, label=f"{name} formula")
        if model != "dryden":  # Dryden's filter is its formula
            a.plot(f, sel["filter"], color="tab:red", ls=":", lw=1.2, label="rational filter")
        title = (f"{name} {p['component']} gust: sigma = {p['sigma']:g} m/s, "
                 f"L = {p['length_scale']:g} m, V = {p['airspeed']:g} m/s")  # fmt: skip
        drawn.append(psd_panel(a, top, title, ylabel="PSD ((m/s)²/Hz)"))
    require_drawn(drawn, "gust spectra")
    return finish_figure(fig, path)
