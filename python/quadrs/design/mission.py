"""Will the parcel survive this route? Per phase of a Monte Carlo batch (a route's legs and
holds under ``phases = "legs"``, or any scenario's own phases) and for the whole flight: the
probability that the payload's peak acceleration exceeds a limit, the worst and a high
quantile of the swing and the cable tension, and the tracking errors, each with an interval.

Built on the batch's runs table with :mod:`quadrs.stats.risk` (exact Clopper-Pearson intervals for
probabilities, order-statistic intervals for quantiles) and :func:`quadrs.stats.summary.mean_ci`
(Student-t intervals for means). A realisation that diverged counts as exceeding every limit
and as +inf in quantiles and worst values, from the phase it diverged in on (as everywhere in
quadrs). Metric columns the results lack (an older engine, a model without them) are left
out, never shown as zeros.

The whole flight: the results' own ``flight`` phase when they have one; otherwise the worst
over the scenario's phases (``all phases``; only the per-flight extremes are shown there, and
it covers the flight only where the phases do).

The answer leads with whether the route was flown at all (:attr:`MissionReport.route`): a
flight is off its route in a phase if its tracking error (``max_tracking``, the 3-D distance
from the reference) or its cross-track error (``max_cross_track``) passed the user's limit, or
if it diverged; the time at the thrust limit (``saturated_time``) and near the law's tilt
limit (``near_tilt_time``: above 90 % of ``controller.tilt_limit``) are shown beside it.

A route that lowers its parcel (``trajectory.lower``) leads with the last metres
(:attr:`MissionReport.last_metres`): the probability that the parcel touches down faster than
``touchdown_limit`` (m/s), over the flights that touched down, with its interval; per phase in
which a parcel touched down or was lowered, the touchdown's speed, drift and miss, the release
and the vehicle's height change after it, and the swing while lowering.

Each per-phase interval is a 95 % interval on its own, not a joint one: the "any phase" line
(:attr:`MissionReport.joint`) is the fraction of flights that exceeded in at least one phase,
with its own interval. A count that is zero in every flight is shown as "0 of N flights,
P <= x %", x the upper end of the same two-sided 95 % Clopper-Pearson interval every other
count, figure and ``ci_high`` gives (docs/risk.md, "One interval convention"), not as an
interval "0 [0, 0]".
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass

import numpy as np
import pandas as pd

from quadrs.design.mission_tables import (
    ALL_PHASES,
    ANY_PHASE,
    DEGREES,
    DURATIONS,
    FLIGHT_PHASE,
    IN_FLIGHT,
    LOWS,
    PEAKS,
    TOUCHDOWN,
    TOUCHDOWN_LIMIT,
    TRACK_LIMIT,
    _joint,
    _last_metres_table,
    _mean_columns,
    _route_table,
    _tracking_metrics,
    _worst,
    contact_split,
    none_seen_bound,
)
from quadrs.design.mission_text import (
    _acceleration_text,
    _g,
    _interval,
    _joint_line,
    _last_metres_text,
    _limits_text,
    _payload_text,
    _pct,
    _route_text,
    _shown_limit,
    _shown_name,
    _tracking_text,
)
from quadrs.design.route_limits import LimitClash, route_clashes
from quadrs.present.terminal import fit_columns, terminal_text
from quadrs.runs.montecarlo_result import MonteCarloResult
from quadrs.stats.rates import one_sided_upper
from quadrs.stats.risk import exceedance_stats, quantile_interval
from quadrs.stats.summary import phase_diverged

#: What this module offers (its tables and text are made beside it, in mission_tables and
#: mission_text).
__all__ = [
    "ALL_PHASES",
    "ANY_PHASE",
    "DEGREES",
    "DURATIONS",
    "FLIGHT_PHASE",
    "LOWS",
    "PEAKS",
    "TOUCHDOWN_LIMIT",
    "TRACK_LIMIT",
    "MissionReport",
    "mission_report",
    "none_seen_bound",
    "one_sided_upper",
]


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
    #: Was the route flown? Per phase: ``n``, ``diverged``, ``off_route`` (tracking or
    #: cross-track past its limit, or diverged), ``probability``/``ci_low``/``ci_high`` (exact,
    #: two-sided) and ``p_max`` (its upper end, ``ci_high``: "P <= p_max" when none), the
    #: worst ``max_tracking`` and ``max_cross_track`` and the ``saturated_time`` mean and
    #: worst where the results have them.
    route: pd.DataFrame | None = None
    #: The joint rows (index ``acceleration`` and ``route``): the fraction of flights that
    #: exceeded (or left the route) in any of the scenario's phases, with its interval.
    joint: pd.DataFrame | None = None
    track_limit: float = TRACK_LIMIT
    cross_track_limit: float = TRACK_LIMIT
    #: Why diverged flights ended (status -> count), over the whole flight.
    statuses: tuple[tuple[str, int], ...] = ()
    #: Does the scenario fly a route (``trajectory.interpolation = "route"``)?
    routed: bool = True
    #: The parcel metric ``limit`` applies to (the ``acceleration`` table's).
    metric: str = "max_accel"
    #: The last metres, per phase with a touchdown or a lowering and the whole flight (None
    #: without them): ``n`` (flights), ``touchdowns``, ``diverged``, ``exceedances``,
    #: ``judged`` (touchdowns and diverged flights), ``probability``/``ci_low``/``ci_high`` of
    #: touchdown_speed > ``touchdown_limit`` among them (a diverged flight exceeds),
    #: ``speed_q``/``_q_low``/``_q_high`` (its ``quantile``), ``speed_worst``, ``drift_worst``,
    #: ``miss_worst``, ``miss_q``, ``released``, ``height_change_worst`` and
    #: ``lowering_swing_worst`` (rad).
    last_metres: pd.DataFrame | None = None
    touchdown_limit: float = TOUCHDOWN_LIMIT

    #: The legs whose reference asks as much as or more than a limit of the law (a velocity
    #: limit, the tilt limit, the rotors' thrust), known before flying
    #: (:func:`quadrs.design.route_limits.route_clashes`): why a route may not be flown.
    clashes: tuple[LimitClash, ...] = ()

    def last_metres_line(self) -> str:
        """The lead line: how often the parcel touches down faster than the limit."""
        t = self.last_metres
        if t is None:
            return ""
        r = t.loc[self.whole]
        n, k, judged = int(r["n"]), int(r["exceedances"]), int(r["judged"])
        touched, diverged = int(r["touchdowns"]), int(r["diverged"])
        level = f"{self.confidence:.0%}"
        off = self._off_route()
        if off == n:  # no flight reached its drop point on its route: nothing to judge there
            return (f"Last metres: not judged: the route was NOT FLOWN ({off} of {n} flights "
                    f"off it), so no parcel was lowered at its drop point ({touched} "
                    "touched the ground elsewhere)")  # fmt: skip
        if judged == 0:
            return (f"Last metres: no parcel touched down in {n} flights "
                    f"(touchdown_limit {self.touchdown_limit:g} m/s not judged)")  # fmt: skip
        if k == 0:
            said = f"0 of {judged}, p <= {_g(none_seen_bound(judged, self.confidence))}"
        else:
            said = (f"p = {_g(r['probability'])} [{_g(r['ci_low'])}, {_g(r['ci_high'])}] "
                    f"({level} interval), {k} of {judged}")  # fmt: skip
        what = f"{touched} touchdowns" + (f" and {diverged} diverged flights (too fast)"
                                          if diverged else "")  # fmt: skip
        missed = n - touched - diverged
        rest = f"; {missed} of {n} flights never touched down" if missed else ""
        strayed = f"; {off} of {n} flights were off their route" if off else ""
        return (f"Last metres: touchdown faster than {self.touchdown_limit:g} m/s: {said} "
                f"({what}){rest}{strayed}")  # fmt: skip

    def _off_route(self) -> int:
        """Flights off their route (or diverged) somewhere; 0 without tracking metrics."""
        return 0 if self.route is None else int(self.route.loc[self.whole, "off_route"])

    def parcel_line(self) -> str:
        """The parcel's answer with its touchdown apart (empty when no parcel touched down):
        in flight, and at the ground contact, whose peak is the contact law's."""
        from quadrs.present.labels import STANDARD_GRAVITY, in_g

        t = self.acceleration
        if TOUCHDOWN not in t.index:
            return ""

        def said(row: str) -> str:
            r = t.loc[row]
            k, n = int(r["exceedances"]), int(r["n"])
            worst = float(r["worst"]) / STANDARD_GRAVITY
            return f"{k} of {n} flights" + (f" (worst {_g(worst)} g)" if in_g(self.metric) else "")

        return (f"Parcel {self.metric} past {_shown_limit(self)}: in flight {said(IN_FLIGHT)}; "
                f"at touchdown {said(TOUCHDOWN)}, the ground contact's peak (the contact "
                "law's: ground.stiffness, ground.dissipation), not the flight's")  # fmt: skip

    @property
    def route_flown(self) -> bool:
        """True if no flight left its route or diverged, anywhere."""
        if self.route is None:
            return True
        return int(self.route.loc[self.whole, "off_route"]) == 0

    def verdict(self) -> str:
        """The first line of the answer: was the route flown, in how many flights."""
        if self.route is None:
            return "Route: the results have no tracking metrics (an older file): not judged"
        r = self.route.loc[self.whole]
        n, k = int(r["n"]), int(r["off_route"])
        limits = _limits_text(self.track_limit, self.cross_track_limit)
        kind = "" if self.routed else " (this scenario flies waypoints, not a route)"
        if k == 0:
            return (f"Route{kind}: flown in all {n} flights (tracking and cross-track within "
                    f"{limits}, none diverged): P(off route) <= {_pct(r['p_max'])} %")  # fmt: skip
        why = []
        strayed = k - int(r["diverged"])
        if strayed:
            worst = f"worst tracking {_g(r.get('max_tracking_worst', math.nan))} m"
            why.append(f"{strayed} strayed beyond {limits} ({worst})")
        if int(r["diverged"]):
            causes = ", ".join(f"{s} {c}" for s, c in self.statuses)
            why.append(f"{int(r['diverged'])} diverged" + (f" ({causes})" if causes else ""))
        if self.clashes:
            law = self.controller.upper()
            why.append(f"the route asks more than the {law} law allows: "
                       + "; ".join(str(c) for c in self.clashes))  # fmt: skip
        return (f"Route{kind}: NOT FLOWN in {k} of {n} flights, P(off route) = "
                f"{_interval(r['probability'], r['ci_low'], r['ci_high'], 100.0)} %: "
                + "; ".join(why))  # fmt: skip

    def __repr__(self) -> str:
        """One line: what was asked and the whole flight's answer."""
        p = self.acceleration.loc[self.whole]
        return (
            f"<MissionReport {self.controller.upper()}, {self.runs} realisations: "
            f"P({self.metric} > {_shown_limit(self)}) over {self.whole} "
            f"{100 * p['probability']:.3g} % "
            f"[{100 * p['ci_low']:.3g}, {100 * p['ci_high']:.3g}]>"
        )

    def _repr_html_(self) -> str:
        """In a notebook: the tables of :meth:`to_text` (swing in degrees), as HTML; the
        numbers themselves are the frames ``route``, ``acceleration``, ``payload`` and
        ``tracking`` (SI: swing in radians)."""
        from quadrs.present.html import render

        qp = f"q{100 * self.quantile:g}"
        tables = [] if self.route is None else [(self.verdict(), _route_text(self.route))]
        if self.last_metres is not None:
            tables.insert(0, (self.last_metres_line(), _last_metres_text(self.last_metres, qp)))
        tables.append((f"parcel {_shown_name(self.metric)}, P(> {_shown_limit(self)}) in %",
                       _acceleration_text(self.acceleration, qp, self.metric)))  # fmt: skip
        if len(self.payload.columns):
            tables.append(("swing (deg), tension (N), slack time (s)",
                           _payload_text(self.payload, qp)))  # fmt: skip
        if len(self.tracking.columns):
            tables.append(("tracking errors (m)", _tracking_text(self.tracking)))
        return render(repr(self), tables)

    def to_text(self, width: int = 100) -> str:
        """The tables for a terminal, each at most ``width`` columns wide (split into blocks
        of columns when needed)."""
        level = f"{self.confidence:.0%}"
        qp = f"q{100 * self.quantile:g}"
        head = (
            f"Parcel: {self.controller.upper()}, {self.runs} realisations; {level} intervals "
            "(probabilities exact, quantiles distribution-free, means Student t; an open bound "
            "shows as inf: too few runs to bound it); diverged flights count as exceeding"
        )

        def fill(text: str) -> str:
            return textwrap.fill(terminal_text(text), width) if text else ""

        limits = _limits_text(self.track_limit, self.cross_track_limit)
        parts = [fill(self.verdict()), ""]
        if self.parcel_line():
            parts = [fill(self.parcel_line()), "", *parts]
        if self.last_metres is not None:
            parts = [
                fill(self.last_metres_line()),
                fill("Touchdown speed (m/s) and its " + qp + ", drift (m/s), miss from the "
                     "drop point (m), flights released, the vehicle's height change after "
                     "the release (m) and the line's swing while lowering (deg), per phase"),
                fit_columns(_last_metres_text(self.last_metres, qp), width),
                "",
                *parts,
            ]  # fmt: skip
        if self.route is not None:
            parts += [
                fill(f"Route: off route = tracking or cross-track error past {limits}, or "
                     "diverged; P in %; time at the thrust limit and near the tilt limit in s"),
                fit_columns(_route_text(self.route), width),
                fill(_joint_line(self.joint, "route", "left the route")),
                "",
            ]  # fmt: skip
        parts += [
            fill(head),
            "",
            fill(
                f"Parcel {_shown_name(self.metric)}: P({self.metric} > {_shown_limit(self)}) "
                f"in % and its {qp}"
            ),
            fit_columns(_acceleration_text(self.acceleration, qp, self.metric), width),
            fill(
                f"'{IN_FLIGHT}': each flight's phases but the one its parcel touched down in; "
                f"'{TOUCHDOWN}': that phase, its peak the ground contact's"
                if TOUCHDOWN in self.acceleration.index
                else ""
            ),
            fill(
                _joint_line(
                    self.joint,
                    "acceleration",
                    f"exceeded {_shown_limit(self)}"
                    + (" (touchdowns included)" if TOUCHDOWN in self.acceleration.index else ""),
                )
            ),
        ]
        if not self.payload.empty and len(self.payload.columns):
            parts += ["", "Swing (deg) and tension (N); slack time in s", fit_columns(
                _payload_text(self.payload, qp), width)]  # fmt: skip
        if not self.tracking.empty and len(self.tracking.columns):
            parts += ["", "Tracking errors (m): mean [interval] and worst",
                      fit_columns(_tracking_text(self.tracking), width)]  # fmt: skip
        parts += [
            "",
            fill(
                f"Each row's interval is {level} for that phase alone, not joint over the phases; "
                f"the '{ANY_PHASE}' lines count a flight once if it exceeded in any phase. "
                f"'0 of N flights, P <= x %': none in N, x the upper end of the two-sided "
                f"{level} interval (as every interval here)."
            ),
        ]
        if self.whole == ALL_PHASES:
            note = (f"'{ALL_PHASES}': the worst over the phases (these results have no "
                    "whole-flight phase); blank where that is not defined")  # fmt: skip
            parts += ["", fill(note)]
        return "\n".join(parts)


