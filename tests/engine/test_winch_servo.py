"""The winch's servo (docs/model.md, "The last metres"): the line's rate follows the winch's
command within its acceleration limit, so a faster winch never pays out slower, and the
touchdown speed the docs tell to lower with `payload.winch_speed` moves with it one way."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

from tests.engine.test_last_metres import KW, fly, lowering

SPEEDS = (0.5, 1.0, 2.0, 3.0, 5.0)  # m/s


def _lowered(payout: float, speed: float, accel: float = 1.0) -> Any:
    """``lowering(payout)`` with the winch at ``speed`` and ``accel``, the flight long enough."""
    sc = lowering(
        payout,
        **{
            "payload.winch_speed": speed,
            "payload.winch_acceleration": accel,
            "integrator.duration": payout / speed + 2 * speed / accel + 11.0,
            "integrator.dt": 0.001,
        },
    )
    return fly(sc, record_every=10)


def test_a_faster_winch_never_pays_out_slower() -> None:
    """6 m of line from a 6 m hover (the parcel, 4.8 m up, reaches the ground 1.2 m before
    the line's end): the peak pay-out rate and the touchdown speed never fall as the winch's
    speed rises. Before, the servo's position gain a / v made 5 m/s pay out at 0.88 m/s at most
    (the peak fell from 1.85 m/s at 2 m/s)."""
    peaks, touchdowns = [], []
    for v in SPEEDS:
        flight = _lowered(6.0, v)
        assert not flight.diverged, v
        peaks.append(float(flight.trace["line_rate"].max()))
        touchdowns.append(float(flight.metrics.set_index("phase").loc["lower1", "touchdown_speed"]))
    assert all(b >= a - 1e-9 for a, b in itertools.pairwise(peaks)), peaks
    assert all(b >= a - 1e-3 for a, b in itertools.pairwise(touchdowns)), touchdowns
    # A slow winch reaches its speed; a fast one the profile's peak (accelerating at a, stopping
    # at a / 2) sqrt(2 a P / 3) = 2 m/s.
    assert peaks[0] == pytest.approx(0.5, abs=1e-6)
    assert peaks[-1] > 1.9, peaks


@pytest.mark.parametrize(("v", "a"), [(0.5, 0.5), (1.5, 1.0)])
def test_the_line_reaches_its_speed_when_the_acceleration_limit_says(v: float, a: float) -> None:
    """From rest the line's rate rises at ``a`` and reaches ``v`` at v / a, within the speed
    loop's lag a / kw (kw = 20 1/s), settled 5 / kw later."""
    winch = {"payload.winch_speed": v, "payload.winch_acceleration": a,
             "integrator.duration": 6.0 / v + 2 * v / a + 11.0}  # fmt: skip
    flight = fly(lowering(6.0, **winch), record_every=1)
    rate = flight.trace["line_rate"]

    def at(t: float) -> float:
        return float(np.interp(t, rate.index.to_numpy(), rate.to_numpy()))

    assert at(0.5 * v / a) == pytest.approx(0.5 * v, abs=1e-6)
    assert abs(at(v / a) - v) <= a / KW
    assert at(v / a + 5 / KW) == pytest.approx(v, abs=0.01 * a / KW)


def test_a_late_vehicle_lowers_over_the_point_not_on_the_way() -> None:
    """The vehicle starts 12 m short of the drop point when the lowering is due (t = 0; its
    tilt held to 0.3 rad, so that the PD flies there rather than tumbles): the winch waits
    until it is within LOWER_RADIUS (10 m, PX4's NAV_ACC_RAD) of the point, then pays out; the
    parcel touches down at the point. Before, the winch started on the time alone, the vehicle
    still on its way (issue 72: 70 m before the point on a late flight)."""
    from tests.engine.test_last_metres import DROP

    sc = lowering(6.0, **{"initial.position": [DROP[0] - 12.0, DROP[1], 6.0],
                          "controller.tilt_limit": 0.3,
                          "integrator.dt": 0.001})  # fmt: skip
    flight = fly(sc, record_every=10)
    assert not flight.diverged
    tr = flight.trace
    off = np.hypot(tr["x"] - DROP[0], tr["y"] - DROP[1])
    started = tr.index[tr["line"] > 1.0 + 1e-9][0]
    over = tr.index[off <= 10.0][0]
    assert started >= over - 0.011, (started, over)
    assert off[tr.index < started].min() > 9.9
    assert started > 0.3  # not on the time alone
    miss = flight.metrics.set_index("phase").loc["flight", "touchdown_miss"]
    assert miss < 1.0, miss
