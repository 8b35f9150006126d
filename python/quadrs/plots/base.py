"""What every figure module shares: the paper's styles, plain-English labels with units,
the Agg-backed figure and its panels, saving, and small drawing helpers. Imported by
:mod:`quadrs.plots` and every figure module beside it (none of which imports another).
Units as shown come from :mod:`quadrs.present.labels`."""

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

from quadrs import _core
from quadrs.io.files import atomic_write
from quadrs.present.labels import PLAIN_LABELS, UNITS
from quadrs.runs.flight import Flight
from quadrs.scenario.route import FLIGHT_PHASE

#: Default frequency range of spectra (Hz): the payload modes of interest sit well below.
FMAX = 10.0
FORMATS = ("png", "svg")
#: Each law's line, by its place among the engine's laws (``_core.CONTROLLER_NAMES``: the
#: paper's PD and SMC first, in the paper's style), its legend its label
#: (``_core.CONTROLLER_LABELS``): a law the engine registers has a style without an edit here.
_LAW_LINES = (
    {"color": "tab:blue", "linestyle": "--", "marker": "*"},
    {"color": "tab:red", "linestyle": "-", "marker": "+"},
    {"color": "tab:green", "linestyle": ":", "marker": "o"},
    {"color": "tab:purple", "linestyle": "-.", "marker": "x"},
    {"color": "tab:brown", "linestyle": (0, (5, 1)), "marker": "s"},
    {"color": "tab:olive", "linestyle": (0, (3, 1, 1, 1)), "marker": "^"},
)
_LAWS = zip(_core.CONTROLLER_NAMES, _core.CONTROLLER_LABELS, strict=True)
STYLE: dict[str, dict[str, Any]] = {
    name: {**_LAW_LINES[i % len(_LAW_LINES)], "label": label}
    for i, (name, label) in enumerate(_LAWS)
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
    "max_specific_force": "Peak payload specific force",
}
#: What the trace's e_o = (zc - z) + d0 is called on a figure.
DISPLACEMENT = "payload relative displacement"
CYCLE = ("tab:blue", "black", "goldenrod", "tab:green", "tab:purple", "tab:brown")

Flights = Flight | Sequence[Flight] | Mapping[str, Flight]
#: Where to draw: None (a new figure), one Axes, or one Axes per panel.
AxesArg = Axes | Sequence[Axes] | None


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
            try:
                atomic_write(
                    target,
                    lambda f, fmt=fmt, meta=meta: fig.savefig(
                        f, format=fmt, dpi=120, metadata=meta
                    ),  # type: ignore[misc]
                )
            except ValueError as e:
                if "log-scaled" not in str(e):
                    raise
                raise ValueError("nothing to draw on a log scale: the data has no positive, "
                                 "finite value") from None  # fmt: skip
            written.append(target)
    return written


def finish_figure(fig: Figure, path: str | Path | None) -> Figure:
    if path is not None:
        save(fig, path)
    return fig


