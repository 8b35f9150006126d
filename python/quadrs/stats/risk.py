"""Risk answers from Monte Carlo runs: exceedance probabilities, tail quantiles, run counts.

Everything here works on plain arrays first (``exceedance_interval``, ``exceedance_stats``,
``paired_exceedance``, ``quantile_interval``, ``runs_needed``); the table functions apply them
per controller and phase of a tidy runs table, and :class:`quadrs.MonteCarloResult` and
:class:`quadrs.runs.sweep.SweepResult` call those. The intervals come from scipy.stats:

- exceedance probability: exact Clopper-Pearson, ``binomtest(k, n).proportion_ci("exact")``;
- quantile: distribution-free order-statistic interval, ``quantile_test(...)
  .confidence_interval()``;
- paired difference of two controllers' exceedance probabilities: Newcombe's hybrid score
  interval for paired proportions (his method 10, Stat. Med. 17 (1998) 2635-2650), built from
  scipy's Wilson intervals of the two marginals and the pairs' phi correlation, with the exact
  McNemar test (``binomtest`` on the discordant pairs) as its p-value.

Diverged realisations: a flight that diverged certainly shook its cargo, so it counts as an
exceedance of every threshold, and as +inf when a quantile is taken, in the phase in which it
diverged and the later ones; a phase that ended before the divergence keeps its own value
(:func:`quadrs.present.table3.phase_diverged`). The tables report how many
there were (column ``diverged``); nothing is dropped silently. Rows that did not diverge but
whose metric is undefined (NaN: e.g. a spectral peak of a phase too short for a spectrum) are
left out of ``n`` and counted in ``undefined``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pandas as pd
from scipy import optimize, stats

from quadrs import _core
from quadrs.stats.summary import phase_diverged

#: Default target half-width of the exceedance interval for "runs needed": 1 percentage point.
HALF_WIDTH = 0.01


def _check_confidence(confidence: float) -> float:
    confidence = float(confidence)
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    return confidence


def check_metric(metric: str) -> str:
    """``metric`` if it is a metric column of the runs table, else ValueError naming it."""
    names = tuple(_core.METRIC_NAMES)
    if metric not in names:
        raise ValueError(f"metric must be one of {', '.join(names)}; got {metric!r}")
    return metric


def check_threshold(threshold: float) -> float:
    """A finite float, else ValueError naming the value."""
    try:
        value = float(threshold)
    except (TypeError, ValueError):
        raise ValueError(f"threshold must be a number, got {threshold!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"threshold must be finite, got {threshold!r}")
    return value


def check_pair(have: Sequence[str], controllers: tuple[str, str]) -> tuple[str, str]:
    """``controllers`` if it names two different controllers of ``have``, else ValueError."""
    a, b = controllers
    if a == b or a not in have or b not in have:
        raise ValueError(
            f"controllers must be two different ones of {tuple(have)}, got {tuple(controllers)}"
        )
    return a, b


# -- arrays -------------------------------------------------------------------------------------
def exceedance_interval(k: int, n: int, confidence: float = 0.95) -> tuple[float, float, float]:
    """k exceedances in n runs -> (k/n, low, high), the exact Clopper-Pearson interval
    (``scipy.stats.binomtest``). NaNs when n = 0."""
    confidence = _check_confidence(confidence)
    if n == 0:
        return math.nan, math.nan, math.nan
    low, high = _binomial_ci(int(k), int(n), confidence, "exact")
    return k / n, low, high


@lru_cache(maxsize=4096)
def _binomial_ci(k: int, n: int, confidence: float, method: str) -> tuple[float, float]:
    """scipy's interval for k successes in n trials (memoised: it depends on k and n only, and
    a table or curve asks for the same few counts again and again)."""
    ci = stats.binomtest(k, n).proportion_ci(confidence, method=method)
    return float(ci.low), float(ci.high)


@lru_cache(maxsize=4096)
def _mcnemar_p(only_a: int, discordant: int) -> float:
    """Exact McNemar test: ``only_a`` of the discordant pairs against Binomial(m, 1/2)."""
    return float(stats.binomtest(only_a, discordant, 0.5).pvalue)


@dataclass(frozen=True)
class Exceedance:
    """P(metric > threshold) from one sample: ``k`` exceedances (``diverged`` of them by
    divergence) in ``n`` runs; ``undefined`` rows (NaN, not diverged) left out."""

    n: int
    k: int
    diverged: int
    undefined: int
    probability: float
    ci_low: float
    ci_high: float


def exceeds(
    values: np.ndarray, threshold: float, diverged: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Per run: (exceeded, defined). A diverged run exceeds; a NaN value that did not diverge
    is undefined."""
    values = np.asarray(values, dtype=float)
    div = np.zeros(values.shape, bool) if diverged is None else np.asarray(diverged, bool)
    with np.errstate(invalid="ignore"):
        over = values > threshold
    defined = div | ~np.isnan(values)
    return (over | div) & defined, defined


