"""What :func:`quadrs.rare_event` found: the estimate, its uncertainty, the levels, the failures."""

from __future__ import annotations

import dataclasses
import html
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from quadrs.rare.subset import SubsetRun, lognormal_interval

if TYPE_CHECKING:  # pragma: no cover
    from quadrs.flight import Flight
    from quadrs.rare.scenario_model import RareEventModel

__all__ = ["RareEventComparison", "RareEventResult"]

#: Columns of ``RareEventResult.levels``.
LEVEL_COLUMNS = ("level", "threshold", "conditional_p", "acceptance_rate", "flights", "above",
                 "gamma", "cov", "sigma")  # fmt: skip


@dataclass
class RareEventResult:
    """P(value > threshold) estimated by subset simulation.

    ``probability``: the estimate (None if no sample crossed the threshold: then
    ``upper_bound`` holds the estimated probability of the highest level reached, which the
    failure probability does not exceed, and ``closest`` the largest value seen).
    ``cov``: its coefficient of variation (Au & Beck, with the chains' correlation).
    ``interval``: 95 % interval, lognormal with that coefficient of variation.
    ``levels``: one row per level (see :data:`LEVEL_COLUMNS`). ``flights``: model evaluations
    in all. ``failures``: the last level's failure samples (each chain state once; ``copies``:
    how many of the level's samples it stands for), their values; their standard normals are
    the rows of ``xi``. ``flight(k)`` re-flies failure sample ``k`` (scenario runs only).
    """

    run: SubsetRun = field(repr=False)
    #: What the value is: the metric and phase of a scenario run, or "limit_state".
    value_name: str = "value"
    #: "subset" (the only method so far).
    method: str = "subset"
    #: The model of flights that produced a scenario run (None for a limit-state function).
    model: RareEventModel | None = field(default=None, repr=False)
    confidence: float = 0.95

    # -- the estimate ---------------------------------------------------------------------
    @property
    def probability(self) -> float | None:
        """The estimate of P(value > threshold); None if no failure was found."""
        return self.run.probability

    @property
    def cov(self) -> float | None:
        """The estimate's coefficient of variation; None if no failure was found."""
        return self.run.cov

    @property
    def interval(self) -> tuple[float, float] | None:
        """The 95 % interval (lognormal, from :attr:`cov`); (0, upper_bound) if no failure
        was found."""
        if self.run.probability is None or self.run.cov is None:
            return None if self.run.upper_bound is None else (0.0, self.run.upper_bound)
        return lognormal_interval(self.run.probability, self.run.cov, self.confidence)

    @property
    def upper_bound(self) -> float | None:
        """Without a failure: the estimated probability of the highest level reached."""
        return self.run.upper_bound

    @property
    def reached(self) -> bool:
        """True if some sample crossed the threshold."""
        return self.run.reached

    @property
    def threshold(self) -> float:
        return self.run.threshold

    @property
    def closest(self) -> float:
        """The largest value any sample reached."""
        return self.run.closest

    @property
    def dimension(self) -> int:
        """Standard normals per sample."""
        return self.run.dimension

    @property
    def seed(self) -> int:
        return self.run.seed

    @property
    def flights(self) -> int:
        """Model evaluations (flights) in all."""
        return self.run.flights

    @property
    def monte_carlo_flights(self) -> float | None:
        """Flights plain Monte Carlo would need for the same coefficient of variation:
        (1 - p) / (p cov^2)."""
        p, c = self.run.probability, self.run.cov
        if p is None or c is None or c == 0:
            return None
        return (1.0 - p) / (p * c * c)

    # -- tables ---------------------------------------------------------------------------
    @property
    def levels(self) -> pd.DataFrame:
        """level, threshold (the cut the level set; the target on the last), conditional_p,
        acceptance_rate (NaN on level 0), flights, above (samples above the cut), gamma (the
        chains' correlation factor), cov (of conditional_p), sigma (the proposal's step)."""
        rows = [dataclasses.asdict(level) for level in self.run.levels]
        return pd.DataFrame(rows, columns=list(LEVEL_COLUMNS))

    @property
    def failures(self) -> pd.DataFrame:
        """One row per failure sample k: ``sample`` (k), the value (column named after it),
        ``copies``, ``chain`` and ``step`` (where the chain reached it; on level 0, ``chain``
        is the sample's index). Their standard normals: ``xi[k]``."""
        run = self.run
        return pd.DataFrame(
            {
                "sample": np.arange(len(run.failure_values)),
                self.value_name: run.failure_values,
                "copies": run.failure_copies,
                "chain": run.failure_chain,
                "step": run.failure_step,
            }
        )

    @property
    def xi(self) -> np.ndarray:
        """The failure samples' standard normals, shape (failures, dimension)."""
        return self.run.failure_xi

    def flight(self, k: int) -> Flight:
        """Re-fly failure sample ``k`` with its trace (scenario runs only)."""
        n = len(self.run.failure_values)
        if isinstance(k, bool) or not isinstance(k, int | np.integer) or not 0 <= k < n:
            raise IndexError(f"k must be a failure sample index in 0 .. {n - 1}, got {k!r}")
        if self.model is None:
            raise ValueError(
                "flight(k) re-flies a failure of a scenario run; this result is of a "
                "limit_state function, which has no flight: its failure sample k is "
                "result.xi[k] and its value result.failures.loc[k]"
            )
        return self.model.fly(self.run.failure_xi[int(k)])

    # -- display --------------------------------------------------------------------------
    def _headline(self) -> str:
        run = self.run
        if run.probability is None:
            return (
                f"no failure found: P({self.value_name} > {run.threshold:g}) <= about "
                f"{run.upper_bound:.3g} (highest level reached; largest value {run.closest:.4g})"
            )
        lo, hi = self.interval or (math.nan, math.nan)
        return (
            f"P({self.value_name} > {run.threshold:g}) = {run.probability:.3g} "
            f"(cov {run.cov:.2f}, 95 % [{lo:.3g}, {hi:.3g}])"
        )

    def __repr__(self) -> str:
        run = self.run
        return (
            f"<RareEventResult {self._headline()}; {len(run.levels)} levels, {run.flights} "
            f"flights, {len(run.failure_values)} failure samples, {run.dimension} dimensions, "
            f"p0 {run.p0:g}, {run.per_level} per level, seed {run.seed}>"
        )

    def _repr_html_(self) -> str:
        """The headline and the levels table, for notebooks."""
        head = html.escape(self._headline())
        meta = html.escape(
            f"{self.run.flights} flights, {self.run.dimension} dimensions, p0 {self.run.p0:g}, "
            f"{self.run.per_level} per level, seed {self.run.seed}"
        )
        return f"<p><b>{head}</b><br>{meta}</p>" + self.levels.to_html(index=False)


