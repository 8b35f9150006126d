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

import numpy as np

from quadrs.engine.calls import check_int, check_memory
from quadrs.rare.chains import _Evaluator, _Failures, _move, _Reservoir, chain_gamma
from quadrs.rare.intervals import (
    CONFIDENCE,
    _binomial_interval,
    _interval,
    lognormal_interval,
    no_failure_bound,
)
from quadrs.rare.levels import (
    INITIAL_SPREAD,
    MIN_SEEDS,
    SMALLEST_PROBABILITY,
    TARGET_ACCEPTANCE,
    Level,
    Model,
    SubsetRun,
    check_settings,
    check_threshold,
)
from quadrs.rare.pilot import _adaptive, _steps_of, pilot_size

__all__ = [
    "CONFIDENCE",
    "INITIAL_SPREAD",
    "MIN_SEEDS",
    "SMALLEST_PROBABILITY",
    "TARGET_ACCEPTANCE",
    "Level",
    "Model",
    "SubsetRun",
    "chain_gamma",
    "check_settings",
    "check_threshold",
    "lognormal_interval",
    "pilot_size",
    "subset_simulation",
]


#: Bytes one float64 takes.
_F8 = 8


def subset_memory(dimension: int, per_level: int, p0: float) -> int:
    """Bytes subset simulation holds at once in ``dimension`` normals a flight with
    ``per_level`` samples a level. Measured with tracemalloc
    (tests/guarantees/test_delivery_and_rare.py): about seven chain-sized arrays of rows
    (states, candidates, the pilot's running best and its pool, the seeds' reservoir); per
    sample about eight numbers (the level's values, their copies, indicators, ancestries, sort
    order, copy counts); and the failure samples, up to a whole level's rows, held twice while
    joined."""
    seeds = per_level // round(1.0 / p0)
    return (7 * seeds * dimension + 8 * per_level + 2 * per_level * dimension) * _F8


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
    check_memory(
        f"subset simulation in {dimension} dimensions with {seeds} chains of {per_level} "
        f"samples a level",
        subset_memory(dimension, per_level, p0),
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
                return _no_failure(levels, closest, first_above, run_of)
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
    closest: float,
    first_above: np.ndarray | None,
    run_of: Callable[..., SubsetRun],
) -> SubsetRun:
    """No sample of the last level reached lies above its cut: a 95 % upper confidence bound
    (:func:`quadrs.rare.intervals.no_failure_bound`)."""
    bound = no_failure_bound(run_of(levels=levels), CONFIDENCE)
    return run_of(levels=levels, upper_bound=bound, closest=closest, first_above=first_above,
                  interval=(0.0, bound))  # fmt: skip
