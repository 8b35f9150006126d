"""The Markov chains of a level of subset simulation: the model's checked evaluation, the
best samples of a level, the failure samples kept, the reservoir that seeds the next level,
the chains' correlation factor, a level's cut and the preconditioned Crank-Nicolson move."""

from __future__ import annotations

import numpy as np

from quadrs.rare.levels import (
    Model,
)


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
    if len(lower) == 0 and w == -np.inf:
        # -inf is an event's metric without its event (rare.scenario_model): no flight of
        # the level had one, so there is nothing to climb towards the threshold.
        raise ValueError(
            f"the event too rarely happened: {int((values == -np.inf).sum())} of {len(values)} "
            "flights of a level have no value of the metric in the phase (an event's metric, "
            "such as touchdown_speed, where no parcel touched down); give the phase the event "
            "falls in (--phase), or "
            "a scenario where it happens"
        )
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
