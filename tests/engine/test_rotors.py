"""Rotors (docs/model.md "Rotors"): four rotors with a speed lag and per-rotor thrust limits.

The engine's flights are checked against an integration written here from the equations
(docs/model.md sections 1 and "Rotors"), against the ideal actuators they must reduce to, and
against their limits."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest

import quadrs
from quadrs.runs.flight import METRIC_COLUMNS

OMEGA = ["omega_1", "omega_2", "omega_3", "omega_4"]


@pytest.fixture(scope="module")
def climb(paper: quadrs.Scenario) -> quadrs.Scenario:
    """A 3 s step climb to 2 m in still air with the paper's initial yaw of 0.5 rad, on rotors
    whose limits bind: the yaw demand and the climb both ask for more than they give."""
    return paper.override(
        {
            "actuator.model": "rotors",
            "actuator.thrust_max": 7.0,
            "actuator.thrust_min": 0.5,
            "gust.enabled": False,
            "integrator.duration": 3.0,
            "phases": [{"name": "all", "start": 0.0, "end": 3.0}],
        }
    )


# -- an independent integration of the same equations ------------------------------------------
def _allocation(layout: str, arm: float, cq: float) -> np.ndarray:
    """M: rows U1, tau_phi, tau_theta, tau_psi; column i is rotor i at angle a_i."""
    first = 45.0 if layout == "x" else 0.0
    a = np.radians(first + 90.0 * np.arange(4))
    spin = np.array([1.0, -1.0, 1.0, -1.0])
    return np.array([np.ones(4), arm * np.sin(a), -arm * np.cos(a), cq * spin])


_STILL = np.zeros(3)


class _Plant:
    """The vertical-spring quadrotor (docs/model.md section 1) on rotors, in still air."""

    def __init__(self, s: quadrs.Scenario) -> None:
        self.m = s["vehicle.mass"]
        self.mc = s["payload.mass"]
        self.g = s["environment.gravity"]
        self.inertia = np.add(s["vehicle.inertia"], s["vehicle.inertia_error"])
        self.kc = self.mc * (2 * np.pi * s["payload.natural_frequency"]) ** 2
        self.cc = s["payload.damping"]
        rho = s["gust.air_density"]
        self.drag = 0.5 * rho * s["vehicle.drag_area"]
        self.drag_lat = 0.5 * rho * s["vehicle.lateral_drag_area"]
        self.drag_c = 0.5 * rho * s["payload.drag_area"]
        self.kf = s["actuator.thrust_coefficient"]
        self.tau_m = s["actuator.time_constant"]
        self.t_min, self.t_max = s["actuator.thrust_min"], s["actuator.thrust_max"]
        arm, cq = s["vehicle.arm_length"], s["actuator.torque_ratio"]
        self.M = _allocation(s["actuator.layout"], arm, cq)
        self.M_inv = np.linalg.inv(self.M)

    def speed_command(self, u1: float, tau: np.ndarray) -> np.ndarray:
        wanted = self.M_inv @ np.array([u1, *tau])
        return np.sqrt(np.clip(wanted, self.t_min, self.t_max) / self.kf)

    def f(self, s: np.ndarray, w_cmd: np.ndarray, wind: np.ndarray = _STILL) -> np.ndarray:
        _, _, z, phi, th, psi, zc, vx, vy, vz, p, q, r, vzc = s[:14]
        wx, wy, wz = wind
        w = s[14:]
        u1, tx, ty, tz = self.M @ (self.kf * w**2)
        cf, sf, ct, st = np.cos(phi), np.sin(phi), np.cos(th), np.sin(th)
        cp, sp = np.cos(psi), np.sin(psi)
        fs = self.kc * (z - zc) + self.cc * (vz - vzc)
        ml = self.m + self.mc
        # Drag on the velocity through the air (the wind held over the step).
        ax = ((cf * st * cp + sp * sf) * u1 - self.drag_lat * (vx - wx) * abs(vx - wx)) / ml
        ay = ((cf * st * sp - sf * cp) * u1 - self.drag_lat * (vy - wy) * abs(vy - wy)) / ml
        az = (-self.m * self.g + cf * ct * u1 - fs - self.drag * (vz - wz) * abs(vz - wz)) / self.m
        azc = (-self.mc * self.g + fs - self.drag_c * (vzc - wz) * abs(vzc - wz)) / self.mc
        ixx, iyy, izz = self.inertia
        pd = ((iyy - izz) * q * r + tx) / ixx
        qd = ((izz - ixx) * p * r + ty) / iyy
        rd = ((ixx - iyy) * p * q + tz) / izz
        wd = (w_cmd - w) / self.tau_m
        return np.array([vx, vy, vz, p, q, r, vzc, ax, ay, az, pd, qd, rd, azc, *wd])


def _windy(climb: quadrs.Scenario) -> quadrs.Scenario:
    """The climb through test_wind's sheared mean wind with one ramp and one pulse gust."""
    from tests.engine.test_wind import WIND

    long = {"integrator.duration": 11.0, "phases": [{"name": "all", "start": 0.0, "end": 11.0}]}
    return climb.override({**{f"wind.{k}": v for k, v in WIND.items()}, **long})


