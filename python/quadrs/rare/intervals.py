"""The intervals and bounds subset simulation states: lognormal intervals of a product of
level fractions, the exact (Clopper-Pearson) interval of one level, and the upper bound when
no sample failed; all at :data:`CONFIDENCE`."""

from __future__ import annotations

import math

#: Confidence of every interval and bound the sampler states.
CONFIDENCE = 0.95


def _lognormal_s(cov: float) -> float:
    return math.sqrt(math.log1p(cov * cov))


def _upper_bound_zero(n: int, confidence: float) -> float:
    """The upper end of the two-sided exact (Clopper-Pearson) ``confidence`` interval of a
    probability with 0 events in n independent trials, 1 - ((1 - confidence) / 2)^(1/n): the
    one interval convention of every table and figure (docs/risk.md)."""
    return -math.expm1(math.log((1.0 - confidence) / 2.0) / n)


def _interval(probability: float, cov: float, clusters: int) -> tuple[float, float]:
    """Lognormal interval P exp(-+ q s), s^2 = log(1 + cov^2), q the t quantile with
    ``clusters - 1`` degrees of freedom (the failures' independent ancestries), the upper
    end at most 1."""
    from scipy.stats import t as student

    q = float(student.ppf(0.5 + CONFIDENCE / 2, max(clusters - 1, 1)))
    s = _lognormal_s(cov)
    return probability * math.exp(-q * s), min(1.0, probability * math.exp(q * s))


def _binomial_interval(k: int, n: int) -> tuple[float, float]:
    """Clopper-Pearson (exact) interval of k events in n independent trials, from the beta
    quantiles directly (scipy's binomtest also computes a p-value, over arrays of size n)."""
    from scipy.stats import beta

    tail = (1.0 - CONFIDENCE) / 2
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
