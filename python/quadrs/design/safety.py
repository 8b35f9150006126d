"""The numbers a safety case files (docs/risk.md, "Per flight hour" and "The safety case"):
a mission's failure modes, each per flight and per flight hour with its bound, the targets
met or not, the winds that make the risk, and the assumptions behind them.

The failure modes, over the whole flight of each realisation of one law:

- ``containment``: the flight left the operational volume (``left_volume``, ``[volume]``)
  or diverged (a flight that ran away is not contained); not judged without ``[volume]``;
- ``control``: loss of control, the flight diverged (any exit status but ``ok``);
- ``parcel``: the parcel over its limit, the mission's question (``P(metric > limit)``,
  the mission report's whole-flight row: a diverged flight exceeds);
- ``touchdown``: a hard touchdown, faster than the touchdown limit (the mission report's
  last metres; a diverged flight counts); not judged where no parcel is lowered.

Each is a count over the flights (the probability per flight, exact Clopper-Pearson), and
over the flight hours flown (:func:`quadrs.stats.rates.flight_rate`: each flight's own
duration, a diverged one until it ended). The numbers of the parcel and touchdown modes are
the mission report's own (:class:`quadrs.design.mission.MissionReport`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from quadrs.design.mission import MissionReport
from quadrs.runs.montecarlo_result import MonteCarloResult
from quadrs.stats.rates import BOUND_LEVEL, TARGET_MODES, Rate, Verdict, flight_rate, judge

__all__ = ["MODE_TITLES", "FailureMode", "SafetyCase", "assumptions_of", "safety_case",
           "wind_bands"]  # fmt: skip

#: m/s, the width of the wind bands (of the drawn ``wind.speed``).
BAND_WIDTH = 2.0
#: Each mode's name on the page, its event said after it.
MODE_TITLES = {
    "containment": "Containment loss",
    "control": "Loss of control",
    "parcel": "Parcel over its limit",
    "touchdown": "Hard touchdown",
}


@dataclass(frozen=True)
class FailureMode:
    """One failure mode: ``events`` of ``flights`` (None if not counted: not judged, with
    ``why``, or estimated, with a ``rate``), the probability per flight with its interval,
    and the rate per flight hour."""

    mode: str
    label: str
    events: int | None
    flights: int
    probability: float = math.nan
    ci_low: float = math.nan
    ci_high: float = math.nan
    rate: Rate | None = None
    why: str = ""

    @property
    def judged(self) -> bool:
        return self.rate is not None

    @property
    def tally(self) -> str:
        """How it was counted: ``k of n`` flights, or the estimate's method."""
        if self.events is not None:
            return f"{self.events} of {self.flights}"
        return "not judged" if self.rate is None else f"estimated ({self.flights:,} flights)"


@dataclass(frozen=True)
class SafetyCase:
    """A mission's safety-case numbers for one law (see the module docstring)."""

    controller: str
    flights: int
    hours: float
    method: str
    modes: dict[str, FailureMode]
    verdicts: tuple[Verdict, ...] = ()
    #: (what, value) pairs from the result's own provenance.
    assumptions: tuple[tuple[str, str], ...] = ()
    #: Per wind band of the drawn wind.speed (None without a dispersed wind).
    bands: pd.DataFrame | None = field(default=None, repr=False)
    #: The intervals' level (two-sided) and the bounds' (one-sided).
    confidence: float = BOUND_LEVEL
    #: What the rates' intervals are (the printed head and the page say it).
    intervals: str = ("per flight Clopper-Pearson, per flight hour Garwood (Poisson), the "
                      "bounds one-sided")  # fmt: skip
    #: How a flight's hours are counted.
    hours_said: str = "a flight's hours run until it ended (a diverged flight until it diverged)"

    def rows(self) -> pd.DataFrame:
        """One row per failure mode: events, flights, per flight [interval], per flight hour
        [interval], its one-sided upper bound, per 10,000 deliveries (NaN where not judged)."""
        out = []
        for m in self.modes.values():
            r = m.rate
            out.append({"mode": m.mode, "events": m.events, "flights": m.flights,
                        "per_flight": m.probability, "ci_low": m.ci_low, "ci_high": m.ci_high,
                        "per_hour": r.rate if r else math.nan,
                        "hour_low": r.ci_low if r else math.nan,
                        "hour_high": r.ci_high if r else math.nan,
                        "hour_upper": r.upper if r else math.nan,
                        "per_10k": r.per_10k if r else math.nan,
                        "per_10k_upper": r.per_10k_upper if r else math.nan})  # fmt: skip
        return pd.DataFrame(out).set_index("mode")

    def to_text(self, width: int = 100) -> str:
        """The per-flight-hour block of ``quadrs mission``'s answer, ``width`` columns wide."""
        from quadrs.design.safety_text import rates_text

        return rates_text(self, width)

    def to_markdown(self) -> str:
        """The one-page safety-case summary (markdown)."""
        from quadrs.design.safety_text import safety_markdown

        return safety_markdown(self)


