"""The figures ``mc``, ``sweep`` and ``report`` write with ``--plots``: a batch's distributions,
spectra, exceedance curves and dispersion scatter, and a sweep's metrics against its keys.
One figure that cannot be drawn is named on stderr and costs none of the others."""

from __future__ import annotations

import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from quadrs.cli.common import one_line
from quadrs.present.terminal import terminal_text

__all__ = ["mc_plots", "sweep_plots"]


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
    files: list[Path] = []
    for name, make in figures:
        # One figure without data to draw (every flight diverged: nothing on a log scale)
        # must not cost the others.
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
    files = plots.save(plots.sweep_metric(summ, "max_abs"), directory / "sweep_max_abs")
    files += plots.save(plots.sweep_metric(summ, "iae"), directory / "sweep_iae")
    fig = plots.distributions(result.runs, by=result.keys)  # one box per grid point
    files += plots.save(fig, directory / "distributions")
    print(f"wrote {len(files)} figure files to {directory}", file=sys.stderr)
