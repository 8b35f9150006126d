"""One flight: :func:`simulate` and its result, :class:`Flight`."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from quadrs import _core
from quadrs.engine.calls import CONTROLLERS, check_controller, check_int, run_cancellable
from quadrs.hover.stability import warn_before_running
from quadrs.io.integrity import RunRecord, _fail
from quadrs.scenario.scenario import Scenario

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


_META_KEY = b"quadrs"
#: What a trace file records beside the run identity (name -> type), checked on read.
_TRACE_META = {"realisation": int, "record_every": int, "controller": str, "metrics": list}


class SpectraNotSaved(Mapping[str, pd.DataFrame]):
    """``Flight.spectra`` of a flight read from a trace file: the spectra are computed from the
    full-rate signal during the flight and are not saved; asking for one says how to get it."""

    def __init__(self, flight: str) -> None:
        self._flight = flight

    def __getitem__(self, phase: str) -> pd.DataFrame:
        raise KeyError(
            f"spectra are not saved in trace files: fly {self._flight} again with "
            f"quadrs.simulate to get them (phase {phase!r})"
        )

    def __iter__(self) -> Iterator[str]:
        return iter(())

    def __len__(self) -> int:
        return 0


def metrics_frame(phases: list[str], values: np.ndarray) -> pd.DataFrame:
    """Per-phase metrics (rows in phase order) as a DataFrame with a ``phase`` column."""
    frame = pd.DataFrame(values, columns=list(METRIC_COLUMNS))
    frame.insert(0, "phase", pd.Series(phases, dtype=str))  # plain strings, as in mc.runs
    return frame


@dataclass(frozen=True)
class Flight:
    """One simulated flight.

    ``metrics``: one row per phase (``phase`` and the metric columns), then the whole
    flight's row ``flight`` (every scenario has it: it is not one more phase, so a sum over
    the rows counts the flight twice; :meth:`phases_only` leaves it out). ``trace``: indexed by
    time ``t`` (s): states, references, controls, wind, ``e_o``, the magnitude of the payload's
    inertial acceleration ``accel_c`` (m/s^2), the vertical drag on the quadrotor ``drag_z``
    (N, the force the engine's dynamics use), the attachment's ``swing`` (rad) and ``tension``
    (N), then the actuator's own columns (``scenario.trace_columns`` lists them all).
    ``spectra``: per phase, the amplitude spectrum of e_o (``frequency`` in Hz, ``amplitude``
    in m).
    """

    scenario: Scenario
    controller: str
    seed: int
    realisation: int
    metrics: pd.DataFrame
    trace: pd.DataFrame
    spectra: Mapping[str, pd.DataFrame] = field(repr=False)
    diverged_at: float = float("nan")
    #: The trace keeps every ``record_every``-th integration step.
    record_every: int = 1
    #: Why the flight ended: "ok", or what ran away ("non_finite", "distance", "tilt",
    #: "speed", "rate"; ``_core.EXIT_MESSAGES`` says each in a sentence).
    status: str = "ok"
    #: What this flight is, when not realisation ``realisation`` of ``seed`` (a re-flown
    #: rare-event failure sample: ``"failure sample 3 of a rare-event run"``).
    label: str = ""
    #: With ``navigation.mode = "ekf"``: what the sensors gave the filter and the filter's
    #: state at the end (docs/model.md, "Navigation"): ``imu`` rows (t, gyro x3, accel x3),
    #: ``gnss`` rows (t fused, position x3, velocity x3, received), ``baro`` and ``heading``
    #: rows (t, value), ``initial`` (position, velocity, quaternion w x y z), ``state`` (the
    #: nominal state: p, v, q, gyro bias, accel bias, GNSS drift, baro bias), ``covariance``
    #: (19 x 19, row-major), ``truth`` (the sensors' biases and drifts at the start). None
    #: when the laws read the state.
    navigation: Mapping[str, np.ndarray] | None = field(default=None, repr=False)

    def phases_only(self) -> pd.DataFrame:
        """``metrics`` without the whole flight's ``flight`` row: the scenario's phases alone."""
        from quadrs.scenario.route import FLIGHT_PHASE

        return self.metrics[self.metrics["phase"] != FLIGHT_PHASE].reset_index(drop=True)

    def __repr__(self) -> str:
        """A summary, not the frames: controller, gust realisation, span, outcome."""
        t = self.trace.index
        span = f"{t[0]:g}-{t[-1]:g} s, {len(t)} trace rows" if len(t) else "no trace"
        end = (
            f"diverged at {self.diverged_at:g} s ({self.status})"
            if self.diverged
            else "did not diverge"
        )
        what = self.label or f"seed {self.seed}, realisation {self.realisation}"
        return f"<Flight {self.controller.upper()}, {what}, {span}, {end}; {self.scenario!r}>"

    def _repr_html_(self) -> str:
        """In a notebook: the per-phase metrics as an HTML table."""
        from quadrs.present.html import render

        return render(repr(self), [("metrics per phase", self.metrics.set_index("phase"))])

    @property
    def diverged(self) -> bool:
        """True if the state went non-finite or ran away (see ``divergence.*`` keys)."""
        return not np.isnan(self.diverged_at)

    # -- files ----------------------------------------------------------------------------
    def record(self) -> RunRecord:
        """The run record of this flight: scenario, seed, controller, and under ``trace`` the
        realisation and the trace thinning."""
        extra = {"realisation": self.realisation, "record_every": self.record_every}
        return RunRecord(self.scenario, self.seed, (self.controller,), False, "trace", extra)

    def metadata(self) -> dict[str, Any]:
        """What produced this flight (scenario, controller, seed, realisation, trace thinning,
        quadrs version), its metrics and divergence time, and the run identity over them."""
        return self.record().metadata(
            kind="flight",
            controller=self.controller,
            realisation=self.realisation,
            record_every=self.record_every,
            diverged_at=None if np.isnan(self.diverged_at) else float(self.diverged_at),
            status=self.status,
            metrics=self.metrics[list(METRIC_COLUMNS)].to_numpy().tolist(),
        )

    def to_parquet(self, path: str | Path) -> None:
        """Write the trace (indexed by ``t``, every trace column) with :meth:`metadata` in the
        file; written to a temporary file, then renamed, so never half-written. The spectra
        are not saved (see :class:`SpectraNotSaved`)."""
        from quadrs.io.parquet import write_frame

        write_frame(self.trace, path, _META_KEY, _json_safe(self.metadata()), index=True)

    @classmethod
    def read_parquet(cls, path: str | Path) -> Flight:
        """Read a file written by :meth:`to_parquet`, refusing one that is foreign, edited or
        from another quadrs version (:class:`quadrs.io.integrity.CorruptRunError`)."""
        from quadrs.io.parquet import read_frame

        def validate(meta: Any) -> None:
            if not isinstance(meta, dict) or meta.get("kind") != "flight":
                raise _fail(path, "it is not a quadrs flight trace (no flight metadata)")
            RunRecord.read(meta, path, "trace", _TRACE_META)
            if meta["trace"] != {k: meta[k] for k in ("realisation", "record_every")}:
                raise _fail(path, "its trace fields disagree with its run identity (edited?)")
            if meta["controllers"] != [meta["controller"]]:
                raise _fail(path, f"its controller {meta['controller']!r} disagrees with "
                                  f"{meta['controllers']!r}")  # fmt: skip

        frame, meta = read_frame(path, _META_KEY, validate=validate)
        scenario = RunRecord.read(meta, path, "trace", _TRACE_META).scenario
        ctrl = meta["controller"]
        if frame.index.name != "t" or list(frame.columns) != scenario.trace_columns:
            raise _fail(path, "its columns are not those of a quadrs trace")
        phases = scenario.phase_names
        values = np.asarray(meta["metrics"], dtype=np.float64)
        if values.shape != (len(phases), len(METRIC_COLUMNS)):
            raise _fail(path, f"its metrics have shape {values.shape}")
        diverged = meta.get("diverged_at")
        status = meta.get("status", "ok" if diverged is None else "non_finite")
        if status not in _core.EXIT_STATUSES or (status == "ok") != (diverged is None):
            raise _fail(path, f"its status {status!r} disagrees with its divergence time")
        trace = frame
        realisation = meta["realisation"]
        return cls(
            scenario=scenario,
            controller=ctrl,
            seed=meta["seed"],
            realisation=realisation,
            metrics=metrics_frame(phases, values),
            trace=trace,
            spectra=SpectraNotSaved(f"{ctrl} seed {meta['seed']} realisation {realisation}"),
            diverged_at=float("nan") if diverged is None else float(diverged),
            record_every=meta["record_every"],
            status=status,
        )

    def to_csv(self, path: str | Path) -> None:
        """Write the trace as plain CSV (header ``t,x,...``, values at 12 significant digits, so
        0.1 + 0.05 prints 0.15). CSV has no place for metadata: :meth:`to_parquet` keeps what
        produced the flight and checks it on reading."""
        from quadrs.io.files import atomic_write_frame

        atomic_write_frame(self.trace, path)


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
    the step starting at t = k * dt. The last row is not flown (no step follows it): the
    trace's closing row holds the last step's wind, like every other wind. For deterministic
    inputs, e.g. a sinusoid to measure a frequency response (docs/design-loop.md).
    """
    check_controller(controller)
    seed = check_int("seed", seed)
    realisation = check_int("realisation", realisation)
    scenario = scenario.realisation(seed, realisation)
    # Loud only if the scenario excites an unstable mode (the flight will diverge).
    warn_before_running(scenario, (controller,), gains=False, stacklevel=2)
    if record_every is None:
        record_every = default_record_every(scenario)
    record_every = check_int("record_every", record_every, 1, 2**63 - 1)
    prescribed = None
    if wind is not None:
        prescribed = np.ascontiguousarray(wind, dtype=np.float64)
        if prescribed.ndim != 2 or prescribed.shape[1] != 3:
            raise ValueError(f"wind must have shape (steps + 1, 3), got {prescribed.shape}")
    # The engine polls a cancel flag, so Ctrl-C stops even a long flight promptly.
    progress = _core.Progress()
    engine = scenario.engine
    out, _ = run_cancellable(
        lambda: engine.simulate(controller, seed, realisation, record_every, prescribed, progress),
        progress,
    )
    return flight_of(out, scenario, controller, (seed, realisation), record_every)


def default_record_every(scenario: Scenario) -> int:
    """Steps between a trace's rows by default: about one row a millisecond."""
    return max(1, round(1e-3 / float(scenario["integrator.dt"])))


def flight_of(
    out: _core.SimulateResult,
    scenario: Scenario,
    controller: str,
    gust: tuple[int, int],
    record_every: int,
) -> Flight:
    """The :class:`Flight` of the engine's result of one flight (``simulate``,
    ``simulate_innovations``) of ``scenario`` by ``controller``: the trace in the scenario's
    own layout (its payload and actuator models add or drop columns), per phase the metrics
    and the amplitude spectrum. ``gust``: the (seed, realisation) it flew."""
    raw = out["trace"]
    columns = out["trace_columns"]
    trace = pd.DataFrame(raw[:, 1:], index=pd.Index(raw[:, 0], name="t"), columns=columns)
    phases = scenario.phase_names
    freqs = scenario.spectrum_frequencies
    spectra = {
        name: pd.DataFrame({"frequency": f, "amplitude": a})
        for name, f, a in zip(phases, freqs, out["spectra"], strict=True)
    }
    return Flight(
        scenario=scenario,
        controller=controller,
        seed=gust[0],
        realisation=gust[1],
        metrics=metrics_frame(phases, out["metrics"]),
        trace=trace,
        spectra=spectra,
        diverged_at=float(out["diverged_at"]),
        record_every=record_every,
        status=out["status"],
        navigation=out["navigation"],
    )


def _json_safe(value: Any) -> Any:
    """NaN metrics (phases after a divergence) as JSON null; read back as NaN."""
    if isinstance(value, float) and not np.isfinite(value):
        return None
    if isinstance(value, list):
        return [_json_safe(v) for v in value]
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    return value
