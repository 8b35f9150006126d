"""What a run of subset simulation (:mod:`quadrs.rare.subset`) is made of and reports: the
batched model it samples, its tuning constants, one level (:class:`Level`), the run
(:class:`SubsetRun`), and the checks of its settings and threshold."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from quadrs.engine.calls import check_int

#: A batched model: (N, n) standard normals -> (N,) values (failure: value > threshold).
Model = Callable[[np.ndarray], npt.ArrayLike]

#: The acceptance rate the proposal's step is steered to (Papaioannou et al. 2015: 0.44).
TARGET_ACCEPTANCE = 0.44
#: The proposal's step sigma on the first conditional level (Papaioannou et al.: 0.6).
INITIAL_SPREAD = 0.6
#: Fewest chains (seeds) per level: with fewer, the chains' correlation (and so the coefficient
#: of variation) is too poorly estimated to trust.
MIN_SEEDS = 10
#: Default deepest level: enough levels to reach probabilities of about 1e-12.
SMALLEST_PROBABILITY = 1e-12


@dataclass(frozen=True)
class Level:
    """One level of a run. ``threshold``: the cut this level's samples set (the target
    threshold on the last level); ``conditional_p``: the fraction of the level's samples above
    it (``above`` of ``per_level``); ``acceptance_rate``: of the chains' moves (NaN on level 0,
    plain Monte Carlo); ``flights``: model evaluations spent on the level; ``gamma``: the
    chains' correlation factor of Au & Beck; ``cov``: the coefficient of variation of
    ``conditional_p``; ``sigma``: the proposal's step (NaN on level 0)."""

    level: int
    threshold: float
    conditional_p: float
    above: int
    acceptance_rate: float
    flights: int
    gamma: float
    cov: float
    sigma: float


@dataclass
class SubsetRun:
    """What one run of :func:`subset_simulation` found (see :class:`RareEventResult` for the
    user-facing form). ``probability``/``cov`` are None when no failure was found; then
    ``upper_bound`` is the estimated probability of the highest level reached, which the
    failure probability does not exceed. Failure samples are those of the last level, each
    chain state once (``copies``: how many of the level's samples it stands for)."""

    probability: float | None
    cov: float | None
    upper_bound: float | None
    levels: list[Level]
    flights: int
    failure_xi: np.ndarray
    failure_values: np.ndarray
    failure_copies: np.ndarray
    failure_chain: np.ndarray
    failure_step: np.ndarray
    closest: float
    dimension: int
    threshold: float
    per_level: int
    p0: float
    seed: int
    max_levels: int
    #: True if Ctrl-C stopped the run: ``levels`` are the levels done, ``upper_bound`` the
    #: estimated probability of the last cut they set (None before the first), no estimate.
    interrupted: bool = False
    #: Level 0's samples above its cut (the threshold if it was the last level), in the order
    #: drawn: paired runs share level 0, and their ratio's interval uses its correlation.
    first_above: np.ndarray | None = None
    #: The 95 % interval (or, with no failure, (0, the 95 % upper confidence bound)), inside
    #: [0, 1]; None when interrupted. See :func:`subset_simulation`.
    interval: tuple[float, float] | None = None
    #: Flights of the pilot run that placed the levels (included in ``flights``).
    pilot_flights: int = 0
    #: Independent ancestries (level-0 samples) the failures descend from; the interval's t
    #: quantile has ``clusters - 1`` degrees of freedom.
    clusters: int = 0

    @property
    def reached(self) -> bool:
        """True if samples above the threshold were found (the estimate is then a number)."""
        return self.probability is not None


def check_settings(per_level: object, p0: object, max_levels: object) -> tuple[int, float, int]:
    """(per_level, p0, max_levels) checked: p0 = 1/L for a whole number L >= 2 (chains of equal
    length L), p0 * per_level a whole number of at least MIN_SEEDS chains; ValueError naming
    the argument otherwise. ``max_levels`` None: enough levels to reach about 1e-12."""
    if isinstance(p0, bool) or not isinstance(p0, int | float) or not 0 < p0 <= 0.5:
        raise ValueError(f"p0 must be a number in (0, 0.5], got {p0!r}")
    p0 = float(p0)
    length = round(1.0 / p0)
    if abs(length * p0 - 1.0) > 1e-12:
        raise ValueError(
            f"p0 must be 1/L for a whole number L (each seed starts a chain of L samples), "
            f"got {p0!r}; e.g. 0.1, 0.2, 0.25 or 0.5"
        )
    per_level = check_int("per_level", per_level, 1, 2**40)
    if per_level % length:
        raise ValueError(
            f"per_level must be a multiple of 1/p0 = {length} (p0 * per_level seeds, whole), "
            f"got per_level = {per_level}"
        )
    if per_level // length < MIN_SEEDS:
        raise ValueError(
            f"per_level = {per_level} with p0 = {p0} gives {per_level // length} seeds per level; "
            f"at least {MIN_SEEDS} are needed: raise per_level to {MIN_SEEDS * length} or more"
        )
    if max_levels is None:
        max_levels = max(1, math.ceil(math.log(SMALLEST_PROBABILITY) / math.log(p0)))
    max_levels = check_int("max_levels", max_levels, 1, 1000)
    return per_level, p0, max_levels


def check_threshold(threshold: object) -> float:
    """``threshold`` as a finite float, else ValueError naming it."""
    if isinstance(threshold, bool) or not isinstance(threshold, int | float | np.floating):
        raise ValueError(f"threshold must be a number, got {threshold!r}")
    if not math.isfinite(threshold):
        raise ValueError(f"threshold must be finite, got {threshold!r}")
    return float(threshold)
