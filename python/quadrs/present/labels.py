"""Units and labels as people read them: the unit shown for each metric and scenario key, its
plain-English label, and the scale from a stored (SI) value to the shown one (degrees for
angles; g beside m/s² for accelerations). One table for everything a person
reads: the figures, the mission tables, ``--limit``."""

from __future__ import annotations

import math

from quadrs import _core
from quadrs.scenario.units import LABELS as KEY_LABELS
from quadrs.scenario.units import UNITS as KEY_UNITS

__all__ = [
    "DEGREE_METRICS",
    "INPUT_UNITS",
    "PLAIN_LABELS",
    "STANDARD_GRAVITY",
    "UNITS",
    "display_scale",
    "in_g",
    "is_angle",
    "metric_value",
    "shown_unit",
    "shown_value",
]


def is_angle(name: str) -> bool:
    """Whether metric ``name`` is an angle: the results hold it in radians (its engine unit,
    ``_core.METRIC_UNITS``, is "rad") and every figure and table shows it in degrees (one unit
    per quantity in everything a person reads: the mission tables, the figures, --limit). A
    new angle metric is one by its unit alone: read from the engine's registry at each call."""
    return _core.METRIC_UNITS.get(name) == "rad"


#: The angle metrics (:func:`is_angle`) of the engine this package was imported with.
DEGREE_METRICS = tuple(m for m in _core.METRIC_UNITS if is_angle(m))


def _shown(unit: str) -> str:
    """A unit as a person reads it (``m/s^2`` -> ``m/s²``)."""
    return unit.replace("^2", "²").replace("^3", "³")


def _metric_unit(unit: str) -> str:
    """A metric's engine unit as shown: an angle's ``rad`` in ``deg``."""
    return "deg" if unit == "rad" else _shown(unit)


#: Units of the metric columns (the engine's, ``_core.METRIC_UNITS``, angles in degrees) and
#: of every scenario key, for axis labels.
UNITS = {
    **{m: _metric_unit(u) for m, u in _core.METRIC_UNITS.items()},
    # every scenario key, from the package's one table of them (quadrs.scenario.units)
    **{key: _shown(unit) for key, unit in KEY_UNITS.items()},
}
#: Standard gravity (m/s²), what "g" means where an acceleration is also shown or given in g
#: (``--limit max_specific_force=2g``, the mission tables' g column): packaging fragility is
#: stated in multiples of it (ISTA, ASTM D4169), whatever the scenario's own gravity.
STANDARD_GRAVITY = 9.80665


def in_g(name: str) -> bool:
    """Whether metric ``name`` is an acceleration (m/s²), so also shown and accepted in g."""
    return shown_unit(name) == "m/s²"


def display_scale(name: str) -> float:
    """The factor from a metric's stored (SI) value to the value shown: 180/pi for angles."""
    return 180.0 / math.pi if is_angle(name) else 1.0


#: Plain-English axis labels of metrics and scenario keys, with units. Every figure labels a
#: metric or key through these (a key not listed, an indexed one, shows as itself).
PLAIN_LABELS = {
    # every metric, from the engine's definition (``_core.METRIC_LABELS``)
    **{m: f"{label} ({UNITS[m]})" for m, label in _core.METRIC_LABELS.items()},
    # every scenario key, from its declaration (``quadrs.scenario.units.LABELS``)
    **{
        key: label if UNITS[key] == "-" else f"{label} ({UNITS[key]})"
        for key, label in KEY_LABELS.items()
    },
}


#: The one convention for a metric's value typed on the command line (``--limit``, ``tune
#: --constraint``, ``rare --threshold``), said in their help: the unit the tables show.
INPUT_UNITS = (
    "in the unit the tables show: degrees for swing, m/s² for accelerations (or g with a g "
    "suffix, 1.5g), SI otherwise; a deg or rad suffix says the angle's unit outright"
)

_SUFFIXES = {"deg": math.pi / 180.0, "rad": 1.0}


def shown_unit(name: str) -> str:
    """The unit a metric's (or a key's) values are shown and typed in (``max_swing`` ->
    ``deg``): a metric's from the engine's registry at the call."""
    unit = _core.METRIC_UNITS.get(name)
    return _metric_unit(unit) if unit is not None else UNITS.get(name, "")


def metric_value(name: str, text: str) -> float:
    """A value of metric ``name`` as typed (:data:`INPUT_UNITS`) -> the results' unit (SI:
    radians, m/s²). ``30`` for max_swing is 30 degrees, ``0.5rad`` half a radian, ``1.5g`` for
    an acceleration 1.5 standard g. ValueError for anything else (a unit that does not fit the
    metric, a number that is not finite)."""
    raw = text.strip()
    scale = 1.0 / display_scale(name)
    angle = is_angle(name)
    for suffix, factor in _SUFFIXES.items():
        if raw.lower().endswith(suffix):
            if not angle:
                raise ValueError(f"{name} is not an angle: {text!r} takes no {suffix} suffix")
            scale, raw = factor, raw[: -len(suffix)].strip()
            break
    else:
        if raw[-1:] in ("g", "G"):
            if not in_g(name):
                raise ValueError(f"{name} is not an acceleration: {text!r} takes no g suffix")
            scale, raw = STANDARD_GRAVITY, raw[:-1].strip()
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise ValueError(f"{name}: threshold must be a finite number {INPUT_UNITS}, got {text!r}")
    return value * scale


def shown_value(name: str, value: float) -> float:
    """A metric's value in the results' unit (SI) -> as shown and typed (degrees for swing)."""
    return value * display_scale(name)