def exceedance_stats(
    values: np.ndarray,
    threshold: float,
    diverged: np.ndarray | None = None,
    confidence: float = 0.95,
) -> Exceedance:
    """P(value > threshold) with its exact interval; diverged runs count as exceedances."""
    threshold = check_threshold(threshold)
    hit, defined = exceeds(values, threshold, diverged)
    div = np.zeros(hit.shape, bool) if diverged is None else np.asarray(diverged, bool)
    n, k = int(defined.sum()), int(hit.sum())
    p, lo, hi = exceedance_interval(k, n, confidence)
    return Exceedance(n, k, int(div.sum()), int((~defined).sum()), p, lo, hi)


def _width(p: float, n: float, confidence: float) -> float:
    """Half-width of the Clopper-Pearson interval at a fraction ``p`` of ``n`` runs, for a
    real ``n`` (its bounds are beta quantiles, continuous in the count)."""
    alpha = 1 - confidence
    k = p * n
    lo = 0.0 if k <= 0 else stats.beta.ppf(alpha / 2, k, n - k + 1)
    hi = 1.0 if k >= n else stats.beta.ppf(1 - alpha / 2, k + 1, n - k)
    return float(hi - lo) / 2


def runs_needed(
    p: float,
    half_width: float = HALF_WIDTH,
    confidence: float = 0.95,
    relative: bool = False,
) -> float:
    """Runs n for which the exact (Clopper-Pearson) interval at an observed exceedance
    fraction ``p`` has half-width (high - low)/2 at most ``half_width`` (a probability, e.g.
    0.01 = +-1 percentage point; with ``relative``, a fraction of ``p``, e.g. 0.1 = +-10 %).

    Found by root-finding on the interval's half-width as a continuous function of n
    (``scipy.optimize.brentq``), then checked and stepped up, if need be, with
    ``binomtest`` at the whole count round(p n). ``inf`` for a relative width at p = 0.
    """
    confidence = _check_confidence(confidence)
    p = float(p)
    if not 0 <= p <= 1:
        raise ValueError(f"p must be in [0, 1], got {p}")
    if not half_width > 0:
        raise ValueError(f"half_width must be > 0, got {half_width}")
    target = half_width * p if relative else half_width
    if target <= 0:
        return math.inf
    if target >= 0.5:
        return 1.0

    def excess(n: float) -> float:
        return _width(p, n, confidence) - target

    hi = 2.0
    while excess(hi) > 0:
        hi *= 2
        if hi > 1e12:
            return math.inf
    lo = max(hi / 2, 1.0)
    n = lo if excess(lo) <= 0 else optimize.brentq(excess, lo, hi, xtol=0.5)
    n = max(1, math.ceil(n))
    for _ in range(10_000):  # rounding k can widen the interval a little: step up
        _, low, high = exceedance_interval(round(p * n), n, confidence)
        if (high - low) / 2 <= target:
            break
        n += 1
    return float(n)


@dataclass(frozen=True)
class PairedExceedance:
    """Two controllers flown on the same gusts: ``n`` pairs, ``both``/``only_a``/``only_b``/
    ``neither`` exceeded; P(a exceeds) - P(b exceeds) with Newcombe's paired interval and the
    exact McNemar p-value (NaN without discordant pairs)."""

    n: int
    both: int
    only_a: int
    only_b: int
    neither: int
    p_a: float
    p_b: float
    difference: float
    ci_low: float
    ci_high: float
    mcnemar_p: float


