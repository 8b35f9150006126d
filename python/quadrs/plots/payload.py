"""Figures of a slung payload (docs/model.md, "Cable-slung payload"): how far the load swings
and how hard the line pulls, and where the load goes beside the vehicle.

The conventions are those of :mod:`quadrs.plots`: each function returns a Figure built without
pyplot, saves PNG and SVG when given ``path``, and draws into the caller's Axes with ``ax=``
(one per panel, in the order the docstring gives).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from quadrs.plots.base import (
    AxesArg,
    Figure,
    Flights,
    add_legend,
    finish_figure,
    flight_title,
    flights_by_label,
    line_style,
    panel_axes,
    shade_gust,
)

__all__ = ["payload_path", "swing_tension"]


def swing_tension(
    flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None
) -> Figure:
    """The cable's angle from hanging straight down (degrees) and its tension (N) against time:
    two panels, one line per flight (PD dashed blue, SMC solid red), the gust window shaded.
    Read from ``Flight.trace`` columns ``swing`` (rad) and ``tension`` (N); for the vertical
    spring the angle is 0 and the "tension" is the spring force."""
    named = flights_by_label(flights)
    fig, (angle, pull) = panel_axes(ax, 2)
    for i, (label, flight) in enumerate(named.items()):
        tr = flight.trace
        angle.plot(tr.index, np.degrees(tr["swing"].to_numpy()), lw=1.0, **line_style(label, i))
        pull.plot(tr.index, tr["tension"].to_numpy(), lw=1.0, **line_style(label, i))
    first = next(iter(named.values()))
    for a in (angle, pull):
        shade_gust(a, first)
    angle.set(
        xlabel="time (s)",
        ylabel="cable angle from vertical (deg)",
        title="how far the load swings",
    )
    pull.set(xlabel="time (s)", ylabel="cable tension (N)", title="how hard the line pulls")
    pull.axhline(0.0, color="0.5", lw=0.8, label="slack (no tension)")
    add_legend(angle)
    add_legend(pull)
    return finish_figure(fig, path)


def _payload_xyz(trace: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The payload's inertial position; a vertical spring's load moves sideways with the
    vehicle, so its x and y are the vehicle's."""
    x = trace["xc"] if "xc" in trace else trace["x"]
    y = trace["yc"] if "yc" in trace else trace["y"]
    return x.to_numpy(), y.to_numpy(), trace["zc"].to_numpy()


def payload_path(flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """The payload's path beside the vehicle's, seen from the side (x-z) and from above (x-y):
    two panels per flight (one row each), the vehicle solid, the payload dashed, both starting
    at a dot. Positions in metres, from ``Flight.trace`` columns ``x, y, z`` and ``xc, yc,
    zc``."""
    named = flights_by_label(flights)
    fig, axes = panel_axes(ax, len(named), 2, width=9.0, height=3.6)
    for row, (label, flight) in enumerate(named.items()):
        side, top = axes[2 * row], axes[2 * row + 1]
        tr = flight.trace
        xc, yc, zc = _payload_xyz(tr)
        x, y, z = (tr[c].to_numpy() for c in ("x", "y", "z"))
        for a, (h, v, hc, vc, vlabel) in (
            (side, (x, z, xc, zc, "height z (m)")),
            (top, (x, y, xc, yc, "sideways y (m)")),
        ):
            a.plot(h, v, color="tab:blue", lw=1.0, label="vehicle")
            a.plot(hc, vc, color="black", ls="--", lw=1.0, label="payload")
            a.plot(h[:1], v[:1], "o", color="tab:blue", ms=4, label="start")
            a.plot(hc[:1], vc[:1], "o", color="black", ms=4, label="_start")
            a.set(xlabel="forward x (m)", ylabel=vlabel)
            add_legend(a)
        # Equal scales: a swing looks like a swing. The side view spans the line's length.
        top.set_aspect("equal", adjustable="datalim")
        side.set_aspect("equal", adjustable="datalim")
        side.set_title(f"side view; {flight_title(label, flight)}")
        top.set_title("seen from above")
    return finish_figure(fig, path)
