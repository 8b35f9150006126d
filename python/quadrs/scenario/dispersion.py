"""Uncertain parameters: the values each realisation of a dispersed scenario flies.

A scenario's ``[dispersions]`` table gives dotted numeric keys a distribution (validated by the
engine, like every other field). This module draws the values: a design of uniforms in
(0, 1)^d (``random``, ``lhs`` or ``sobol``) mapped through each distribution's inverse CDF
(scipy.stats semantics; ``choice``'s a discrete one). The keys are taken in sorted order, so
equal scenarios give equal designs. A ``[wind.climate]`` disperses ``wind.heading`` and
``wind.speed`` with one joint law (:mod:`quadrs.scenario.climate`): two design columns like
any others, mapped together.

- ``random``: realisation i's value of a key depends only on (seed, key, i): a counter-based
  stream (Philox) per key, separate from the gust's, so adding or removing a dispersion never
  changes another key's values or any gust, and any slice of realisations can be drawn alone.
- ``lhs`` / ``sobol``: one design of ``runs`` points drawn from (seed, runs) by scipy.stats.qmc;
  a chunk takes its rows. Stratified over the whole batch, so a realisation's values depend on
  ``runs`` as well.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from quadrs.scenario.climate import CLIMATE_KEYS, Climate, climate_of

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd


class ScenarioLike(Protocol):
    """What this module reads of a scenario: ``get("dispersions")``. A
    :class:`~quadrs.scenario.scenario.Scenario` is one; typed by what is read so that the
    scenario module, which draws through this one, is not imported back."""

    def get(self, key: str, default: Any = None) -> Any: ...


__all__ = [
    "DISTRIBUTIONS",
    "SAMPLINGS",
    "describe",
    "dispersed_keys",
    "distribution",
    "draw",
    "key_ranges",
    "unit_design",
    "values_of_uniforms",
]

#: Sampling schemes of `monte_carlo(..., sampling=...)`.
SAMPLINGS = ("random", "lhs", "sobol")
#: The distributions a dispersion may name, with their parameters in their conventional order
#: (the order the command line's ``--disperse KEY=DIST(ARGS)`` takes them in). lognormal's
#: are those of the logarithm.
DISTRIBUTIONS: dict[str, tuple[str, ...]] = {
    "uniform": ("low", "high"),
    "normal": ("mean", "std"),
    "truncnorm": ("mean", "std", "low", "high"),
    "lognormal": ("mu", "sigma"),
    "triangular": ("low", "mode", "high"),
    "weibull": ("shape", "scale"),
    "choice": ("values", "weights"),
}
#: Tags the dispersion streams apart from every other use of the seed.
_STREAM_TAG = 0x51D15
#: Uniforms are kept this far inside (0, 1): an inverse CDF of an unbounded distribution is
#: finite there (about 8.2 standard deviations for a normal).
_EDGE = 1e-16


def dispersed_keys(scenario: ScenarioLike) -> list[str]:
    """The scenario's dispersed keys, sorted (the design's dimensions, the result columns):
    those of ``[dispersions]`` and, with a ``[wind.climate]``, ``wind.heading`` and
    ``wind.speed`` (:mod:`quadrs.scenario.climate`)."""
    keys = set(scenario.get("dispersions", {}) or {})
    if scenario.get("wind.climate") is not None:
        keys |= set(CLIMATE_KEYS)
    return sorted(keys)


def _climate(scenario: ScenarioLike) -> Climate | None:
    wind = scenario.get("wind")
    return climate_of({"wind": wind}) if isinstance(wind, dict) else None


def values_of_uniforms(
    scenario: ScenarioLike, keys: Sequence[str], u: np.ndarray
) -> dict[str, np.ndarray]:
    """Each dispersed key's values of uniforms ``u`` (rows, len(keys)) in (0, 1): a key of
    ``[dispersions]`` by its distribution's inverse CDF, the climate's two keys jointly
    (:meth:`quadrs.scenario.climate.Climate.values` of their two columns)."""
    table = scenario.get("dispersions", {}) or {}
    column = {k: u[..., j] for j, k in enumerate(keys)}
    out = {k: distribution(table[k]).ppf(column[k]) for k in keys if k in table}
    climate = _climate(scenario)
    if climate is not None:
        out |= climate.values(*(column[k] for k in CLIMATE_KEYS))
    return {k: np.asarray(out[k], dtype=float) for k in keys}


def key_ranges(scenario: ScenarioLike, edge: float) -> dict[str, list[float]]:
    """Each dispersed key's smallest and largest value over uniforms in [edge, 1 - edge]."""
    table = scenario.get("dispersions", {}) or {}
    ranges = {k: [float(x) for x in distribution(table[k]).ppf([edge, 1.0 - edge])]
              for k in dispersed_keys(scenario) if k in table}  # fmt: skip
    climate = _climate(scenario)
    return ranges | (climate.ranges(edge) if climate is not None else {})