def paired_exceedance(a: np.ndarray, b: np.ndarray, confidence: float = 0.95) -> PairedExceedance:
    """Paired difference of exceedance probabilities from boolean arrays ``a``, ``b`` (one
    entry per pair): Newcombe's method 10 from the Wilson intervals of each marginal
    (``binomtest(...).proportion_ci("wilson")``) and the phi coefficient of the 2x2 table."""
    confidence = _check_confidence(confidence)
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    if a.shape != b.shape:
        raise ValueError(f"paired samples differ in length: {a.shape} vs {b.shape}")
    n = len(a)
    both, only_a = int((a & b).sum()), int((a & ~b).sum())
    only_b, neither = int((~a & b).sum()), int((~a & ~b).sum())
    if n == 0:
        nan = math.nan
        return PairedExceedance(0, 0, 0, 0, 0, nan, nan, nan, nan, nan, nan)
    p1, p2 = (both + only_a) / n, (both + only_b) / n
    l1, u1 = _binomial_ci(both + only_a, n, confidence, "wilson")
    l2, u2 = _binomial_ci(both + only_b, n, confidence, "wilson")
    denom = (both + only_a) * (only_b + neither) * (both + only_b) * (only_a + neither)
    phi = (both * neither - only_a * only_b) / math.sqrt(denom) if denom > 0 else 0.0
    d1lo, d1hi, d2lo, d2hi = p1 - l1, u1 - p1, p2 - l2, u2 - p2
    delta = math.sqrt(max(d1lo**2 - 2 * phi * d1lo * d2hi + d2hi**2, 0.0))
    eps = math.sqrt(max(d1hi**2 - 2 * phi * d1hi * d2lo + d2lo**2, 0.0))
    diff = p1 - p2
    m = only_a + only_b
    mcnemar = _mcnemar_p(only_a, m) if m > 0 else math.nan
    return PairedExceedance(
        n,
        both,
        only_a,
        only_b,
        neither,
        p1,
        p2,
        diff,
        max(diff - delta, -1.0),
        min(diff + eps, 1.0),
        float(mcnemar),
    )


def quantile_interval(
    values: np.ndarray, q: float, confidence: float = 0.95
) -> tuple[int, float, float, float]:
    """(n, estimate, low, high) of the ``q``-quantile of ``values``: the estimate is the
    order statistic ``np.quantile(method="inverted_cdf")`` (the smallest value with at least a
    fraction q of the sample at or below it), the interval the distribution-free
    order-statistic one of ``scipy.stats.quantile_test``. +inf values (diverged runs) are kept;
    NaNs are left out. Bounds are -inf/+inf when the sample is too small for them."""
    confidence = _check_confidence(confidence)
    q = float(q)
    if not 0 < q < 1:
        raise ValueError(f"q must be in (0, 1), got {q}")
    x = np.asarray(values, dtype=float)
    x = x[~np.isnan(x)]
    n = len(x)
    if n == 0:
        return 0, math.nan, math.nan, math.nan
    est = float(np.quantile(x, q, method="inverted_cdf"))
    ci = stats.quantile_test(x, q=0.0, p=q).confidence_interval(confidence)
    # scipy gives NaN for a bound no order statistic of the sample can provide: unbounded.
    lo = -math.inf if math.isnan(ci.low) else float(ci.low)
    hi = math.inf if math.isnan(ci.high) else float(ci.high)
    return n, est, lo, hi


# -- tables -------------------------------------------------------------------------------------
def _phase_rows(runs: pd.DataFrame, phase: str, controller: str) -> pd.DataFrame:
    sel = runs[(runs["phase"] == phase) & (runs["controller"] == controller)]
    return sel.sort_values("realisation")


def exceedance_table(
    runs: pd.DataFrame,
    metric: str,
    threshold: float,
    controllers: Sequence[str],
    phases: Sequence[str],
    confidence: float = 0.95,
    half_width: float = HALF_WIDTH,
    relative: bool = False,
) -> pd.DataFrame:
    """Tidy: per controller and phase, ``n``, ``exceedances``, ``diverged`` (counted among the
    exceedances), ``undefined``, ``probability``, ``ci_low``, ``ci_high`` (exact) and
    ``runs_needed`` for the interval half-width ``half_width`` at the observed probability."""
    check_metric(metric)
    threshold = check_threshold(threshold)
    rows = []
    for c in controllers:
        for phase in phases:
            sel = _phase_rows(runs, phase, c)
            e = exceedance_stats(
                sel[metric].to_numpy(float),
                threshold,
                phase_diverged(sel),
                confidence,
            )
            need = runs_needed(e.probability, half_width, confidence, relative) if e.n else math.nan
            rows.append(
                {
                    "controller": c,
                    "phase": phase,
                    "metric": metric,
                    "threshold": threshold,
                    "n": e.n,
                    "exceedances": e.k,
                    "diverged": e.diverged,
                    "undefined": e.undefined,
                    "probability": e.probability,
                    "ci_low": e.ci_low,
                    "ci_high": e.ci_high,
                    "runs_needed": need,
                }
            )
    return pd.DataFrame(rows)


