"""The figures ``mc``, ``mission``, ``sweep`` and ``report`` write with ``--plots``: a batch's
distributions, spectra, exceedance curves and dispersion scatter, a mission's risk per phase,
and a sweep's metrics against its keys;
and how every command writes its figures (``write_figures``): one figure that cannot be drawn
is named on stderr and costs none of the others."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from quadrs.cli.common import one_line
from quadrs.present.terminal import terminal_text

__all__ = ["mc_plots", "mission_plots", "sweep_plots", "write_figures"]


def mc_plots(mc: Any, directory: Path, limits: Sequence[tuple[str, float]] = ()) -> None:
    """A batch's figures into ``directory``; an exceedance curve per ``--limit`` metric."""
    from quadrs import plots

    figures: list[tuple[str, Any]] = [("distributions", lambda: plots.distributions(mc.runs))]
    if mc.spectra is not None:
        figures += [("spectra", lambda: plots.ensemble_spectra(mc.spectra)),
                    ("psd", lambda: plots.ensemble_psd(mc.spectra))]  # fmt: skip
    for metric in dict.fromkeys([m for m, _ in limits] or ["max_accel"]):
        marks = [t for m, t in limits if m == metric]
        curves = lambda m=metric, t=marks: plots.exceedance_curves(mc.runs, m, t)  # noqa: E731
        figures.append((f"exceedance_{metric}", curves))
    if mc.dispersed_keys:
        figures.append(("dispersion_iae", lambda: plots.dispersion_scatter(mc, "iae")))
    write_figures(figures, directory)


def write_figures(figures: Sequence[tuple[str, Callable[[], Any]]], directory: Path) -> None:
    """Each ``(name, make)``'s figure into ``directory`` as ``name`` (PNG and SVG), then how many
    files were written, on stderr. A figure without data to draw (every flight diverged, every
    value zero: nothing on a log scale) is named in a warning line and costs none of the others."""
    from quadrs import plots

    files: list[Path] = []
    for name, make in figures:
        try:
            files += plots.save(make(), directory / name)
        except ValueError as e:
            print(terminal_text(f"quadrs: warning: figure {name} not drawn ({one_line(str(e))})"),
                  file=sys.stderr)  # fmt: skip
    print(f"wrote {len(files)} figure files to {directory}", file=sys.stderr)


def sweep_plots(result: Any, directory: Path) -> None:
    """A sweep's figures into ``directory``."""
    from quadrs import plots

    summ = result.summary()
    write_figures(
        [
            ("sweep_max_abs", lambda: plots.sweep_metric(summ, "max_abs")),
            ("sweep_iae", lambda: plots.sweep_metric(summ, "iae")),
            # one box per grid point
            ("distributions", lambda: plots.distributions(result.runs, by=result.keys)),
        ],
        directory,
    )


def _curves(runs: Any, metric: str, marks: list[float]) -> Callable[[], Any]:
    from quadrs import plots

    return lambda: plots.exceedance_curves(runs, metric, marks)


def mission_plots(mc: Any, reports: Sequence[Any], directory: Path) -> None:
    """A mission's figures into ``directory``: per-phase risk with intervals (one figure per
    law's report, ``MissionReport``), and the exceedance curves of the payload's peaks (every
    law on each)."""
    from quadrs.plots.mission import mission_risk

    def risk(r: Any) -> Callable[[], Any]:
        return lambda: mission_risk(r)

    one = len(reports) == 1
    figures: list[tuple[str, Callable[[], Any]]] = [
        ("mission_risk" if one else f"mission_risk_{r.controller}", risk(r)) for r in reports
    ]
    report = reports[0]
    shown = [(m, [report.limit] if m == report.metric else []) for m in
             dict.fromkeys([report.metric, "max_accel", "max_swing", "max_tension"])]  # fmt: skip
    for metric, marks in shown:
        if metric in mc.runs:
            figures.append((f"exceedance_{metric}", _curves(mc.runs, metric, marks)))
    write_figures(figures, directory)
