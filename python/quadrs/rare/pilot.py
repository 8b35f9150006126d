"""The pilot run of subset simulation: adaptive subset simulation (Au & Beck 2001) whose cuts
and proposal steps place the levels of the main run (:func:`quadrs.rare.subset.subset_simulation`);
its own estimate is not reported."""

from __future__ import annotations

import math

import numpy as np

from quadrs.rare.chains import (
    _Arrays,
    _Best,
    _cut,
    _Evaluator,
    _Failures,
    _groups,
    _move,
    _none,
    chain_gamma,
)
from quadrs.rare.levels import (
    INITIAL_SPREAD,
    MIN_SEEDS,
    TARGET_ACCEPTANCE,
    Level,
    SubsetRun,
)


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
            if level == 0:
                values, accepted = _first_level(evaluate, rng, threshold, best, failures,
                                                (length, seeds, dimension))  # fmt: skip
            else:
                # From the previous level's best (its states ours to move in place).
                values, accepted = _chains(evaluate, rng, (seeds_xi, seeds_val.copy()),
                                           levels[-1].threshold, spread, threshold, best,
                                           failures, length)  # fmt: skip
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


def _first_level(
    evaluate: _Evaluator,
    rng: np.random.Generator,
    threshold: float,
    best: _Best,
    failures: _Failures,
    shape: tuple[int, int, int],
) -> tuple[np.ndarray, int]:
    """The first level: ``length`` blocks of ``seeds`` independent draws of ``dimension``
    (``shape``), ``best`` and ``failures`` offered each; its values (block l, row c) and no
    moves accepted."""
    length, seeds, dimension = shape
    values = np.empty((length, seeds))
    for block in range(length):
        xi = rng.standard_normal((seeds, dimension))
        v = evaluate(xi)
        values[block] = v
        best.offer(xi, v)
        hit = v > threshold
        failures.add(xi[hit], v[hit], np.flatnonzero(hit) + block * seeds, 0, False)
    return values, 0


def _chains(
    evaluate: _Evaluator,
    rng: np.random.Generator,
    start: tuple[np.ndarray, np.ndarray],
    below: float,
    sigma: float,
    threshold: float,
    best: _Best,
    failures: _Failures,
    length: int,
) -> tuple[np.ndarray, int]:
    """A level above the first: a chain of ``length`` samples from each seed (``start``: its
    states, moved in place, and their values) by preconditioned Crank-Nicolson steps of
    ``sigma`` kept above ``below``; its values (sample l of chain c) and the moves accepted. A
    chain's failure state is recorded when reached, then its copies counted."""
    state, value = start
    values = np.empty((length, len(value)))
    rho = math.sqrt(1.0 - sigma * sigma)
    values[0] = value
    best.offer(state, value)
    hit = value > threshold
    failures.add(state[hit], value[hit], np.flatnonzero(hit), 0)
    candidate = np.empty_like(state)
    accepted = 0
    for step in range(1, length):
        move = _move(rng, evaluate, state, value, candidate, sigma, rho, below)
        accepted += int(move.sum())
        values[step] = value
        best.offer(state, value)
        new = move & (value > threshold)
        held = ~move & (value > threshold)
        failures.add(state[new], value[new], np.flatnonzero(new), step)
        failures.hold(np.flatnonzero(held))
    return values, accepted


def pilot_size(per_level: int, p0: float) -> int:
    """The pilot's samples per level: a fifth of ``per_level``, a whole number of chains, and
    at least MIN_SEEDS of them."""
    length = round(1.0 / p0)
    return max(MIN_SEEDS * length, (per_level // 5) // length * length)


def _steps_of(pilot: SubsetRun) -> list[float]:
    """The proposal's step on each conditional level of the main run: the pilot's own step
    on that level, and past its last, its rule applied once more."""
    steps = [lv.sigma for lv in pilot.levels[1:]]
    if len(pilot.levels) > 1:
        last = pilot.levels[-1]
        steps.append(min(last.sigma * math.exp(last.acceptance_rate - TARGET_ACCEPTANCE), 1.0))
    steps.append(INITIAL_SPREAD)
    return [x if math.isfinite(x) and 0 < x <= 1 else INITIAL_SPREAD for x in steps]
