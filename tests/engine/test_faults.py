"""Rotor faults and battery sag (docs/model.md, "Rotor faults and battery sag"): a failed rotor
gives a fraction of its commanded thrust from its fault's start, the battery lowers the rotors'
thrust limit linearly over the flight, and a fault that leaves too little thrust to hover is
refused, never flown to an ``ok`` that is really a fall."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

import quadrs
from quadrs import _core
from quadrs.scenario import units
from tests.conftest import DELIVERY_DROP
from tests.engine.test_rotors import OMEGA, _Plant

U = ["U1", "tau_phi", "tau_theta", "tau_psi"]
THRUST = ["thrust_1", "thrust_2", "thrust_3", "thrust_4"]


@pytest.fixture(scope="module")
def climb(paper: quadrs.Scenario) -> quadrs.Scenario:
    """test_rotors' 3 s step climb on rotors whose limits bind (level at the start: the
    paper's 0.5 rad yaw error with a fault on top tilts the vehicle over), with rotor 2 giving
    90 % of its command from 1 s and a battery that loses 10 % of thrust_max by the end."""
    return paper.override(
        {
            "actuator.model": "rotors",
            "actuator.thrust_max": 7.0,
            "actuator.thrust_min": 0.5,
            "actuator.faults": [{"rotor": 2, "start": 1.0, "thrust_fraction": 0.9}],
            "actuator.battery_sag": 0.1,
            "initial.attitude": [0.0, 0.0, 0.0],
            "gust.enabled": False,
            "integrator.duration": 3.0,
            "phases": [{"name": "all", "start": 0.0, "end": 3.0}],
        }
    )


def _command(plant: _Plant, s: quadrs.Scenario, u: np.ndarray, t: float) -> np.ndarray:
    """The rotors' speed command from docs/model.md: M^-1 u clamped to [thrust_min, thrust_max
    (1 - sag t / T)], times each failed rotor's fraction from its start."""
    sag, duration = s["actuator.battery_sag"], s["integrator.duration"]
    limit = plant.t_max * (1.0 - sag * t / duration)
    thrust = np.clip(plant.M_inv @ u, plant.t_min, limit)
    for f in s["actuator.faults"]:
        if t >= f["start"]:
            thrust[f["rotor"] - 1] *= f["thrust_fraction"]
    return np.sqrt(thrust / plant.kf)


def test_a_failed_rotor_and_a_sagging_battery_match_an_independent_integration(climb) -> None:
    """Controls from the engine's trace, rotor commands with the fault and the sag, rotor lag
    and plant from the equations (test_rotors' plant), by a hand RK4: the states agree to 1e-9
    over the climb, and the fault and the sag both bind."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StabilityWarning)
        flight = quadrs.simulate(climb, "pd", record_every=1)
    assert flight.status == "ok"
    tr = flight.trace
    states = tr[climb.state_names].to_numpy()
    controls = tr[U].to_numpy()
    t = tr.index.to_numpy(float)
    plant = _Plant(climb)
    dt = climb["integrator.dt"]
    s = states[0].copy()
    worst = 0.0
    for k in range(len(tr) - 1):
        w_cmd = _command(plant, climb, controls[k], t[k])
        k1 = plant.f(s, w_cmd)
        k2 = plant.f(s + 0.5 * dt * k1, w_cmd)
        k3 = plant.f(s + 0.5 * dt * k2, w_cmd)
        k4 = plant.f(s + dt * k3, w_cmd)
        s = s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        worst = max(worst, float(np.max(np.abs(s - states[k + 1]) / np.maximum(1.0, np.abs(s)))))
    assert worst < 1e-9, worst
    # The sagging limit bound late in the climb (the command clamped below 7 N).
    late = t > 1.5
    limit = 7.0 * (1.0 - 0.1 * t / 3.0)
    wanted = controls @ plant.M_inv.T
    assert np.any(wanted[late].max(axis=1) > limit[late])
    assert np.any(tr["saturated"].to_numpy()[late] == 1.0)


def test_the_thrust_column_is_the_fraction_of_the_command_from_the_start(climb) -> None:
    """From the trace alone: the rotors' speeds obey the lag dw/dt = (w_cmd - w) / tau with
    w_cmd^2 = f T_cmd / kf, so one RK4 step is exactly w' = c + (w - c) R(-dt / tau); the
    thrust column kf w^2 of the failed rotor is the fraction of the (clamped) command from the
    fault's start on, and its full command before it."""
    flight = quadrs.simulate(climb, "pd", record_every=1)
    tr = flight.trace
    plant = _Plant(climb)
    t = tr.index.to_numpy(float)
    dt, tau = climb["integrator.dt"], climb["actuator.time_constant"]
    z = -dt / tau
    gain = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    w = tr[OMEGA].to_numpy()
    thrust = tr[THRUST].to_numpy()
    np.testing.assert_allclose(thrust, plant.kf * w**2, rtol=1e-15)
    controls = tr[U].to_numpy()
    limit = 7.0 * (1.0 - 0.1 * t / 3.0)
    clamped = np.clip(controls @ plant.M_inv.T, 0.5, limit[:, None])
    fraction = np.where(t >= 1.0, 0.9, 1.0)
    told = clamped.copy()
    told[:, 1] *= fraction  # rotor 2
    c = np.sqrt(told / plant.kf)
    predicted = plant.kf * (c[:-1] + (w[:-1] - c[:-1]) * gain) ** 2
    np.testing.assert_allclose(thrust[1:], predicted, rtol=1e-12)
    # The same prediction without the fault misses rotor 2 after the start, and only there.
    c_healthy = np.sqrt(clamped / plant.kf)
    healthy = plant.kf * (c_healthy[:-1] + (w[:-1] - c_healthy[:-1]) * gain) ** 2
    off = np.abs(thrust[1:] - healthy) > 1e-9 * np.abs(healthy)
    assert not off[t[:-1] < 1.0].any()
    assert off[t[:-1] >= 1.0, 1].all() and not off[:, [0, 2, 3]].any()


