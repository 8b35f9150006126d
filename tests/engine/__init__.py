"""Engine tests."""

from typing import Any

import quadrs

#: The delivery preset's vehicle flown on its state at every step (navigation "truth", every
#: loop and the wind at every 1 ms step): what a comparison of its physics with an independent
#: integration, or a hover's stability, is about. The preset itself flies on its senses, its
#: loops at PX4's rates and its wind at 100 Hz, on a 2 ms step.
ON_THE_STATE: dict[str, Any] = {
    "navigation.mode": "truth",
    "controller.position_rate": 0.0,
    "controller.attitude_rate": 0.0,
    "controller.inner_rate": 0.0,
    "gust.rate": 0.0,
    "integrator.dt": 0.001,
}


def delivery_on_the_state() -> quadrs.Scenario:
    """The delivery preset with ``ON_THE_STATE``."""
    return quadrs.Scenario.preset("delivery").override(ON_THE_STATE)
