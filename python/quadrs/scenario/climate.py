"""A site's wind climate (``[wind.climate]``, docs/dispersions.md "A site's wind climate"):
the mean wind's heading and speed drawn per realisation, as wind atlases give them.

    [wind.climate]
    sectors = [
        { heading = 0.0, frequency = 0.30, shape = 2.0, scale = 6.0 },
        { heading = 90.0, frequency = 0.70, shape = 1.8, scale = 4.5 },
    ]

(or ``[[wind.climate.sectors]]`` tables). Each sector: ``heading`` (deg, the wind's
``wind.heading``: the direction it blows toward, counter-clockwise from +x), ``frequency``
(its share of the year, normalised by the sectors' sum, so percentages do) and the Weibull
``shape`` and ``scale`` (m/s) of its speed at the height ``wind.speed`` is given for (W20,
6.1 m). It is a dispersion of the two ``[wind]`` keys ``wind.heading`` and ``wind.speed``
with one joint law: a realisation's first uniform picks the sector (with probability its
frequency) and the heading within it, its second the speed by the sector's Weibull inverse
CDF. Both uniforms are the batch's design columns of those keys
(:mod:`quadrs.scenario.dispersion`), so the same seed gives the same winds and a Latin
hypercube or Sobol' design stratifies them too. Python alone reads the table: the engine
sees each realisation's heading and speed.

A sector stands for the headings nearer to it than to its neighbours (an atlas's 12 sectors
of 30 deg each: its heading +- 15 deg): it reaches half-way to the next sector's heading on
each side, round the circle, and the heading is drawn uniform within it. Where the first
uniform u falls in the sector's share of (0, 1), (u - its start) / its frequency, is itself
uniform and independent of which sector it picked: it places the heading, so no third
column is needed and a design that stratifies u stratifies the headings within a sector
too. A lone sector has no neighbours: its heading is its own.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from quadrs.scenario.keys import scenario_error

__all__ = [
    "CLIMATE_KEYS",
    "SECTOR_KEYS",
    "Climate",
    "climate_of",
    "sector_extents",
    "strip_climate",
]

#: The keys a climate disperses, in the design's (sorted) order.
CLIMATE_KEYS = ("wind.heading", "wind.speed")
#: A sector's keys: unit and label (Python alone reads them: quadrs.scenario.units).
SECTOR_KEYS: dict[str, tuple[str, str]] = {
    "heading": ("deg", "Wind climate sector heading (toward, from +x)"),
    "frequency": ("-", "Wind climate sector frequency (share of the year)"),
    "shape": ("-", "Wind climate sector Weibull shape"),
    "scale": ("m/s", "Wind climate sector Weibull scale (at the height of wind.speed)"),
}


@dataclass(frozen=True)
class Climate:
    """The sectors: headings (deg), probabilities (normalised frequencies), Weibull shapes
    and scales (m/s), and each sector's extent about its heading: from ``lows`` to ``highs``
    (deg, half-way to each neighbour; both the heading for a lone sector)."""

    headings: np.ndarray
    probabilities: np.ndarray
    shapes: np.ndarray
    scales: np.ndarray
    lows: np.ndarray
    highs: np.ndarray

    def sectors_of(self, u: np.ndarray) -> np.ndarray:
        """The sector index of uniforms ``u`` in (0, 1): the first whose cumulative
        probability reaches u (a sector of frequency 0 is never drawn)."""
        cum = np.cumsum(self.probabilities)
        idx = np.searchsorted(cum, np.asarray(u, dtype=float), side="left")
        return np.minimum(idx, len(cum) - 1)

    def values(self, u_heading: np.ndarray, u_speed: np.ndarray) -> dict[str, np.ndarray]:
        """``wind.heading`` and ``wind.speed`` of uniforms in (0, 1): the sector by the first,
        the speed by that sector's Weibull inverse CDF of the second."""
        from scipy import stats

        u = np.asarray(u_heading, dtype=float)
        sector = self.sectors_of(u)
        start = np.concatenate(([0.0], np.cumsum(self.probabilities)))[sector]
        within = np.clip((u - start) / self.probabilities[sector], 0.0, 1.0)
        low, high = self.lows[sector], self.highs[sector]
        speed = stats.weibull_min.ppf(np.asarray(u_speed, dtype=float), self.shapes[sector],
                                      scale=self.scales[sector])  # fmt: skip
        return {"wind.heading": (low + within * (high - low)).astype(float),
                "wind.speed": np.asarray(speed, dtype=float)}  # fmt: skip

    def ranges(self, edge: float) -> dict[str, list[float]]:
        """Each key's smallest and largest value over uniforms in [edge, 1 - edge]."""
        from scipy import stats

        low = stats.weibull_min.ppf(edge, self.shapes, scale=self.scales)
        high = stats.weibull_min.ppf(1.0 - edge, self.shapes, scale=self.scales)
        drawn = self.probabilities > 0
        return {"wind.heading": [float(self.lows[drawn].min()),
                                 float(self.highs[drawn].max())],
                "wind.speed": [float(low[drawn].min()), float(high[drawn].max())]}  # fmt: skip

    def describe(self) -> str:
        """One line: the sectors' headings, shares and Weibull parameters."""
        parts = [f"{h:g} deg [{lo:g}, {hi:g}] {100 * p:.3g} % weibull(shape={k:g}, scale={c:g})"
                 for h, lo, hi, p, k, c in zip(self.headings, self.lows, self.highs,
                                               self.probabilities, self.shapes, self.scales,
                                               strict=True)]  # fmt: skip
        return "wind climate: " + "; ".join(parts)


