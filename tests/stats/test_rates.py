"""Rates per flight hour (quadrs.stats.rates): the exact Garwood interval against
scipy.stats, the zero-event bound, and the three verdicts of a target."""

from __future__ import annotations

import math

import pytest
from scipy import stats

from quadrs.stats.rates import (
    MET,
    NOT_MET,
    NOT_SHOWN,
    flight_rate,
    flights_to_show,
    judge,
    parse_target,
)


@pytest.mark.parametrize("k", [1, 3, 17])
def test_the_interval_is_garwoods_checked_against_the_poisson_law(k: int) -> None:
    hours = 12.5
    r = flight_rate(k, 400, hours)
    assert r.rate == k / hours
    # The exact interval's ends are where the Poisson tails hold a/2 each.
    assert stats.poisson.sf(k - 1, r.ci_low * hours) == pytest.approx(0.025, rel=1e-9)
    assert stats.poisson.cdf(k, r.ci_high * hours) == pytest.approx(0.025, rel=1e-9)
    assert stats.poisson.cdf(k, r.upper * hours) == pytest.approx(0.05, rel=1e-9)
    # and scipy's own exact Poisson interval (k over T hours) agrees.
    low, high = stats.chi2.ppf([0.025, 0.975], [2 * k, 2 * k + 2]) / 2 / hours
    assert (r.ci_low, r.ci_high) == pytest.approx((low, high), rel=1e-12)
    # per 10,000 deliveries: the count per flight, its Clopper-Pearson one-sided bound.
    assert r.per_10k == pytest.approx(1e4 * k / 400)
    cp = stats.binomtest(k, 400).proportion_ci(confidence_level=0.90, method="exact").high
    assert r.per_10k_upper == pytest.approx(1e4 * cp, rel=1e-9)


def test_no_event_gives_the_bound_three_over_the_hours() -> None:
    r = flight_rate(0, 1000, 50.0)
    assert r.rate == 0.0 and r.ci_low == 0.0
    assert r.upper == pytest.approx(stats.chi2.ppf(0.95, 2) / 2 / 50.0, rel=1e-14)
    assert r.upper == pytest.approx(-math.log(0.05) / 50.0, rel=1e-12)
    assert r.upper * 50.0 == pytest.approx(3.0, abs=0.005)


def test_bad_counts_are_refused_by_name() -> None:
    with pytest.raises(ValueError, match="hours must be finite and > 0"):
        flight_rate(1, 10, 0.0)
    with pytest.raises(ValueError, match="cannot exceed flights"):
        flight_rate(11, 10, 1.0)
    with pytest.raises(ValueError, match="mode must be one of containment"):
        parse_target("crash=1e-4")
    with pytest.raises(ValueError, match="must be finite and > 0"):
        parse_target("containment=-1")
    assert parse_target("containment=1e-4") == ("containment", 1e-4)


def test_a_target_is_met_not_met_or_not_yet_shown() -> None:
    # Below: no loss in 40,000 flight hours bounds the rate at 7.5e-5 < 1e-4.
    below = flight_rate(0, 200_000, 40_000.0)
    assert judge("containment", 1e-4, below).status == MET
    # Above: 30 losses in 10,000 hours is 3e-3, above 1e-4 whatever the bound.
    above = flight_rate(30, 50_000, 10_000.0)
    assert judge("containment", 1e-4, above).status == NOT_MET
    # Not yet shown: none in 1,000 hours (bound 3.0e-3) against 1e-3.
    few = flight_rate(0, 5_000, 1_000.0)
    v = judge("containment", 1e-3, few)
    assert v.status == NOT_SHOWN
    # 3.0 / 1e-3 = 2,996 hours: 1,996 more at 0.2 h a flight, 9,979 flights.
    assert v.more == math.ceil(-math.log(0.05) / 1e-3 / 0.2) - 5_000
    assert "more flights" in v.text(few)


def test_the_flights_to_show_are_the_fewest_that_bring_the_bound_down() -> None:
    r = flight_rate(4, 2_000, 400.0)  # 1e-2 per hour, bound 2.3e-2
    target = 1.5e-2
    more = flights_to_show(r, target)
    per_flight = 400.0 / 2_000

    def bound(flights: int) -> float:
        hours = flights * per_flight
        return float(stats.gamma.ppf(0.95, r.rate * hours + 1)) / hours

    assert bound(2_000 + more) <= target < bound(2_000 + more - 1)


def test_quadrs_rare_prints_its_estimate_per_flight_hour_and_its_one_sided_bound() -> None:
    """Subset simulation's probability per flight over the flight's hours (36 s: 0.01 h); the
    bound a target is judged against is the one-sided 95 % (the printed 95 % interval's end
    is the one-sided 97.5 %), its level said."""
    import dataclasses
    from types import SimpleNamespace

    import quadrs
    from quadrs.cli.rare import per_hour_rows
    from quadrs.rare.intervals import one_sided_upper

    model = SimpleNamespace(scenario={"integrator.duration": 36.0})
    found = quadrs.rare_event(limit_state=lambda x: x[:, 0], dimension=2, threshold=3.0,
                              per_level=500, seed=1)  # fmt: skip
    assert found.probability is not None and len(found.levels) > 1
    rows = dict(per_hour_rows(dataclasses.replace(found, model=model)))
    lo, hi = found.interval
    p = found.probability
    assert rows["per flight hour [95 % interval]"] == (
        f"{p / 0.01:.3g} [{lo / 0.01:.3g}, {hi / 0.01:.3g}] (36 s flights)"
    )
    upper = one_sided_upper(found.run, 0.95)
    assert upper < hi
    assert rows["upper bound per flight hour"] == (
        f"{upper / 0.01:.3g} (one-sided 95 %, subset simulation)"
    )
    assert rows["per 10,000 deliveries"] == f"{1e4 * p:.3g}, <= {1e4 * upper:.3g} (one-sided 95 %)"
    assert per_hour_rows(found) == []  # a limit-state function flies no flight


def test_a_verdict_says_its_bound_is_one_sided_95() -> None:
    few = flight_rate(0, 5_000, 1_000.0)
    assert "one-sided 95 % upper bound 0.003" in judge("containment", 1e-3, few).text(few)
