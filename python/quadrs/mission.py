"""Will the parcel survive this route? Per phase of a Monte Carlo batch (a route's legs and
holds under ``phases = "legs"``, or any scenario's own phases) and for the whole flight: the
probability that the payload's peak acceleration exceeds a limit, the worst and a high
quantile of the swing and the cable tension, and the tracking errors, each with an interval.

Built on the batch's runs table with :mod:`quadrs.risk` (exact Clopper-Pearson intervals for
probabilities, order-statistic intervals for quantiles) and :func:`quadrs.summary.mean_ci`
(Student-t intervals for means). A realisation that diverged counts as exceeding every limit
and as +inf in quantiles and worst values, from the phase it diverged in on (as everywhere in
quadrs). Metric columns the results lack (an older engine, a model without them) are left
out, never shown as zeros.

The whole flight: the results' own ``flight`` phase when they have one; otherwise the worst
over the scenario's phases (``all phases``; only the per-flight extremes are shown there, and
it covers the flight only where the phases do).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from quadrs.results import MonteCarloResult
from quadrs.risk import exceedance_stats, quantile_interval
from quadrs.summary import mean_ci, phase_diverged
from quadrs.terminal import terminal_text

__all__ = ["ALL_PHASES", "FLIGHT_PHASE", "MissionReport", "mission_report"]

#: The whole-flight phase of results that carry one.
FLIGHT_PHASE = "flight"
#: The row standing for the whole flight when the results have no FLIGHT_PHASE.
ALL_PHASES = "all phases"
#: Payload metrics whose worst realisation is its largest value (and a high quantile).
PEAKS = ("max_swing", "max_tension")
#: ... and whose worst is its smallest value.
LOWS = ("min_tension",)
#: Time spent in a bad state (s): the mean with its interval and the worst.
DURATIONS = ("slack_time", "saturated_time")
#: Shown in degrees: angles in the results are radians.
DEGREES = ("max_swing", "rms_swing")


def _tracking_metrics(columns: Sequence[str]) -> list[str]:
    """The tracking-error metrics the results have (3-D RMS, and any per-leg maximum or
    cross-track error the engine adds)."""
    return [c for c in columns if "tracking" in c or "cross_track" in c]


@dataclass(frozen=True)
class MissionReport:
    """The answer, per phase (rows, ``whole`` last): numeric tables.

    ``acceleration``: ``n``, ``exceedances``, ``diverged``, ``probability`` of max_accel >
    ``limit`` with ``ci_low``/``ci_high`` (exact), ``worst`` and the ``quantile``-quantile
    ``q`` with ``q_low``/``q_high``. ``payload``: per payload metric present, ``{m}_worst``
    and for peaks ``{m}_q`` (``_q_low``, ``_q_high``); for durations ``{m}_mean`` with
    ``{m}_ci_low``/``{m}_ci_high``. ``tracking``: per tracking metric ``{m}_mean`` with its
    interval and ``{m}_worst``. ``whole``: the row standing for the whole flight.
    """

    controller: str
    limit: float
    quantile: float
    confidence: float
    runs: int
    whole: str
    acceleration: pd.DataFrame
    payload: pd.DataFrame
    tracking: pd.DataFrame

    def __repr__(self) -> str:
        """One line: what was asked and the whole flight's answer."""
        p = self.acceleration.loc[self.whole]
        return (
            f"<MissionReport {self.controller.upper()}, {self.runs} realisations: P(max_accel > "
            f"{self.limit:g}) over {self.whole} {100 * p['probability']:.3g} % "
            f"[{100 * p['ci_low']:.3g}, {100 * p['ci_high']:.3g}]>"
        )

    def _repr_html_(self) -> str:
        """In a notebook: the three tables, as HTML."""
        from quadrs.display import render

        tables = [("payload acceleration", self.acceleration)]
        if len(self.payload.columns):
            tables.append(("swing (rad), tension (N), durations (s)", self.payload))
        if len(self.tracking.columns):
            tables.append(("tracking errors (m)", self.tracking))
        return render(repr(self), tables)

    def to_text(self, width: int = 100) -> str:
        """The tables for a terminal, each at most ``width`` columns wide (split into blocks
        of columns when needed)."""
        level = f"{self.confidence:.0%}"
        qp = f"q{100 * self.quantile:g}"
        head = (
            f"{self.controller.upper()}, {self.runs} realisations; {level} intervals "
            "(probabilities exact, quantiles distribution-free, means Student t; an open bound "
            "shows as inf: too few runs to bound it); diverged flights count as exceeding"
        )
        parts = [
            textwrap.fill(terminal_text(head), width),
            "",
            f"Payload acceleration (m/s^2): P(max_accel > {self.limit:g}) in % and its {qp}",
            _fit(_acceleration_text(self.acceleration, qp), width),
        ]
        if not self.payload.empty and len(self.payload.columns):
            parts += ["", "Swing (deg) and tension (N); durations in s", _fit(
                _payload_text(self.payload, qp), width)]  # fmt: skip
        if not self.tracking.empty and len(self.tracking.columns):
            parts += ["", "Tracking errors (m): mean [interval] and worst",
                      _fit(_tracking_text(self.tracking), width)]  # fmt: skip
        if self.whole == ALL_PHASES:
            note = (f"'{ALL_PHASES}': the worst over the phases (these results have no "
                    "whole-flight phase); blank where that is not defined")  # fmt: skip
            parts += ["", textwrap.fill(note, width)]
        return "\n".join(parts)