@pytest.mark.parametrize("air", ["still", "sheared wind with a ramp and a pulse"])
def test_a_climb_with_binding_limits_matches_an_independent_integration(climb, air) -> None:
    """Controls from the engine's trace (held per step), rotor commands, rotor lag and plant
    from the equations, by a hand RK4: the states agree to 1e-9 over the whole climb, in still
    air and through a sheared mean wind with a 1-cosine ramp and pulse (the wind held per step
    as the engine met it, itself checked against the formulas of test_wind)."""
    from tests.engine.test_wind import expected_wind, held

    if air != "still":
        climb = _windy(climb)
    with warnings.catch_warnings():
        # The wind excites the PD's x/pitch mode that the 30 ms lag makes unstable (slowly:
        # see the test below); it does not matter to the equations being checked.
        warnings.simplefilter("ignore", quadrs.StabilityWarning)
        flight = quadrs.simulate(climb, "pd", record_every=1)
    tr = flight.trace
    names = climb.state_names
    assert names[14:] == OMEGA
    states = tr[names].to_numpy()
    controls = tr[["U1", "tau_phi", "tau_theta", "tau_psi"]].to_numpy()
    plant = _Plant(climb)
    dt = climb["integrator.dt"]
    wind = tr[["wind_x", "wind_y", "wind_z"]].to_numpy(float)
    if air == "still":
        assert not wind.any()
    else:
        t, z = tr.index.to_numpy(float), tr["z"].to_numpy(float)
        assert np.max(np.abs(wind - held(expected_wind(t, z)))) < 1e-12
        assert wind[:, 0].max() > 1.0 and np.abs(wind[:, 2]).max() > 0.3
    s = states[0].copy()
    hover = np.sqrt((plant.m + plant.mc) * plant.g / (4 * plant.kf))
    np.testing.assert_allclose(s[14:], hover, rtol=1e-15)
    clamped = 0
    worst = 0.0
    for k in range(len(tr) - 1):
        wanted = plant.M_inv @ controls[k]
        clamped += bool(np.any((wanted > plant.t_max) | (wanted < plant.t_min)))
        w_cmd = plant.speed_command(controls[k][0], controls[k][1:])
        k1 = plant.f(s, w_cmd, wind[k])
        k2 = plant.f(s + 0.5 * dt * k1, w_cmd, wind[k])
        k3 = plant.f(s + 0.5 * dt * k2, w_cmd, wind[k])
        k4 = plant.f(s + dt * k3, w_cmd, wind[k])
        s = s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        scale = np.maximum(1.0, np.abs(s))
        worst = max(worst, float(np.max(np.abs(s - states[k + 1]) / scale)))
    assert worst < 1e-9, worst
    # The limits did bind, for a good part of the climb (the yaw demand at the start and the
    # climb's thrust).
    assert clamped > 0.1 * len(tr), clamped


def _maneuver(paper: quadrs.Scenario, tau: float | None) -> quadrs.Scenario:
    """A 6 s smooth climb, sidestep and turn; rotors with time constant tau (dt = tau) and
    limits that never bind, or ideal actuators (tau None, dt = 1 ms)."""
    dt = 1e-3 if tau is None else tau
    s = paper.override(
        {
            "gust.enabled": False,
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.interpolation": "min_jerk",
            "trajectory.transition": 3.0,
            "trajectory.waypoints": [
                [0, 0, 0, 2, 0],
                [2, 1.0, -0.5, 2.5, 0.3],
                [6, 1.0, -0.5, 2.5, 0.3],
            ],
            "integrator.duration": 6.0,
            "integrator.dt": dt,
            "phases": [{"name": "all", "start": 0.0, "end": 6.0}],
        }
    )
    if tau is None:
        return s
    return s.override(
        {
            "actuator.model": "rotors",
            "actuator.time_constant": tau,
            "actuator.thrust_max": 1000.0,
        }
    )