def panel_axes(
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


def axes_of(fig: Figure) -> list[Axes]:
    return list(fig.axes)


def flights_by_label(flights: Flights) -> dict[str, Flight]:
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


def line_style(label: str, index: int, markers: bool = False) -> dict[str, Any]:
    """The paper's style for "pd"/"smc"; otherwise the ``index``-th colour and dash."""
    base = STYLE.get(label.lower())
    if base is not None:
        style = dict(base)
    else:
        style = {
            "color": CYCLE[index % len(CYCLE)],
            "linestyle": ("-", "--", "-.", ":")[index % 4],
            "marker": "o",
            "label": label,
        }
    if not markers:
        style.pop("marker")
    return style


def controller_label(ctrl: str) -> str:
    return str(STYLE.get(ctrl.lower(), {}).get("label", ctrl))


def gust_window(flight: Flight) -> tuple[float, float] | None:
    s = flight.scenario
    return (float(s["gust.start"]), float(s["gust.end"])) if s["gust.enabled"] else None


def label_with_unit(name: str) -> str:
    """The plain label of a metric or key with its unit; ``name (unit)`` if it has none."""
    if name in PLAIN_LABELS:
        return PLAIN_LABELS[name]
    return f"{name} ({UNITS[name]})" if name in UNITS else name


def short_label(name: str) -> str:
    """A metric's or key's name for a title: short, without its unit."""
    return SHORT_NAMES.get(name) or label_with_unit(name).split(" (")[0]


#: What an empty panel says instead of a legend.
NO_DATA = "nothing to draw: no finished, non-diverged flight has values here"


def add_legend(ax: Axes, **kwargs: Any) -> None:
    """A legend of every labelled artist (call after drawing them all); a panel with none says
    that it has nothing to draw (not matplotlib's "No artists with labels")."""
    if not ax.get_legend_handles_labels()[0]:
        ax.text(0.5, 0.5, NO_DATA, transform=ax.transAxes, ha="center", va="center",
                color="0.4", fontsize="small")  # fmt: skip
        return
    ax.legend(loc="best", fontsize="small", **kwargs)


def flight_title(label: str, flight: Flight) -> str:
    what = flight.label or f"seed {flight.seed}, realisation {flight.realisation}"
    return f"{controller_label(label)}: {what}"


def shade_gust(ax: Axes, flight: Flight) -> None:
    window = gust_window(flight)
    if window is not None:
        ax.axvspan(*window, color="0.9", zorder=0, label="gust window")


#: What a log-log panel without a point to show says instead, and why (a figure of such panels
#: raises with both): a log scale shows no zero or negative value.
NO_LOG_DATA = "nothing to draw on log axes"
NO_LOG_DATA_WHY = (
    "no positive, finite value (no flight finished without diverging, or every value is zero)"
)


def psd_panel(a: Axes, fmax: float, title: str, ylabel: str = "PSD (m²/Hz)") -> bool:
    """A spectral-density panel finished: its labels and ``title``, log-log axes up to
    ``fmax`` (:func:`loglog_axes`) and, where it drew, the legend; whether it drew."""
    a.set(xlabel="frequency (Hz)", ylabel=ylabel, title=title)
    drawn = loglog_axes(a, fmax)
    if drawn:
        add_legend(a)
    return drawn


def panel_rows(frame: pd.DataFrame, column: str, value: Any, top: float) -> pd.DataFrame:
    """One panel's rows of a spectra frame: those whose ``column`` is ``value``, at the
    frequencies a log-log axis shows up to ``top`` (0 < f <= top Hz)."""
    sel = frame[(frame[column] == value) & (frame["frequency"] > 0)]
    return sel[sel["frequency"] <= top]


def welch_band(a: Axes, sel: pd.DataFrame, label: str) -> np.ndarray:
    """The ensemble-mean Welch PSD of ``sel`` (columns ``frequency``, ``welch``,
    ``welch_se``) with its band of +-2 standard errors; returns the frequencies."""
    f = sel["frequency"].to_numpy(float)
    mean, se = sel["welch"].to_numpy(float), sel["welch_se"].to_numpy(float)
    a.plot(f, mean, color="tab:blue", lw=1.2, label=label)
    a.fill_between(f, np.maximum(mean - 2 * se, 0), mean + 2 * se, color="tab:blue", alpha=0.2,
                   label="±2 standard errors")  # fmt: skip
    return f


def loglog_axes(a: Axes, fmax: float) -> bool:
    """Log-log axes up to ``fmax``, if some line has a point with both coordinates positive
    and finite; else (every value zero: a released parcel's) the panel says it has nothing to
    draw. Returns whether it drew; a figure none of whose panels drew raises
    (:func:`require_drawn`)."""
    drawable = False
    for line in a.get_lines():
        x = np.asarray(line.get_xdata(), dtype=float)
        y = np.asarray(line.get_ydata(), dtype=float)
        drawable = drawable or bool((np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)).any())
    if not drawable:
        for line in list(a.get_lines()):
            line.remove()
        a.text(0.5, 0.5, f"{NO_LOG_DATA}:\n{NO_LOG_DATA_WHY}", transform=a.transAxes,
               ha="center", va="center", color="0.4", fontsize="small")  # fmt: skip
        a.set_yticks([])  # no scale to read
        return False
    a.set_xscale("log")
    a.set_yscale("log")
    a.set_xlim(right=fmax)
    a.grid(True, which="both", alpha=0.3)
    return True


def require_drawn(drawn: Sequence[bool], what: str) -> None:
    """A ValueError saying what the data lacks if no panel of the figure ``what`` could be
    drawn on log axes (:func:`loglog_axes`): a figure of empty panels is not written."""
    if not any(drawn):
        raise ValueError(f"{NO_LOG_DATA} ({what}): {NO_LOG_DATA_WHY}")


def all_phases(df: pd.DataFrame) -> list[str]:
    """Every phase of a table, the whole-flight phase (if any) last."""
    own = own_phases(df)
    return own + ([FLIGHT_PHASE] if (df["phase"] == FLIGHT_PHASE).any() else [])


def own_phases(df: pd.DataFrame) -> list[str]:
    """The phases in a table's ``phase`` column, the whole-flight phase left out."""
    return [str(p) for p in pd.unique(df["phase"]) if p != FLIGHT_PHASE]
