"""Subset simulation (Au & Beck 2001) with a preconditioned Crank-Nicolson conditional sampler
whose step is adapted as in Papaioannou et al. (2015), on any batched model of standard
normals. Independent of the engine.

A *model* maps an (N, n) array of independent standard normals to N values; failure is
``value > threshold``. Every call the sampler makes has ``p0 * per_level`` rows (the chains'
candidates of one step; level 0 is drawn in blocks of the same size), so a model that flies
flights can fly each call as one batch.

Memory stays bounded by a few times ``p0 * per_level * n`` numbers: the chains' states, their
candidates and the running best ``p0 * per_level`` samples of the level (the next level's
seeds), plus the failure samples of the level in progress (the final level's are kept).
Every evaluation's value is kept only until its level's statistics are done.

See docs/rare-events.md for the method, its assumptions and its cost.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from quadrs.engine.calls import check_int, check_memory

__all__ = [
    "CONFIDENCE",
    "MIN_SEEDS",
    "TARGET_ACCEPTANCE",
    "Level",
    "Model",
    "SubsetRun",
    "check_settings",
    "check_threshold",
    "pilot_size",
    "subset_simulation",
]

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
#: Bytes one float64 takes.
_F8 = 8


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


class _Evaluator:
    """Calls the model on a block, checks what it returns, counts the evaluations."""

    def __init__(self, model: Model, name: str) -> None:
        self.model = model
        self.name = name
        self.count = 0

    def __call__(self, xi: np.ndarray) -> np.ndarray:
        values = np.asarray(self.model(xi), dtype=np.float64)
        if values.shape != (xi.shape[0],):
            raise ValueError(
                f"{self.name} must return one value per row: shape ({xi.shape[0]},) for input "
                f"{xi.shape}, got {values.shape}"
            )
        bad = np.isnan(values)
        if bad.any():
            raise ValueError(
                f"{self.name} returned NaN for {int(bad.sum())} of {len(values)} rows (e.g. row "
                f"{int(np.argmax(bad))}); it must return a number (or +-inf) for every row"
            )
        self.count += len(values)
        return values


class _Best:
    """The ``size`` samples of largest value seen in a level so far (ties: earliest first)."""

    def __init__(self, size: int, dimension: int) -> None:
        self.xi = np.empty((size, dimension))
        self.values = np.full(size, -np.inf)
        self.filled = 0

    def offer(self, xi: np.ndarray, values: np.ndarray) -> None:
        size = len(self.values)
        pool = np.concatenate([self.values[: self.filled], values])
        # Stable order of -value: equal values keep the earlier one first.
        keep = np.argsort(-pool, kind="stable")[:size]
        old = keep[keep < self.filled]
        new = keep[keep >= self.filled] - self.filled
        free = np.setdiff1d(np.arange(size), old)[: len(new)]
        self.xi[free] = xi[new]
        self.values[free] = values[new]
        self.filled = min(size, self.filled + len(values))


_Arrays = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


def _none(dimension: int) -> _Arrays:
    """No failure samples: (xi, values, copies, chain, step), all empty."""
    ints = np.empty(0, dtype=np.int64)
    return np.empty((0, dimension)), np.empty(0), ints, ints, ints


class _Failures:
    """The failure samples of the level in progress: each chain state once, with ``copies``,
    the number of the level's samples that are that state (a chain that stays repeats it)."""

    def __init__(self, chains: int, capacity: int) -> None:
        self.xi: list[np.ndarray] = []
        self.values: list[np.ndarray] = []
        self.chain: list[np.ndarray] = []
        self.step: list[np.ndarray] = []
        self.copies = np.zeros(capacity, dtype=np.int64)
        self.count = 0
        self.record_of = np.full(chains, -1)  # each chain's latest record

    def add(
        self, xi: np.ndarray, values: np.ndarray, chain: np.ndarray, step: int, track: bool = True
    ) -> None:
        """New failure states of chains ``chain`` (``track=False`` on level 0, where ``chain``
        holds the samples' indices and no state is held)."""
        k = len(values)
        if k:
            # Callers pass fresh arrays (boolean-indexed), kept as they are.
            self.xi.append(xi)
            self.values.append(values)
            self.chain.append(chain)
            self.step.append(np.full(k, step))
            index = np.arange(self.count, self.count + k)
            self.copies[index] = 1
            if track:
                self.record_of[chain] = index
            self.count += k

    def hold(self, chains: np.ndarray) -> None:
        """``chains`` stayed in their failure state: one more copy of each."""
        self.copies[self.record_of[chains]] += 1

    def arrays(self, dimension: int) -> _Arrays:
        """(xi, values, copies, chain, step) of the records."""
        if not self.values:
            return _none(dimension)
        return (
            np.concatenate(self.xi),
            np.concatenate(self.values),
            self.copies[: self.count].copy(),
            np.concatenate(self.chain).astype(np.int64),
            np.concatenate(self.step).astype(np.int64),
        )


