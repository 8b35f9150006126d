"""Route figures (docs/model.md, "Routes"): the ground track (x-y) and the altitude profile
(z against the distance flown along the route), each with the reference, the quadrotor and
the payload.

The payload's path is the trace's ``xc, yc, zc`` columns when the payload model has them (a
cable), otherwise the quadrotor's ``x, y`` with the payload's ``zc`` (a spring payload moves
laterally with the vehicle). Conventions as :mod:`quadrs.plots` (no pyplot, ``path=`` writes
PNG and SVG, ``ax=`` one Axes per panel).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
import pandas as pd
from matplotlib.figure import Figure

from quadrs.plots.base import (
    AxesArg,
    Flights,
    add_legend,
    controller_label,
    finish_figure,
    flights_by_label,
    panel_axes,
)
from quadrs.runs.flight import Flight

Array = npt.NDArray[np.float64]


def payload_xyz(trace: pd.DataFrame) -> tuple[Array, Array, Array]:
    """The payload's x, y, z (m) in a trace: ``xc, yc, zc`` if present, else ``x, y, zc``."""
    x, y = ("xc", "yc") if {"xc", "yc"} <= set(trace.columns) else ("x", "y")
    return (
        trace[x].to_numpy(float),
        trace[y].to_numpy(float),
        trace["zc"].to_numpy(float),
    )


def along_track(points: Array, x: Array, y: Array) -> Array:
    """Horizontal distance (m) along the route's ground track (the polyline through
    ``points[:, :2]``) of the track point nearest each (x, y): the abscissa of an altitude
    profile. Vertical legs have no horizontal length; with no horizontal leg at all it is 0."""
    xy = np.asarray(points, float)[:, :2]
    seg = np.diff(xy, axis=0)
    lengths = np.hypot(seg[:, 0], seg[:, 1])
    keep = lengths > 0
    if not keep.any():
        return np.zeros_like(np.asarray(x, float))
    starts, seg, lengths = xy[:-1][keep], seg[keep], lengths[keep]
    before = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])
    p = np.stack([np.asarray(x, float), np.asarray(y, float)], axis=1)
    # (samples, legs): projection parameter clipped to the leg, distance to that point.
    rel = p[:, None, :] - starts[None, :, :]
    u = np.clip((rel * seg[None, :, :]).sum(axis=2) / lengths**2, 0.0, 1.0)
    off = rel - u[:, :, None] * seg[None, :, :]
    nearest = np.argmin(np.hypot(off[..., 0], off[..., 1]), axis=1)
    rows = np.arange(len(p))
    return np.asarray(before[nearest] + u[rows, nearest] * lengths[nearest], dtype=np.float64)


def _route_points(flight: Flight) -> Array:
    route = flight.scenario.route
    if route is None:
        raise ValueError(
            'route figures need a route (trajectory.interpolation = "route"), got '
            f"{flight.scenario['trajectory.interpolation']!r}"
        )
    pts = [route.segments[0].origin] + [s.target for s in route.segments]
    return np.asarray(pts, float)


def ground_track(flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """The route seen from above: the reference's, the quadrotor's and the payload's x-y
    paths and the route's points, one panel per flight."""
    named = flights_by_label(flights)
    fig, axes = panel_axes(ax, len(named), width=6.0, height=5.0)
    for a, (label, flight) in zip(axes, named.items(), strict=True):
        tr, pts = flight.trace, _route_points(flight)
        xc, yc, _ = payload_xyz(tr)
        a.plot(tr["x_ref"], tr["y_ref"], color="tab:red", lw=1.2, label="reference")
        a.plot(tr["x"], tr["y"], color="tab:blue", lw=1.0, label="quadrotor")
        a.plot(xc, yc, color="black", ls="--", lw=1.0, label="payload")
        a.plot(pts[:, 0], pts[:, 1], "o", color="tab:red", ms=4, label="route points")
        a.set(xlabel="x (m)", ylabel="y (m)", title=f"{controller_label(label)}: ground track")
        a.set_aspect("equal", adjustable="datalim")
        add_legend(a)
    return finish_figure(fig, path)


def altitude_profile(
    flights: Flights, path: str | Path | None = None, *, ax: AxesArg = None
) -> Figure:
    """Altitude against the horizontal distance along the route (:func:`along_track`) for the
    reference, the quadrotor and the payload, one panel per flight."""
    named = flights_by_label(flights)
    fig, axes = panel_axes(ax, len(named))
    for a, (label, flight) in zip(axes, named.items(), strict=True):
        tr, pts = flight.trace, _route_points(flight)
        xc, yc, zc = payload_xyz(tr)
        ref = along_track(pts, tr["x_ref"].to_numpy(float), tr["y_ref"].to_numpy(float))
        quad = along_track(pts, tr["x"].to_numpy(float), tr["y"].to_numpy(float))
        a.plot(ref, tr["z_ref"], color="tab:red", lw=1.2, label="reference")
        a.plot(quad, tr["z"], color="tab:blue", lw=1.0, label="quadrotor")
        a.plot(along_track(pts, xc, yc), zc, color="black", ls="--", lw=1.0, label="payload")
        a.set(
            xlabel="distance along the ground track (m)",
            ylabel="altitude (m)",
            title=f"{controller_label(label)}: altitude profile",
        )
        add_legend(a)
    return finish_figure(fig, path)
