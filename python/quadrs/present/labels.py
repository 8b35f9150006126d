"""Units as people read them: the unit shown for each metric and scenario key, and the scale from
a stored (SI) value to the shown one (degrees for angles). One table for everything a person
reads: the figures, the mission tables, ``--limit``."""

from __future__ import annotations

import math

from quadrs.scenario.units import UNITS as KEY_UNITS

__all__ = ["DEGREE_METRICS", "UNITS", "display_scale"]

#: Units of the metric columns and of common sweep keys, for axis labels.
UNITS = {
    "iae": "m s",
    "itae": "m s²",
    "max_abs": "m",
    "rms": "m",
    "tracking_rms": "m",
    "peak_frequency": "Hz",
    "peak_amplitude": "m",
    "max_accel": "m/s²",
    "rms_accel": "m/s²",
    "max_swing": "deg",
    "rms_swing": "deg",
    "max_tension": "N",
    "min_tension": "N",
    "slack_time": "s",
    "saturated_time": "s",
    "max_tracking": "m",
    "rms_cross_track": "m",
    "max_cross_track": "m",
    "max_specific_force": "m/s²",
    # every scenario key, from the package's one table of them (quadrs.scenario.units)
    **{key: unit.replace("^2", "²").replace("^3", "³") for key, unit in KEY_UNITS.items()},
}
#: Metrics the results hold in radians and every figure and table shows in degrees (one unit
#: per quantity in everything a person reads: the mission tables, the figures, --limit).
DEGREE_METRICS = ("max_swing", "rms_swing")


def display_scale(name: str) -> float:
    """The factor from a metric's stored (SI) value to the value shown: 180/pi for angles."""
    return 180.0 / math.pi if name in DEGREE_METRICS else 1.0
