"""A rare-event estimate as a safety case states it (docs/risk.md, "Per flight hour" and
"The safety case"): its event as one failure mode, per flight and per flight hour with the
one-sided 95 % upper bound a target is judged against, and the page of
:mod:`quadrs.design.safety_text`.

The event P(metric in phase > threshold), a diverged flight counting, is a failure mode by
its metric: ``left_volume`` a containment loss, ``touchdown_speed`` a hard touchdown, any
other metric measured through the flight (the parcel's acceleration, its swing, ...) the
parcel over its limit, as ``quadrs mission --limit`` asks it. The other event metrics (a
margin, the touchdown's drift or miss, the release) are none of the modes: a target or a
page of them is refused.

Per flight hour the probability is over the flight's scheduled duration (subset simulation
estimates a probability per flight, not the hours of the flights that ended early). Where
the threshold was reached on level 0 (plain Monte Carlo) the answer is a count, k of n
flights, and its rate the mission's (Garwood, :func:`quadrs.stats.rates.flight_rate`);
deeper, the estimator's own interval (:func:`quadrs.rare.intervals.one_sided_upper`).
"""

from __future__ import annotations

import math
from typing import Any

from quadrs.design.safety import MODE_TITLES, FailureMode, SafetyCase, assumptions_of
from quadrs.rare.intervals import one_sided_upper
from quadrs.rare.result import RareEventResult
from quadrs.stats.rates import (
    BOUND_LEVEL,
    SECONDS_PER_HOUR,
    Rate,
    estimated_rate,
    flight_rate,
    flights_to_show,
    judge,
)

__all__ = ["RARE_MODES", "check_rare_targets", "rare_mode", "rare_rate", "rare_safety_case"]

#: The event metrics that are a failure mode; any other metric that is no event: parcel.
RARE_MODES = {"left_volume": "containment", "touchdown_speed": "touchdown"}


def rare_mode(metric: str) -> str | None:
    """The failure mode an exceedance of ``metric`` is (None: none of them)."""
    from quadrs import _core

    if metric in RARE_MODES:
        return RARE_MODES[metric]
    return None if metric in _core.EVENT_METRICS else "parcel"


def check_rare_targets(metric: str, targets: dict[str, float], what: str) -> str:
    """The mode of ``metric``'s exceedance, checked before any flight: a ValueError if it is
    none (``what``: the option that asks for it) or a target names another mode."""
    mode = rare_mode(metric)
    if mode is None:
        named = ", ".join(f"{m} ({k})" for k, m in RARE_MODES.items())
        raise ValueError(f"{what}: an exceedance of {metric} is none of the failure modes "
                         f"(the event metrics that are: {named}; any metric measured through "
                         "the flight is the parcel's)")  # fmt: skip
    for other in targets:
        if other != mode:
            raise ValueError(f"--target {other}: quadrs rare --metric {metric} estimates the "
                             f"{mode} mode only (quadrs mission judges every mode)")  # fmt: skip
    return mode


def flight_hours(result: RareEventResult) -> float | None:
    """Hours of one flight (the scenario's duration); None without a scenario."""
    scenario = getattr(result.model, "scenario", None)
    if scenario is None:
        return None
    return float(scenario["integrator.duration"]) / SECONDS_PER_HOUR


def rare_rate(result: RareEventResult, hours: float | None = None,
              confidence: float = BOUND_LEVEL) -> Rate | None:  # fmt: skip
    """The estimate per flight hour of ``hours`` a flight (default the scenario's duration)
    with its interval and one-sided ``confidence`` bound; None when interrupted or without
    a flight (a limit-state function)."""
    hours = flight_hours(result) if hours is None else hours
    run = result.run
    if hours is None or run.interrupted or not run.levels:
        return None
    if len(run.levels) == 1:  # plain Monte Carlo: a count of flights, as a mission's
        k = run.levels[0].above if run.probability is not None else 0
        return flight_rate(k, run.per_level, run.per_level * hours, confidence)
    upper = one_sided_upper(run, confidence)
    interval = result.interval
    assert upper is not None and interval is not None
    p = math.nan if result.probability is None else result.probability
    method = "subset simulation" + ", no failure" * (result.probability is None)
    return estimated_rate(p, interval, upper, hours, result.flights, confidence, method)