# -- the delivery vehicle --------------------------------------------------------------------
@pytest.fixture(scope="module")
def drop() -> quadrs.Scenario:
    """The delivery preset over its drop point (19 s: a 2 m descent, then a 15 s hover)."""
    return quadrs.Scenario.preset("delivery").override(DELIVERY_DROP)


def test_a_weak_motor_flies_on_and_tracks_worse(drop) -> None:
    """Rotor 1 at 80 % from 5 s (4 x 12 N healthy, 45.6 N left for 26.5 N of weight): the
    flight ends ok over the drop point, the other rotors and the attitude take up the loss,
    and the tracking is worse than on healthy rotors through the same gusts."""
    weak = drop.override({"actuator.faults": [{"rotor": 1, "start": 5.0, "thrust_fraction": 0.8}]})
    a = quadrs.simulate(drop, "pd", seed=3, record_every=10)
    b = quadrs.simulate(weak, "pd", seed=3, record_every=10)
    assert a.status == b.status == "ok"
    before = b.trace.index < 5.0
    np.testing.assert_array_equal(
        a.trace.loc[before, "z"].to_numpy(), b.trace.loc[before, "z"].to_numpy()
    )
    flight = a.metrics.set_index("phase").loc["flight"]
    weak_flight = b.metrics.set_index("phase").loc["flight"]
    assert weak_flight["tracking_rms"] > flight["tracking_rms"]
    # In the hover the airframe's torques balance, so the rotors' actual thrusts stay near
    # one another; rotor 1 is told 1 / 0.8 of what it gives.
    hover = b.trace.index > 10.0
    thrust = b.trace.loc[hover, THRUST].mean()
    assert abs(thrust["thrust_1"] / thrust["thrust_3"] - 1.0) < 0.05, thrust


def test_too_little_thrust_to_hover_is_refused_with_the_numbers(drop) -> None:
    """0.3 on three rotors from 10, 11 and 12 s leaves 3 x 3.6 + 12 = 22.8 N for 26.5 N: the
    scenario is refused in one line naming the fault that takes the total below the weight
    (the third), the total and the weight, so no flight ends ``ok`` while falling."""
    faults = [{"rotor": r, "start": 9.0 + r, "thrust_fraction": 0.3} for r in (1, 2, 3)]
    with pytest.raises(quadrs.ScenarioError) as e:
        drop.override({"actuator.faults": faults})
    message = str(e.value)
    assert e.value.key == "actuator.faults[2].thrust_fraction"
    assert "too little thrust to hover" in message and "\n" not in message
    assert ("22.8" in message or "22.7999" in message) and "26.487" in message
    with pytest.raises(quadrs.ScenarioError, match=r"actuator\.battery_sag = 0\.5 leaves"):
        drop.override({"actuator.battery_sag": 0.5})


def test_a_lost_rotor_ends_with_an_honest_status(drop) -> None:
    """Rotor 1 stuck off from 8 s: 36 N would hold the weight, but no four-rotor allocation
    holds the attitude on three (docs/model.md): the flight ends early, on its tilt, rate or
    the ground, never ``ok``."""
    lost = drop.override({"actuator.faults": [{"rotor": 1, "start": 8.0, "thrust_fraction": 0.0}]})
    f = quadrs.simulate(lost, "pd", seed=3)
    assert f.status in {"tilt", "rate", "ground", "distance", "speed"}, f.status
    assert 8.0 < f.diverged_at < 19.0