def exceedance_difference_table(
    runs: pd.DataFrame,
    metric: str,
    threshold: float,
    phases: Sequence[str],
    controllers: tuple[str, str] = ("smc", "pd"),
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Per phase: P(a exceeds) - P(b exceeds) for ``controllers = (a, b)`` over the
    realisations both flew, with the paired counts, Newcombe's interval and McNemar's exact
    p-value (see :func:`paired_exceedance`)."""
    check_metric(metric)
    threshold = check_threshold(threshold)
    a, b = controllers
    rows = []
    for phase in phases:
        hits = {}
        for c in (a, b):
            sel = _phase_rows(runs, phase, c)
            hit, defined = exceeds(sel[metric].to_numpy(float), threshold, phase_diverged(sel))
            real = sel["realisation"].to_numpy()
            hits[c] = pd.Series(hit[defined], index=real[defined])
        common = hits[a].index.intersection(hits[b].index)
        r = paired_exceedance(
            hits[a].loc[common].to_numpy(bool), hits[b].loc[common].to_numpy(bool), confidence
        )
        rows.append(
            {
                "phase": phase,
                "metric": metric,
                "threshold": threshold,
                "n_pairs": r.n,
                "both": r.both,
                f"only_{a}": r.only_a,
                f"only_{b}": r.only_b,
                "neither": r.neither,
                f"p_{a}": r.p_a,
                f"p_{b}": r.p_b,
                "difference": r.difference,
                "ci_low": r.ci_low,
                "ci_high": r.ci_high,
                "mcnemar_p": r.mcnemar_p,
            }
        )
    return pd.DataFrame(rows)


def _with_divergence(sel: pd.DataFrame, metric: str) -> np.ndarray:
    """The metric with diverged runs as +inf (NaN kept for undefined ones)."""
    x = sel[metric].to_numpy(float).copy()
    x[phase_diverged(sel)] = np.inf
    return x


def quantile_table(
    runs: pd.DataFrame,
    metric: str,
    q: float,
    controllers: Sequence[str],
    phases: Sequence[str],
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Tidy: per controller and phase the ``q``-quantile of ``metric`` (``quantile``) with its
    distribution-free interval, ``n`` and ``diverged`` (taken as +inf)."""
    check_metric(metric)
    rows = []
    for c in controllers:
        for phase in phases:
            sel = _phase_rows(runs, phase, c)
            n, est, lo, hi = quantile_interval(_with_divergence(sel, metric), q, confidence)
            rows.append(
                {
                    "controller": c,
                    "phase": phase,
                    "metric": metric,
                    "q": float(q),
                    "n": n,
                    "diverged": int(phase_diverged(sel).sum()),
                    "quantile": est,
                    "ci_low": lo,
                    "ci_high": hi,
                }
            )
    return pd.DataFrame(rows)


def quantile_difference_table(
    runs: pd.DataFrame,
    metric: str,
    q: float,
    phases: Sequence[str],
    controllers: tuple[str, str] = ("smc", "pd"),
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Per phase: the ``q``-quantile of the per-realisation difference ``metric(a) -
    metric(b)`` (same gust for both) with its distribution-free interval: with q = 0.5, the
    median improvement. Pairs where either diverged are left out and counted in
    ``diverged_pairs`` (a difference of two infinities has no value)."""
    check_metric(metric)
    a, b = controllers
    rows = []
    for phase in phases:
        wide = {}
        for c in (a, b):
            sel = _phase_rows(runs, phase, c)
            wide[c] = pd.Series(_with_divergence(sel, metric), index=sel["realisation"].to_numpy())
        common = wide[a].index.intersection(wide[b].index)
        xa, xb = wide[a].loc[common].to_numpy(), wide[b].loc[common].to_numpy()
        finite = np.isfinite(xa) & np.isfinite(xb)
        div = int((np.isinf(xa) | np.isinf(xb)).sum())
        n, est, lo, hi = quantile_interval(xa[finite] - xb[finite], q, confidence)
        rows.append(
            {
                "phase": phase,
                "metric": metric,
                "q": float(q),
                "n_pairs": n,
                "diverged_pairs": div,
                "quantile_difference": est,
                "ci_low": lo,
                "ci_high": hi,
            }
        )
    return pd.DataFrame(rows)


#: The largest values every exceedance curve shows one by one (its tail, to the worst).
TAIL_POINTS = 20


def survival_curve(
    values: np.ndarray,
    diverged: np.ndarray | None = None,
    confidence: float = 0.95,
    points: int = 120,
) -> pd.DataFrame:
    """The empirical exceedance curve P(value > x) at up to ``points`` thresholds x spread over
    the sample (its order statistics) and at each of its ``TAIL_POINTS`` largest values, with
    pointwise exact (Clopper-Pearson) intervals from :func:`exceedance_stats`: columns
    ``threshold``, ``probability``, ``ci_low``, ``ci_high``, ``n``. Diverged runs exceed every
    threshold."""
    values = np.asarray(values, dtype=float)
    div = np.zeros(values.shape, bool) if diverged is None else np.asarray(diverged, bool)
    finite = np.sort(values[np.isfinite(values) & ~div])
    if len(finite) == 0:
        return pd.DataFrame(columns=["threshold", "probability", "ci_low", "ci_high", "n"])
    n = len(finite)
    # Spread over the sample, and every one of the largest values: the tail is what is read.
    spread = np.linspace(0, n - 1, min(points, n)).round().astype(int)
    idx = np.unique(np.r_[spread, np.arange(max(0, n - TAIL_POINTS), n)])
    xs = np.unique(np.r_[finite[0] - 1e-12 * (1 + abs(finite[0])), finite[idx]])
    rows = []
    for x in xs:
        e = exceedance_stats(values, float(x), div, confidence)
        rows.append((x, e.probability, e.ci_low, e.ci_high, e.n))
    return pd.DataFrame(rows, columns=["threshold", "probability", "ci_low", "ci_high", "n"])


# -- limits (the CLI's --limit METRIC=THRESHOLD) --------------------------------------------------
def parse_limit(text: str) -> tuple[str, float]:
    """``"max_accel=2.0"`` -> ``("max_accel", 2.0)``; ValueError naming what is wrong."""
    metric, sep, value = text.partition("=")
    metric = metric.strip()
    if not sep or not metric:
        raise ValueError(f"expected METRIC=THRESHOLD, got {text!r}")
    check_metric(metric)
    try:
        threshold = float(value)
    except ValueError:
        raise ValueError(f"{metric}: threshold must be a number, got {value.strip()!r}") from None
    if not math.isfinite(threshold):
        raise ValueError(f"{metric}: threshold must be finite, got {value.strip()!r}")
    return metric, threshold


def _pct(p: float, lo: float, hi: float) -> str:
    if not math.isfinite(p):
        return ""
    return f"{100 * p:.2f} [{100 * lo:.2f}, {100 * hi:.2f}]"


def limits_table(
    result: object,
    limits: Sequence[tuple[str, float]],
    half_width: float = HALF_WIDTH,
    confidence: float = 0.95,
) -> pd.DataFrame:
    """For a MonteCarloResult or SweepResult: per limit, controller and phase, P(metric >
    threshold) in percent with its exact interval, the counts, and the runs needed for an
    interval of +-``half_width`` (a probability) at the observed rate. For printing."""
    parts = [
        result.exceedance(m, t, confidence, half_width=half_width)  # type: ignore[attr-defined]
        for m, t in limits
    ]
    table = pd.concat(parts, ignore_index=True)
    level = f"{confidence:.0%}"
    table[f"P % [{level} CI]"] = [
        _pct(r.probability, r.ci_low, r.ci_high) for r in table.itertuples()
    ]
    need = f"runs for ±{100 * half_width:g} pp"
    table[need] = [f"{v:.0f}" if math.isfinite(v) else "" for v in table["runs_needed"]]
    drop = ["probability", "ci_low", "ci_high", "runs_needed", "undefined"]
    if table["undefined"].any():
        drop.pop()
    return table.drop(columns=drop).set_index("metric")


def limits_difference_table(
    result: object,
    limits: Sequence[tuple[str, float]],
    controllers: tuple[str, str] = ("smc", "pd"),
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Per limit and phase, the paired difference P(a exceeds) - P(b exceeds) in percentage
    points with Newcombe's interval and McNemar's exact p-value. For printing."""
    parts = [
        result.exceedance(m, t, confidence, paired=True, controllers=controllers)  # type: ignore[attr-defined]
        for m, t in limits
    ]
    table = pd.concat(parts, ignore_index=True)
    a, b = controllers
    table[f"{a.upper()} - {b.upper()} pp [{confidence:.0%} CI]"] = [
        _pct(r.difference, r.ci_low, r.ci_high) for r in table.itertuples()
    ]
    drop = [f"p_{a}", f"p_{b}", "difference", "ci_low", "ci_high"]
    return table.drop(columns=drop).set_index("metric")