@pytest.mark.filterwarnings("ignore::quadrs.hover.stability.StepSizeWarning")
def test_rotors_reduce_to_ideal_actuators_as_the_lag_vanishes(paper) -> None:
    """With limits that never bind, the rotor flight tends to the ideal flight at the same dt
    as tau (and dt with it) -> 0, at first order: halving tau halves the difference."""
    columns = ["x", "y", "z", "phi", "theta", "psi", "zc"]
    taus = [4e-3, 2e-3, 1e-3, 5e-4]
    gaps = []
    for tau in taus:
        ideal = quadrs.simulate(_maneuver(paper, None).override({"integrator.dt": tau}), "pd")
        rotors = quadrs.simulate(_maneuver(paper, tau), "pd")
        wanted = rotors.trace["U1"].to_numpy()
        assert np.all(np.isfinite(wanted))
        diff = rotors.trace[columns].to_numpy() - ideal.trace[columns].to_numpy()
        gaps.append(float(np.max(np.abs(diff))))
    # Measured: 3.06e-3, 1.52e-3, 7.58e-4, 3.78e-4 (m or rad) for tau = 4, 2, 1, 0.5 ms.
    ratios = [a / b for a, b in itertools.pairwise(gaps)]
    assert gaps[0] < 5e-3, gaps
    assert all(1.7 < r < 2.3 for r in ratios), (gaps, ratios)


def test_the_trace_and_state_names_carry_the_rotor_speeds(climb) -> None:
    assert climb.state_names[-4:] == OMEGA
    tr = quadrs.simulate(climb, "pd").trace
    assert set(OMEGA) <= set(tr.columns)
    kf = climb["actuator.thrust_coefficient"]
    w_max = np.sqrt(climb["actuator.thrust_max"] / kf)
    w_min = np.sqrt(climb["actuator.thrust_min"] / kf)
    speeds = tr[OMEGA].to_numpy()
    # A first-order lag toward commands inside the limits never leaves them.
    assert speeds.max() <= w_max * (1 + 1e-12) and speeds.min() >= w_min * (1 - 1e-12)
    assert speeds.max() > 0.99 * w_max


@pytest.mark.parametrize(
    ("changes", "key", "says"),
    [
        ({"actuator.thrust_max": 5.0}, "actuator.thrust_max", "too small to hover"),
        ({"payload.mass": 3.0}, "actuator.thrust_max", "too small to hover"),
        ({"actuator.thrust_min": 6.5}, "actuator.thrust_min", "too large to hover"),
        ({"actuator.time_constant": 1e-4}, "actuator.time_constant", "integrator.dt"),
        ({"actuator.layout": "h"}, "actuator.layout", "actuator.layout"),
        ({"actuator.thrust_coefficient": -1e-6}, "actuator.thrust_coefficient", "> 0"),
        ({"actuator.torque_ratio": 0.0}, "actuator.torque_ratio", "> 0"),
        ({"actuator.thrust_max": 0.4}, "actuator.thrust_max", "exceed actuator.thrust_min"),
        ({"vehicle.arm_length": 0.0}, "vehicle.arm_length", "rotors"),
    ],
)
def test_bad_rotors_are_refused_naming_the_key(paper, changes, key, says) -> None:
    with pytest.raises(quadrs.ScenarioError, match=says) as err:
        s = paper.override({"actuator.model": "rotors", "actuator.thrust_min": 0.5, **changes})
        quadrs.simulate(s, "pd")
    assert key in str(err.value)


def test_rotor_keys_disperse_per_realisation(climb) -> None:
    """Each lane of a batch flies its own rotors: a batch row is the single flight of its
    drawn values, bit for bit."""
    d = climb.override(
        {
            "dispersions": {
                "actuator.time_constant": {"dist": "uniform", "low": 0.02, "high": 0.05},
                "actuator.thrust_max": {"dist": "uniform", "low": 6.5, "high": 9.0},
            }
        }
    )
    mc = quadrs.monte_carlo(d, runs=5, seed=1, progress=False, spectra=False, controllers=["pd"])
    metrics = list(METRIC_COLUMNS)
    assert mc.runs["actuator.thrust_max"].nunique() == 5
    for i in (0, 3):
        fixed = mc.scenario_of(i)
        one = quadrs.simulate(fixed, "pd", seed=1, realisation=i)
        row = mc.runs[mc.runs.realisation == i]
        np.testing.assert_array_equal(
            row[metrics].to_numpy().view(np.uint64), one.metrics[metrics].to_numpy().view(np.uint64)
        )


