"""The rigid body (`vehicle.body = "rigid"`) against RotorPy 3.0 itself: its `Multirotor`
(aerodynamics on, its parameters mapped from the quadrs scenario) under its `SE3Control`, and
quadrs' rigid body on the rotors under the `se3` law, fly the same flights: a hover, a 10 m
leg, a 3 m/s crosswind and a replayed turbulence series, with no aerodynamics and with all of
them (body drag, the rotors' H-force, blade flapping, translational lift), and in the
crosswind each term alone.

RotorPy's own `Multirotor.step` integrates with `solve_ivp` (RK45, adaptive), whose error alone
is above 1e-6 m over 12 s; here RotorPy's state derivative (`Multirotor._s_dot_fn`, its
equations untouched) is integrated with classical RK4 at quadrs' step, controls and wind held
over the step, and the quaternion renormalised after each step as `Multirotor.step` does:
the integrator is quadrs', the physics and the law are RotorPy's.

RotorPy has no payload: quadrs' cable carries 1e-9 kg (its pull, ~1e-8 N, moves the vehicle
by less than 1e-8 m). The references have zero yaw rate (RotorPy's `W_d = (0, 0, yaw_dot)`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rotorpy.controllers.quadrotor_control import SE3Control
from rotorpy.vehicles.multirotor import Multirotor

import quadrs
from tests.engine import delivery_on_the_state

#: The weightless payload's swing is marginal and its bounce fast: both known, both harmless here.
pytestmark = [
    pytest.mark.filterwarnings("ignore::quadrs.hover.stability.StabilityWarning"),
    pytest.mark.filterwarnings("ignore:integrator.dt"),
]

DURATION = 12.0
DT = 0.002
#: N/(m/s)^2, the delivery preset's body drag (docs/model.md, "Bodies").
DRAG = [0.12, 0.12, 0.2]
#: Rotor aerodynamics (RotorPy's k_d, k_z; k_flap; k_h), for the test: each large enough to
#: move the flight by millimetres at least.
ROTOR_DRAG = [6e-4, 6e-4, 1.2e-3]
FLAPPING = 1e-5
LIFT = 3e-3
TERMS = {
    "none": set(),
    "all": {"drag", "rotor_drag", "flapping", "lift"},
    "drag": {"drag"},
    "rotor_drag": {"rotor_drag"},
    "flapping": {"flapping"},
    "lift": {"lift"},
}
#: quadrs' se3 defaults (docs/model.md, "The geometric controller `se3`").
GAINS = {"kx": [1.0, 1.0, 4.0], "kv": [1.6, 1.6, 3.2], "kR": [100.0, 100.0, 40.0],
         "kW": [14.0, 14.0, 9.0]}  # fmt: skip


def scenario(flight: str, terms: set[str]) -> quadrs.Scenario:
    z0 = 10.0
    legs = {
        "hover": [[0.0, 0.0, 0.0, z0, 0.0], [2.0, 0.0, 0.0, z0, 0.0]],
        "leg": [[0.0, 0.0, 0.0, z0, 0.0], [2.0, 10.0, 0.0, z0, 0.0]],
        "crosswind": [[0.0, 0.0, 0.0, z0, 0.0], [2.0, 10.0, 0.0, z0, 0.0]],
        "turbulence": [[0.0, 0.0, 0.0, z0, 0.0], [2.0, 10.0, 0.0, z0, 0.0]],
    }[flight]
    windy = flight in ("crosswind", "turbulence")
    return delivery_on_the_state().override(
        {
            "vehicle.body": "rigid",
            "vehicle.drag_coefficients": DRAG if "drag" in terms else [0.0, 0.0, 0.0],
            "actuator.rotor_drag": ROTOR_DRAG if "rotor_drag" in terms else [0.0, 0.0, 0.0],
            "actuator.flapping": FLAPPING if "flapping" in terms else 0.0,
            "actuator.translational_lift": LIFT if "lift" in terms else 0.0,
            "vehicle.inertia_error": [0.0, 0.0, 0.0],
            "payload.mass": 1e-9,
            "payload.damping": 3.14e-9,  # 5 % of critical, as the preset's
            "payload.drag_area": 0.0,
            "controller.mass_compensation": False,
            "controller.se3": GAINS,
            "initial.position": [0.0, 0.0, z0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.interpolation": "min_jerk",
            "trajectory.transition": 5.0,
            "trajectory.waypoints": legs,
            "trajectory.route": None,
            "trajectory.hold": None,
            "trajectory.names": None,
            "trajectory.speed": None,
            "trajectory.acceleration": None,
            "phases": [{"name": "all", "start": 0.0, "end": DURATION}],
            "integrator.dt": DT,
            "integrator.duration": DURATION,
            "wind.speed": 3.0 if windy else 0.0,
            "wind.heading": 90.0,
            "wind.shear": "none",
            "gust.enabled": flight == "turbulence",
            "gust.end": DURATION,
            "ground.enabled": False,
        }
    )


def rotorpy_params(sc: quadrs.Scenario) -> dict:
    """RotorPy's `quad_params` for the scenario's airframe and rotors."""
    ixx, iyy, izz = np.add(sc["vehicle.inertia"], sc["vehicle.inertia_error"])
    arm, kf = sc["vehicle.arm_length"], sc["actuator.thrust_coefficient"]
    h = math.sqrt(0.5)
    arms = [[h, h], [-h, h], [-h, -h], [h, -h]]  # layout "x": rotor i at 45 + 90 i degrees
    assert sc["actuator.layout"] == "x"
    c_d = sc["vehicle.drag_coefficients"]
    assert sc["actuator.rotor_drag"][0] == sc["actuator.rotor_drag"][1]  # RotorPy's one k_d
    return {
        "mass": sc["vehicle.mass"],
        "Ixx": ixx, "Iyy": iyy, "Izz": izz, "Ixy": 0.0, "Ixz": 0.0, "Iyz": 0.0,
        "c_Dx": c_d[0], "c_Dy": c_d[1], "c_Dz": c_d[2],
        "num_rotors": 4,
        "rotor_pos": {f"r{i + 1}": arm * np.array([c, s, 0.0]) for i, (c, s) in enumerate(arms)},
        "rotor_directions": np.array([1.0, -1.0, 1.0, -1.0]),
        "rotor_speed_min": 0.0,
        "rotor_speed_max": math.sqrt(sc["actuator.thrust_max"] / kf),
        "k_eta": kf,
        "k_m": sc["actuator.torque_ratio"] * kf,
        "k_d": sc["actuator.rotor_drag"][0], "k_z": sc["actuator.rotor_drag"][2],
        "k_h": sc["actuator.translational_lift"], "k_flap": sc["actuator.flapping"],
        "tau_m": sc["actuator.time_constant"],
        "motor_noise_std": 0.0,
    }  # fmt: skip


def min_jerk(sc: quadrs.Scenario, t: float) -> dict:
    """The min-jerk reference of docs/model.md section 3 (yaw 0 throughout)."""
    wps = np.array(sc["trajectory.waypoints"], dtype=float)
    a, b = np.array(sc["initial.position"], dtype=float), wps[0, 1:4]
    t0 = wps[0, 0]
    if len(wps) > 1 and t + 1e-9 >= wps[1, 0]:
        a, b, t0 = wps[0, 1:4], wps[1, 1:4], wps[1, 0]
    dur = sc["trajectory.transition"]
    tau = min(max((t - t0) / dur, 0.0), 1.0)
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    ds = 30 * tau**2 * (1 - 2 * tau + tau**2) / dur
    dds = 60 * tau * (1 - 3 * tau + 2 * tau**2) / dur**2
    return {"x": a + (b - a) * s, "x_dot": (b - a) * ds, "x_ddot": (b - a) * dds,
            "yaw": 0.0, "yaw_dot": 0.0}  # fmt: skip


def fly_rotorpy(sc: quadrs.Scenario, first: np.ndarray, winds: np.ndarray) -> np.ndarray:
    """RotorPy's vehicle and law from quadrs' first state, RK4 at DT; rows of x, y, z and the
    quaternion (qw, qx, qy, qz) at every step."""
    params = rotorpy_params(sc)
    vehicle = Multirotor(params, aero=True)
    law = SE3Control(params)
    g = sc["controller.se3"]
    law.kp_pos, law.kd_pos = np.array(g["kx"]), np.array(g["kv"])
    law.kp_att, law.kd_att = np.array(g["kR"]), np.array(g["kW"])
    x, v, q, w, omega = first
    state = {"x": x, "v": v, "q": q, "w": w, "wind": np.zeros(3), "rotor_speeds": omega}
    out = []
    for k in range(winds.shape[0]):
        out.append(np.concatenate([state["x"], state["q"][[3, 0, 1, 2]]]))
        if k == winds.shape[0] - 1:
            break
        state["wind"] = winds[k]
        control = law.update(k * DT, state, min_jerk(sc, k * DT))
        cmd = np.clip(control["cmd_motor_speeds"], params["rotor_speed_min"],
                      params["rotor_speed_max"])  # fmt: skip
        s = Multirotor._pack_state(state)

        def f(s: np.ndarray, cmd: np.ndarray = cmd) -> np.ndarray:
            return vehicle._s_dot_fn(0.0, s, cmd)

        k1 = f(s)
        k2 = f(s + DT / 2 * k1)
        k3 = f(s + DT / 2 * k2)
        k4 = f(s + DT * k3)
        s = s + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        state = Multirotor._unpack_state(s)
        state["q"] = state["q"] / np.linalg.norm(state["q"])
    return np.array(out)


def angle_between(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """rad, the rotation from each quaternion (w, x, y, z) of `qa` to `qb`'s."""
    dot = np.abs(np.sum(qa * qb, axis=1)).clip(max=1.0)
    return 2 * np.arccos(dot)