class Choice:
    """A discrete law over ``values`` with probabilities ``weights`` / their sum, with the
    frozen scipy.stats interface the draws use (``ppf``, ``cdf``, ``mean``)."""

    def __init__(self, values: Sequence[float], weights: Sequence[float]) -> None:
        self.values = np.asarray(values, dtype=float)
        w = np.asarray(weights, dtype=float)
        self.probabilities = w / w.sum()
        self._cum = np.cumsum(self.probabilities)

    def ppf(self, u: Any) -> np.ndarray:
        """The value whose cumulative probability first reaches u (a value of weight 0 is
        never drawn): the inverse CDF, so a uniform u gives each value its probability."""
        idx = np.searchsorted(self._cum, np.asarray(u, dtype=float), side="left")
        return self.values[np.minimum(idx, len(self.values) - 1)]

    def cdf(self, x: Any) -> np.ndarray:
        """P(X <= x)."""
        x = np.asarray(x, dtype=float)
        return np.asarray((self.probabilities * (self.values <= x[..., None])).sum(axis=-1))

    def mean(self) -> float:
        return float(self.probabilities @ self.values)


def distribution(spec: Mapping[str, Any]) -> Any:
    """A frozen scipy.stats distribution for one (engine-validated) dispersion entry."""
    from scipy import stats

    d = spec["dist"]
    if d == "uniform":
        return stats.uniform(loc=spec["low"], scale=spec["high"] - spec["low"])
    if d == "normal":
        return stats.norm(loc=spec["mean"], scale=spec["std"])
    if d == "truncnorm":
        m, s = spec["mean"], spec["std"]
        a, b = (spec["low"] - m) / s, (spec["high"] - m) / s
        return stats.truncnorm(a, b, loc=m, scale=s)
    if d == "lognormal":
        return stats.lognorm(s=spec["sigma"], scale=float(np.exp(spec["mu"])))
    if d == "triangular":
        lo, hi = spec["low"], spec["high"]
        return stats.triang(c=(spec["mode"] - lo) / (hi - lo), loc=lo, scale=hi - lo)
    if d == "weibull":
        return stats.weibull_min(c=spec["shape"], scale=spec["scale"])
    if d == "choice":
        return Choice(spec["values"], spec["weights"])
    raise ValueError(f"unknown distribution {d!r}")  # the engine refuses it first


def describe(scenario: ScenarioLike) -> list[str]:
    """One line per dispersed key: ``payload.mass ~ uniform(low=0.1, high=0.4)``; the
    climate's keys ``wind.heading ~ wind climate: ...``."""
    table = scenario.get("dispersions", {}) or {}
    climate = _climate(scenario)
    lines = []
    for key in dispersed_keys(scenario):
        if key not in table and climate is not None:
            lines.append(f"{key} ~ {climate.describe()}")
            continue
        spec = dict(table[key])
        name = spec.pop("dist")
        args = ", ".join(f"{k}={_shown(v)}" for k, v in spec.items())
        lines.append(f"{key} ~ {name}({args})")
    return lines