def flight_hours(mc: MonteCarloResult, controller: str) -> pd.Series:
    """Per realisation, the hours it flew: until it diverged, else the whole duration."""
    runs = mc.runs[mc.runs["controller"] == controller]
    ended = runs.groupby("realisation")["diverged_at"].min()
    duration = float(mc.scenario["integrator.duration"])
    return ended.fillna(duration).clip(upper=duration) / 3600.0


def _per_flight(events: pd.Series) -> pd.Series:
    """Per realisation, whether the event happened in any of its rows."""
    return events.groupby(level=0).any()


def _mode_events(mc: MonteCarloResult, report: MissionReport) -> dict[str, Any]:
    """Per mode: a boolean Series by realisation, or the reason it is not judged."""
    runs = mc.runs[mc.runs["controller"] == report.controller].set_index("realisation")
    diverged = _per_flight(runs["diverged"].astype(bool))
    out: dict[str, Any] = {"control": diverged}
    if mc.scenario.get("volume") and "left_volume" in runs:
        out["containment"] = _per_flight(runs["left_volume"].fillna(0) > 0) | diverged
    else:
        out["containment"] = "no [volume] in the scenario: containment not judged"
    out["parcel"] = (int(report.acceleration.loc[report.whole, "exceedances"]),
                     int(report.acceleration.loc[report.whole, "n"]))  # fmt: skip
    last = report.last_metres
    if last is None:
        out["touchdown"] = "the route lowers no parcel: touchdown not judged"
    else:
        out["touchdown"] = (int(last.loc[report.whole, "exceedances"]),
                            int(last.loc[report.whole, "n"]))  # fmt: skip
    return out


def _parcel_events(mc: MonteCarloResult, report: MissionReport) -> dict[str, pd.Series]:
    """The parcel mode per realisation (its whole-flight row past the limit, or diverged),
    where the results carry the whole flight's row; else nothing."""
    from quadrs.design.mission import FLIGHT_PHASE

    if report.whole != FLIGHT_PHASE:
        return {}
    runs = mc.runs[(mc.runs["controller"] == report.controller)
                   & (mc.runs["phase"] == FLIGHT_PHASE)].set_index("realisation")  # fmt: skip
    return {"parcel": (runs[report.metric] > report.limit) | runs["diverged"].astype(bool)}


def _labels(report: MissionReport) -> dict[str, str]:
    from quadrs.present.labels import shown_unit, shown_value

    limit = f"{shown_value(report.metric, report.limit):g} {shown_unit(report.metric)}".rstrip()
    said = {
        "containment": "left the operational volume, or diverged",
        "control": "the flight diverged",
        "parcel": f"{report.metric} > {limit}",
        "touchdown": f"faster than {report.touchdown_limit:g} m/s",
    }
    return {mode: f"{MODE_TITLES[mode]} ({said[mode]})" for mode in TARGET_MODES}


def _mode(mode: str, label: str, events: Any, flights: int, hours: float,
          confidence: float) -> FailureMode:  # fmt: skip
    from scipy import stats

    if isinstance(events, str):
        return FailureMode(mode, label, None, flights, why=events)
    k, n = (int(events.sum()), len(events)) if isinstance(events, pd.Series) else events
    if n == 0:  # e.g. a hard touchdown where no parcel touched down: nothing to count
        return FailureMode(mode, label, None, flights, why="no flight has the event's metric")
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=confidence, method="exact")
    rate = flight_rate(k, n, hours, confidence)
    return FailureMode(mode, label, k, n, k / n, float(ci.low), float(ci.high), rate)


