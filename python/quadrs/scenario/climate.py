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
frequency), its second the speed by the sector's Weibull inverse CDF. Both uniforms are the
batch's design columns of those keys (:mod:`quadrs.scenario.dispersion`), so the same seed
gives the same winds and a Latin hypercube or Sobol' design stratifies them too. Python
alone reads the table: the engine sees each realisation's heading and speed.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from quadrs.scenario.keys import scenario_error

__all__ = ["CLIMATE_KEYS", "SECTOR_KEYS", "Climate", "climate_of", "strip_climate"]

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
    and scales (m/s)."""

    headings: np.ndarray
    probabilities: np.ndarray
    shapes: np.ndarray
    scales: np.ndarray

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

        sector = self.sectors_of(u_heading)
        speed = stats.weibull_min.ppf(np.asarray(u_speed, dtype=float), self.shapes[sector],
                                      scale=self.scales[sector])  # fmt: skip
        return {"wind.heading": self.headings[sector].astype(float),
                "wind.speed": np.asarray(speed, dtype=float)}  # fmt: skip

    def ranges(self, edge: float) -> dict[str, list[float]]:
        """Each key's smallest and largest value over uniforms in [edge, 1 - edge]."""
        from scipy import stats

        low = stats.weibull_min.ppf(edge, self.shapes, scale=self.scales)
        high = stats.weibull_min.ppf(1.0 - edge, self.shapes, scale=self.scales)
        drawn = self.probabilities > 0
        return {"wind.heading": [float(self.headings[drawn].min()),
                                 float(self.headings[drawn].max())],
                "wind.speed": [float(low[drawn].min()), float(high[drawn].max())]}  # fmt: skip

    def describe(self) -> str:
        """One line: the sectors' headings, shares and Weibull parameters."""
        parts = [f"{h:g} deg {100 * p:.3g} % weibull(shape={k:g}, scale={c:g})"
                 for h, p, k, c in zip(self.headings, self.probabilities, self.shapes,
                                       self.scales, strict=True)]  # fmt: skip
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
    return Climate(heading, frequency / total, shape, scale)


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