@dataclass
class RareEventComparison:
    """Paired runs: one subset simulation per controller (or model) on the same seed, so
    level 0 flies the very same samples and the chains draw the same proposal normals.
    ``results``: name -> :class:`RareEventResult`. :meth:`ratio` compares two of them."""

    results: Mapping[str, RareEventResult]

    def __getitem__(self, name: str) -> RareEventResult:
        return self.results[name]

    def ratio(self, a: str, b: str, confidence: float = 0.95) -> dict[str, Any]:
        """P_a / P_b with an interval on the log scale from both coefficients of variation,
        taken as independent (the runs share their first level, which correlates them
        positively and makes this interval conservative). None values when either run found
        no failure."""
        for name in (a, b):
            if name not in self.results:
                raise KeyError(f"{name!r} is not one of {sorted(self.results)}")
        ra, rb = self.results[a].run, self.results[b].run
        if ra.probability is None or rb.probability is None or ra.cov is None or rb.cov is None:
            return {"ratio": None, "low": None, "high": None}
        from scipy.stats import norm

        z = float(norm.ppf(0.5 + confidence / 2))
        s = math.sqrt(math.log1p(ra.cov**2) + math.log1p(rb.cov**2))
        r = ra.probability / rb.probability
        return {"ratio": r, "low": r * math.exp(-z * s), "high": r * math.exp(z * s)}

    def __repr__(self) -> str:
        parts = ", ".join(
            f"{k}: {'none found' if v.probability is None else f'{v.probability:.3g}'}"
            for k, v in self.results.items()
        )
        return f"<RareEventComparison {parts}>"
