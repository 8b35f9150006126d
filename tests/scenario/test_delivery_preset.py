"""The delivery preset (docs/model.md, "The delivery preset"): what it is built of, gains
stable at hover for both laws, and a whole mission flown by the PD leg by leg."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import quadrs
from quadrs.scenario.route import FLIGHT_PHASE


@pytest.fixture(scope="module")
def delivery() -> quadrs.Scenario:
    return quadrs.Scenario.preset("delivery")


def test_the_preset_is_the_vehicle_a_delivery_engineer_flies(delivery) -> None:
    assert delivery["payload.model"] == "cable" and delivery["actuator.model"] == "rotors"
    assert delivery["trajectory.interpolation"] == "route"
    assert delivery["gust.altitude"] == "vehicle" and delivery["gust.airspeed"] == "relative"
    assert len(delivery["gust.components"]) == 3 and delivery["wind.shear"] == "log"
    assert delivery["gust.start"] == 0.0
    assert delivery["gust.end"] == delivery["integrator.duration"]
    legs = [s for s in delivery.route.segments if s.kind == "leg"]
    transit = max(legs, key=lambda s: s.length)
    assert 500.0 <= transit.length <= 2000.0 and transit.peak_speed == 10.0
    # The flight lasts past the last arrival: the drop hover is flown.
    assert delivery.route.segments[-1].end == delivery["integrator.duration"]
    assert delivery.route.segments[-1].arrival < delivery["integrator.duration"] - 10.0


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_its_gains_are_stable_at_hover_with_the_line_and_the_rotors(delivery, controller) -> None:
    st = quadrs.stability(delivery, controller)
    assert st.stable and (st.poles["real"] < -0.05).all(), st.poles
    assert len(st.poles) == 22  # 12 rigid + 6 payload + 4 rotor speeds
    assert {"swing x"} <= set(st.poles["mode"])


def test_the_pd_flies_the_mission_leg_by_leg(delivery) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no step-size or stability warning either
        f = quadrs.simulate(delivery, "pd", seed=1)
    assert f.status == "ok"
    m = f.metrics.set_index("phase")
    assert list(m.index) == [s.name for s in delivery.route.segments] + [FLIGHT_PHASE]
    assert np.isfinite(m.to_numpy(dtype=float, na_value=np.nan)[:, :12]).all()
    # The line never goes slack, carries about the parcel's weight, and swings.
    weight = delivery["payload.mass"] * delivery["environment.gravity"]
    assert (m["slack_time"] == 0).all()
    assert 0.5 * weight < m.loc[FLIGHT_PHASE, "min_tension"] < weight
    assert weight < m.loc[FLIGHT_PHASE, "max_tension"] < 2 * weight
    assert 0.05 < m.loc[FLIGHT_PHASE, "max_swing"] < 1.2
    # It arrives: within a few metres of the drop point, hovering.
    end = f.trace.iloc[-1]
    target = np.array(delivery.route.segments[-1].target)
    assert np.linalg.norm(end[["x", "y", "z"]].to_numpy(dtype=float) - target) < 3.0