def _parcel_row(name: str, x: np.ndarray, limit: float, quantile: float,
                confidence: float) -> dict[str, object]:  # fmt: skip
    """A row of the parcel's table: P(x > limit) with its interval, the worst and the
    ``quantile`` with its interval; a diverged flight (+inf) exceeds."""
    e = exceedance_stats(np.where(np.isinf(x), np.nan, x), limit, np.isinf(x), confidence)
    _, qv, qlo, qhi = quantile_interval(x, quantile, confidence)
    return {
        "phase": name,
        "n": e.n,
        "exceedances": e.k,
        "diverged": e.diverged,
        "probability": e.probability,
        "ci_low": e.ci_low,
        "ci_high": e.ci_high,
        "worst": _worst(x, "max"),
        "quantile": qv,
        "q_low": qlo,
        "q_high": qhi,
    }


def mission_report(
    mc: MonteCarloResult,
    limit: float,
    controller: str | None = None,
    quantile: float = 0.95,
    confidence: float = 0.95,
    track_limit: float = TRACK_LIMIT,
    cross_track_limit: float | None = None,
    metric: str = "max_accel",
    touchdown_limit: float = TOUCHDOWN_LIMIT,
) -> MissionReport:
    """The per-phase answer of :class:`MissionReport` for one controller of ``mc`` (default:
    its first). ``limit``: the payload acceleration limit (m/s^2); ``track_limit`` and
    ``cross_track_limit`` (m, default the tracking one): how far from its reference a flight
    may stray and still count as flying the route. ``metric``: the parcel's metric ``limit``
    applies to (default max_accel; any metric of the results, in its stored unit).
    ``touchdown_limit``: the touchdown speed (m/s) the last metres' lead line judges."""
    from quadrs.stats.risk import check_metric, check_threshold

    check_metric(metric)
    if metric not in mc.runs:
        raise ValueError(f"metric {metric!r}: these results have no such column")

    limit = check_threshold(limit)
    touchdown_limit = check_threshold(touchdown_limit)
    cross_track_limit = track_limit if cross_track_limit is None else cross_track_limit
    for name, v in (("track_limit", track_limit), ("cross_track_limit", cross_track_limit)):
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be finite and > 0 (m), got {v}")
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
            x[phase_diverged(sel)] = sign * np.inf
            return x
        cols = pd.DataFrame({p: pd.Series(values(metric, p, worst), index=wide[p].index)
                             for p in own})  # fmt: skip
        return (cols.max(axis=1) if worst == "max" else cols.min(axis=1)).to_numpy(float)

    present = set(runs.columns)
    acc_rows, pay_rows, trk_rows = [], [], []
    for phase in rows:
        acc_rows.append(_parcel_row(phase, values(metric, phase), limit, quantile, confidence))
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
    split = contact_split(own, values, present, metric)
    for name, x in (split or {}).items():  # the flights' touchdowns apart from their flight
        acc_rows.append(_parcel_row(name, x[~np.isnan(x)], limit, quantile, confidence))
    route = _route_table(rows, values, wide, runs, present, confidence, track_limit,
                         cross_track_limit)  # fmt: skip
    joint = _joint(own, values, present, limit, confidence, track_limit, cross_track_limit,
                   metric)  # fmt: skip
    whole_rows = runs[runs["phase"] == whole] if whole != ALL_PHASES else runs
    statuses: tuple[tuple[str, int], ...] = ()
    if "status" in runs:
        per = whole_rows.drop_duplicates("realisation")["status"].astype(str)
        counts = per[per != "ok"].value_counts()
        statuses = tuple((str(k), int(v)) for k, v in counts.items())
    routed = str(mc.scenario["trajectory.interpolation"]) == "route"
    last = _last_metres_table(rows, values, present, touchdown_limit, quantile, confidence)
    acceleration = pd.DataFrame(acc_rows).set_index("phase")
    payload = pd.DataFrame(pay_rows).set_index("phase")
    tracking = pd.DataFrame(trk_rows).set_index("phase")
    if whole == ALL_PHASES:  # a per-phase mean or duration has no whole-flight value here
        for frame in (payload, tracking):
            cols = [c for c in frame.columns if "_mean" in c or "_ci_" in c]
            frame.loc[ALL_PHASES, cols] = math.nan
    return MissionReport(ctrl, limit, float(quantile), float(confidence),
                         int(runs["realisation"].nunique()), whole, acceleration, payload,
                         tracking, route, joint, float(track_limit), float(cross_track_limit),
                         statuses, routed, metric, last, float(touchdown_limit),
                         tuple(route_clashes(mc.scenario, ctrl)))  # fmt: skip
