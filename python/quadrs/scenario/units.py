"""The unit of every scenario key, in one table (SI throughout; frequencies in Hz).

``quadrs scenario keys`` prints them beside the values, and the plausibility checks
(:mod:`quadrs.scenario.plausibility`) quote them. Indexed keys share one entry:
``phases[2].end`` has the unit of ``phases[].end`` and ``controller.pd.kp[0]`` that of
``controller.pd.kp``.
"""

from __future__ import annotations

import re

from quadrs import _core

#: Dotted key (array indices dropped) -> unit; "-" for dimensionless values and names. The keys
#: a kind owns (``controller.*``, the wind sources' ``wind.*``) come from the engine, which
#: declares them with the kind.
UNITS: dict[str, str] = {
    **_core.KEY_UNITS,
    "vehicle.mass": "kg",
    "vehicle.inertia": "kg m^2",
    "vehicle.inertia_error": "kg m^2",
    "vehicle.arm_length": "m",
    "vehicle.drag_area": "m^2",
    "vehicle.lateral_drag_area": "m^2",
    "payload.model": "-",
    "payload.mass": "kg",
    "payload.natural_frequency": "Hz",
    "payload.stiffness": "N/m",
    "payload.damping": "N s/m",
    "payload.drag_area": "m^2",
    "payload.cable_length": "m",
    "payload.attachment_offset": "m",
    "environment.gravity": "m/s^2",
    "initial.position": "m",
    "initial.attitude": "rad",
    "actuator.model": "-",
    "actuator.layout": "-",
    "actuator.thrust_coefficient": "N s^2/rad^2",
    "actuator.torque_ratio": "m",
    "actuator.time_constant": "s",
    "actuator.thrust_min": "N",
    "actuator.thrust_max": "N",
    "trajectory.interpolation": "-",
    "trajectory.transition": "s",
    "trajectory.waypoints": "[s, m, m, m, rad]",
    "trajectory.route": "[m, m, m]",
    "trajectory.speed": "m/s",
    "trajectory.acceleration": "m/s^2",
    "trajectory.hold": "s",
    "trajectory.names": "-",
    "phases": "-",
    "phases.name": "-",
    "phases.start": "s",
    "phases.end": "s",
    "gust.enabled": "-",
    "gust.model": "-",
    "gust.components": "-",
    "gust.start": "s",
    "gust.end": "s",
    "gust.altitude": "m",
    "gust.w20": "m/s",
    "gust.airspeed": "m/s",
    "gust.air_density": "kg/m^3",
    "gust.mean_wind": "m/s",
    "gust.intensity": "-",
    "gust.min_airspeed": "m/s",
    "ground.enabled": "-",
    "ground.altitude": "m",
    "wind.table.file": "-",  # read in Python; the wind sources' own keys come from the engine
    "integrator.dt": "s",
    "integrator.duration": "s",
    "metrics.spectrum_rate": "Hz",
    "divergence.max_distance": "m",
    "divergence.max_tilt": "rad",
    "divergence.max_speed": "m/s",
    "divergence.max_rate": "rad/s",
}

#: Units of a dispersion's parameters: those of the dispersed key, except lognormal's, which
#: are of its logarithm, and the distribution's name.
_DISPERSION_SAME_UNIT = frozenset({"low", "high", "mean", "std", "mode"})
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