def safety_case(
    mc: MonteCarloResult,
    report: MissionReport,
    targets: dict[str, float] | None = None,
) -> SafetyCase:
    """The failure modes of ``report``'s law over ``mc``'s flights, per flight and per flight
    hour, judged against ``targets`` (mode -> rate per flight hour). Intervals two-sided and
    bounds one-sided at :data:`~quadrs.stats.rates.BOUND_LEVEL` (95 %, what a safety case
    files), whatever the report's own confidence."""
    targets = dict(targets or {})
    for mode in targets:
        if mode not in TARGET_MODES:
            raise ValueError(f"target mode must be one of {', '.join(TARGET_MODES)}, got {mode!r}")
    hours = flight_hours(mc, report.controller)
    total = float(hours.sum())
    labels = _labels(report)
    modes = {m: _mode(m, labels[m], e, len(hours), total, BOUND_LEVEL)
             for m, e in _mode_events(mc, report).items()}  # fmt: skip
    modes = {m: modes[m] for m in TARGET_MODES}
    verdicts = []
    for mode, target in targets.items():
        rate = modes[mode].rate
        if rate is None:
            raise ValueError(f"--target {mode}: {modes[mode].why}")
        verdicts.append(judge(mode, target, rate))
    return SafetyCase(report.controller, len(hours), total,
                      f"plain Monte Carlo, {len(hours):,} flights ({total:.4g} flight hours)",
                      modes, tuple(verdicts),
                      assumptions_of(mc.scenario, report.controller, mc.controllers, mc.seed,
                                     f"sampling {mc.sampling}"),
                      wind_bands(mc, report, modes))  # fmt: skip


def assumptions_of(s: Any, controller: str, laws: Any, seed: int,
                   sampling: str) -> tuple[tuple[str, str], ...]:  # fmt: skip
    """What the numbers assume, from a result's own provenance: its scenario ``s``, the law,
    the laws flown, the seed, how the dispersions were sampled, and the engine's version."""
    from quadrs import _core
    from quadrs.scenario.dispersion import describe

    rows = [("model", f"vehicle.body = {s.get('vehicle.body', 'paper')}, payload.model = "
                      f"{s.get('payload.model', 'spring')}, actuator.model = "
                      f"{s.get('actuator.model', 'ideal')}"),
            ("control law", controller),
            ("laws flown", ", ".join(laws))]  # fmt: skip
    if s.get("navigation.mode") is not None:
        rows.append(("navigation", str(s.get("navigation.mode"))))
    wind = (f"mean wind {s.get('wind.speed', 0.0):g} m/s toward {s.get('wind.heading', 0.0):g}"
            " deg (W20)")  # fmt: skip
    lines = describe(s)
    climate = [ln.split(" ~ ", 1)[1] for ln in lines if ln.startswith("wind.speed ~ wind climate")]
    rows.append(("wind", climate[0] if climate else wind))
    rows.append(("turbulence", f"gust.enabled = {s.get('gust.enabled')}, W20 "
                               f"{s.get('gust.w20', s.get('gust.intensity'))}"))  # fmt: skip
    volume = s.get("volume") or {}
    if volume:
        rows.append(("operational volume", ", ".join(f"{k} = {v:g} m" for k, v in volume.items())))
    others = [ln for ln in lines if not ln.startswith("wind.") or not climate]
    if others:
        rows.append(("dispersions", "; ".join(others) + f" ({sampling})"))
    flight = f"{float(s['integrator.duration']):g} s, dt {float(s['integrator.dt']):g} s"
    rows += [("flight", flight),
             ("seed", str(seed)), ("quadrs", str(_core.__version__))]  # fmt: skip
    return tuple(rows)


def wind_bands(
    mc: MonteCarloResult, report: MissionReport, modes: dict[str, FailureMode]
) -> pd.DataFrame | None:
    """Per band of the drawn ``wind.speed`` (BAND_WIDTH m/s wide): flights, their share, and
    per judged mode the events, the probability per flight in the band and the band's share
    of all the mode's events: which winds make the risk. None if the wind is not drawn."""
    if "wind.speed" not in mc.dispersed_keys:
        return None
    runs = mc.runs[mc.runs["controller"] == report.controller]
    speed = runs.groupby("realisation")["wind.speed"].first()
    top = max(BAND_WIDTH, math.ceil(float(speed.max()) / BAND_WIDTH) * BAND_WIDTH)
    edges = np.arange(0.0, top + BAND_WIDTH / 2, BAND_WIDTH)
    band = pd.cut(speed, edges, right=False, include_lowest=True)
    table = pd.DataFrame({"flights": speed.groupby(band, observed=False).size()})
    table["share"] = table["flights"] / len(speed)
    events = _mode_events(mc, report) | _parcel_events(mc, report)
    for mode, m in modes.items():
        e = events[mode]
        if not m.judged or not isinstance(e, pd.Series):
            continue
        k = e.reindex(speed.index).fillna(False).groupby(band, observed=False).sum()
        table[f"{mode}_events"] = k.astype(int)
        table[f"{mode}_p"] = k / table["flights"].where(table["flights"] > 0)
        table[f"{mode}_share"] = k / max(int(e.sum()), 1)
    table.index = [f"[{b.left:g}, {b.right:g})" for b in table.index]
    table.index.name = "wind_speed_m_s"
    return table
