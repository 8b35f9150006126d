"""The paper's question on the real vehicle: several control laws flown through the same gust
realisations, compared leg by leg (``quadrs mission --controller pd,smc``; docs/delivery.md).

Each law's own answer is :func:`quadrs.design.mission.mission_report`'s. The comparison adds what
pairing buys, as the paper's Table 3 does for IAE: per phase, each law's mean of the parcel
metric and of the worst tracking error as 100 x its mean over the first law's, with the paired
delta-method interval (:func:`quadrs.stats.summary.ratio_ci`), and the difference of the exceedance
probabilities with Newcombe's paired interval (:func:`quadrs.stats.risk.paired_exceedance`).
"""

from __future__ import annotations

import math
import textwrap
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pandas as pd

from quadrs.design.mission import MissionReport, mission_report, none_seen_bound
from quadrs.design.mission_tables import FLIGHT_PHASE, IN_FLIGHT, TOUCHDOWN, contact_split
from quadrs.design.mission_text import _shown_limit, _shown_name
from quadrs.present.terminal import fit_columns, terminal_text
from quadrs.runs.montecarlo_result import MonteCarloResult
from quadrs.stats.risk import exceeds, paired_exceedance
from quadrs.stats.summary import phase_diverged, ratio_ci

__all__ = ["LawComparison", "compare_laws"]

#: The tracking metric compared: the worst 3-D distance from the reference in the phase.
TRACKING = "max_tracking"


@dataclass(frozen=True)
class LawComparison:
    """Laws flown on the same realisations. ``reports``: each law's :class:`MissionReport`.
    ``paired``: per phase (index level 0) and law other than the first (level 1):
    ``n_pairs``; ``ratio``/``ratio_low``/``ratio_high`` = 100 mean(law)/mean(first) of the
    parcel metric over the pairs both flew without diverging; ``track_ratio`` (and its
    interval) likewise for ``max_tracking``; ``p_difference``/``p_low``/``p_high``, P(law
    exceeds) - P(first exceeds) over every pair (a diverged flight exceeds), and
    ``mcnemar_p``."""

    controllers: tuple[str, ...]
    metric: str
    limit: float
    confidence: float
    reports: dict[str, MissionReport]
    paired: pd.DataFrame
    #: Per phase (rows) and law: the mean of the parcel metric and of ``max_tracking`` over
    #: the flights that did not diverge (columns ``(law, "metric")``, ``(law, "tracking")``).
    means: pd.DataFrame

    @property
    def reference(self) -> str:
        return self.controllers[0]

    def to_text(self, width: int = 100) -> str:
        """The comparison for a terminal: each law's verdict, then per phase the parcel's
        risk and the tracking by law, then the paired ratios against the first law."""
        first = self.reports[self.reference]

        def fill(text: str) -> str:
            return textwrap.fill(terminal_text(text), width)

        level = f"{100 * self.confidence:g} %"
        laws = ", ".join(c.upper() for c in self.controllers)
        limit = _shown_limit(first)
        parts = [
            fill(f"{laws} on the same {first.runs} gust realisations (paired): the route, the "
                 f"parcel's {self.metric} and the tracking, per phase."),
            "",
            *[fill(f"{c.upper()}: {self.reports[c].verdict()}") for c in self.controllers],
            *[fill(f"{c.upper()}: {self.reports[c].parcel_line()}") for c in self.controllers
              if self.reports[c].parcel_line()],
            "",
            fill(f"P({self.metric} > {limit}) in % with its exact {level} interval; a diverged "
                 "flight exceeds"),
            fit_columns(self._by_law(lambda r, p: _risk(r, p)), width),
            "",
            fill(f"Mean {_shown_name(self.metric)} and mean worst tracking error (m) by law, over "
                 "the flights that did not diverge"),
            fit_columns(self._means_text(), width),
        ]  # fmt: skip
        if len(self.controllers) > 1:
            parts += [
                "",
                fill(f"Paired against {self.reference.upper()} (the same gusts): 100 x mean / "
                     f"{self.reference.upper()}'s for {self.metric} and for the tracking, and the "
                     f"difference of P(exceed) in points, each with its {level} interval"),
                fit_columns(self._paired_text(), width),
            ]  # fmt: skip
        parts += [
            "",
            fill(f"Each interval is {level} for its phase and law alone, not joint. Below 100 a "
                 f"law has the smaller mean; an interval that excludes 100 (or 0 for P) is a "
                 "difference the gusts cannot explain."),
        ]  # fmt: skip
        return "\n".join(parts)

    def _by_law(self, cell: object) -> pd.DataFrame:
        first = self.reports[self.reference]
        out = pd.DataFrame(index=first.acceleration.index)
        for c in self.controllers:
            r = self.reports[c]
            out[c] = [cell(r, p) for p in out.index]  # type: ignore[operator]
        return out

    def _means_text(self) -> pd.DataFrame:
        from quadrs.present.labels import display_scale

        scale = display_scale(self.metric)
        out = pd.DataFrame(index=self.means.index)
        for c in self.controllers:
            out[f"{c} {_short(self.metric)}"] = [_g(scale * v) for v in self.means[(c, "metric")]]
            out[f"{c} track"] = [_g(v) for v in self.means[(c, "tracking")]]
        return out

    def _paired_text(self) -> pd.DataFrame:
        rows: dict[str, dict[str, str]] = {}
        for (phase, law), r in self.paired.iterrows():
            rows.setdefault(phase, {})
            rows[phase][f"{law} {_short(self.metric)} %"] = _ci(
                r["ratio"], r["ratio_low"], r["ratio_high"]
            )
            rows[phase][f"{law} track %"] = _ci(
                r["track_ratio"], r["track_ratio_low"], r["track_ratio_high"]
            )
            rows[phase][f"{law} dP"] = _ci(
                100 * r["p_difference"], 100 * r["p_low"], 100 * r["p_high"]
            )
        return pd.DataFrame.from_dict(rows, orient="index").rename_axis("phase")

    def __repr__(self) -> str:
        runs = self.reports[self.reference].runs
        laws = ", ".join(self.controllers)
        limit = _shown_limit(self.reports[self.reference])
        return f"<LawComparison {laws} on {runs} realisations, {self.metric} > {limit}>"