def chain_gamma(indicator: np.ndarray, groups: np.ndarray | None = None) -> float:
    """Au & Beck's correlation factor gamma of an estimate that averages ``indicator``
    (shape (L, chains): sample l of each chain): Var = p (1 - p) / N * (1 + gamma).

    Along each chain, from the pooled lag-k autocovariance R(k):
    gamma = 2 sum_{k=1}^{L-1} (1 - k/L) R(k) / R(0). Chains in the same ``groups`` entry
    (started from copies of one state) add their cross-covariance, estimated from the
    products of their sums' deviations (Au & Beck's chains are independent: no such term)."""
    steps, chains = indicator.shape
    total = steps * chains
    p = float(indicator.mean())
    r0 = p * (1.0 - p)
    if r0 <= 0.0:
        return 0.0
    ind = indicator.astype(np.float64)
    gamma = 0.0
    for k in range(1, steps):
        rk = float((ind[:-k] * ind[k:]).sum()) / (total - k * chains) - p * p
        gamma += 2.0 * (1.0 - k / steps) * rk / r0
    if groups is not None:
        dev = ind.sum(axis=0) - steps * p  # each chain's sum, centred
        by_group = np.bincount(groups, weights=dev)
        # sum over ordered pairs of distinct chains in a group = (sum)^2 - sum of squares
        cross = float((by_group**2).sum() - (dev**2).sum())
        gamma += cross / (total * r0)
    return gamma


def _groups(seed_values: np.ndarray) -> np.ndarray:
    """Chains whose seeds have the same value (copies of one state) share a group number."""
    return np.unique(seed_values, return_inverse=True)[1].ravel()


def _cut(values: np.ndarray, seeds: int, threshold: float) -> tuple[float, int]:
    """The level's cut between the ``seeds``-th largest value and the next smaller distinct
    one, and how many values lie above it (``seeds``, or more where repeated chain states tie
    at the cut). ValueError if no value lies below the ``seeds``-th largest (an atom)."""
    ordered = np.sort(values)[::-1]
    w = ordered[seeds - 1]
    lower = ordered[ordered < w]
    if len(lower) == 0:
        tied = int((values == w).sum())
        raise ValueError(
            f"the model's values have an atom: {tied} of {len(values)} samples of a level share "
            f"the value {w!r}, so no level can be cut there on the way to threshold = "
            f"{threshold!r} (a constant model; a metric that is 0 for most flights; one that "
            f"saturates below the threshold, which it can then never exceed)"
        )
    below = lower[0]
    cut = 0.5 * (w + below) if np.isfinite(w) else np.nextafter(below, np.inf)
    if not np.isfinite(cut):  # w = +inf and below = +-huge: any number between works
        cut = below
    return float(cut), int((values > cut).sum())


def _lognormal_s(cov: float) -> float:
    return math.sqrt(math.log1p(cov * cov))