def mission_report(
    mc: MonteCarloResult,
    limit: float,
    controller: str | None = None,
    quantile: float = 0.95,
    confidence: float = 0.95,
) -> MissionReport:
    """The per-phase answer of :class:`MissionReport` for one controller of ``mc`` (default:
    its first). ``limit``: the payload acceleration limit (m/s^2)."""
    from quadrs.risk import check_threshold

    limit = check_threshold(limit)
    if not 0 < quantile < 1:
        raise ValueError(f"quantile must be in (0, 1), got {quantile}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    ctrl = controller or mc.controllers[0]
    if ctrl not in mc.controllers:
        raise ValueError(f"controller must be one of {mc.controllers}, got {ctrl!r}")
    runs = mc.runs[mc.runs["controller"] == ctrl]
    names = list(mc.scenario.phase_names)
    if FLIGHT_PHASE not in names and (runs["phase"] == FLIGHT_PHASE).any():
        names.append(FLIGHT_PHASE)  # results that carry the whole flight without naming it
    phases = [p for p in names if (runs["phase"] == p).any()]
    whole = FLIGHT_PHASE if FLIGHT_PHASE in phases else ALL_PHASES
    own = [p for p in phases if p != FLIGHT_PHASE]
    rows = [*own, whole]
    wide = {p: runs[runs["phase"] == p].set_index("realisation").sort_index() for p in phases}

    def values(metric: str, phase: str, worst: str = "max") -> np.ndarray:
        """Per realisation, diverged as +inf (-inf for a low); the worst over the phases for
        ALL_PHASES (NaN if undefined there)."""
        sign = 1.0 if worst == "max" else -1.0
        if phase != ALL_PHASES:
            sel = wide[phase]
            x = sel[metric].to_numpy(float).copy()
            x[phase_diverged(sel.reset_index())] = sign * np.inf
            return x
        cols = pd.DataFrame({p: pd.Series(values(metric, p, worst), index=wide[p].index)
                             for p in own})  # fmt: skip
        return (cols.max(axis=1) if worst == "max" else cols.min(axis=1)).to_numpy(float)

    present = set(runs.columns)
    acc_rows, pay_rows, trk_rows = [], [], []
    for phase in rows:
        x = values("max_accel", phase)
        e = exceedance_stats(np.where(np.isinf(x), np.nan, x), limit, np.isinf(x), confidence)
        _, qv, qlo, qhi = quantile_interval(x, quantile, confidence)
        acc_rows.append({"phase": phase, "n": e.n, "exceedances": e.k, "diverged": e.diverged,
                         "probability": e.probability, "ci_low": e.ci_low,
                         "ci_high": e.ci_high, "worst": _worst(x, "max"), "quantile": qv,
                         "q_low": qlo, "q_high": qhi})  # fmt: skip
        pay: dict[str, object] = {"phase": phase}
        for m in [m for m in PEAKS if m in present]:
            x = values(m, phase)
            _, qv, qlo, qhi = quantile_interval(x, quantile, confidence)
            pay.update({f"{m}_worst": _worst(x, "max"), f"{m}_q": qv, f"{m}_q_low": qlo,
                        f"{m}_q_high": qhi})  # fmt: skip
        for m in [m for m in LOWS if m in present]:
            pay[f"{m}_worst"] = _worst(values(m, phase, "min"), "min")
        for m in [m for m in DURATIONS if m in present]:
            pay.update(_mean_columns(m, phase, wide, confidence))
        pay_rows.append(pay)
        trk: dict[str, object] = {"phase": phase}
        for m in _tracking_metrics(list(runs.columns)):
            trk.update(_mean_columns(m, phase, wide, confidence))
            trk[f"{m}_worst"] = _worst(values(m, phase), "max") if phase != ALL_PHASES or (
                m.startswith("max_")) else math.nan  # fmt: skip
        trk_rows.append(trk)
    acceleration = pd.DataFrame(acc_rows).set_index("phase")
    payload = pd.DataFrame(pay_rows).set_index("phase")
    tracking = pd.DataFrame(trk_rows).set_index("phase")
    if whole == ALL_PHASES:  # a per-phase mean or duration has no whole-flight value here
        for frame in (payload, tracking):
            cols = [c for c in frame.columns if "_mean" in c or "_ci_" in c]
            frame.loc[ALL_PHASES, cols] = math.nan
    return MissionReport(ctrl, limit, float(quantile), float(confidence),
                         int(runs["realisation"].nunique()), whole, acceleration, payload,
                         tracking)  # fmt: skip


def _worst(x: np.ndarray, worst: str) -> float:
    x = x[~np.isnan(x)]
    if not x.size:
        return math.nan
    return float(x.max() if worst == "max" else x.min())


def _mean_columns(
    metric: str, phase: str, wide: dict[str, pd.DataFrame], confidence: float
) -> dict[str, float]:
    if phase == ALL_PHASES:
        return {f"{metric}_mean": math.nan, f"{metric}_ci_low": math.nan,
                f"{metric}_ci_high": math.nan}  # fmt: skip
    sel = wide[phase]
    x = sel[metric].to_numpy(float)
    x = x[~phase_diverged(sel.reset_index())]
    _, mean, lo, hi = mean_ci(x, confidence)
    return {f"{metric}_mean": mean, f"{metric}_ci_low": lo, f"{metric}_ci_high": hi}


# -- text ---------------------------------------------------------------------------------------
def _g(v: float, digits: int = 3) -> str:
    if isinstance(v, float) and math.isnan(v):
        return ""
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return f"{v:.{digits}g}"


def _interval(v: float, lo: float, hi: float, scale: float = 1.0, digits: int = 3) -> str:
    if math.isnan(v):
        return ""
    return f"{_g(scale * v, digits)} [{_g(scale * lo, digits)}, {_g(scale * hi, digits)}]"


def _acceleration_text(t: pd.DataFrame, qp: str) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "runs": t["n"].astype(int),
            "diverged": t["diverged"].astype(int),
            "exceed": t["exceedances"].astype(int),
            "P exceed %": [
                _interval(r.probability, r.ci_low, r.ci_high, 100.0) for r in t.itertuples()
            ],
            qp: [_interval(r.quantile, r.q_low, r.q_high) for r in t.itertuples()],
            "worst": [_g(v) for v in t["worst"]],
        },
        index=t.index,
    )


