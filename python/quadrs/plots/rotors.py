"""Rotor figures (docs/model.md "Rotors"): what each rotor did over a flight, against its limits.

Re-exported by :mod:`quadrs.plots`; same conventions (a Figure without pyplot, ``path`` saves
PNG and SVG, ``ax=`` draws into existing Axes).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt
from matplotlib.figure import Figure

from quadrs.plots.base import AxesArg, add_legend, finish_figure, flight_title, panel_axes
from quadrs.runs.flight import Flight

#: Trace columns of the rotors: speeds (states, rad/s) and actual thrusts kf w^2 (N).
SPEEDS = ("omega_1", "omega_2", "omega_3", "omega_4")
THRUSTS = ("thrust_1", "thrust_2", "thrust_3", "thrust_4")
#: Trace column: 1 in the steps whose rotor command was clamped to a thrust limit, else 0.
SATURATED = "saturated"
_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple")


def saturated_intervals(
    t: npt.ArrayLike, flag: npt.ArrayLike, step: float
) -> list[tuple[float, float]]:
    """The time intervals in which ``flag`` (one value per trace row at times ``t``) is
    nonzero: each run of flagged rows from its first time to its last time plus ``step`` (the
    row spacing: a flagged row holds its command over the step that follows it)."""
    t = np.asarray(t, dtype=float)
    on = np.asarray(flag, dtype=float) != 0.0
    edges = np.diff(np.concatenate(([0], on.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
    return [(float(t[a]), float(t[b]) + step) for a, b in zip(starts, ends, strict=True)]


def rotors(flight: Flight, path: str | Path | None = None, *, ax: AxesArg = None) -> Figure:
    """Rotor speeds (rad/s) and thrusts (N) against time, two panels: each rotor's trace
    (``omega_i``, and ``thrust_i`` = kf omega_i^2, the thrust the airframe feels), the limits
    (``actuator.thrust_min``/``thrust_max``, and the speeds sqrt(limit / kf) that give them),
    and, shaded, the intervals in which any rotor's command was clamped to a limit.

    Raises ValueError for a flight whose scenario does not fly rotors."""
    s = flight.scenario
    model = s.get("actuator.model", "ideal")
    if model != "rotors":
        raise ValueError(f"rotors needs a flight with actuator.model = 'rotors', got {model!r}")
    tr = flight.trace
    missing = [c for c in (*SPEEDS, *THRUSTS, SATURATED) if c not in tr.columns]
    if missing:
        raise ValueError(f"the flight's trace has no rotor columns {missing}")
    kf = float(s["actuator.thrust_coefficient"])
    limits = (float(s["actuator.thrust_min"]), float(s["actuator.thrust_max"]))
    t = tr.index.to_numpy(dtype=float)
    step = float(t[1] - t[0]) if len(t) > 1 else float(s["integrator.dt"])
    shaded = saturated_intervals(t, tr[SATURATED], step)
    fig, axes = panel_axes(ax, 2, height=2.8)
    panels = (
        (SPEEDS, tuple(float(np.sqrt(x / kf)) for x in limits), "rotor speed (rad/s)", "ω"),
        (THRUSTS, limits, "rotor thrust (N)", "T"),
    )
    for a, (columns, (low, high), ylabel, symbol) in zip(axes, panels, strict=True):
        for k, (column, colour) in enumerate(zip(columns, _COLOURS, strict=True)):
            a.plot(t, tr[column], color=colour, lw=1.0, label=f"{symbol}{k + 1}")
        a.axhline(high, color="black", ls="--", lw=0.9, label="limits")
        if low > 0:
            a.axhline(low, color="black", ls="--", lw=0.9)
        for i, (start, end) in enumerate(shaded):
            a.axvspan(start, end, color="0.85", zorder=0, lw=0, label="clamped" if i == 0 else None)
        a.set(xlabel="time (s)", ylabel=ylabel)
        add_legend(a, ncols=3)
    layout = s["actuator.layout"]
    axes[0].set_title(f"Rotors ({layout} layout), {flight_title(flight.controller, flight)}")
    return finish_figure(fig, path)