def compare_laws(
    mc: MonteCarloResult,
    limit: float,
    controllers: Sequence[str] | None = None,
    metric: str = "max_accel",
    quantile: float = 0.95,
    confidence: float = 0.95,
    track_limit: float | None = None,
    cross_track_limit: float | None = None,
) -> LawComparison:
    """Compare ``controllers`` (default: every law of ``mc``, the first as reference) flown on
    the same realisations: each law's :func:`mission_report` and the paired table of
    :class:`LawComparison`. ``limit`` applies to ``metric`` (its stored unit)."""
    laws = tuple(controllers or mc.controllers)
    missing = [c for c in laws if c not in mc.controllers]
    if missing or not laws:
        raise ValueError(f"controllers must be among {mc.controllers}, got {list(laws)}")
    if len(set(laws)) != len(laws):
        raise ValueError(f"controllers must differ, got {list(laws)}")
    extra = {} if track_limit is None else {"track_limit": track_limit}
    if cross_track_limit is not None:
        extra["cross_track_limit"] = cross_track_limit
    reports = {c: mission_report(mc, limit, c, quantile, confidence, metric=metric, **extra)
               for c in laws}  # fmt: skip
    ref = laws[0]
    phases = list(reports[ref].acceleration.index)
    per = {(c, p): _per_realisation(mc, c, p, metric, limit) for c in laws for p in phases}
    means = pd.DataFrame(
        {(c, k): [float(np.nanmean(per[c, p][col])) if per[c, p][col].notna().any() else math.nan
                  for p in phases]
         for c in laws for k, col in (("metric", "value"), ("tracking", "track"))},
        index=pd.Index(phases, name="phase"),
    )  # fmt: skip
    rows = []
    for phase in phases:
        base = per[ref, phase]
        for law in laws[1:]:
            other = per[law, phase]
            both = base.index.intersection(other.index)
            a, b = other.loc[both], base.loc[both]
            ratio = ratio_ci(a["value"].to_numpy(float), b["value"].to_numpy(float), confidence)
            track = ratio_ci(a["track"].to_numpy(float), b["track"].to_numpy(float), confidence)
            pe = paired_exceedance(a["hit"].to_numpy(bool), b["hit"].to_numpy(bool), confidence)
            rows.append({"phase": phase, "controller": law, "n_pairs": len(both),
                         "ratio": ratio[0], "ratio_low": ratio[1], "ratio_high": ratio[2],
                         "track_ratio": track[0], "track_ratio_low": track[1],
                         "track_ratio_high": track[2], "p_difference": pe.difference,
                         "p_low": pe.ci_low, "p_high": pe.ci_high,
                         "mcnemar_p": pe.mcnemar_p})  # fmt: skip
    columns = ["phase", "controller", "n_pairs", "ratio", "ratio_low", "ratio_high",
               "track_ratio", "track_ratio_low", "track_ratio_high", "p_difference", "p_low",
               "p_high", "mcnemar_p"]  # fmt: skip
    paired = pd.DataFrame(rows, columns=columns).set_index(["phase", "controller"])
    return LawComparison(laws, metric, float(limit), float(confidence), reports, paired, means)


