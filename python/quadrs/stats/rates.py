"""Rates per flight hour: what a safety case counts (docs/risk.md, "Per flight hour").

A count of events over the flight hours flown (each flight's own duration: a flight that
diverged or stopped at the ground counts until it ended) is a Poisson rate; its interval is
the exact (Garwood) one, lambda in [chi2(a/2, 2k) / 2T, chi2(1 - a/2, 2k + 2) / 2T], and the
one-sided upper bound at the confidence level chi2(c, 2k + 2) / 2T: for no event,
-ln(1 - c) / T (2.996 / T at 95 %, the "rule of three"). Per 10,000 deliveries is the count
per flight times 10,000, each flight one delivery, with its exact (Clopper-Pearson) one-sided
upper bound.

A target on a rate (``--target containment=1e-4``: at most one containment loss per 10,000
flight hours) is met when the upper bound is at or below it, not met when the estimate is at
or above it, and not yet shown in between: then :func:`flights_to_show` says how many more
flights, at the same mean duration and the same rate, would bring the bound below it.

Every bound judged against a target is one-sided at :data:`BOUND_LEVEL` (95 %, the level a
safety case files), whatever the estimator: the Poisson count's here, subset simulation's in
:mod:`quadrs.rare.safety` (:func:`estimated_rate`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

__all__ = [
    "BOUND_LEVEL",
    "MET",
    "NOT_MET",
    "NOT_SHOWN",
    "TARGET_MODES",
    "Rate",
    "Verdict",
    "estimated_rate",
    "flight_rate",
    "flights_to_show",
    "judge",
    "one_sided_upper",
    "parse_target",
]

#: The failure modes a target may name (``--target MODE=RATE``), per flight hour.
TARGET_MODES = ("containment", "control", "parcel", "touchdown")
MET, NOT_MET, NOT_SHOWN = "met", "not met", "not yet shown"
#: Deliveries the second rate is counted per.
DELIVERIES = 10_000
SECONDS_PER_HOUR = 3600.0
#: The one-sided level of every upper bound a target is judged against.
BOUND_LEVEL = 0.95


@dataclass(frozen=True)
class Rate:
    """``events`` in ``flights`` flights totalling ``hours`` flight hours: ``rate`` per flight
    hour with its exact two-sided interval ``ci_low``/``ci_high`` and one-sided ``upper``
    bound (each at ``confidence``), and ``per_10k`` per 10,000 deliveries with its one-sided
    ``per_10k_upper`` (Clopper-Pearson). ``events`` None: an estimate, not a count (subset
    simulation's, :func:`estimated_rate`); ``method`` says whose interval it is."""

    events: int | None
    flights: int
    hours: float
    confidence: float
    rate: float
    ci_low: float
    ci_high: float
    upper: float
    per_10k: float
    per_10k_upper: float
    method: str = "Garwood (Poisson)"

    @property
    def per_flight(self) -> float:
        """Events per flight (k / n; an estimate's probability per flight)."""
        return self.per_10k / DELIVERIES


def _check(events: int, flights: int, hours: float, confidence: float) -> None:
    if isinstance(events, bool) or int(events) != events or events < 0:
        raise ValueError(f"events must be a whole number >= 0, got {events!r}")
    if isinstance(flights, bool) or int(flights) != flights or flights < 1:
        raise ValueError(f"flights must be a whole number >= 1, got {flights!r}")
    if events > flights:
        raise ValueError(f"events ({events}) cannot exceed flights ({flights})")
    if not (math.isfinite(hours) and hours > 0):
        raise ValueError(f"hours must be finite and > 0, got {hours!r}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence!r}")


def flight_rate(events: int, flights: int, hours: float, confidence: float = 0.95) -> Rate:
    """The rate of ``events`` over ``hours`` flight hours of ``flights`` flights (each a
    delivery), with exact intervals at ``confidence``."""
    from scipy import stats

    _check(events, flights, hours, confidence)
    k, n, a = int(events), int(flights), 1.0 - confidence
    low = 0.0 if k == 0 else float(stats.chi2.ppf(a / 2, 2 * k)) / 2 / hours
    high = float(stats.chi2.ppf(1 - a / 2, 2 * k + 2)) / 2 / hours
    upper = float(stats.chi2.ppf(confidence, 2 * k + 2)) / 2 / hours
    return Rate(k, n, float(hours), float(confidence), k / hours, low, high, upper,
                DELIVERIES * k / n, DELIVERIES * one_sided_upper(k, n, confidence))  # fmt: skip


def one_sided_upper(k: int, n: int, confidence: float = 0.95) -> float:
    """The one-sided exact (Clopper-Pearson) upper bound of a probability seen ``k`` times in
    ``n`` (the upper end of the two-sided interval at 2 confidence - 1): ``1 - (1 -
    confidence)**(1/n)`` for k = 0 (3/n, the "rule of three", for large n)."""
    from scipy import stats

    if n <= 0:
        return math.nan
    if k >= n:
        return 1.0
    return float(stats.beta.ppf(confidence, k + 1, n - k))


def estimated_rate(probability: float, interval: tuple[float, float], upper: float,
                   flight_hours: float, flights: int, confidence: float,
                   method: str) -> Rate:  # fmt: skip
    """The rate of an estimated probability per flight (not a count: subset simulation's),
    each flight ``flight_hours`` long: the probability, its two-sided ``interval`` at
    ``confidence`` and its one-sided ``upper`` bound, each over the flight's hours, and per
    10,000 deliveries. ``probability`` NaN: no estimate, only the bound (no failure found).
    ``flights``: those flown for it (``hours`` their total)."""
    if not (math.isfinite(flight_hours) and flight_hours > 0):
        raise ValueError(f"flight hours must be finite and > 0, got {flight_hours!r}")
    low, high = interval
    return Rate(None, int(flights), flights * flight_hours, float(confidence),
                probability / flight_hours, low / flight_hours, high / flight_hours,
                upper / flight_hours, DELIVERIES * probability, DELIVERIES * upper,
                method)  # fmt: skip


def parse_target(text: str) -> tuple[str, float]:
    """``MODE=RATE`` (``containment=1e-4``): a mode of :data:`TARGET_MODES` and a rate per
    flight hour, finite and > 0. A ValueError names what is wrong."""
    mode, sep, value = text.partition("=")
    mode = mode.strip()
    if not sep:
        raise ValueError(f"--target {text!r}: expected MODE=RATE, e.g. containment=1e-4")
    if mode not in TARGET_MODES:
        raise ValueError(f"--target {text!r}: the mode must be one of {', '.join(TARGET_MODES)}")
    try:
        rate = float(value)
    except ValueError:
        raise ValueError(f"--target {text!r}: the rate is not a number: {value!r}") from None
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"--target {text!r}: the rate (per flight hour) must be finite and > 0")
    return mode, rate