def per_level_to_show(result: RareEventResult) -> Any:
    """``to_show`` of :func:`quadrs.stats.rates.judge` for a rare result: the flights a level
    (``--per-level``, a multiple of 1/p0) that would bring the bound to the target. A count
    (level 0): the flights of :func:`~quadrs.stats.rates.flights_to_show`. An estimate: its
    coefficient of variation shrinks as 1/sqrt(per level) (the t quantile held); 0 without an
    estimate."""
    from scipy.stats import t as student

    run = result.run
    length = round(1.0 / run.p0)

    def whole(flights: float) -> int:
        return math.ceil(flights / length - 1e-9) * length

    def to_show(rate: Rate, target: float) -> int:
        if rate.events is not None:
            return whole(run.per_level + flights_to_show(rate, target))
        if run.probability is None or run.cov is None or not run.cov > 0:
            return 0
        q = float(student.ppf(rate.confidence, max(run.clusters - 1, 1)))
        s_needed = math.log(target / rate.rate) / q  # bound = p exp(q s), s^2 = log(1 + cov^2)
        cov_needed = math.sqrt(math.expm1(s_needed**2))
        return whole(run.per_level * (run.cov / cov_needed) ** 2)

    return to_show


def rare_safety_case(result: RareEventResult, targets: dict[str, float] | None = None,
                     laws: tuple[str, ...] = ()) -> SafetyCase:  # fmt: skip
    """The page of one law's rare-event result: its one mode per flight and per flight hour,
    the targets (of that mode) judged against the one-sided 95 % bound, the method and the
    assumptions from the result's own provenance (its scenario, law, seed)."""
    from quadrs.present.labels import shown_unit, shown_value

    model: Any = result.model
    targets = dict(targets or {})
    mode = check_rare_targets(model.metric, targets, "--safety-case")
    rate = rare_rate(result)
    if rate is None:
        raise ValueError("a rare-event result without an estimate (interrupted) has no page")
    run = result.run
    limit = f"{shown_value(model.metric, result.threshold):g} {shown_unit(model.metric)}"
    label = (f"{MODE_TITLES[mode]} ({model.metric} in {model.phase} > {limit.rstrip()}, or "
             "diverged)")  # fmt: skip
    low, high = result.interval or (math.nan, math.nan)
    counted = len(run.levels) == 1
    events = rate.events if counted else None
    p = rate.per_flight if counted else (result.probability or math.nan)
    failure = FailureMode(mode, label, events, rate.flights, p, low, high, rate)
    verdicts = tuple(judge(m, t, rate, per_level_to_show(result), "per_level")
                     for m, t in targets.items())  # fmt: skip
    if counted:
        method = (f"plain Monte Carlo (level 0 of subset simulation reached the threshold), "
                  f"{run.per_level:,} flights")  # fmt: skip
        intervals = ("per flight Clopper-Pearson, per flight hour Garwood (Poisson), the bounds "
                     "one-sided")  # fmt: skip
    else:
        method = (f"subset simulation, {len(run.levels)} levels of {run.per_level:,} flights "
                  f"(p0 {run.p0:g}), {result.flights:,} flights in all")  # fmt: skip
        intervals = ("subset simulation's own (lognormal with a t quantile on the failures' "
                     "ancestries; with no failure the levels' product and a zero count), the "
                     "bounds one-sided: the upper end of its two-sided "
                     f"{100 * (2 * rate.confidence - 1):.3g} % interval")  # fmt: skip
    duration = float(model.scenario["integrator.duration"])
    said = (f"a flight's hours are its scheduled {duration:g} s (subset simulation estimates "
            "a probability per flight)")  # fmt: skip
    laws = laws or (model.controller,)
    provenance = assumptions_of(model.scenario, model.controller, laws, result.seed,
                                "drawn from standard normals")  # fmt: skip
    provenance += (("command", f"quadrs rare ({result.method} method)"),)
    return SafetyCase(model.controller, rate.flights, rate.hours, method, {mode: failure},
                      verdicts, provenance, None, rate.confidence, intervals, said)  # fmt: skip