def _number(sector: Mapping[str, Any], name: str, i: int) -> float:
    key = f"wind.climate.sectors[{i}].{name}"
    if name not in sector:
        raise scenario_error(f"{key} is required (each sector gives heading, frequency, shape "
                             "and scale)", key)  # fmt: skip
    value = sector[name]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise scenario_error(f"{key} must be a number, got {value!r}", key)
    x = float(value)
    if not math.isfinite(x):
        raise scenario_error(f"{key} must be a finite number, got {value!r}", key)
    if name in ("shape", "scale") and not x > 0:
        raise scenario_error(f"{key} must be > 0, got {value!r}", key)
    if name == "frequency" and x < 0:
        raise scenario_error(f"{key} must be >= 0, got {value!r}", key)
    return x


def climate_of(data: Mapping[str, Any]) -> Climate | None:
    """The climate a scenario's table gives (``data``: the nested mapping), checked; None
    without ``[wind.climate]``. A ScenarioError names the key at fault."""
    wind = data.get("wind")
    table = wind.get("climate") if isinstance(wind, Mapping) else None
    if table is None:
        return None
    if not isinstance(table, Mapping):
        raise scenario_error(f"wind.climate must be a table, got {table!r}", "wind.climate")
    for key in table:
        if key != "sectors":
            raise scenario_error(f"wind.climate.{key}: unknown key (wind.climate has sectors)",
                                 f"wind.climate.{key}")  # fmt: skip
    sectors = table.get("sectors")
    if not isinstance(sectors, list) or not sectors:
        raise scenario_error("wind.climate.sectors must list at least one sector, got "
                             f"{sectors!r}", "wind.climate.sectors")  # fmt: skip
    rows = []
    for i, sector in enumerate(sectors):
        if not isinstance(sector, Mapping):
            raise scenario_error(f"wind.climate.sectors[{i}] must be a table, got {sector!r}",
                                 f"wind.climate.sectors[{i}]")  # fmt: skip
        for key in sector:
            if key not in SECTOR_KEYS:
                raise scenario_error(
                    f"wind.climate.sectors[{i}].{key}: unknown key (a sector has "
                    f"{', '.join(SECTOR_KEYS)})", f"wind.climate.sectors[{i}].{key}")  # fmt: skip
        rows.append([_number(sector, name, i) for name in SECTOR_KEYS])
    heading, frequency, shape, scale = np.array(rows, dtype=float).T
    total = float(frequency.sum())
    if not total > 0:
        raise scenario_error("wind.climate.sectors: the frequencies must sum to > 0, got "
                             f"{total:g}", "wind.climate.sectors")  # fmt: skip
    _check_not_dispersed(data)
    low, high = sector_extents(heading)
    return Climate(heading, frequency / total, shape, scale, low, high)


def sector_extents(headings: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each sector's first and last heading (deg): half-way to its neighbours round the
    circle, on the heading's own side of 360 (a sector at 0 with neighbours at 90 and 270
    reaches from -45 to 45). A lone sector: its heading alone. Two sectors at one heading
    (modulo 360) are refused, naming the second."""
    n = len(headings)
    if n == 1:
        return headings.copy(), headings.copy()
    turned = np.mod(headings, 360.0)
    order = np.argsort(turned, kind="stable")
    ring = turned[order]
    gaps = np.diff(np.concatenate((ring, [ring[0] + 360.0])))  # to the next, round the circle
    for j in np.flatnonzero(gaps == 0.0):
        first, second = sorted((int(order[j]), int(order[(j + 1) % n])))
        key = f"wind.climate.sectors[{second}].heading"
        raise scenario_error(f"{key}: {headings[second]:g} deg is sector {first}'s heading "
                             "again (modulo 360): give each heading once", key)  # fmt: skip
    after = np.empty(n)
    before = np.empty(n)
    after[order] = gaps / 2.0
    before[order] = np.roll(gaps, 1) / 2.0
    return headings - before, headings + after


def _check_not_dispersed(data: Mapping[str, Any]) -> None:
    """A climate draws wind.heading and wind.speed: [dispersions] may not draw them too."""
    table = data.get("dispersions") or {}
    for key in CLIMATE_KEYS:
        if key in table:
            raise scenario_error(f"dispersions.{key}: [wind.climate] draws {key} already "
                                 "(give one of them)", f"dispersions.{key}")  # fmt: skip


def strip_climate(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` without ``wind.climate`` (in place; the engine's form: the engine sees the
    drawn keys, never the table), and without an emptied ``[wind]``."""
    wind = data.get("wind")
    if isinstance(wind, dict) and "climate" in wind:
        del wind["climate"]
        if not wind:
            del data["wind"]
    return data
