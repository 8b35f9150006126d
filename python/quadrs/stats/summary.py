"""Statistics of Monte Carlo runs: per phase and controller, the mean of each index with its
confidence interval, and P = 100 SMC / PD with a paired interval. The core of the tables
(`quadrs.present.table3` formats them); no presentation here."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pandas as pd

from quadrs import _core

#: Metric names, from the engine (one list for the whole package).
_METRICS = tuple(_core.METRIC_NAMES)


def mean_ci(values: np.ndarray, confidence: float) -> tuple[int, float, float, float]:
    """n, mean and the Student-t confidence interval of the mean (NaN below two values)."""
    values = values[np.isfinite(values)]
    n = len(values)
    if n == 0:
        return 0, np.nan, np.nan, np.nan
    mean = float(values.mean())
    if n < 2:
        return n, mean, np.nan, np.nan
    from scipy import stats  # imported here: it takes seconds, and most commands never need it

    half = stats.t.ppf(0.5 + confidence / 2, n - 1) * values.std(ddof=1) / np.sqrt(n)
    return n, mean, mean - half, mean + half


def ratio_ci(num: np.ndarray, den: np.ndarray, confidence: float) -> tuple[float, float, float]:
    """P = 100 mean(num) / mean(den) over paired samples, with the delta-method interval:
    SE(R) = sd(num_i - R den_i) / (sqrt(n) |mean(den)|). Pairing (the same gust for both)
    cancels the gust-to-gust spread that both controllers share."""
    ok = np.isfinite(num) & np.isfinite(den)
    num, den = num[ok], den[ok]
    n = len(num)
    if n == 0 or den.mean() == 0:
        return np.nan, np.nan, np.nan
    r = num.mean() / den.mean()
    if n < 2:
        return 100 * r, np.nan, np.nan
    se = (num - r * den).std(ddof=1) / (np.sqrt(n) * abs(den.mean()))
    from scipy import stats

    half = stats.t.ppf(0.5 + confidence / 2, n - 1) * se
    return 100 * r, 100 * (r - half), 100 * (r + half)


def phase_diverged(runs: pd.DataFrame) -> np.ndarray:
    """Per row of a runs table: did the flight diverge before this phase ended? The engine
    keeps the metrics of the phases that ended before a flight diverged (the flight up to then
    is what it is, whatever came later) and gives NaN for the phase in progress and the later
    ones; those rows are the diverged ones of their phase."""
    diverged = runs["diverged"].to_numpy(bool)
    columns = [m for m in _METRICS if m in runs]
    if not columns or not diverged.any():  # (no metric is read where no flight diverged)
        return diverged
    return diverged & runs[columns].isna().all(axis=1).to_numpy()


def summarise(
    runs: pd.DataFrame,
    controllers: Sequence[str],
    phases: Sequence[str],
    confidence: float = 0.95,
) -> pd.DataFrame:
    """Rows (metric, phase); per controller ``{c}_mean, {c}_ci_low, {c}_ci_high, {c}_n``
    (the realisations in the mean) and ``{c}_diverged`` (realisations whose flight diverged
    before the phase ended, see :func:`phase_diverged`); with both PD and SMC,
    ``P, P_ci_low, P_ci_high`` (P = 100 SMC / PD, over the realisations both flew through
    the phase); ``diverged``: realisations in which any controller diverged by the phase's
    end."""
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be in (0, 1), got {confidence}")
    rows = []
    gone = pd.Series(phase_diverged(runs), index=runs.index)
    for metric in [m for m in _METRICS if m in runs]:  # files from older versions lack some
        for phase in phases:
            sel = runs[runs["phase"] == phase]
            wide = sel.pivot(index="realisation", columns="controller", values=metric)
            lost = gone[sel.index]
            row: dict[str, object] = {"metric": metric, "phase": phase}
            for c in controllers:
                n, mean, lo, hi = mean_ci(wide[c].to_numpy(float), confidence)
                mine = lost[(sel["controller"] == c).to_numpy()]
                row.update({f"{c}_mean": mean, f"{c}_ci_low": lo, f"{c}_ci_high": hi, f"{c}_n": n,
                            f"{c}_diverged": int(mine.sum())})  # fmt: skip
            if "pd" in controllers and "smc" in controllers:
                p, lo, hi = ratio_ci(
                    wide["smc"].to_numpy(float), wide["pd"].to_numpy(float), confidence
                )
                row.update({"P": p, "P_ci_low": lo, "P_ci_high": hi})
            row["diverged"] = int(lost.groupby(sel["realisation"].to_numpy()).any().sum())
            rows.append(row)
    return pd.DataFrame(rows).set_index(["metric", "phase"])