def _per_realisation(
    mc: MonteCarloResult, law: str, phase: str, metric: str, limit: float
) -> pd.DataFrame:
    """Per realisation of ``law`` in ``phase`` (the worst over the phases for 'all phases'):
    the metric and the tracking (NaN where the flight diverged) and whether it exceeded."""
    runs = mc.runs[mc.runs["controller"] == law]
    if phase in (IN_FLIGHT, TOUCHDOWN):
        value, diverged, index = _contact_part(runs, phase, metric)
        track = np.full(len(index), np.nan)
    elif phase in set(runs["phase"]):
        sel = runs[runs["phase"] == phase].set_index("realisation").sort_index()
        diverged = phase_diverged(sel)
        value = sel[metric].to_numpy(float)
        track = sel[TRACKING].to_numpy(float) if TRACKING in sel else np.full(len(sel), np.nan)
        index = sel.index
    else:  # the worst over the scenario's phases
        wide = runs.pivot_table(index="realisation", columns="phase", values=metric,
                                aggfunc="max")  # fmt: skip
        value = wide.max(axis=1).to_numpy(float)
        index = wide.index
        div = runs.assign(d=phase_diverged(runs)).groupby("realisation")["d"].any()
        diverged = div.loc[index].to_numpy(bool)
        track = np.full(len(index), np.nan)
        if TRACKING in runs:
            t = runs.pivot_table(index="realisation", columns="phase", values=TRACKING,
                                 aggfunc="max")  # fmt: skip
            track = t.max(axis=1).loc[index].to_numpy(float)
    hit, _ = exceeds(np.where(diverged, np.nan, value), limit, diverged)
    value = np.where(diverged, np.nan, value)
    track = np.where(diverged, np.nan, track)
    return pd.DataFrame({"value": value, "track": track, "hit": hit}, index=index)


def _contact_part(
    runs: pd.DataFrame, part: str, metric: str
) -> tuple[np.ndarray, np.ndarray, pd.Index]:  # fmt: skip
    """Per realisation, the parcel ``metric`` in flight or at its touchdowns (``part``: the
    mission's rows, :func:`quadrs.design.mission_tables.contact_split`), whether the flight
    diverged, and the realisations."""
    own = [p for p in dict.fromkeys(runs["phase"]) if p != FLIGHT_PHASE]
    by_phase = runs.assign(diverged_=phase_diverged(runs)).set_index(["realisation", "phase"])
    present = {metric, "touchdown_speed", "touchdown_peak_force"} & set(runs.columns)
    table = {m: by_phase[m].unstack("phase").sort_index() for m in present}
    diverged = by_phase["diverged_"].unstack("phase").sort_index()

    def values(m: str, p: str) -> np.ndarray:
        x = table[m][p].to_numpy(float)
        return np.where(diverged[p].to_numpy(bool), np.inf, x) if m == metric else x

    index = table[metric].index
    split = contact_split(own, values, present, metric)
    x = split[part] if split is not None else np.full(len(index), np.nan)
    return x, np.isinf(x), index


def _risk(r: MissionReport, phase: str) -> str:
    if phase not in r.acceleration.index:  # "touchdown" for a law none of whose parcels landed
        return ""
    a = r.acceleration.loc[phase]
    n, k = int(a["n"]), int(a["exceedances"])
    if k == 0:
        return f"0 of {n}, P <= {_g(100 * none_seen_bound(n))}"
    return _ci(100 * a["probability"], 100 * a["ci_low"], 100 * a["ci_high"])


def _short(metric: str) -> str:
    """``accel`` for max_accel, ``swing (deg)`` for max_swing: a column header."""
    from quadrs.present.labels import is_angle

    name = metric.removeprefix("max_")
    return f"{name} (deg)" if is_angle(metric) else name


def _ci(v: float, lo: float, hi: float) -> str:
    if not math.isfinite(v):
        return ""
    if not (math.isfinite(lo) and math.isfinite(hi)):
        return _g(v)
    return f"{_g(v)} [{_g(lo)}, {_g(hi)}]"


def _g(v: float) -> str:
    """Three figures; blank where the row has no value (the tracking of 'in flight')."""
    return f"{v:.3g}" if math.isfinite(v) else ""
