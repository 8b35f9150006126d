"""The unit and label of every scenario key (SI throughout; frequencies in Hz), from the
engine (``_core.KEY_UNITS``, ``_core.KEY_LABELS``: each key declared beside its section's struct
or in its kind's file) and the few keys Python alone holds.

``quadrs scenario keys`` prints the units beside the values, and the plausibility checks
(:mod:`quadrs.scenario.plausibility`) quote them. Indexed keys share one entry:
``phases[2].end`` has the unit of ``phases[].end`` and ``controller.pd.kp[0]`` that of
``controller.pd.kp``.
"""

from __future__ import annotations

import re

from quadrs import _core
from quadrs.scenario.climate import SECTOR_KEYS

#: The keys only Python reads (a file the scenario names, read into numbers before the engine
#: sees them): dotted key -> (unit, plain-English label).
_PYTHON_KEYS: dict[str, tuple[str, str]] = {
    "wind.table.file": ("-", "Wind table file (CSV, or a PX4 .ulg log by time)"),
    **{f"wind.climate.sectors.{k}": v for k, v in SECTOR_KEYS.items()},
}

#: Dotted key (array indices dropped) -> unit; "-" for dimensionless values and names. The
#: engine declares each key beside its section's struct or in its kind's file
#: (``_core.KEY_UNITS``); the few Python holds are above.
UNITS: dict[str, str] = {
    **_core.KEY_UNITS,
    **{key: unit for key, (unit, _) in _PYTHON_KEYS.items()},
}

#: Dotted key (array indices dropped) -> plain-English label (no unit), for the same keys.
LABELS: dict[str, str] = {
    **_core.KEY_LABELS,
    **{key: label for key, (_, label) in _PYTHON_KEYS.items()},
}

#: Units of a dispersion's parameters: those of the dispersed key, except lognormal's, which
#: are of its logarithm, and the distribution's name.
_DISPERSION_SAME_UNIT = frozenset({"low", "high", "mean", "std", "mode", "scale", "values"})
_INDEX = re.compile(r"\[\d+\]")


def unit(key: str) -> str:
    """The unit of a dotted scenario key (``"payload.mass"`` -> ``"kg"``); indices are
    ignored; a dispersion's parameter has the unit of the key it disperses. Raises KeyError
    for a key the table does not know."""
    if key.startswith("dispersions."):
        inner, _, param = key.removeprefix("dispersions.").rpartition(".")
        inner = inner.strip('"')
        if param in _DISPERSION_SAME_UNIT:
            return unit(inner)
        if param == "mu":  # lognormal: the mean of the value's logarithm
            return f"ln({unit(inner)})"
        return "-"
    return UNITS[_INDEX.sub("", key)]


def label(key: str) -> str:
    """The plain-English label of a dotted scenario key (``"payload.mass"`` -> ``"Payload
    mass"``), without its unit; indices are ignored; a dispersion's parameter is labelled by the
    key it disperses. Raises KeyError for a key the table does not know."""
    if key.startswith("dispersions."):
        inner, _, param = key.removeprefix("dispersions.").rpartition(".")
        inner = inner.strip('"')
        return f"{label(inner)}: dispersion {param}"
    return LABELS[_INDEX.sub("", key)]