@pytest.mark.parametrize(
    ("changes", "key", "says"),
    [
        ({"actuator.faults": [{"rotor": 0, "start": 1.0, "thrust_fraction": 0.5}]},
         "actuator.faults[0].rotor", "must be 1, 2, 3 or 4, got 0"),
        ({"actuator.faults": [{"rotor": 1, "start": -2.0, "thrust_fraction": 0.5}]},
         "actuator.faults[0].start", "got -2.0"),
        ({"actuator.faults": [{"rotor": 1, "start": 1.0, "thrust_fraction": 1.2}]},
         "actuator.faults[0].thrust_fraction", "must be in [0, 1]"),
        ({"actuator.faults": [{"rotor": 1, "start": 1.0}]},
         "actuator.faults[0]", "thrust_fraction"),
        ({"actuator.battery_sag": 1.0}, "actuator.battery_sag", "must be in [0, 1)"),
        ({"actuator.battery_sag": -0.1}, "actuator.battery_sag", "must be in [0, 1)"),
    ],
)  # fmt: skip
def test_bad_fault_keys_are_one_line_naming_the_key(drop, changes, key, says) -> None:
    with pytest.raises(quadrs.ScenarioError) as e:
        drop.override(changes)
    assert key in str(e.value) and says in str(e.value) and "\n" not in str(e.value)


def test_faults_need_rotors(paper) -> None:
    """The ideal actuators have no rotor to fail: refused, naming the key."""
    fault = {"actuator.faults": [{"rotor": 1, "start": 1.0, "thrust_fraction": 0.5}]}
    with pytest.raises(
        quadrs.ScenarioError, match=r'actuator\.faults needs actuator\.model = "rotors"'
    ):
        paper.override(fault)
    with pytest.raises(quadrs.ScenarioError, match=r"actuator\.battery_sag needs"):
        paper.override({"actuator.battery_sag": 0.1})


def test_fault_keys_have_units_labels_and_disperse(drop) -> None:
    """Every new key has a unit and a label from the engine; the numeric ones disperse, and a
    batch's row is the single flight of its realisation's scenario, bit for bit."""
    for key, unit in [
        ("actuator.faults.rotor", "-"),
        ("actuator.faults.start", "s"),
        ("actuator.faults.thrust_fraction", "-"),
        ("actuator.battery_sag", "-"),
    ]:
        assert _core.KEY_UNITS[key] == unit and _core.KEY_LABELS[key].strip()
        assert units.unit(key.replace("faults.", "faults[0].")) == unit
    short = drop.override(
        {
            "actuator.faults": [{"rotor": 4, "start": 2.0, "thrust_fraction": 0.85}],
            "dispersions": {
                "actuator.faults[0].thrust_fraction": {"dist": "uniform", "low": 0.7, "high": 1.0},
                "actuator.faults[0].start": {"dist": "uniform", "low": 1.0, "high": 6.0},
                "actuator.battery_sag": {"dist": "uniform", "low": 0.0, "high": 0.2},
            },
        }
    )
    mc = quadrs.monte_carlo(short, runs=3, seed=5, controllers=("pd",))
    runs = mc.runs
    assert runs["actuator.faults[0].thrust_fraction"].nunique() == 3
    for i in range(3):
        single = quadrs.simulate(short.realisation(5, i), "pd", seed=5, realisation=i)
        row = runs[(runs["realisation"] == i) & (runs["phase"] == "flight")].iloc[0]
        flight = single.metrics.set_index("phase").loc["flight"]
        assert row["tracking_rms"] == flight["tracking_rms"]
    with pytest.raises(quadrs.ScenarioError, match="not a number"):
        drop.override(
            {
                "actuator.faults": [{"rotor": 4, "start": 2.0, "thrust_fraction": 0.85}],
                "dispersions": {
                    "actuator.faults[0].rotor": {"dist": "uniform", "low": 1, "high": 4}
                },
            }
        )


def test_a_weak_motor_on_the_last_leg_is_one_mission_run(tmp_path) -> None:
    """Will the parcel survive a weak motor on the last leg?" is one command: the delivery
    route with rotor 2 at 75 % from the descent (about 140 s), 4 runs."""
    fault = "actuator.faults=[{rotor = 2, start = 140.0, thrust_fraction = 0.75}]"
    r = subprocess.run(
        [sys.executable, "-m", "quadrs.cli", "mission", "--preset", "delivery", "--set", fault,
         "--runs", "4", "--no-progress"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "descent" in r.stdout and "drop" in r.stdout
    bad = subprocess.run(
        [sys.executable, "-m", "quadrs.cli", "mission", "--preset", "delivery", "--set",
         "actuator.faults=[{rotor = 7, start = 1.0, thrust_fraction = 0.5}]", "--runs", "4"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert bad.returncode == 2
    assert bad.stderr.strip().count("\n") == 0 and "actuator.faults[0].rotor" in bad.stderr
