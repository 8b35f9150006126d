"""One flight: :func:`simulate` and its result, :class:`Flight`."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pandas as pd

from quadrs import _core
from quadrs.guard import CONTROLLERS, check_controller, check_int, run_cancellable
from quadrs.scenario import Scenario
from quadrs.stability import warn_before_running

__all__ = [
    "CONTROLLERS",
    "METRIC_COLUMNS",
    "TRACE_COLUMNS",
    "Flight",
    "check_controller",
    "simulate",
]

METRIC_COLUMNS: tuple[str, ...] = tuple(_core.METRIC_NAMES)
TRACE_COLUMNS: tuple[str, ...] = tuple(_core.TRACE_COLUMNS)


def metrics_frame(phases: list[str], values: np.ndarray) -> pd.DataFrame:
    """Per-phase metrics (rows in phase order) as a DataFrame with a ``phase`` column."""
    frame = pd.DataFrame(values, columns=list(METRIC_COLUMNS))
    frame.insert(0, "phase", pd.Series(phases, dtype=str))  # plain strings, as in mc.runs
    return frame


@dataclass(frozen=True)
class Flight:
    """One simulated flight.

    ``metrics``: one row per phase (``phase`` and the metric columns). ``trace``: indexed by
    time ``t`` (s): states, references, controls, wind and ``e_o``. ``spectra``: per phase, the
    amplitude spectrum of e_o (``frequency`` in Hz, ``amplitude`` in m).
    """

    scenario: Scenario
    controller: str
    seed: int
    realisation: int
    metrics: pd.DataFrame
    trace: pd.DataFrame
    spectra: dict[str, pd.DataFrame] = field(repr=False)
    diverged_at: float = float("nan")

    def __repr__(self) -> str:
        """A summary, not the frames: controller, gust realisation, span, outcome."""
        t = self.trace.index
        span = f"{t[0]:g}-{t[-1]:g} s, {len(t)} trace rows" if len(t) else "no trace"
        end = f"diverged at {self.diverged_at:g} s" if self.diverged else "did not diverge"
        return (
            f"<Flight {self.controller.upper()}, seed {self.seed}, realisation "
            f"{self.realisation}, {span}, {end}; {self.scenario!r}>"
        )

    @property
    def diverged(self) -> bool:
        """True if the state went non-finite or ran away (see ``divergence.*`` keys)."""
        return not np.isnan(self.diverged_at)


def simulate(
    scenario: Scenario,
    controller: str = "smc",
    seed: int = 0,
    *,
    realisation: int = 0,
    record_every: int | None = None,
    wind: npt.ArrayLike | None = None,
) -> Flight:
    """Fly ``scenario`` once with ``controller`` ("pd" or "smc").

    The gust is realisation ``realisation`` of master ``seed``: the same pair gives the same
    gust in :func:`quadrs.monte_carlo`. ``record_every`` thins the trace to every n-th step
    (default: about one row per millisecond). A dispersed scenario flies the values that
    realisation drew under ``sampling="random"`` (``flight.scenario`` is that fixed scenario).

    ``wind``: a prescribed wind (m/s, inertial x, y, z; z up) flown instead of the gust model
    (the ``gust`` keys are then ignored), shape ``(scenario.steps + 1, 3)``: row k is held over
    the step starting at t = k * dt (the last row only shows in the trace). For deterministic
    inputs, e.g. a sinusoid to measure a frequency response (docs/design-loop.md).
    """
    check_controller(controller)
    seed = check_int("seed", seed)
    realisation = check_int("realisation", realisation)
    scenario = scenario.realisation(seed, realisation)
    # Loud only if the scenario excites an unstable mode (the flight will diverge).
    warn_before_running(scenario, (controller,), gains=False, stacklevel=2)
    if record_every is None:
        record_every = max(1, round(1e-3 / float(scenario["integrator.dt"])))
    record_every = check_int("record_every", record_every, 1, 2**63 - 1)
    prescribed = None
    if wind is not None:
        prescribed = np.ascontiguousarray(wind, dtype=np.float64)
        if prescribed.ndim != 2 or prescribed.shape[1] != 3:
            raise ValueError(f"wind must have shape (steps + 1, 3), got {prescribed.shape}")
    # The engine polls a cancel flag, so Ctrl-C stops even a long flight promptly.
    progress = _core.Progress()
    config_json = scenario.to_json()
    out, _ = run_cancellable(
        lambda: _core.simulate(
            config_json, controller, seed, realisation, record_every, prescribed, progress
        ),
        progress,
    )
    raw = out["trace"]
    trace = pd.DataFrame(raw[:, 1:], index=pd.Index(raw[:, 0], name="t"), columns=TRACE_COLUMNS)
    phases = scenario.phase_names
    freqs = scenario.spectrum_frequencies
    spectra = {
        name: pd.DataFrame({"frequency": f, "amplitude": a})
        for name, f, a in zip(phases, freqs, out["spectra"], strict=True)
    }
    return Flight(
        scenario=scenario,
        controller=controller,
        seed=seed,
        realisation=realisation,
        metrics=metrics_frame(phases, out["metrics"]),
        trace=trace,
        spectra=spectra,
        diverged_at=float(out["diverged_at"]),
    )
