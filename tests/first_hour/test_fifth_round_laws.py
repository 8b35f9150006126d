"""A delivery engineer's first hour, fifth round (issue 72), the laws' items: each of the four
laws tuned for the delivery preset flies its route (item 2), and the start trimmed in the wind
is an equilibrium of the closed loop, the law's integrators included (item 6), the SMC's at its
reference. Each fails on the code before issue 72's fix but the last, a characterisation of the
lift's jolt."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs.design.mission_tables import TRACK_LIMIT

LAWS = ("pd", "smc", "px4", "se3")

#: The delivery vehicle hovering 6 s at its start, 2 m up (then a 1 m climb ends the flight), in
#: a steady 8 m/s wind (at 20 ft, log shear: 6.2 m/s at 2 m) across the route, no turbulence.
HOVER_IN_WIND = {
    "trajectory.route": [[0.0, 0.0, 2.0], [0.0, 0.0, 3.0]],
    "trajectory.hold": [6.0, 0.0],
    "trajectory.lower": [0.0, 0.0],
    "wind.speed": 8.0,
    "gust.enabled": False,
}


@pytest.fixture(scope="module")
def delivery() -> quadrs.Scenario:
    return quadrs.Scenario.preset("delivery")


# -- 2. each law tuned for the delivery preset flies its route ---------------------------------
@pytest.fixture(scope="module")
def route_mc(delivery: quadrs.Scenario) -> quadrs.MonteCarloResult:
    """Three flights of the whole route by each law through the same gusts (about 4 s)."""
    return quadrs.monte_carlo(delivery, runs=3, seed=0, controllers=LAWS, progress=False,
                              spectra=False)  # fmt: skip


@pytest.mark.parametrize("law", LAWS)
def test_each_law_flies_the_delivery_route(route_mc: quadrs.MonteCarloResult, law: str) -> None:
    """In the 6.6 m/s crosswind at 30 m with the body's and rotors' drag, every law stays on
    the route (`quadrs mission`'s verdict: tracking and cross-track within 10 m, none
    diverged); the three laws retuned for it with a margin, their worst tracking below 6 m
    (before the retuning the SMC trailed 17 m, PX4 12 m and the geometric law 34 m in one
    flight of four). The PD, the preset's own tuning and unchanged, trails about 7 m."""
    runs = route_mc.runs
    flight = runs[(runs.controller == law) & (runs.phase == "flight")]
    assert len(flight) == 3
    assert not flight.diverged.any(), law
    assert (flight.status == "ok").all(), flight.status.tolist()
    assert TRACK_LIMIT == 10.0
    bound = TRACK_LIMIT if law == "pd" else 6.0
    worst = float(flight.max_tracking.max())
    assert worst < bound, (law, worst)
    assert float(flight.max_cross_track.max()) < bound, law


def test_the_smc_integral_surface_holds_the_reference_in_a_steady_wind(
    delivery: quadrs.Scenario,
) -> None:
    """The SMC's integral sliding surface (`controller.smc.integral`, the preset's delivery
    tuning) takes out the offset the wind's drag holds the paper's surface at."""
    # From rest (not trimmed), 30 s: the integral builds up from zero.
    hover = delivery.override(HOVER_IN_WIND | {"navigation.mode": "truth", "initial.trim": "rest",
                                               "trajectory.hold": [30.0, 0.0]})  # fmt: skip
    offsets = {}
    for integral in ([0.0, 0.0, 0.0], [0.3, 0.3, 2.0]):
        s = hover.override({"controller.smc.integral": integral})
        t = quadrs.simulate(s, "smc", record_every=100).trace
        offsets[integral[0]] = float(np.hypot(t.x - t.x_ref, t.y - t.y_ref).iloc[-1])
    assert offsets[0.0] > 4.0, offsets  # the paper's surface: metres downwind
    # After 30 s the integral has taken out nine tenths of it (0.54 m against 5.07 m).
    assert offsets[0.3] < 0.15 * offsets[0.0], offsets


def test_a_negative_smc_integral_gain_is_refused_by_name(
    delivery: quadrs.Scenario,
) -> None:
    with pytest.raises(ValueError, match=r"controller\.smc\.integral\[1\]"):
        delivery.override({"controller.smc.integral": [0.3, -1.0, 2.0]})


# -- 6. the start trimmed in the wind is an equilibrium -----------------------------------------
def swing_drift(s: quadrs.Scenario, law: str, until: float = 5.0) -> tuple[float, float]:
    """The parcel's swing at the start and its largest departure from it over `until` s."""
    t = quadrs.simulate(s, law, record_every=10).trace
    swing = t.swing[t.index <= until].to_numpy()
    return float(swing[0]), float(np.max(np.abs(swing - swing[0])))


@pytest.mark.parametrize("law", LAWS)
def test_a_hover_from_the_trimmed_start_holds_its_swing(
    delivery: quadrs.Scenario, law: str
) -> None:
    """Trimmed in a steady wind, each law's start is its closed loop's equilibrium (the tilt,
    the swing, the integrators): hovering there, the parcel stays within 1e-3 rad of its
    start's swing for 5 s (before: 0.142 -> 0.026 -> 0.345 rad in 2 s, the law levelling the
    vehicle the plant's trim had tilted)."""
    hover = delivery.override(HOVER_IN_WIND | {"navigation.mode": "truth"})
    start, drift = swing_drift(hover, law)
    assert start == pytest.approx(0.142, abs=0.002)  # the parcel's drag on its weight at 6.2 m/s
    assert drift < 1e-3, (law, drift)


