"""The touchdown as flown (docs/model.md, "The last metres"): Hunt and Crossley's contact, the
touchdown's metrics at the contact instant converging in the step, the drop height, and the
winch's final approach."""

from __future__ import annotations

import itertools
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import quadrs
from tests.engine import delivery_on_the_state

from .test_last_metres import DROP, A, V, fly, lowering

#: The steps the convergence is shown over (s), and its tolerances (relative).
STEPS = (2e-3, 1e-3, 5e-4, 2.5e-4)
SPEED_TOLERANCE, FORCE_TOLERANCE = 1e-3, 2e-2


def delivery_touchdown(dt: float) -> dict[str, float]:
    """The delivery preset's touchdown (the `lower` phase) in its mean wind without the
    turbulence (whose draws are per step, so a smaller step would fly another gust)."""
    sc = delivery_on_the_state().override({"gust.enabled": False,
                                                      "integrator.dt": dt})  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StepSizeWarning)
        m = fly(sc).metrics.set_index("phase").loc["lower"]
    names = ("touchdown_speed", "touchdown_drift", "touchdown_drop_height", "touchdown_peak_force")
    return {name: float(m[name]) for name in names}


def test_the_touchdown_converges_in_the_step_on_the_delivery_preset() -> None:
    """Before (the linear spring-damper, speed and drift from the row before the contact):
    the peak specific force was the damper's jump c v0 / m at whatever depth the first step
    in contact found, and the speed the previous row's."""
    runs = [delivery_touchdown(dt) for dt in STEPS]
    for coarse, fine in itertools.pairwise(runs):
        speed = abs(coarse["touchdown_speed"] / fine["touchdown_speed"] - 1)
        force = abs(coarse["touchdown_peak_force"] / fine["touchdown_peak_force"] - 1)
        assert speed < SPEED_TOLERANCE and force < FORCE_TOLERANCE, (coarse, fine)
    finest = runs[-1]
    # The final approach's speed (0.3 m/s) with the vehicle's own motion in the mean wind.
    assert 0.25 < finest["touchdown_speed"] < 0.35, finest
    g = delivery_on_the_state()["environment.gravity"]
    assert finest["touchdown_drop_height"] == pytest.approx(
        finest["touchdown_speed"] ** 2 / (2 * g), rel=1e-12
    )
    # A few g: the contact law at 0.3 m/s (not the tens of g of the damper's jump).
    assert 30 < finest["touchdown_peak_force"] < 100, finest


APPROACH_HEIGHT, APPROACH_SPEED = 1.0, 0.2


def test_the_final_approach_touches_down_at_its_speed() -> None:
    """Before: no final approach (the winch paid out at its speed to the ground)."""
    extra: dict[str, Any] = {"payload.approach_height": APPROACH_HEIGHT,
                             "payload.approach_speed": APPROACH_SPEED,
                             "integrator.duration": 60.0}  # fmt: skip
    sc = lowering(6.0, **extra)
    # The lowering lasts the pay-out at each speed (the parcel hangs the hook's offset and
    # 1 m of line below the vehicle at 6 m: 3.95 m fast, the other 2.05 m at the approach's
    # speed) and the winch's ramps.
    (lower,) = [s for s in sc.route.segments if s.kind == "lower"]
    fast = 6.0 - sc["payload.attachment_offset"] - 1.0 - APPROACH_HEIGHT
    assert lower.end - lower.start == pytest.approx(fast / V + (6.0 - fast) / APPROACH_SPEED
                                                     + 2 * V / A)  # fmt: skip
    sc = sc.override({"integrator.duration": lower.end + 8.0 + 3.0})
    flight = fly(sc, record_every=1)
    assert not flight.diverged
    m, tr = flight.metrics.set_index("phase"), flight.trace
    low = m.loc["lower1"]
    assert abs(low["touchdown_speed"] - APPROACH_SPEED) < 0.01 * APPROACH_SPEED, low
    # The winch slowed where the parcel's height as the vehicle knows it (its height less the
    # hook's offset and the line) crossed the approach's height: its rate leaves V there.
    known = tr["z"] - sc["payload.attachment_offset"] - tr["line"]
    slowing = tr.index[(tr["line_rate"] < V - 1e-3) & (tr.index > 2.0)][0]
    assert abs(known.loc[slowing] - APPROACH_HEIGHT) < 5e-3, known.loc[slowing]
    # and then paid out at the approach's speed.
    # and then paid out at the approach's speed (the speed servo's settling, exp(-4 a t / v),
    # done).
    later = tr[(tr.index > slowing + 3.0) & (tr["zc"] > 0.05)]
    assert len(later) > 1000
    np.testing.assert_allclose(later["line_rate"], APPROACH_SPEED, rtol=0, atol=1e-4)