def _payload_text(t: pd.DataFrame, qp: str) -> pd.DataFrame:
    out = pd.DataFrame(index=t.index)
    for m in PEAKS:
        if f"{m}_worst" not in t:
            continue
        scale = 180 / math.pi if m in DEGREES else 1.0
        name = m.removeprefix("max_")
        out[f"{name} {qp}"] = [
            _interval(a, b, c, scale)
            for a, b, c in zip(t[f"{m}_q"], t[f"{m}_q_low"], t[f"{m}_q_high"], strict=True)
        ]
        out[f"{name} worst"] = [_g(scale * v) for v in t[f"{m}_worst"]]
    for m in LOWS:
        if f"{m}_worst" in t:
            out["tension lowest"] = [_g(v) for v in t[f"{m}_worst"]]
    for m in DURATIONS:
        if f"{m}_mean" in t:
            out[f"{m} mean"] = [
                _interval(a, b, c)
                for a, b, c in zip(t[f"{m}_mean"], t[f"{m}_ci_low"], t[f"{m}_ci_high"], strict=True)
            ]
    return out


def _tracking_text(t: pd.DataFrame) -> pd.DataFrame:
    out = pd.DataFrame(index=t.index)
    for col in [c for c in t.columns if c.endswith("_mean")]:
        m = col.removesuffix("_mean")
        out[f"{m} mean"] = [
            _interval(a, b, c)
            for a, b, c in zip(t[f"{m}_mean"], t[f"{m}_ci_low"], t[f"{m}_ci_high"], strict=True)
        ]
        out[f"{m} worst"] = [_g(v) for v in t[f"{m}_worst"]]
    return out


def _fit(frame: pd.DataFrame, width: int) -> str:
    """``frame`` as text in blocks of columns, each at most ``width`` wide (the index repeated
    in each; a single column wider than ``width`` gets a block of its own)."""

    def render(cols: list[str]) -> str:
        return terminal_text(frame[cols].to_string())

    blocks: list[str] = []
    current: list[str] = []
    for col in frame.columns:
        trial = [*current, col]
        if current and max(len(line) for line in render(trial).splitlines()) > width:
            blocks.append(render(current))
            current = [col]
        else:
            current = trial
    if current or not blocks:
        blocks.append(render(current) if current else terminal_text(frame.to_string()))
    return "\n\n".join(blocks)