def _move(
    rng: np.random.Generator,
    evaluate: _Evaluator,
    state: np.ndarray,
    value: np.ndarray,
    candidate: np.ndarray,
    sigma: float,
    rho: float,
    cut: float,
) -> np.ndarray:
    """One preconditioned Crank-Nicolson step of every chain, in place: candidate =
    rho x + sigma z, kept where its value lies above ``cut``; returns which chains moved.
    ``candidate`` is the only temporary of the chains' size."""
    rng.standard_normal(out=candidate)
    candidate *= sigma
    candidate += rho * state
    v = evaluate(candidate)
    move = v > cut
    state[move] = candidate[move]
    value[move] = v[move]
    return move


def _adaptive(
    evaluate: _Evaluator,
    dimension: int,
    threshold: float,
    per_level: int,
    p0: float,
    seed: int,
    max_levels: int,
    rng: np.random.Generator,
) -> SubsetRun:
    """The adaptive subset simulation of Au & Beck (2001), used as the pilot that places the
    levels: each cut between the (p0 N)-th largest value of its level and the next; chains of
    1/p0 samples started from the level's best p0 N by preconditioned Crank-Nicolson, sigma
    steered between levels towards TARGET_ACCEPTANCE, the same in every component (scaling it
    per component by the seeds' spread biases a sum-of-squares tail low five-fold in 1000
    dimensions: docs/rare-events.md). Its own estimate is biased (order 1/N per level) and is
    not reported: only its cuts and steps are used."""
    length = round(1.0 / p0)
    seeds = per_level // length
    levels: list[Level] = []
    spread = INITIAL_SPREAD
    seeds_xi = np.empty((0, dimension))
    seeds_val = np.empty(0)
    cov2 = 0.0
    product = 1.0
    closest = -math.inf
    first_above: np.ndarray | None = None

    def result(estimate: tuple[float, float] | None, bound: float | None,
               failed: _Arrays, interrupted: bool = False) -> SubsetRun:  # fmt: skip
        fx, fv, fc, fch, fst = failed
        return SubsetRun(
            first_above=first_above,
            probability=None if estimate is None else estimate[0],
            cov=None if estimate is None else estimate[1],
            upper_bound=bound,
            levels=levels,
            flights=evaluate.count,
            failure_xi=fx,
            failure_values=fv,
            failure_copies=fc,
            failure_chain=fch,
            failure_step=fst,
            closest=closest,
            dimension=dimension,
            threshold=threshold,
            per_level=per_level,
            p0=p0,
            seed=seed,
            max_levels=max_levels,
            interrupted=interrupted,
        )

    try:
        for level in range(max_levels):
            best = _Best(seeds, dimension)
            failures = _Failures(seeds, per_level)
            values = np.empty((length, seeds))  # sample l of chain c (level 0: block l, row c)
            accepted = 0
            if level == 0:
                for block in range(length):
                    xi = rng.standard_normal((seeds, dimension))
                    v = evaluate(xi)
                    values[block] = v
                    best.offer(xi, v)
                    hit = v > threshold
                    failures.add(xi[hit], v[hit], np.flatnonzero(hit) + block * seeds, 0, False)
            else:
                state = seeds_xi  # the previous level's best: ours to move in place
                value = seeds_val.copy()
                cut = levels[-1].threshold
                sigma = spread
                rho = math.sqrt(1.0 - sigma * sigma)
                values[0] = value
                best.offer(state, value)
                hit = value > threshold
                failures.add(state[hit], value[hit], np.flatnonzero(hit), 0)
                candidate = np.empty_like(state)
                for step in range(1, length):
                    move = _move(rng, evaluate, state, value, candidate, sigma, rho, cut)
                    accepted += int(move.sum())
                    values[step] = value
                    best.offer(state, value)
                    # A chain's failure state is recorded when reached, then its copies counted.
                    new = move & (value > threshold)
                    held = ~move & (value > threshold)
                    failures.add(state[new], value[new], np.flatnonzero(new), step)
                    failures.hold(np.flatnonzero(held))
            flat = values.ravel()
            closest = max(closest, float(flat.max()))
            n_fail = int((flat > threshold).sum())
            rate = accepted / (seeds * (length - 1)) if level else math.nan
            last = n_fail >= seeds or level == max_levels - 1
            # The last level's fraction is of the threshold itself (when anything crossed it).
            cut, above = (threshold, n_fail) if last and n_fail else _cut(flat, seeds, threshold)
            p = above / per_level
            if level == 0:
                first_above = flat > cut
            # Chains started from copies of one state (a repeated chain state among the seeds)
            # are correlated with each other, not only along themselves: group them by seed.
            gamma = chain_gamma(values > cut, _groups(values[0])) if level else 0.0
            cov_level = math.sqrt((1.0 - p) / (per_level * p) * (1.0 + gamma))
            flights = per_level if level == 0 else seeds * (length - 1)
            levels.append(Level(level, cut, p, above, rate, flights, gamma, cov_level,
                                spread if level else math.nan))  # fmt: skip
            if last:
                if not n_fail:
                    return result(None, product * p, _none(dimension))
                estimate = (product * p, math.sqrt(cov2 + cov_level**2))
                return result(estimate, None, failures.arrays(dimension))
            cov2 += cov_level**2
            product *= p
            if level:
                # Steer the step towards the target acceptance (Papaioannou et al.'s rule, applied
                # once per level so that every chain of a level moves by the same kernel).
                spread = min(spread * math.exp(rate - TARGET_ACCEPTANCE), 1.0)
            seeds_xi, seeds_val = best.xi, best.values
    except KeyboardInterrupt:
        # Keep what the finished levels found: the probability of the last cut they set.
        bound = math.prod(lv.conditional_p for lv in levels) if levels else None
        return result(None, bound, _none(dimension), interrupted=True)
    raise AssertionError("unreachable: the last level returns")  # pragma: no cover