def test_final_approach_keys_are_checked_naming_them() -> None:
    cases = {
        "payload.approach_speed": {"payload.approach_height": 1.0},
        "payload.approach_height": {"payload.approach_height": -1.0, "payload.approach_speed": 0.1},
    }
    for key, change in cases.items():
        with pytest.raises(quadrs.ScenarioError, match=key.replace(".", r"\.")):
            lowering(5.0, **change)
    with pytest.raises(quadrs.ScenarioError, match=r"at most payload\.winch_speed"):
        lowering(5.0, **{"payload.approach_height": 1.0, "payload.approach_speed": 2 * V})


def test_the_linear_dampers_key_is_refused_naming_it() -> None:
    """`ground.damping` (the spring-damper's, N s/m) is gone: a scenario that gives it is
    refused naming it, not flown with another law's number."""
    with pytest.raises(quadrs.ScenarioError, match="damping"):
        lowering(5.0, **{"ground.damping": 100.0})


def test_hunt_crossley_has_no_jump_at_the_first_instant_of_contact() -> None:
    """The ground's force in the first row in contact is k d (1 + alpha d') at a depth d of at
    most one step's travel: it vanishes with the step. Before, the damper's c v0 at once
    (100 N s/m x 0.5 m/s = 50 N, whatever the step)."""
    dt = 1e-4
    sc = lowering(6.0, **{"integrator.dt": dt, "integrator.duration": 30.0})
    tr = fly(sc, record_every=1).trace
    k, alpha = sc["ground.stiffness"], sc["ground.dissipation"]
    mc, g = sc["payload.mass"], sc["environment.gravity"]
    first = int(np.argmax(tr["zc"].to_numpy() < 0))
    row = tr.iloc[first]
    depth, rate = -row["zc"], -row["vzc"]
    assert 0 < depth <= V * dt * 1.01
    ground = k * depth * (1 + alpha * rate)
    assert ground <= k * V * dt * 1.01 * (1 + alpha * V * 1.01) < 4.0, ground
    # The parcel's acceleration there is the line's pull, gravity and that force (and the
    # drag of 0.5 m/s of still air, under 0.2 m/s^2).
    up = row["tension"] / mc + ground / mc - g
    assert math.isclose(row["accel_c"], abs(up), abs_tol=0.2), (row["accel_c"], up)


SLACK = {"payload.release": "slack", "payload.slack_tension": 1.0, "payload.release_delay": 0.5}


def test_the_slack_hook_opens_its_delay_after_the_measured_tension_falls() -> None:
    """Before: no slack hook (the hook opened on an oracle: the parcel at rest, the line
    slack). Without the load cell's noise the measured tension is the line's."""
    sc = lowering(6.0, **SLACK)
    flight = fly(sc, record_every=1)
    tr, m = flight.trace, flight.metrics.set_index("phase")
    release = m.loc["flight", "release_time"]
    # The last step the tension read at or above the threshold before the hook opened: the
    # run below it began one step later, and the hook opened release_delay after that.
    before = tr[(tr.index < release) & (tr["tension"] >= SLACK["payload.slack_tension"])]
    first_slack = tr.index[tr.index > before.index[-1]][0]
    assert release == pytest.approx(first_slack + SLACK["payload.release_delay"], abs=1e-9)
    assert (tr.loc[first_slack:release, "tension"] < 1.0).all()
    touched = tr.index[tr["zc"] < 0][0]
    assert touched <= first_slack < release


def test_with_the_load_cells_noise_the_slack_hook_never_opens_before_the_touchdown() -> None:
    """The hanging parcel pulls 2.2 N; a threshold of 1 N with 0.3 N of noise: a run of
    noise below it for 0.5 s while it hangs never happens, and after the touchdown the noise
    above the threshold breaks some runs (the opening waits), per seed."""
    sc = lowering(6.0, **SLACK, **{"payload.tension_noise": 0.3})
    released, touched = [], []
    for seed in range(6):
        flight = fly(sc, seed=seed, record_every=10)
        release = flight.metrics.set_index("phase").loc["flight", "release_time"]
        tr = flight.trace
        touched.append(tr.index[tr["zc"] < 0][0])
        released.append(release)
    assert all(r > t + 0.5 for r, t in zip(released, touched, strict=True)), (released, touched)
    # The stream is the seed's: not every flight opens at the same step.
    assert len(set(released)) > 1, released


def test_the_load_cells_noise_is_the_realisations_own_in_a_batch_as_alone() -> None:
    """Its stream is keyed by (seed, realisation): a batch's lanes draw what single flights
    of the same realisations draw, bit for bit."""
    sc = lowering(6.0, **SLACK, **{"payload.tension_noise": 0.3})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StabilityWarning)
        runs = quadrs.monte_carlo(sc, runs=4, seed=3, controllers=("pd",)).runs
    batch = runs[runs["phase"] == "flight"].set_index("realisation")["release_time"]
    alone = [fly(sc, seed=3, realisation=i).metrics.set_index("phase").loc["flight"]
             for i in range(4)]  # fmt: skip
    assert [m["release_time"] for m in alone] == batch.loc[[0, 1, 2, 3]].tolist()
    assert batch.nunique() > 1, batch