# -- 6, follow-up: each law's start at its own equilibrium, the SMC's at its reference ----------
def start_offset(s: quadrs.Scenario, law: str) -> tuple[np.ndarray, pd.DataFrame]:
    """The start's position less the reference (m, x y z) and the trace."""
    t = quadrs.simulate(s, law, record_every=10).trace
    first = t.iloc[0]
    offset = np.array([first.x - first.x_ref, first.y - first.y_ref, first.z - first.z_ref])
    return offset, t


@pytest.mark.parametrize(("law", "bound"), [("smc", 0.01), ("px4", 0.02)])
def test_a_law_with_integral_action_starts_at_its_reference(
    delivery: quadrs.Scenario, law: str, bound: float
) -> None:
    """In the steady 8 m/s wind the SMC's integral surface starts at its reference: the start
    is solved with the position pinned there and the integrals within their limits (before:
    3.54 m upwind, its y integral wound past its limit, where it no longer moves and any
    value balances). PX4 within 2 cm: its horizontal anti-windup, tracking the acceleration
    the thrust gives, leaves 1.1 cm. The hover holds there: within 1 mm and 1e-3 rad of swing
    for 5 s."""
    hover = delivery.override(HOVER_IN_WIND | {"navigation.mode": "truth"})
    offset, t = start_offset(hover, law)
    assert np.abs(offset).max() < bound, (law, offset)
    early = t[t.index <= 5.0]
    drift = np.hypot(early.x - early.x.iloc[0], early.y - early.y.iloc[0]).max()
    assert drift < 1e-3, (law, drift)
    assert np.abs(early.swing - early.swing.iloc[0]).max() < 1e-3


@pytest.mark.parametrize("law", ["pd", "se3"])
def test_a_law_without_integral_action_starts_downwind(delivery: quadrs.Scenario, law: str) -> None:
    """The PD and the geometric law hold the wind's drag with their position error: they start
    downwind (+y) of the reference, 2.5 m and 1.2 m at 8 m/s, on the route's side of 10 m."""
    hover = delivery.override(HOVER_IN_WIND | {"navigation.mode": "truth"})
    offset, _ = start_offset(hover, law)
    assert 1.0 < offset[1] < TRACK_LIMIT, (law, offset)
    assert abs(offset[0]) < 1e-3, (law, offset)


def test_the_smc_is_refused_a_wind_its_integral_surface_cannot_hold(
    delivery: quadrs.Scenario,
) -> None:
    """At 12 m/s (at 20 ft) holding the drag at the reference needs the integral surface's term
    past its limit g: the SMC has no equilibrium there and its flight is refused by name (it
    used to start 1 m downwind, its integral at the limit, without a word); the PD flies."""
    hover = delivery.override(HOVER_IN_WIND | {"navigation.mode": "truth", "wind.speed": 12.0})
    match = r"controller\.smc\.integral = \[0\.3, 0\.3, 2\.0\]: .* on y past its limit"
    with pytest.raises(quadrs.ScenarioError, match=match) as refused:
        quadrs.simulate(hover, "smc")
    assert "controller.smc.eta" in str(refused.value) and "wind.speed" in str(refused.value)
    with pytest.raises(quadrs.ScenarioError, match=r"controller\.smc\.integral"):
        quadrs.monte_carlo(hover, runs=1, controllers=("pd", "smc"), progress=False)
    assert quadrs.simulate(hover, "pd").status == "ok"


def test_the_lift_jolt_is_gone_with_the_filter_aligned_on_the_pad(
    delivery: quadrs.Scenario,
) -> None:
    """The delivery's jolt at the lift (1 SMC flight in 20, about 15 g) was not the law's start:
    reading the state, no SMC flight of 20 moves its parcel by more than 0.3 g in the first 4 s.
    It was the filter's: started on a GNSS fix alone (its initial vertical sigma the GNSS's
    0.75 m), realisation 3's estimate starts 0.70 m above the truth, the law descends about 1 m
    to it and the parcel, 0.95 m below the vehicle, strikes the pad. Aligned on the pad (the
    preset's ``navigation.height_error`` 0.1 m, as PX4's EKF2 sets its height origin there),
    the same flight's parcel stays clear of it under 0.3 g."""
    lift = delivery.override(HOVER_IN_WIND | {"wind.speed": 5.0, "gust.enabled": True})
    truth = lift.override({"navigation.mode": "truth"})
    peaks = [
        float(quadrs.simulate(truth, "smc", realisation=i, record_every=5).trace.accel_c.max())
        for i in range(20)
    ]
    assert max(peaks) < 0.3 * 9.81, peaks
    gnss = lift.override({"navigation.height_error": None})
    t = quadrs.simulate(gnss, "smc", realisation=3, record_every=1).trace
    assert t.z_est.iloc[0] - t.z.iloc[0] > 0.5
    early = t[t.index <= 4.0]
    assert early.zc.min() < 0.0 and early.accel_c.max() > 5 * 9.81
    t = quadrs.simulate(lift, "smc", realisation=3, record_every=1).trace
    assert abs(t.z_est.iloc[0] - t.z.iloc[0]) < 0.3
    early = t[t.index <= 4.0]
    assert early.zc.min() > 0.3 and early.accel_c.max() < 0.3 * 9.81