#: Confidence of every interval and bound the sampler states.
CONFIDENCE = 0.95


def pilot_size(per_level: int, p0: float) -> int:
    """The pilot's samples per level: a fifth of ``per_level``, a whole number of chains, and
    at least MIN_SEEDS of them."""
    length = round(1.0 / p0)
    return max(MIN_SEEDS * length, (per_level // 5) // length * length)


class _Reservoir:
    """A uniform random subset (without replacement) of the samples offered, of at most
    ``size``; with fewer offered, all of them. Each survivor of a level is then equally
    likely to seed the next one, which keeps the product of the levels' fractions unbiased."""

    def __init__(self, size: int, dimension: int, rng: np.random.Generator) -> None:
        self.xi = np.empty((size, dimension))
        self.values = np.empty(size)
        self.eve = np.empty(size, dtype=np.int64)
        self.seen = 0
        self.rng = rng

    def offer(self, xi: np.ndarray, values: np.ndarray, eve: np.ndarray, up: np.ndarray) -> None:
        """Offer the rows ``up`` (a mask) of ``xi``, ``values``, ``eve``, one at a time (no
        copy of the block)."""
        size = len(self.values)
        for i in np.flatnonzero(up):
            slot = self.seen if self.seen < size else int(self.rng.integers(0, self.seen + 1))
            if slot < size:
                self.xi[slot] = xi[i]
                self.values[slot] = values[i]
                self.eve[slot] = eve[i]
            self.seen += 1

    def seeds(self, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``count`` seeds (xi, values, eve, group): each held sample floor(count / held)
        times, a random subset of them once more (so each is picked count / held times on
        average); ``group`` numbers the held sample a seed copies."""
        held = min(self.seen, len(self.values))
        base = np.repeat(np.arange(held), count // held)
        extra = self.rng.choice(held, size=count - len(base), replace=False)
        pick = np.concatenate([base, extra])
        return self.xi[pick].copy(), self.values[pick].copy(), self.eve[pick].copy(), pick


def _steps_of(pilot: SubsetRun) -> list[float]:
    """The proposal's step on each conditional level of the main run: the pilot's own step
    on that level, and past its last, its rule applied once more."""
    steps = [lv.sigma for lv in pilot.levels[1:]]
    if len(pilot.levels) > 1:
        last = pilot.levels[-1]
        steps.append(min(last.sigma * math.exp(last.acceptance_rate - TARGET_ACCEPTANCE), 1.0))
    steps.append(INITIAL_SPREAD)
    return [x if math.isfinite(x) and 0 < x <= 1 else INITIAL_SPREAD for x in steps]


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


def subset_simulation(
    model: Model,
    dimension: int,
    threshold: float,
    *,
    per_level: int = 1000,
    p0: float = 0.1,
    seed: int = 0,
    max_levels: int | None = None,
    name: str = "the model",
    on_level: Callable[[Level], None] | None = None,
    pilot: int | None = None,
) -> SubsetRun:
    """Estimate P(model(xi) > threshold) for xi ~ N(0, I_dimension) by subset simulation,
    in two stages, so that the estimate is unbiased and its interval honest.

    1. A *pilot*: adaptive subset simulation (Au & Beck 2001) with ``pilot`` samples per level
       (default :func:`pilot_size`, a fifth of ``per_level``) places the levels b_1 < b_2 < ...
       below the threshold and the proposal's step on each. Its estimate is discarded: with
       cuts set by the same samples that are counted, adaptive subset simulation reads high by
       order (levels (1 - p0)/(N p0)) (1 + gamma) (Cerou et al. 2012), 1.1-1.3x on flights at
       N = 500.
    2. The *main run*, with those levels fixed: level 0 is plain Monte Carlo of ``per_level``
       samples; each later level starts ``p0 * per_level`` chains from survivors of the level
       below (v > b_j), drawn uniformly among all of them, and moves them ``1/p0 - 1`` steps by
       preconditioned Crank-Nicolson (candidate = sqrt(1 - sigma^2) x + sigma z, kept if above
       b_j). The estimate, the product of the levels' fractions above their cuts, is then
       exactly unbiased (a Feynman-Kac particle estimate with fixed levels and kernels that
       leave each conditional law invariant; Del Moral 2004, Cerou et al. 2012).

    Its coefficient of variation is the larger of Au & Beck's (the levels' variances with
    the chains' correlation gamma, floored at 0, summed) and the spread of the failures over
    their independent ancestries: every failure descends from one level-0 sample, and the
    estimate is (1/N) sum_i Z_i over those iid samples (Z_i: N P times sample i's share of the
    failures; Chan & Lai 2013). The second sees what the first cannot: chains started from one
    state, and levels that share ancestors. The interval is lognormal with a t quantile on
    ``clusters - 1`` degrees of freedom (few ancestries, wide interval), its upper end at most
    1. One level (the threshold reached by plain Monte Carlo): the Clopper-Pearson interval.
    No failure: ``probability`` None and ``interval`` (0, a 95 % upper confidence bound).

    Evaluations: the pilot's plus ``per_level + (levels - 1) * per_level * (1 - p0)``.
    ``on_level(level)`` is called as each level of the main run is done. Ctrl-C (a
    KeyboardInterrupt from the model or between its calls) stops the run and returns what the
    finished levels found, with ``interrupted=True``.
    """
    per_level, p0, max_levels = check_settings(per_level, p0, max_levels)
    dimension = check_int("dimension", dimension, 1, 2**40)
    seed = check_int("seed", seed)
    threshold = check_threshold(threshold)
    length = round(1.0 / p0)
    if pilot is None:
        pilot = pilot_size(per_level, p0)
    pilot, _, _ = check_settings(pilot, p0, max_levels)
    seeds = per_level // length
    # Measured with tracemalloc (tests/guarantees/test_delivery_and_rare.py): about seven
    # chain-sized arrays of rows (states, candidates, the pilot's running best and its pool,
    # the seeds' reservoir);
    # per sample about eight numbers (the level's values, their copies, indicators, ancestries,
    # sort order, copy counts); and the failure samples, up to a whole level's rows, held
    # twice while joined.
    check_memory(
        f"subset simulation in {dimension} dimensions with {seeds} chains of {per_level} "
        f"samples a level",
        (7 * seeds * dimension + 8 * per_level + 2 * per_level * dimension) * _F8,
    )
    evaluate = _Evaluator(model, name)
    pilot_rng, main_rng = (np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(2))
    first = _adaptive(evaluate, dimension, threshold, pilot, p0, seed, max_levels, pilot_rng)
    pilot_flights = evaluate.count

    def run_of(**found: object) -> SubsetRun:
        base: dict[str, object] = dict(
            probability=None, cov=None, upper_bound=None, levels=[], flights=evaluate.count,
            failure_xi=np.empty((0, dimension)), failure_values=np.empty(0),
            failure_copies=np.empty(0, dtype=np.int64), failure_chain=np.empty(0, dtype=np.int64),
            failure_step=np.empty(0, dtype=np.int64), closest=-math.inf, dimension=dimension,
            threshold=threshold, per_level=per_level, p0=p0, seed=seed, max_levels=max_levels,
            pilot_flights=pilot_flights,
        )  # fmt: skip
        base.update(found)
        return SubsetRun(**base)  # type: ignore[arg-type]

    if first.interrupted:
        return run_of(interrupted=True, closest=first.closest)
    cuts = [lv.threshold for lv in first.levels if lv.threshold < threshold]
    if first.reached and len(cuts) >= 1 and first.levels[-1].conditional_p >= 0.5:
        # The pilot's last cut lies just below the threshold (most of its last level crossed):
        # a level there would spend a whole level's flights on a fraction near 1.
        cuts = cuts[:-1]
    # At most max_levels levels in all: the cuts, then the threshold.
    cuts = (
        cuts[: min(len(first.levels), max_levels) - 1] if first.reached else cuts[: max_levels - 1]
    )
    return _fixed(evaluate, dimension, threshold, cuts, _steps_of(first), per_level, p0,
                  main_rng, on_level, run_of)  # fmt: skip


def _fixed(
    evaluate: _Evaluator,
    dimension: int,
    threshold: float,
    cuts: list[float],
    steps: list[float],
    per_level: int,
    p0: float,
    rng: np.random.Generator,
    on_level: Callable[[Level], None] | None,
    run_of: Callable[..., SubsetRun],
) -> SubsetRun:
    """The main run of :func:`subset_simulation`: levels at ``cuts`` (then ``threshold``)."""
    length = round(1.0 / p0)
    seeds = per_level // length
    targets = [*cuts, threshold]
    levels: list[Level] = []
    product = 1.0
    var_sum = 0.0
    closest = -math.inf
    first_above: np.ndarray | None = None
    reservoir: _Reservoir | None = None
    try:
        for level, cut in enumerate(targets):
            last = level == len(targets) - 1
            nxt = _Reservoir(seeds, dimension, rng)
            failures = _Failures(seeds, per_level)
            values = np.empty((length, seeds))  # sample l of chain c (level 0: block l, row c)
            eves = np.empty((length, seeds), dtype=np.int64)
            accepted = 0
            groups = None
            if level == 0:
                for block in range(length):
                    xi = rng.standard_normal((seeds, dimension))
                    v = evaluate(xi)
                    eve = np.arange(block * seeds, (block + 1) * seeds)
                    values[block], eves[block] = v, eve
                    up = v > cut
                    nxt.offer(xi, v, eve, up)
                    if last:
                        failures.add(xi[up], v[up], eve[up], 0, False)
            else:
                assert reservoir is not None
                state, value, eve, groups = reservoir.seeds(seeds)
                reservoir = None  # its states are the chains' now
                below = targets[level - 1]
                sigma = steps[min(level - 1, len(steps) - 1)]
                rho = math.sqrt(1.0 - sigma * sigma)
                values[0], eves[:] = value, eve
                up = value > cut
                nxt.offer(state, value, eve, up)
                if last:
                    failures.add(state[up], value[up], np.flatnonzero(up), 0)
                candidate = np.empty_like(state)
                for step in range(1, length):
                    move = _move(rng, evaluate, state, value, candidate, sigma, rho, below)
                    accepted += int(move.sum())
                    values[step] = value
                    up = value > cut
                    nxt.offer(state, value, eve, up)
                    if last:
                        new, held = move & up, ~move & up
                        failures.add(state[new], value[new], np.flatnonzero(new), step)
                        failures.hold(np.flatnonzero(held))
            flat = values.ravel()
            closest = max(closest, float(flat.max()))
            above = int((flat > cut).sum())
            p = above / per_level
            if level == 0:
                first_above = flat > cut
            gamma = 0.0
            if level and 0 < above < per_level:
                # Negative estimates are noise (chains of one level do not anti-correlate):
                # floored at 0, so 1 + gamma never cancels.
                gamma = max(0.0, chain_gamma(values > cut, groups))
            cov_level = (
                math.sqrt((1.0 - p) / (per_level * p) * (1.0 + gamma)) if above else math.inf
            )
            rate = accepted / (seeds * (length - 1)) if level else math.nan
            flights = per_level if level == 0 else seeds * (length - 1)
            sigma_used = steps[min(level - 1, len(steps) - 1)] if level else math.nan
            levels.append(Level(level, cut, p, above, rate, flights, gamma, cov_level, sigma_used))
            if on_level is not None:
                on_level(levels[-1])
            if above == 0:
                return _no_failure(levels, product, var_sum, seeds, per_level, closest,
                                   first_above, run_of)  # fmt: skip
            product *= p
            var_sum += cov_level**2
            if last:
                fx, fv, fc, fch, fst = failures.arrays(dimension)
                eve_of = eves.ravel()[flat > cut]
                clusters = len(np.unique(eve_of))
                if level == 0:
                    interval = _binomial_interval(above, per_level)
                    cov = math.sqrt((1.0 - p) / (per_level * p))
                else:
                    counts = np.bincount(eve_of, minlength=per_level).astype(np.float64)
                    z = per_level * product * counts / counts.sum()
                    spread = float(((z - product) ** 2).sum()) / per_level**2
                    cov = max(math.sqrt(var_sum), math.sqrt(spread) / product)
                    interval = _interval(product, cov, clusters)
                return run_of(probability=product, cov=cov, levels=levels, failure_xi=fx,
                              failure_values=fv, failure_copies=fc, failure_chain=fch,
                              failure_step=fst, closest=closest, first_above=first_above,
                              interval=interval, clusters=clusters)  # fmt: skip
            reservoir = nxt
    except KeyboardInterrupt:
        bound = math.prod(lv.conditional_p for lv in levels) if levels else None
        return run_of(levels=levels, upper_bound=bound, closest=closest, interrupted=True,
                      first_above=first_above)  # fmt: skip
    raise AssertionError("unreachable: the last level returns")  # pragma: no cover


def _no_failure(
    levels: list[Level],
    product: float,
    var_sum: float,
    seeds: int,
    per_level: int,
    closest: float,
    first_above: np.ndarray | None,
    run_of: Callable[..., SubsetRun],
) -> SubsetRun:
    """No sample of the last level reached lies above its cut: a 95 % upper confidence bound.
    On level 0, 0 of ``per_level`` independent flights (Clopper-Pearson). Deeper, the product
    of the fractions so far (its lognormal 97.5 % upper end) times the bound for 0 events in
    the level's chains counted as independent trials (97.5 %; Bonferroni: 95 % together)."""
    if len(levels) == 1:
        bound = _upper_bound_zero(per_level, CONFIDENCE)
    else:
        tail = 1.0 - (1.0 - CONFIDENCE) / 2
        from scipy.stats import norm

        reached = product * math.exp(float(norm.ppf(tail)) * _lognormal_s(math.sqrt(var_sum)))
        bound = min(1.0, reached * _upper_bound_zero(seeds, tail))
    return run_of(levels=levels, upper_bound=bound, closest=closest, first_above=first_above,
                  interval=(0.0, bound))  # fmt: skip


def lognormal_interval(
    probability: float, cov: float, confidence: float = 0.95
) -> tuple[float, float]:
    """The interval P * exp(-+ z s), s^2 = log(1 + cov^2): P taken as lognormal with the
    estimated coefficient of variation (a product of level fractions is skewed to the right)."""
    from scipy.stats import norm

    z = float(norm.ppf(0.5 + confidence / 2))
    s = _lognormal_s(cov)
    return probability * math.exp(-z * s), probability * math.exp(z * s)