CASES = [
    *(
        (flight, aero)
        for flight in ("hover", "leg", "crosswind", "turbulence")
        for aero in ("none", "all")
    ),
    *(("crosswind", term) for term in ("drag", "rotor_drag", "flapping", "lift")),
]


def fly_quadrs(flight: str, aero: str) -> quadrs.Flight:
    f = quadrs.simulate(scenario(flight, TERMS[aero]), "se3", seed=3, record_every=1)
    assert f.status == "ok"
    return f


@pytest.mark.parametrize(("flight", "aero"), CASES)
def test_the_rigid_body_flies_as_rotorpy(flight: str, aero: str) -> None:
    sc = scenario(flight, TERMS[aero])
    tr = fly_quadrs(flight, aero).trace
    winds = tr[["wind_x", "wind_y", "wind_z"]].to_numpy()
    row = tr.iloc[0]
    first = (
        row[["x", "y", "z"]].to_numpy(float),
        row[["vx", "vy", "vz"]].to_numpy(float),
        row[["qx", "qy", "qz", "qw"]].to_numpy(float),
        row[["wx", "wy", "wz"]].to_numpy(float),
        row[["omega_1", "omega_2", "omega_3", "omega_4"]].to_numpy(float),
    )
    theirs = fly_rotorpy(sc, first, winds)
    pos = tr[["x", "y", "z"]].to_numpy()
    quat = tr[["qw", "qx", "qy", "qz"]].to_numpy()
    assert np.abs(pos - theirs[:, :3]).max() < 1e-6
    assert angle_between(quat, theirs[:, 3:]).max() < 1e-6
    # The flights differ as meant: the leg moved, the wind blew, the drag pulled.
    if flight != "hover":
        assert pos[-1, 0] > 9.0
    if flight in ("crosswind", "turbulence"):
        assert (
            abs(winds[:, 1].mean() - 3.0) < 1.0 and np.abs(tr[["phi", "theta"]]).max().max() > 0.01
        )
    if flight == "turbulence":
        assert winds[:, 0].std() > 0.05
    if aero != "none" and flight != "hover":  # the terms act: the flight differs without them
        bare = fly_quadrs(flight, "none").trace[["x", "y", "z"]].to_numpy()
        assert np.abs(pos - bare).max() > 1e-3, aero


def test_rotor_aerodynamics_are_refused_on_the_papers_body() -> None:
    for key, value in [("actuator.rotor_drag", [1e-4, 1e-4, 0.0]), ("actuator.flapping", 1e-5),
                       ("actuator.translational_lift", 1e-3)]:  # fmt: skip
        paper = {"vehicle.body": "paper", "vehicle.drag_coefficients": None,
                 "actuator.rotor_drag": None, "actuator.flapping": None,
                 "actuator.translational_lift": None}  # fmt: skip
        delivery_on_the_state().override(paper)  # reads without them
        with pytest.raises(quadrs.ScenarioError, match=key.replace(".", r"\.")):
            delivery_on_the_state().override({**paper, key: value})
