"""Figures of a slung payload (docs/model.md, "Cable-slung payload"): how far the load swings
and how hard the line pulls, and where the load goes beside the vehicle.

The conventions are those of :mod:`quadrs.plots`: each function returns a Figure built without
pyplot, saves PNG and SVG when given ``path``, and draws into the caller's Axes with ``ax=``
(one per panel, in the order the docstring gives).
"""

from __future__ import annotations

import math
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
from quadrs.runs.flight import Flight
from quadrs.scenario.route import FLIGHT_PHASE

__all__ = ["lowering_path", "payload_path", "swing_tension"]


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


def _hooks(trace: pd.DataFrame, offset: float) -> np.ndarray:
    """The hook's inertial position (m) at each row: ``offset`` below the centre of gravity
    along the body's z axis (R = Rz(psi) Ry(theta) Rx(phi))."""
    phi, theta, psi = (trace[c].to_numpy() for c in ("phi", "theta", "psi"))
    body_z = np.column_stack([
        np.cos(psi) * np.sin(theta) * np.cos(phi) + np.sin(psi) * np.sin(phi),
        np.sin(psi) * np.sin(theta) * np.cos(phi) - np.cos(psi) * np.sin(phi),
        np.cos(theta) * np.cos(phi),
    ])  # fmt: skip
    return trace[["x", "y", "z"]].to_numpy() - offset * body_z


def lowering_path(
    flight: Flight, path: str | Path | None = None, *, every: float = 1.0, ax: AxesArg = None
) -> Figure:
    """A parcel lowered by the winch, from its first lowering (``trajectory.lower``) to the
    hook's release (or the flight's end): two panels, seen across the route (sideways y
    against height) and from above (forward x against sideways y). The line from the hook to
    the parcel is drawn every ``every`` s (grey), the parcel's path dashed black, the
    vehicle's blue; the touchdown (the parcel's first contact with the ground) is a red cross,
    the drop point it aims at (the lowering's route point, on the ground) a green ring.
    Metres throughout, from ``Flight.trace`` and the scenario's route."""
    sc = flight.scenario
    route = sc.route
    lowerings = route.lowerings if route is not None else []
    if not lowerings:
        raise ValueError("lowering_path: the flight's route lowers no parcel (trajectory.lower)")
    tr = flight.trace
    t = tr["t"].to_numpy() if "t" in tr else tr.index.to_numpy()
    start = lowerings[0].start
    whole = flight.metrics.set_index("phase").loc[FLIGHT_PHASE]
    release = float(whole["release_time"])
    stop = release if math.isfinite(release) else t[-1]
    window = (t >= start) & (t <= stop)
    part = tr[window]
    hooks = _hooks(part, float(sc["payload.attachment_offset"] or 0.0))
    parcel = part[["xc", "yc", "zc"]].to_numpy()
    ground = float(sc["ground.altitude"])
    drop = lowerings[0].origin
    fig, (side, top) = panel_axes(ax, 2, width=9.0, height=4.0)
    step = max(1, round(every / (t[1] - t[0]))) if len(t) > 1 else 1
    for i in range(0, len(part), step):
        for a, (h, v) in ((side, (1, 2)), (top, (0, 1))):
            a.plot([hooks[i, h], parcel[i, h]], [hooks[i, v], parcel[i, v]], color="0.6",
                   lw=0.8, label="line" if i == 0 else "_line")  # fmt: skip
    touched = np.flatnonzero(parcel[:, 2] < ground)
    for a, (h, v), (hl, vl) in ((side, (1, 2), ("sideways y (m)", "height z (m)")),
                                (top, (0, 1), ("forward x (m)", "sideways y (m)"))):  # fmt: skip
        a.plot(part[["x", "y", "z"]].to_numpy()[:, h], part[["x", "y", "z"]].to_numpy()[:, v],
               color="tab:blue", lw=1.0, label="vehicle")  # fmt: skip
        a.plot(parcel[:, h], parcel[:, v], color="black", ls="--", lw=1.0, label="parcel")
        target = (drop[h], ground if v == 2 else drop[v])
        a.plot(*target, "o", mfc="none", mec="tab:green", ms=10, mew=1.5, label="drop point")
        if touched.size:
            k = touched[0]
            a.plot(parcel[k, h], parcel[k, v], "x", color="tab:red", ms=9, mew=2,
                   label="touchdown")  # fmt: skip
        a.set(xlabel=hl, ylabel=vl)
        add_legend(a)
    side.axhline(ground, color="0.3", lw=1.0)
    side.set_title(f"lowering, seen across the route; {flight_title(flight.controller, flight)}")
    miss = float(whole["touchdown_miss"])
    top.set_title(f"seen from above: touchdown {miss:.2f} m from the drop point"
                  if math.isfinite(miss) else "seen from above")  # fmt: skip
    top.set_aspect("equal", adjustable="datalim")
    return finish_figure(fig, path)
