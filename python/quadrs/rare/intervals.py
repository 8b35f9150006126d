"""The intervals and bounds subset simulation states: lognormal intervals of a product of
level fractions, the exact (Clopper-Pearson) interval of one level, and the upper bound when
no sample failed; all at :data:`CONFIDENCE`."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from quadrs.rare.levels import SubsetRun

#: Confidence of every interval and bound the sampler states.
CONFIDENCE = 0.95


def _lognormal_s(cov: float) -> float:
    return math.sqrt(math.log1p(cov * cov))


def _upper_bound_zero(n: int, confidence: float) -> float:
    """The upper end of the two-sided exact (Clopper-Pearson) ``confidence`` interval of a
    probability with 0 events in n independent trials, 1 - ((1 - confidence) / 2)^(1/n): the
    one interval convention of every table and figure (docs/risk.md)."""
    return -math.expm1(math.log((1.0 - confidence) / 2.0) / n)


def _interval(probability: float, cov: float, clusters: int,
              confidence: float = CONFIDENCE) -> tuple[float, float]:  # fmt: skip
    """Lognormal interval P exp(-+ q s), s^2 = log(1 + cov^2), q the t quantile with
    ``clusters - 1`` degrees of freedom (the failures' independent ancestries), the upper
    end at most 1."""
    from scipy.stats import t as student

    q = float(student.ppf(0.5 + confidence / 2, max(clusters - 1, 1)))
    s = _lognormal_s(cov)
    return probability * math.exp(-q * s), min(1.0, probability * math.exp(q * s))


def _binomial_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Clopper-Pearson (exact) interval of k events in n independent trials, from the beta
    quantiles directly (scipy's binomtest also computes a p-value, over arrays of size n)."""
    from scipy.stats import beta

    tail = (1.0 - confidence) / 2
    low = 0.0 if k == 0 else float(beta.ppf(tail, k, n - k + 1))
    high = 1.0 if k == n else float(beta.ppf(1.0 - tail, k + 1, n - k))
    return low, high


def lognormal_interval(
    probability: float, cov: float, confidence: float = 0.95
) -> tuple[float, float]:
    """The interval P * exp(-+ z s), s^2 = log(1 + cov^2): P taken as lognormal with the
    estimated coefficient of variation (a product of level fractions is skewed to the right)."""
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + confidence / 2))
    s = _lognormal_s(cov)
    return probability * math.exp(-z * s), probability * math.exp(z * s)


def no_failure_bound(run: SubsetRun, confidence: float) -> float:
    """With no failure: the upper end of the estimator's ``confidence`` interval (0, bound).
    On level 0, 0 of ``per_level`` independent flights (Clopper-Pearson, two-sided). Deeper,
    the product of the fractions so far (its lognormal upper end at 1 - a/2) times the bound
    for 0 events in the level's chains counted as independent trials (the two-sided
    interval's end at 1 - a/2; Bonferroni: ``confidence`` together)."""
    from scipy.stats import norm

    levels = run.levels
    if len(levels) == 1:
        return _upper_bound_zero(run.per_level, confidence)
    seeds = run.per_level // round(1.0 / run.p0)
    tail = 1.0 - (1.0 - confidence) / 2
    product = math.prod(lv.conditional_p for lv in levels[:-1])
    s = _lognormal_s(math.sqrt(sum(lv.cov**2 for lv in levels[:-1])))
    return min(1.0, product * math.exp(float(norm.ppf(tail)) * s) * _upper_bound_zero(seeds, tail))


def one_sided_upper(run: SubsetRun, confidence: float = CONFIDENCE) -> float | None:
    """The one-sided upper confidence bound at ``confidence`` on the probability (what a
    target is judged against): the upper end of the estimator's own two-sided interval at
    2 confidence - 1, built as that interval is (Clopper-Pearson when level 0 reached the
    threshold, lognormal with the t quantile deeper, the bound of :func:`no_failure_bound`
    without a failure). None when interrupted."""
    if run.interrupted or not run.levels:
        return None
    two_sided = 2.0 * confidence - 1.0
    if run.probability is None:
        return no_failure_bound(run, two_sided)
    if len(run.levels) == 1:
        return _binomial_interval(run.levels[0].above, run.per_level, two_sided)[1]
    assert run.cov is not None
    return _interval(run.probability, run.cov, run.clusters, two_sided)[1]