def _shown(value: Any) -> str:
    """A parameter: a number as %g, a list (choice's) as [a, b, ...]."""
    if isinstance(value, list | tuple):
        return "[" + ", ".join(f"{v:g}" for v in value) + "]"
    return f"{value:g}"


def _key_stream(seed: int, key: str) -> np.random.Philox:
    """The counter-based generator of one key's random values (block i: realisation i)."""
    digest = int.from_bytes(hashlib.blake2b(key.encode(), digest_size=8).digest(), "little")
    ss = np.random.SeedSequence(entropy=seed, spawn_key=(_STREAM_TAG, digest))
    return np.random.Philox(key=ss.generate_state(2, dtype=np.uint64))


def _random_uniforms(seed: int, key: str, first: int, count: int) -> np.ndarray:
    """Uniforms in (0, 1) of realisations first..first+count: the first word of Philox block
    i is realisation i's, so any slice equals the same rows of a longer draw."""
    bits = _key_stream(seed, key)
    bits.advance(first)  # the counter moves by whole 4-word blocks
    raw = bits.random_raw(4 * count).reshape(count, 4)[:, 0]
    return ((raw >> np.uint64(11)).astype(np.float64) + 0.5) * 2.0**-53


def _qmc_design(sampling: str, dims: int, seed: int, runs: int) -> np.ndarray:
    from scipy.stats import qmc

    rng = np.random.default_rng(np.random.SeedSequence(entropy=seed, spawn_key=(_STREAM_TAG,)))
    engine: qmc.QMCEngine
    if sampling == "lhs":
        engine = qmc.LatinHypercube(d=dims, rng=rng)
        return engine.random(runs)
    engine = qmc.Sobol(d=dims, scramble=True, rng=rng)
    # Sobol' balance needs a power of two: draw the next one and keep the first `runs` rows.
    m = max(0, int(np.ceil(np.log2(runs))))
    return engine.random_base2(m)[:runs]


def unit_design(
    keys: Sequence[str], seed: int, first: int, count: int, runs: int, sampling: str
) -> np.ndarray:
    """(count, len(keys)) uniforms in (0, 1). ``random``: those of realisations
    first..first+count. ``lhs``/``sobol``: rows first..first+count of the design of ``runs``
    points (``first`` counted from the batch's first realisation)."""
    if sampling not in SAMPLINGS:
        raise ValueError(f"sampling must be one of {SAMPLINGS}, got {sampling!r}")
    if not keys:
        return np.empty((count, 0))
    if sampling == "random":
        u = np.column_stack([_random_uniforms(seed, k, first, count) for k in keys])
    else:
        if first + count > runs:
            raise ValueError(f"rows {first}..{first + count} lie outside a design of {runs}")
        u = _qmc_design(sampling, len(keys), seed, runs)[first : first + count]
    return np.clip(u, _EDGE, 1.0 - _EDGE)


def draw(
    scenario: ScenarioLike,
    seed: int,
    first: int,
    count: int,
    *,
    runs: int | None = None,
    sampling: str = "random",
    offset: int = 0,
) -> pd.DataFrame:
    """The values realisations first..first+count fly, one column per dispersed key, indexed
    by realisation. For ``lhs``/``sobol`` the design covers the batch's ``runs`` realisations
    starting at ``offset`` (its first realisation)."""
    import pandas as pd

    keys = dispersed_keys(scenario)
    if sampling == "random":
        u = unit_design(keys, seed, first, count, count, sampling)
    else:
        total = count if runs is None else runs
        u = unit_design(keys, seed, first - offset, count, total, sampling)
    columns = values_of_uniforms(scenario, keys, u)
    index = pd.RangeIndex(first, first + count, name="realisation")
    return pd.DataFrame(columns, index=index, columns=keys)
