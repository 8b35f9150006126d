"""The numbers of a mission's answer (:func:`quadrs.design.mission.mission_report`), phase by
phase: whether the route was flown, the last metres, the joint "any phase" rows, the worst
values and the means with their intervals, and the bound of a count that is zero; with the
names of the rows and the groups of metrics the answer shows."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from quadrs.present.labels import DEGREE_METRICS
from quadrs.stats.risk import exceedance_stats, quantile_interval
from quadrs.stats.summary import mean_ci, phase_diverged

#: The whole-flight phase of results that carry one.
FLIGHT_PHASE = "flight"
#: The row standing for the whole flight when the results have no FLIGHT_PHASE.
ALL_PHASES = "all phases"
#: The joint row: a flight counted once if it exceeded in any of the scenario's phases.
ANY_PHASE = "any phase"
#: Default tracking (and cross-track) limit of the route, m.
TRACK_LIMIT = 10.0
#: Payload metrics whose worst realisation is its largest value (and a high quantile).
PEAKS = ("max_swing", "max_tension")
#: ... and whose worst is its smallest value.
LOWS = ("min_tension",)
#: Time spent in a bad state (s): the mean with its interval and the worst.
DURATIONS = ("slack_time", "saturated_time")
#: Shown in degrees: angles in the results are radians (the one list, from the engine's units).
DEGREES = DEGREE_METRICS
#: m/s, the default touchdown speed a parcel is rated for (the lead line's limit).
TOUCHDOWN_LIMIT = 1.0
#: The parcel table's rows that part a flight with a touchdown: its phases but the one its
#: parcel touched down in, and that phase, whose peak is the ground contact's.
IN_FLIGHT = "in flight"
TOUCHDOWN = "touchdown"


def _tracking_metrics(columns: Sequence[str]) -> list[str]:
    """The tracking-error metrics the results have (3-D RMS, and any per-leg maximum or
    cross-track error the engine adds)."""
    return [c for c in columns if "tracking" in c or "cross_track" in c]


def _last_metres_table(
    rows: list[str], values: Any, present: set[str], limit: float, quantile: float,
    confidence: float,
) -> pd.DataFrame | None:  # fmt: skip
    """The last metres per phase with a touchdown or a lowering, and the whole flight (see
    :attr:`MissionReport.last_metres`); None if the results have no touchdown metrics or no
    flight lowered or touched down."""
    need = {"touchdown_speed", "touchdown_drift", "touchdown_miss", "release_time",
            "release_height_change", "lowering_swing"}  # fmt: skip
    if not need <= present:
        return None
    out = []
    for i, phase in enumerate(rows):
        speed = values("touchdown_speed", phase)
        swing = values("lowering_swing", phase)
        whole = i == len(rows) - 1
        if not whole and np.isnan(speed).all() and not (np.nan_to_num(swing) > 0).any():
            continue
        div = np.isinf(speed)
        touched = np.isfinite(speed)
        e = exceedance_stats(np.where(div, np.nan, speed), limit, div, confidence)
        _, qv, qlo, qhi = quantile_interval(speed[touched], quantile, confidence)
        miss = values("touchdown_miss", phase)
        _, mq, _, _ = quantile_interval(miss[np.isfinite(miss)], quantile, confidence)
        released = values("release_time", phase)
        out.append({
            "phase": phase, "n": len(speed), "touchdowns": int(touched.sum()),
            "diverged": int(div.sum()), "judged": e.n, "exceedances": e.k,
            "probability": e.probability, "ci_low": e.ci_low, "ci_high": e.ci_high,
            "speed_q": qv, "speed_q_low": qlo, "speed_q_high": qhi,
            "speed_worst": _worst(speed[touched], "max"),
            "drift_worst": _worst(values("touchdown_drift", phase), "max"),
            "miss_q": mq, "miss_worst": _worst(miss, "max"),
            "released": int(np.isfinite(released).sum()),
            "height_change_worst": _worst(values("release_height_change", phase), "max"),
            "lowering_swing_worst": _worst(swing, "max"),
        })  # fmt: skip
    table = pd.DataFrame(out).set_index("phase")
    if int(table["touchdowns"].sum()) == 0 and len(table) == 1:
        return None
    return table


def contact_split(
    own: list[str], values: Any, present: set[str], metric: str
) -> dict[str, np.ndarray] | None:  # fmt: skip
    """Per flight, the parcel ``metric``'s worst in flight (over its phases but those its
    parcel was on the ground in: the contact's peak is the ground's, not the flight's) and
    over the phases of its ground contacts (NaN for a flight that never touched down; +inf
    for a diverged one, as everywhere). A phase is in contact where its parcel touched down
    in it (``touchdown_speed``, the flight's first contact) or met the ground in it
    (``touchdown_peak_force``: a parcel that bumped the pad at the lift touches down again at
    the drop point, and that contact is not the flight's). None when no flight touched down
    (or the results lack the column)."""
    if "touchdown_speed" not in present or not own:
        return None

    def in_contact(p: str) -> np.ndarray:
        hit = np.isfinite(values("touchdown_speed", p))
        if "touchdown_peak_force" in present:
            hit |= np.isfinite(values("touchdown_peak_force", p))
        return hit

    touched = {p: in_contact(p) for p in own}
    if not any(t.any() for t in touched.values()):
        return None
    per_phase = {p: values(metric, p) for p in own}
    n = len(next(iter(per_phase.values())))
    flight = np.full(n, np.nan)
    contact = np.full(n, np.nan)
    for p in own:
        x = per_phase[p]
        contact = np.fmax(contact, np.where(touched[p], x, np.nan))
        flight = np.fmax(flight, np.where(touched[p], np.nan, x))
    diverged = np.isinf(flight) | np.array([np.isinf(per_phase[p]) for p in own]).any(axis=0)
    contact = np.where(diverged & np.isnan(contact), np.inf, contact)
    return {IN_FLIGHT: np.where(diverged, np.inf, flight), TOUCHDOWN: contact}


def none_seen_bound(n: int, confidence: float = 0.95) -> float:
    """What "0 of N flights, P <= x" prints: the upper end of the two-sided exact
    (Clopper-Pearson) ``confidence`` interval with no event in ``n``, ``1 - ((1 -
    confidence) / 2)**(1/n)``: the ``ci_high`` of the same count, and the figures' error bar
    (one convention everywhere, docs/risk.md)."""
    if n <= 0:
        return math.nan
    return float(1.0 - ((1.0 - confidence) / 2.0) ** (1.0 / n))


def _off_route(
    values: Any, phase: str, present: set[str], track_limit: float, cross_limit: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per realisation: (off the route in ``phase``, defined); diverged counts as off."""
    off: np.ndarray | None = None
    for metric, lim in (("max_tracking", track_limit), ("max_cross_track", cross_limit)):
        if metric not in present:
            continue
        x = values(metric, phase)
        hit = np.where(np.isnan(x), False, x > lim)
        off = hit if off is None else off | hit
    assert off is not None
    return off, np.ones(off.shape, bool)


def _route_table(
    rows: list[str], values: Any, wide: dict[str, pd.DataFrame], runs: pd.DataFrame,
    present: set[str], confidence: float, track_limit: float, cross_limit: float,
) -> pd.DataFrame | None:  # fmt: skip
    """Per row: was the route flown (see :attr:`MissionReport.route`); None if the results
    have no tracking maxima (older files)."""
    from quadrs.stats.risk import exceedance_interval

    if not {"max_tracking", "max_cross_track"} & present:
        return None
    out = []
    for phase in rows:
        off, _ = _off_route(values, phase, present, track_limit, cross_limit)
        ref = values("max_tracking" if "max_tracking" in present else "max_cross_track", phase)
        diverged = int(np.isinf(ref).sum())
        n, k = len(off), int(off.sum())
        p, lo, hi = exceedance_interval(k, n, confidence)
        row: dict[str, Any] = {"phase": phase, "n": n, "diverged": diverged, "off_route": k,
                               "probability": p, "ci_low": lo, "ci_high": hi,
                               "p_max": hi}  # fmt: skip
        for m in ("max_tracking", "max_cross_track"):
            if m in present:
                row[f"{m}_worst"] = _worst(values(m, phase), "max")
        if "saturated_time" in present:
            row.update(_mean_columns("saturated_time", phase, wide, confidence))
            if phase != ALL_PHASES:
                sel = wide[phase]
                x = sel["saturated_time"].to_numpy(float)[~phase_diverged(sel)]
                row["saturated_time_worst"] = _worst(x, "max")
                row["saturated_time_flights"] = int((x > 0).sum())
                row["saturated_time_n"] = int(x.size)
        if "near_tilt_time" in present:
            x = values("near_tilt_time", phase)
            row["near_tilt_time_worst"] = _worst(x, "max")
            if phase != ALL_PHASES:
                row.update(_mean_columns("near_tilt_time", phase, wide, confidence))
        out.append(row)
    return pd.DataFrame(out).set_index("phase")


def _joint(
    own: list[str], values: Any, present: set[str], limit: float, confidence: float,
    track_limit: float, cross_limit: float, metric: str = "max_accel",
) -> pd.DataFrame:  # fmt: skip
    """Flights that exceeded the acceleration limit (or left the route) in any of ``own``.
    A flight whose metric has no value in any phase (an event metric such as
    ``touchdown_speed`` where the event never happened) is not judged: it is not among the
    ``n`` flights but counted in ``flights``."""
    from quadrs.stats.risk import exceedance_interval

    rows = []
    acc = np.zeros(0, bool)
    valued = np.zeros(0, bool)
    off = np.zeros(0, bool)
    for i, phase in enumerate(own):
        x = values(metric, phase)
        hit = np.isinf(x) | np.where(np.isnan(x), False, x > limit)
        acc = hit if i == 0 else acc | hit
        valued = ~np.isnan(x) if i == 0 else valued | ~np.isnan(x)
        if {"max_tracking", "max_cross_track"} & present:
            o, _ = _off_route(values, phase, present, track_limit, cross_limit)
            off = o if i == 0 else off | o
    for name, hit, judged in (("acceleration", acc, valued), ("route", off, None)):
        if not hit.size:
            continue
        n = len(hit) if judged is None else int(judged.sum())
        k = int(hit.sum())
        p, lo, hi = exceedance_interval(k, n, confidence) if n else (math.nan,) * 3
        rows.append({"table": name, "n": n, "count": k, "probability": p, "ci_low": lo,
                     "ci_high": hi, "p_max": hi, "flights": len(hit)})  # fmt: skip
    columns = ["table", "n", "count", "probability", "ci_low", "ci_high", "p_max", "flights"]
    return pd.DataFrame(rows, columns=columns).set_index("table")


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
    x = x[~phase_diverged(sel)]
    _, mean, lo, hi = mean_ci(x, confidence)
    if metric.endswith("_time"):  # a time spent is never negative: nor is its lower bound
        lo = max(lo, 0.0)
    out = {f"{metric}_mean": mean, f"{metric}_ci_low": lo, f"{metric}_ci_high": hi}
    if metric in DURATIONS:  # how many flights spent any time there (0: "0 of N flights")
        out |= {f"{metric}_flights": float((x > 0).sum()), f"{metric}_n": float(x.size)}
    return out