@dataclass(frozen=True)
class Verdict:
    """A target against a rate: ``status`` one of met, not met, not yet shown; ``more``
    flights that would show it (not yet shown only, else 0; 0 there too when nothing says
    how many), counted as ``more_as`` says: ``"flights"`` more flights of the kind flown,
    ``"per_level"`` flights a level of subset simulation (``--per-level``)."""

    mode: str
    target: float
    status: str
    more: int = 0
    more_as: str = "flights"

    def text(self, rate: Rate) -> str:
        """One line: the target, the rate's one-sided bound (its level said) and the verdict."""
        level = f"one-sided {100 * rate.confidence:.3g} %"
        said = "no estimate" if math.isnan(rate.rate) else f"rate {rate.rate:.3g}"
        head = (f"{self.mode} <= {self.target:.3g} per flight hour: {self.status.upper()} "
                f"({said}, {level} upper bound {rate.upper:.3g})")  # fmt: skip
        if self.status != NOT_SHOWN:
            return head
        if not self.more:
            return f"{head}; more flights or deeper levels would show it or not"
        if self.more_as == "per_level":
            return (f"{head}; about --per-level {self.more:,} at this estimate and "
                    "coefficient of variation would show it")  # fmt: skip
        return (f"{head}; about {self.more:,} more flights at this rate and mean duration "
                "would show it")  # fmt: skip

    def more_text(self) -> str:
        """What would show it, for a table's cell ("" unless not yet shown)."""
        if self.status != NOT_SHOWN or not self.more:
            return "" if self.status != NOT_SHOWN else "more flights or levels"
        return f"--per-level {self.more:,}" if self.more_as == "per_level" else f"{self.more:,}"


def judge(mode: str, target: float, rate: Rate,
          to_show: Callable[[Rate, float], int] | None = None,
          more_as: str = "flights") -> Verdict:  # fmt: skip
    """Met (the one-sided upper bound <= target), not met (estimate >= target) or not yet
    shown: then ``to_show(rate, target)`` says how many (default :func:`flights_to_show`,
    more flights of a count; counted as ``more_as``)."""
    if rate.upper <= target:
        return Verdict(mode, target, MET)
    if rate.rate >= target:
        return Verdict(mode, target, NOT_MET)
    more = (to_show or flights_to_show)(rate, target)
    return Verdict(mode, target, NOT_SHOWN, more, more_as)


def flights_to_show(rate: Rate, target: float) -> int:
    """How many more flights, of the mean duration flown so far and with events at the rate
    estimated so far, bring the one-sided upper bound to ``target`` or below (0 if it is
    already there). The bound at T hours and k = rate T events is gamma(c, k + 1) / T (the
    chi-square bound with 2k + 2 degrees of freedom), continuous in T; solved by brentq."""
    from scipy import optimize, stats

    if rate.upper <= target:
        return 0
    if rate.rate >= target:
        raise ValueError(f"the rate {rate.rate:.3g} is not below the target {target:.3g}")
    r, c = rate.rate, rate.confidence

    def excess(hours: float) -> float:
        return float(stats.gamma.ppf(c, r * hours + 1)) / hours - target

    hi = rate.hours
    while excess(hi) > 0:
        hi *= 2
    hours = rate.hours if hi == rate.hours else optimize.brentq(excess, hi / 2, hi)
    per_flight = rate.hours / rate.flights
    return max(0, math.ceil(hours / per_flight - 1e-9) - rate.flights)
