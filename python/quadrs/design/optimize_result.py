"""What :func:`quadrs.design.optimize.optimize` finds: :class:`OptimizeResult` (the best
candidate, the search's history, the untuned baseline beside it) and :class:`Holdout` (the best
re-evaluated on fresh seeds), with the pieces that build them from the flights: the choice of
the best row, the per-phase effects of the tuning and the held-out interval."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from quadrs.design.constraints import Constraint
from quadrs.engine.calls import U64_MAX
from quadrs.runs.montecarlo_result import MonteCarloResult
from quadrs.scenario.scenario import Scenario

#: Offset of the held-out seed from the tuning seed.
HOLDOUT_SEED_OFFSET = 1_000_003
#: Groups the held-out realisations are split into for a callable objective's interval.
HOLDOUT_BATCHES = 8

Objective = str | Callable[[MonteCarloResult], float]


def holdout_seed(seed: int) -> int:
    """The seed the best candidate is re-evaluated on: ``seed + HOLDOUT_SEED_OFFSET``,
    wrapping within the 64-bit seeds (a seed near 2**64 still has one)."""
    return (seed + HOLDOUT_SEED_OFFSET) % (U64_MAX + 1)


class InfeasibleWarning(UserWarning):
    """No candidate met every constraint: the result holds the least-violating one."""


@dataclass(frozen=True)
class Holdout:
    """The best candidate re-evaluated on fresh seeds: ``objective`` with a 95 % interval.

    For a metric objective the interval is Student's t over the per-realisation values; for a
    callable one, over the callable's values on ``HOLDOUT_BATCHES`` disjoint groups of
    realisations (batch means). ``diverged``: realisations that diverged.
    """

    seed: int
    runs: int
    objective: float
    low: float
    high: float
    diverged: int


@dataclass(frozen=True)
class OptimizeResult:
    """What :func:`optimize` found.

    ``best``: {key: value} of the best candidate; ``objective``: its value on the tuning seed;
    ``scenario``: the input scenario with ``best`` applied; ``history``: one row per evaluation
    (``evaluation``, every parameter key, ``objective``, ``stable`` (in every mode),
    ``max_real`` (largest pole real part among the modes the scenario excites, 1/s), ``flown``,
    ``diverged`` (realisations), ``penalised``, ``unstable_modes`` (the excited modes that are
    not stable, e.g. "SMC lateral x/pitch +1.31 ± 3.90j"; "" if none)); ``holdout``: see
    :class:`Holdout` (None if interrupted); ``interrupted``: stopped by Ctrl-C, the best so
    far is kept. ``baseline``: the objective of the untuned input scenario on the tuning seed
    (NaN if its flights diverged or the run was interrupted); ``phase_effects`` (metric
    objectives): per phase, the metric's mean untuned and tuned on the tuning seed, the paired
    change with its 95 % interval and ``worse`` (the interval lies above 0), so a phase
    outside the objective that the tuning made worse shows.

    With ``constraints``: ``history`` has, per constraint, a column named by its statistic
    (e.g. ``P(max_accel>8)``: the value on the tuning seed) and one named by the constraint
    (e.g. ``P(max_accel>8)<=0.01``: met or not), and ``feasible`` (every one met; False for a
    candidate not flown); ``score`` is what the optimiser minimised (the objective, or a
    penalty); ``role`` is "best" on the chosen row, "baseline" on the last row (the untuned
    scenario on the same seed, flown whatever its stability, never a candidate), else "".
    ``feasible`` (the result's): the best met every constraint; when no candidate did, it is
    the least violating one, ``feasible`` is False and an :class:`InfeasibleWarning` is given.
    ``holdout_constraints``: every constraint re-checked on the held-out flights, per
    controller and phase, with its 95 % interval (:meth:`Constraint.check`).
    """

    best: dict[str, float]
    objective: float
    scenario: Scenario
    history: pd.DataFrame = field(repr=False)
    holdout: Holdout | None
    interrupted: bool
    method: str
    seed: int
    runs: int
    baseline: float = math.nan
    phase_effects: pd.DataFrame | None = field(default=None, repr=False)
    constraints: tuple[Constraint, ...] = ()
    feasible: bool = True
    holdout_constraints: pd.DataFrame | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        """The best values and objective, not the history."""
        best = ", ".join(f"{k}={v:.4g}" for k, v in self.best.items())
        note = ", interrupted" if self.interrupted else ""
        if not self.feasible:
            note += ", NO FEASIBLE CANDIDATE (this is the least violating)"
        searched = len(self.evaluations)
        return (
            f"<OptimizeResult {best}: objective {self.objective:.4g} after "
            f"{searched} evaluations{note}>"
        )

    @property
    def evaluations(self) -> pd.DataFrame:
        """The search's own rows of ``history`` (the baseline row left out)."""
        h = self.history
        return h[h["role"] != "baseline"] if "role" in h else h

    @property
    def comparison(self) -> pd.DataFrame:
        """The untuned baseline (the scenario's own values) beside the best candidate: their
        rows of ``history`` indexed by ``role`` (parameters, objective, every constraint's
        value and whether it is met, ``feasible``). No baseline row if interrupted."""
        h = self.history
        if "role" not in h:  # a history written before the baseline row existed
            return h.iloc[:0]
        return h[h["role"].isin(["baseline", "best"])].set_index("role").sort_index()

    def _repr_html_(self) -> str:
        """In a notebook: best values, objective beside the untuned one and the holdout, and
        the per-phase effects, as HTML."""
        from quadrs.present.html import render

        values = pd.DataFrame({"value": self.best}).rename_axis("key")
        ho = self.holdout
        scores = pd.DataFrame(
            {
                "objective": [self.objective, self.baseline, ho.objective if ho else math.nan],
                "ci_low": [math.nan, math.nan, ho.low if ho else math.nan],
                "ci_high": [math.nan, math.nan, ho.high if ho else math.nan],
            },
            index=["best (tuning seed)", "untuned (tuning seed)", "best (held-out seed)"],
        )
        tables = [("best values", values), ("objective", scores)]
        if self.phase_effects is not None:
            tables.append(("per phase, untuned -> tuned (same gusts)", self.phase_effects))
        if self.constraints and not self.comparison.empty:
            tables.append(("untuned and best on the tuning seed", self.comparison.T))
        if self.holdout_constraints is not None:
            tables.append(("constraints on the held-out seed", self.holdout_constraints))
        return render(repr(self), tables)


def choose_best(history: pd.DataFrame) -> tuple[Any, bool]:
    """The best row's label and whether it is feasible: the least objective among the feasible
    candidates flown without penalty; if there is none, the least violation (then objective)
    among those flown without penalty; if none was, the least score (as without
    constraints)."""
    admissible = history[~history["penalised"].astype(bool)]
    ok = admissible[admissible["feasible"].astype(bool)]
    if not ok.empty:
        return ok["objective"].idxmin(), True
    if admissible.empty:
        return history["score"].idxmin(), bool(history["feasible"].all())
    order = admissible.sort_values(["violation", "objective"], kind="stable")
    return order.index[0], False


def phase_effects(
    before: MonteCarloResult, after: MonteCarloResult, metric: str, confidence: float = 0.95
) -> pd.DataFrame:
    """Per phase (rows) of one controller's batches flown on the same gusts: the mean of
    ``metric`` ``untuned`` and ``tuned``, ``change`` (paired mean difference) with its
    Student-t interval ``ci_low``/``ci_high``, ``change_pct`` and ``worse`` (the interval
    lies above 0). Realisations that diverged in a phase in either batch are left out of it."""
    from scipy import stats

    def wide(mc: MonteCarloResult) -> pd.DataFrame:
        return mc.runs.pivot(index="realisation", columns="phase", values=metric)

    a, b = wide(before), wide(after)
    rows = []
    for phase in before.scenario.phase_names:
        x, y = a[phase].to_numpy(float), b[phase].to_numpy(float)
        ok = np.isfinite(x) & np.isfinite(y)
        d = y[ok] - x[ok]
        mean = float(d.mean()) if d.size else math.nan
        half = (
            float(stats.t.ppf(0.5 + confidence / 2, d.size - 1) * d.std(ddof=1) / np.sqrt(d.size))
            if d.size >= 2
            else math.nan
        )
        untuned = float(x[ok].mean()) if d.size else math.nan
        rows.append({
            "phase": phase,
            "untuned": untuned,
            "tuned": float(y[ok].mean()) if d.size else math.nan,
            "change": mean,
            "ci_low": mean - half,
            "ci_high": mean + half,
            "change_pct": 100 * mean / untuned if untuned else math.nan,
            "worse": bool(mean - half > 0),
        })  # fmt: skip
    return pd.DataFrame(rows).set_index("phase")


def holdout_of(
    mc: MonteCarloResult,
    objective: Objective,
    phases: Sequence[str],
    seed: int,
    count: int,
    score: Callable[[MonteCarloResult], tuple[float, int, np.ndarray | None]],
) -> Holdout:
    from scipy import stats

    value, diverged, values = score(mc)
    if values is not None:
        ok = values[np.isfinite(values)]
        value = float(np.mean(ok)) if ok.size else math.nan
        samples = ok
    else:
        real = mc.realisations
        groups = np.array_split(real, min(HOLDOUT_BATCHES, real.size))
        samples = np.array(
            [float(objective(_subset(mc, g))) for g in groups if g.size]  # type: ignore[operator]
        )
    if samples.size >= 2 and np.all(np.isfinite(samples)):
        sem = float(stats.sem(samples))
        low, high = (
            stats.t.interval(0.95, samples.size - 1, loc=float(np.mean(samples)), scale=sem)
            if sem > 0
            else (value, value)
        )
        if values is None:  # centre the batch-means interval on the full-sample value
            half = (high - low) / 2
            low, high = value - half, value + half
    else:
        low = high = math.nan
    return Holdout(
        seed=seed, runs=count, objective=value, low=float(low), high=float(high), diverged=diverged
    )


def _subset(mc: MonteCarloResult, realisations: np.ndarray) -> MonteCarloResult:
    runs = mc.runs[mc.runs["realisation"].isin(realisations)].reset_index(drop=True)
    return MonteCarloResult(
        scenario=mc.scenario, seed=mc.seed, controllers=mc.controllers, runs=runs
    )