def test_linearize_and_stability_see_the_rotor_states(climb) -> None:
    """The rotor speeds are states of the linear model: the lag's -1/tau on A's diagonal, four
    poles labelled "actuator", the rest those of the ideal vehicle moved a little by the lag.
    With RotorS's spin-up lag (12.5 ms) the paper's PD stays stable."""
    fast_rotors = climb.override({"actuator.time_constant": 0.0125})
    lin = quadrs.linearize(fast_rotors, "pd")
    assert list(lin.state_names[-4:]) == OMEGA and lin.A.shape == (18, 18)
    tau = fast_rotors["actuator.time_constant"]
    np.testing.assert_allclose(np.diag(lin.A)[-4:], -1 / tau, rtol=1e-12)
    st = quadrs.stability(fast_rotors, "pd")
    assert st.stable and len(st.poles) == 18
    fast = st.poles[st.poles["mode"] == "actuator"]
    assert len(fast) == 4 and (fast["real"] < -0.5 / tau).all()
    np.testing.assert_allclose(
        np.sort_complex(lin.poles()),
        np.sort_complex(st.poles["real"] + 1j * st.poles["imag"]),
        atol=1e-8,
    )


def test_the_rotor_lag_eats_the_paper_pds_lateral_margin(climb) -> None:
    """The lag is seen where it matters: the paper's PD, stable with ideal actuators, loses its
    x-pitch loop to the default 30 ms lag (a slow growing oscillation near 1 Hz), and the
    ideal vehicle's poles come back as the lag goes to zero."""
    assert climb["actuator.time_constant"] == 0.03
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        slow = quadrs.stability(climb, "pd")
        ideal = quadrs.stability(climb.override({"actuator.model": "ideal"}), "pd")
    assert ideal.stable and not slow.stable
    growing = slow.poles[slow.poles["real"] > 0]
    assert len(growing) == 2 and (np.abs(growing["imag"]) > 2 * np.pi * 0.5).all()
    assert (np.abs(growing["imag"]) < 2 * np.pi * 2.0).all()
    tiny = quadrs.linearize(
        climb.override({"actuator.time_constant": 1e-3, "integrator.dt": 1e-3}), "pd"
    )
    vehicle = np.sort_complex(tiny.poles()[np.abs(tiny.poles()) < 200])
    np.testing.assert_allclose(
        vehicle,
        np.sort_complex(
            quadrs.linearize(climb.override({"actuator.model": "ideal"}), "pd").poles()
        ),
        atol=0.05,
    )


def test_a_binding_limit_holds_every_rotor_and_counts_saturated_time(climb, tmp_path) -> None:
    """The actual thrusts kf w^2 stay inside [thrust_min, thrust_max]; saturated_time is the
    steps with a clamped command times dt, and the figure renders with them shaded."""
    flight = quadrs.simulate(climb, "pd", record_every=1)
    tr = flight.trace
    thrusts = tr[["thrust_1", "thrust_2", "thrust_3", "thrust_4"]].to_numpy()
    kf = climb["actuator.thrust_coefficient"]
    np.testing.assert_allclose(thrusts, kf * tr[OMEGA].to_numpy() ** 2, rtol=1e-15)
    t_min, t_max = climb["actuator.thrust_min"], climb["actuator.thrust_max"]
    assert thrusts.max() <= t_max * (1 + 1e-12) and thrusts.min() >= t_min * (1 - 1e-12)
    assert thrusts.max() > 0.99 * t_max
    saturated = tr["saturated"].to_numpy()
    assert set(np.unique(saturated)) <= {0.0, 1.0}
    dt = climb["integrator.dt"]
    # The trace's last row is t = duration, after the last step: not a step of the metric.
    expected = saturated[:-1].sum() * dt
    got = float(flight.metrics["saturated_time"].iloc[0])
    assert got > 0.1 and got == pytest.approx(expected, rel=1e-12, abs=dt)
    ideal = quadrs.simulate(climb.override({"actuator.model": "ideal"}), "pd")
    assert float(ideal.metrics["saturated_time"].iloc[0]) == 0.0

    from quadrs import plots

    fig = plots.rotors(flight, tmp_path / "rotors")
    assert len(fig.axes) == 2 and (tmp_path / "rotors.png").stat().st_size > 0
    with pytest.raises(ValueError, match=r"actuator\.model = 'rotors'"):
        plots.rotors(ideal)


def test_saturated_intervals_are_the_runs_of_the_flag() -> None:
    from quadrs import plots  # noqa: F401  (quadrs.plots imports plots_rotors)
    from quadrs.plots.rotors import saturated_intervals

    t = np.arange(8) * 0.5
    assert saturated_intervals(t, [1, 1, 0, 0, 1, 0, 1, 1], 0.5) == [
        (0.0, 1.0),
        (2.0, 2.5),
        (3.0, 4.0),
    ]
    assert saturated_intervals(t, np.zeros(8), 0.5) == []
