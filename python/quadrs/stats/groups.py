"""The analysis every result with a tidy ``runs`` table answers the same way: the paper's
summary, exceedance probabilities and quantiles, per group of runs. A Monte Carlo result is
one group; a sweep has one group per grid point, its swept keys leading every table."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pandas as pd

from quadrs.io.integrity import RunRecord
from quadrs.stats.summary import summarise

__all__ = ["RunTables"]

#: One group of runs: the values naming it (empty for a single batch), its rows, its phases.
Group = tuple[dict[str, Any], pd.DataFrame, list[str]]


class RunTables:
    """Summary, exceedance and quantile tables over ``runs``, computed per group
    (:meth:`_groups`); the results that hold runs (:class:`quadrs.MonteCarloResult`,
    :class:`quadrs.SweepResult`) inherit them, so both answer with the same columns."""

    runs: pd.DataFrame
    controllers: tuple[str, ...]
    interrupted: bool

    @property
    def record(self) -> RunRecord:
        raise NotImplementedError

    def _group_keys(self) -> list[str]:
        """The columns naming a group (none for a single batch)."""
        return []

    def _groups(self) -> Iterator[Group]:
        raise NotImplementedError

    def metadata(self) -> dict[str, Any]:
        """What produced this result and its run identity, as its saved file records them."""
        return self.record.metadata(interrupted=self.interrupted)

    def _per_group(self, table: Callable[[pd.DataFrame, list[str]], pd.DataFrame]) -> pd.DataFrame:
        """``table(runs, phases)`` of each group, the group's keys prepended as columns."""
        keys = self._group_keys()
        parts = []
        for named, runs, phases in self._groups():
            part = table(runs, phases)
            if not keys:
                return part
            for k in reversed(keys):
                part.insert(0, k, named[k])
            parts.append(part)
        if not parts:
            raise ValueError("the result holds no finished runs")
        return pd.concat(parts, ignore_index=True)

    def summary(self, confidence: float = 0.95) -> pd.DataFrame:
        """The paper's Table 3 and more: for each (metric, phase), per controller the mean and
        its confidence interval, and P = 100 * mean(SMC) / mean(PD) with a paired CI; per
        group, its keys leading the index."""
        keys = self._group_keys()

        def one(runs: pd.DataFrame, phases: list[str]) -> pd.DataFrame:
            table = summarise(runs, self.controllers, phases, confidence)
            return table.reset_index() if keys else table

        table = self._per_group(one)
        return table.set_index([*keys, "metric", "phase"]) if keys else table

    def exceedance(
        self,
        metric: str,
        threshold: float,
        confidence: float = 0.95,
        *,
        paired: bool = False,
        controllers: tuple[str, str] = ("smc", "pd"),
        half_width: float = 0.01,
        relative: bool = False,
    ) -> pd.DataFrame:
        """P(metric > threshold) per controller and phase with an exact (Clopper-Pearson)
        interval, the counts behind it and ``runs_needed`` for an interval half-width of
        ``half_width`` (default 0.01: +-1 percentage point; with ``relative``, a fraction of the
        probability). Diverged realisations count as exceedances (column ``diverged``) from
        the phase in which they diverged on.

        ``paired=True``: instead, per phase, P(a exceeds) - P(b exceeds) for ``controllers =
        (a, b)`` on the same gusts, with Newcombe's paired interval and McNemar's exact test.
        See :mod:`quadrs.stats.risk` and docs/risk.md."""
        from quadrs.stats import risk

        if paired:
            pair = risk.check_pair(self.controllers, controllers)
            return self._per_group(
                lambda runs, phases: risk.exceedance_difference_table(
                    runs, metric, threshold, phases, pair, confidence
                )
            )
        return self._per_group(
            lambda runs, phases: risk.exceedance_table(
                runs, metric, threshold, self.controllers, phases, confidence, half_width, relative
            )
        )

    def quantile(
        self,
        metric: str,
        q: float,
        confidence: float = 0.95,
        *,
        paired: bool = False,
        controllers: tuple[str, str] = ("smc", "pd"),
    ) -> pd.DataFrame:
        """The ``q``-quantile of ``metric`` per controller and phase with a distribution-free
        (order-statistic) interval; diverged realisations count as +inf. ``paired=True``: per
        phase, the ``q``-quantile of the per-realisation difference a - b instead."""
        from quadrs.stats import risk

        if paired:
            pair = risk.check_pair(self.controllers, controllers)
            return self._per_group(
                lambda runs, phases: risk.quantile_difference_table(
                    runs, metric, q, phases, pair, confidence
                )
            )
        return self._per_group(
            lambda runs, phases: risk.quantile_table(
                runs, metric, q, self.controllers, phases, confidence
            )
        )
