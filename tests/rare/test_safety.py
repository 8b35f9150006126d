"""A rare-event estimate as a safety case states it (quadrs.rare.safety): the one-sided 95 %
upper bound a target is judged against, against the estimator's own interval (its two-sided
95 % interval's end is the one-sided 97.5 % bound) and against scipy's exact forms (Garwood's
chi-square where level 0 counts the flights, Clopper-Pearson per flight); the mode of a
metric. Limit-state runs (no flight): a half-space of standard normals, P(x_1 > t)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import stats

import quadrs
from quadrs.rare import RareEventResult
from quadrs.rare.intervals import one_sided_upper
from quadrs.rare.safety import check_rare_targets, rare_mode, rare_rate

HOURS = 0.01  # a 36 s flight


def _linear(x: np.ndarray) -> np.ndarray:
    return x[:, 0]


def _run(threshold: float, **kw) -> RareEventResult:
    r = quadrs.rare_event(limit_state=_linear, dimension=4, threshold=threshold, seed=3,
                          per_level=kw.pop("per_level", 500), **kw)  # fmt: skip
    assert isinstance(r, RareEventResult)
    return r


@pytest.fixture(scope="module")
def runs() -> dict[str, RareEventResult]:
    return {
        "level 0": _run(1.0),  # P = 0.16: plain Monte Carlo reaches it
        "deep": _run(3.3),  # P = 4.8e-4: three levels
        "none on level 0": _run(8.0, max_levels=1),
        "none deeper": _run(9.0, max_levels=3),
    }


def test_the_estimators_own_interval_is_the_one_sided_975_bound(runs) -> None:
    """The 95 % interval quadrs rare prints ends at the one-sided 97.5 % bound, in every
    case: the one-sided 95 % bound is the same construction a level lower."""
    for name, r in runs.items():
        assert r.interval is not None, name
        assert one_sided_upper(r.run, 0.975) == pytest.approx(r.interval[1], rel=1e-12), name
        bound = one_sided_upper(r.run, 0.95)
        assert bound is not None and 0 < bound < r.interval[1], name


def test_the_one_sided_bound_is_scipys_exact_form(runs) -> None:
    level0 = runs["level 0"].run
    assert len(level0.levels) == 1 and level0.probability is not None
    k, n = level0.levels[0].above, level0.per_level
    cp = stats.binomtest(k, n).proportion_ci(confidence_level=0.90, method="exact").high
    assert one_sided_upper(level0, 0.95) == pytest.approx(cp, rel=1e-10)
    deep = runs["deep"].run
    assert len(deep.levels) > 1 and deep.probability is not None and deep.cov is not None
    q = stats.t.ppf(0.95, deep.clusters - 1)
    expect = deep.probability * math.exp(q * math.sqrt(math.log1p(deep.cov**2)))
    assert one_sided_upper(deep, 0.95) == pytest.approx(expect, rel=1e-12)
    none = runs["none on level 0"].run
    assert one_sided_upper(none, 0.95) == pytest.approx(1 - 0.05 ** (1 / none.per_level))


def test_a_count_on_level_0_is_garwoods_rate_per_flight_hour(runs) -> None:
    """Level 0 is k of n flights: the mission's rate, k over the n flights' hours, with the
    one-sided bound chi2(0.95; 2k + 2) / 2T; none seen, -ln(0.05) / T."""
    r = runs["level 0"]
    k, n = r.run.levels[0].above, r.run.per_level
    rate = rare_rate(r, HOURS)
    assert rate is not None and rate.events == k and rate.flights == n
    assert rate.rate == pytest.approx(k / (n * HOURS), rel=1e-12)
    assert rate.upper == pytest.approx(stats.chi2.ppf(0.95, 2 * k + 2) / 2 / (n * HOURS),
                                       rel=1e-12)  # fmt: skip
    none = rare_rate(runs["none on level 0"], HOURS)
    assert none is not None and none.events == 0
    assert none.upper == pytest.approx(-math.log(0.05) / (none.flights * HOURS), rel=1e-12)


def test_an_estimate_is_per_flight_hour_over_the_flights_duration(runs) -> None:
    """Deeper, the estimate and its interval over one flight's hours; its bound the
    one-sided 95 %, below the printed 95 % interval's end; no failure: the bound alone."""
    r = runs["deep"]
    rate = rare_rate(r, HOURS)
    assert rate is not None and rate.events is None and r.interval is not None
    assert rate.rate == pytest.approx(r.probability / HOURS, rel=1e-12)
    assert (rate.ci_low, rate.ci_high) == pytest.approx(np.array(r.interval) / HOURS)
    assert rate.upper == pytest.approx(one_sided_upper(r.run, 0.95) / HOURS, rel=1e-12)
    assert rate.upper < r.interval[1] / HOURS
    assert rate.per_10k_upper == pytest.approx(1e4 * rate.upper * HOURS, rel=1e-12)
    none = rare_rate(runs["none deeper"], HOURS)
    assert none is not None and math.isnan(none.rate)
    assert none.upper == pytest.approx(one_sided_upper(runs["none deeper"].run) / HOURS)
    assert none.upper < runs["none deeper"].upper_bound / HOURS


def test_a_metric_is_a_failure_mode_or_refused() -> None:
    assert rare_mode("left_volume") == "containment"
    assert rare_mode("touchdown_speed") == "touchdown"
    assert rare_mode("max_specific_force") == "parcel"
    assert rare_mode("touchdown_miss") is None
    with pytest.raises(ValueError, match="touchdown_miss is none of the failure modes"):
        check_rare_targets("touchdown_miss", {}, "--safety-case")
    with pytest.raises(ValueError, match=r"--target containment: .* estimates the parcel mode"):
        check_rare_targets("max_accel", {"containment": 1e-4}, "--target")