def test_a_drop_in_still_air_lands_at_the_closed_form_speed() -> None:
    """`payload.release = { height = h }`: the hook opens where the parcel, once above h,
    comes down to h (here as the vehicle descends from 6.5 m to 5.5 m over the drop point);
    the parcel falls through still air with its quadratic drag, from the speed v0 it had at
    the release: v^2 = vt^2 + (v0^2 - vt^2) exp(-2 g H / vt^2) after a fall of H. Before:
    refused. Without the rotors' downwash (`vehicle.downwash = false`; with it:
    test_released_parcel.py)."""
    dt = 2.5e-4
    sc = lowering(0.0, **{"payload.release": {"height": 4.9}, "trajectory.lower": [0.0, 0.0],
                          "vehicle.downwash": False,
                          "trajectory.route": [[*DROP, 6.5], [*DROP, 5.5]],
                          "initial.position": [*DROP, 6.5], "trajectory.hold": [0.5, 0.0],
                          "integrator.dt": dt, "integrator.duration": 6.0})  # fmt: skip
    flight = fly(sc, record_every=1)
    m, tr = flight.metrics.set_index("phase").loc["flight"], flight.trace
    # Released as the vehicle passed 4.9 m + the hook's offset + the 1 m line: moving down.
    at = tr.loc[m["release_time"]]
    known = at["z"] - sc["payload.attachment_offset"] - 1.0
    assert 4.9 - 1e-3 < known <= 4.9 and at["vzc"] < -0.05, (known, at["vzc"])
    mc, g = sc["payload.mass"], sc["environment.gravity"]
    rho, cda = sc["gust.air_density"], sc["payload.drag_area"]
    vt = math.sqrt(2 * mc * g / (rho * cda))
    assert max(abs(at["vxc"]), abs(at["vyc"])) < 1e-12  # straight down: the closed form's
    v0, fall = -at["vzc"], at["zc"]
    closed = math.sqrt(vt**2 + (v0**2 - vt**2) * math.exp(-2 * g * fall / vt**2))
    assert abs(m["touchdown_speed"] - closed) < 1e-6, (m["touchdown_speed"], closed)
    assert m["touchdown_drop_height"] == pytest.approx(
        m["touchdown_speed"] ** 2 / (2 * g), rel=1e-12
    )
    # It landed below the hook, hard: the contact at several metres a second; and its fall
    # and impact are not the flight's peak (the parcel's metrics stop at the release).
    assert m["touchdown_miss"] < 1e-6 and m["touchdown_peak_force"] > 10 * g
    assert m["max_specific_force"] < 2 * g


def test_a_plans_deliver_and_its_release_in_flight_are_flown(tmp_path: Path) -> None:
    """Before: DO_WINCH action 4 and a DO_GRIPPER release without a lowering were refused."""
    from quadrs.scenario.route_files import RouteFileError, read_plan

    from .test_last_metres import HOME, _item, _plan

    lat, lon = HOME[0], HOME[1]
    takeoff = _item(22, 0, 0, 0, None, None, None, 6.0)
    there = _item(16, 2.0, 0, 0, None, lat, lon, 6.0)
    away = _item(16, 0, 0, 0, None, lat, lon, 7.0)
    deliver = read_plan(_plan(tmp_path, [takeoff, there, _item(42600, 1, 4, 6.0, 0.5),
                                         _item(211, 1, 0), away]), start_height=6.0)  # fmt: skip
    with pytest.raises(RouteFileError, match=r"DO_WINCH action 4 \(deliver\).*approach_height"):
        deliver.apply(lowering(5.0))
    approach = {"payload.approach_height": APPROACH_HEIGHT,
                "payload.approach_speed": APPROACH_SPEED, "integrator.duration": 60.0}  # fmt: skip
    sc = deliver.apply(lowering(5.0, **approach))
    assert sc["trajectory.lower"] == [6.0, 0.0] and sc["payload.release"] == "touchdown"
    m = fly(sc).metrics.set_index("phase").loc["flight"]
    assert abs(m["touchdown_speed"] - APPROACH_SPEED) < 0.01 * APPROACH_SPEED, m
    # A release in flight: dropped as the reference arrives over the point, 2 m further on.
    over = _item(16, 0, 0, 0, None, lat + 2.0 / 111_195, lon, 6.0)
    drop = read_plan(_plan(tmp_path, [takeoff, there, over, _item(211, 1, 0), away]),
                     start_height=6.0).apply(lowering(5.0))  # fmt: skip
    (leg,) = [g for g in drop.route.legs if g.length > 1.0 and g.target[2] == 6.0]
    assert drop["payload.release"] == leg.arrival
    assert drop.to_dict()["trajectory"].get("lower") is None
    m = fly(drop).metrics.set_index("phase").loc["flight"]
    assert m["release_time"] == pytest.approx(leg.arrival, abs=drop["integrator.dt"])
    assert m["touchdown_speed"] > 5.0  # a 4.9 m fall
