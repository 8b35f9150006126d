"""Units and labels as people read them: the unit shown for each metric and scenario key, its
plain-English label, and the scale from a stored (SI) value to the shown one (degrees for
angles; g beside m/s² for accelerations). One table for everything a person
reads: the figures, the mission tables, ``--limit``."""

from __future__ import annotations

import math

from quadrs.scenario.units import UNITS as KEY_UNITS

__all__ = ["DEGREE_METRICS", "PLAIN_LABELS", "STANDARD_GRAVITY", "UNITS", "display_scale", "in_g"]

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
#: Standard gravity (m/s²), what "g" means where an acceleration is also shown or given in g
#: (``--limit max_specific_force=2g``, the mission tables' g column): packaging fragility is
#: stated in multiples of it (ISTA, ASTM D4169), whatever the scenario's own gravity.
STANDARD_GRAVITY = 9.80665


def in_g(name: str) -> bool:
    """Whether metric ``name`` is an acceleration (m/s²), so also shown and accepted in g."""
    return UNITS.get(name) == "m/s²" and name in PLAIN_LABELS


def display_scale(name: str) -> float:
    """The factor from a metric's stored (SI) value to the value shown: 180/pi for angles."""
    return 180.0 / math.pi if name in DEGREE_METRICS else 1.0


#: Plain-English axis labels of metrics and common scenario keys, with units. Every figure
#: labels a metric or key through these (a key not listed shows as itself).
PLAIN_LABELS = {
    "max_accel": "Payload acceleration peak (m/s²)",
    "rms_accel": "Payload acceleration RMS (m/s²)",
    "max_abs": "Peak |payload relative displacement| (m)",
    "rms": "RMS payload relative displacement (m)",
    "iae": "Integrated absolute displacement, IAE (m s)",
    "itae": "Time-weighted IAE, ITAE (m s²)",
    "tracking_rms": "RMS 3-D tracking error (m)",
    "max_tracking": "Peak 3-D tracking error (m)",
    "rms_cross_track": "RMS cross-track error (m)",
    "max_cross_track": "Peak cross-track error (m)",
    "max_specific_force": "Peak specific force on the payload, |a - g| (m/s²)",
    "max_swing": "Peak swing angle of the line (deg)",
    "rms_swing": "RMS swing angle of the line (deg)",
    "max_tension": "Peak line tension (N)",
    "min_tension": "Lowest line tension (N)",
    "slack_time": "Time with the line slack (s)",
    "saturated_time": "Time with a rotor at its limit (s)",
    "peak_frequency": "Frequency of the displacement's spectral peak (Hz)",
    "peak_amplitude": "Amplitude of the displacement's spectral peak (m)",
    "payload.natural_frequency": "Attachment natural frequency (Hz)",
    "payload.stiffness": "Attachment stiffness (N/m)",
    "payload.mass": "Payload mass (kg)",
    "payload.damping": "Attachment damping (N s/m)",
    "payload.drag_area": "Payload drag area (m²)",
    "gust.w20": "Wind at 20 ft (m/s)",
    "gust.airspeed": "Airspeed (m/s)",
    "gust.altitude": "Altitude of the gust model (m)",
    "gust.air_density": "Air density (kg/m³)",
    "vehicle.mass": "Quadrotor mass (kg)",
    "vehicle.drag_area": "Quadrotor drag area (m²)",
    "integrator.dt": "Integration step (s)",
}
