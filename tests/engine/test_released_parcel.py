"""The released parcel (docs/model.md, "The rotors' downwash" and "The last metres"): a dropped
parcel falls through the rotors' wake where it is inside its column and through the wind
alone outside it; once it rests on the ground nothing of it is integrated any more."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import pytest

import quadrs

from .test_last_metres import DROP, fly, lowering

#: The wake's edge band (a fraction of its radius, each side) and the default rotor radius (m).
WAKE_EDGE, ROTOR_RADIUS = 0.1, 0.127


def drop(**extra: Any) -> quadrs.Scenario:
    """The slung preset hovering at 6.5 m over DROP and descending to 5.5 m: the hook opens as
    the parcel passes 4.9 m (a drop, ``payload.release = { height = 4.9 }``), still air."""
    changes: dict[str, Any] = {"payload.release": {"height": 4.9},
                               "trajectory.lower": [0.0, 0.0],
                               "trajectory.route": [[*DROP, 6.5], [*DROP, 5.5]],
                               "initial.position": [*DROP, 6.5], "trajectory.hold": [0.5, 0.0],
                               "integrator.dt": 5e-4, "integrator.duration": 6.0}  # fmt: skip
    changes.update(extra)
    return lowering(0.0, **changes)


def wake_speed(sc: quadrs.Scenario, thrust: np.ndarray) -> np.ndarray:
    """m/s, momentum theory's far wake 2 v_i, v_i = sqrt(T / (2 rho A)), A = 4 pi R^2."""
    area = 4 * math.pi * ROTOR_RADIUS**2  # the default radius (the scenario gives none)
    return 2 * np.sqrt(thrust / (2 * sc["gust.air_density"] * area))


def test_the_rotor_radius_is_checked_naming_it() -> None:
    with pytest.raises(ValueError, match=r"vehicle\.rotor_radius must be > 0, got -0\.1"):
        drop(**{"vehicle.rotor_radius": -0.1})


def test_inside_the_wake_the_parcel_falls_through_the_wakes_air() -> None:
    """Falling straight down below the hovering vehicle (inside the column), the parcel's
    speed through the air is v_z - w_d = v_z + 2 v_i: read from its drag, m (a_z + g) =
    -1/2 rho CdA v_rel^2 (the air falls faster than it: the drag pulls it down), a_z the
    central difference of its trace's v_z (its error O(dt^2), 1e-6 here). Without the
    downwash (before: always) the same reading gives its own speed through still air, v_z."""
    sc = drop()
    flight = fly(sc, record_every=1)
    m, tr = flight.metrics.set_index("phase").loc["flight"], flight.trace
    g, mc, dt = sc["environment.gravity"], sc["payload.mass"], sc["integrator.dt"]
    k = 0.5 * sc["gust.air_density"] * sc["payload.drag_area"]
    vz = tr["vzc"].to_numpy()
    az = np.empty_like(vz)
    az[1:-1] = (vz[2:] - vz[:-2]) / (2 * dt)
    tr = tr.assign(az=az)
    falling = tr[(tr.index > m["release_time"] + 2 * dt) & (tr["zc"] > 0.05)]
    assert len(falling) > 1000 and (falling[["vxc", "vyc"]].abs().to_numpy() < 1e-12).all()
    r = np.hypot(falling["xc"] - falling["x"], falling["yc"] - falling["y"])
    assert (r < 1e-9).all() and (falling["zc"] < falling["z"]).all()  # in the column
    through_air = np.sqrt(-(falling["az"] + g) * mc / k)
    expected = falling["vzc"] + wake_speed(sc, falling["U1"].to_numpy())
    assert (expected > 1.0).all()
    np.testing.assert_allclose(through_air, expected, rtol=1e-4)
    # The wake blows it down: it lands faster than the still-air fall of the same release.
    still = fly(drop(**{"vehicle.downwash": False})).metrics.set_index("phase").loc["flight"]
    assert m["touchdown_speed"] > still["touchdown_speed"] + 2.0, (m, still)


def test_outside_the_wake_the_parcel_falls_as_without_it() -> None:
    """A crosswind holds the hanging parcel 0.7 m downwind of the vehicle (the wake's column is
    0.18 m wide: R sqrt(2)), and blows it further as it falls: the fall is the same, bit for
    bit, with the downwash on or off."""
    wind = {"wind.speed": 8.0, "wind.heading": 90.0}
    on, off = (fly(drop(**wind, **{"vehicle.downwash": w}), record_every=1) for w in (True, False))
    release = on.metrics.set_index("phase").loc["flight", "release_time"]
    falling = on.trace[on.trace.index > release]
    r = np.hypot(falling["xc"] - falling["x"], falling["yc"] - falling["y"])
    radius = ROTOR_RADIUS * math.sqrt(2) * (1 + WAKE_EDGE)
    assert r.min() > radius, r.min()
    cols = ["xc", "yc", "zc", "vxc", "vyc", "vzc"]
    assert on.trace[cols].equals(off.trace[cols])


def test_a_released_parcel_at_rest_stays_where_it_rests_under_a_wind() -> None:
    """Released at touchdown in a crosswind: once it has rested SETTLE_TIME (0.5 s) nothing of
    it moves, to the bit (before: it crept downwind under the wind's drag, the friction's
    regularisation letting it slide), and its contact no longer counts as the parcel's."""
    sc = lowering(6.5, **{"wind.speed": 2.0, "wind.heading": 90.0})
    flight = fly(sc, record_every=1)
    m, tr = flight.metrics.set_index("phase").loc["flight"], flight.trace
    still = tr[tr.index > m["release_time"] + 0.5 + sc["integrator.dt"]]
    assert len(still) > 1000
    for col in ("xc", "yc", "zc", "vxc", "vyc", "vzc"):
        assert still[col].nunique() == 1, (col, still[col].min(), still[col].max())
    assert abs(still["zc"].iloc[0]) < 1e-3  # on the ground (sunk by its weight)
    phases = flight.metrics.set_index("phase")
    last = phases.index[-2]  # the climb away, after the release
    assert math.isnan(phases.loc[last, "touchdown_peak_force"])


def test_each_lanes_wake_and_rest_are_its_own_in_a_batch_as_alone() -> None:
    """Four drops whose parcels' drag differs (each falls, lands and comes to rest at its own
    time): in a batch, each realisation's fall through the wake, impact and rest are those
    it flies alone, bit for bit (the wake and the still parcel are per lane)."""
    sc = drop(**{"integrator.duration": 5.0,
                 "dispersions": {"payload.drag_area": {"dist": "uniform", "low": 0.05,
                                                       "high": 0.15}}})  # fmt: skip
    names = ["touchdown_speed", "touchdown_miss", "touchdown_peak_force", "release_time"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StabilityWarning)
        runs = quadrs.monte_carlo(sc, runs=4, seed=5, controllers=("pd",), progress=False).runs
    batch = runs[runs["phase"] == "flight"].set_index("realisation")[names]
    alone = [fly(sc, seed=5, realisation=i).metrics.set_index("phase").loc["flight", names]
             for i in range(4)]  # fmt: skip
    for i, m in enumerate(alone):
        assert m.tolist() == batch.loc[i].tolist(), (i, m, batch.loc[i])
    assert batch["touchdown_speed"].nunique() == 4
