"""The geometric controller `se3` (docs/model.md, "The geometric controller `se3`"): flights
against an independent closed loop written here from docs/model.md's equations, its
linearisation against central differences of that closed loop, stability with the delivery
preset's line and rotors, the delivery route to the drop point, and its name everywhere."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import warnings

import numpy as np
import pytest

import quadrs
from quadrs import _core
from tests.conftest import DELIVERY_DROP
from tests.engine import delivery_on_the_state

#: The defaults docs/model.md gives (a scenario without [controller.se3] flies them).
DEFAULTS = {"kx": [1.0, 1.0, 4.0], "kv": [1.6, 1.6, 3.2], "kR": [100.0, 100.0, 40.0],
            "kW": [14.0, 14.0, 9.0]}  # fmt: skip
#: tests/conftest.py's DELIVERY_DROP as --set values.
DELIVERY_DROP_TOML = {
    "trajectory.route": "[[0,0,7],[0,0,5]]",
    "trajectory.hold": "[0,15]",
    "trajectory.names": '["descent","drop"]',
    "initial.position": "[0,0,7]",
    "integrator.duration": "19",
    "gust.end": "19",
}
assert set(DELIVERY_DROP_TOML) == set(DELIVERY_DROP)
STATES = ["x", "y", "z", "phi", "theta", "psi", "zc", "vx", "vy", "vz", "p", "q", "r", "vzc"]


# -- docs/model.md sections 1-3 and "The geometric controller `se3`", written again ----------
def rotation(phi: float, theta: float, psi: float) -> np.ndarray:
    """R = Rz(psi) Ry(theta) Rx(phi), body to inertial."""
    c, s = math.cos, math.sin
    rx = np.array([[1, 0, 0], [0, c(phi), -s(phi)], [0, s(phi), c(phi)]])
    ry = np.array([[c(theta), 0, s(theta)], [0, 1, 0], [-s(theta), 0, c(theta)]])
    rz = np.array([[c(psi), -s(psi), 0], [s(psi), c(psi), 0], [0, 0, 1]])
    return rz @ ry @ rx


def vee(m: np.ndarray) -> np.ndarray:
    return np.array([m[2, 1], m[0, 2], m[1, 0]])


class Se3Law:
    """Lee, Leok & McClamroch's law with RotorPy's normalised gains, from docs/model.md."""

    def __init__(self, sc: quadrs.Scenario) -> None:
        m, mc = sc["vehicle.mass"], sc["payload.mass"]
        self.mt = m + mc if sc["controller.mass_compensation"] else m
        self.g = sc["environment.gravity"]
        self.J = np.diag(sc["vehicle.inertia"])  # the controller's (nominal) inertia
        gains = sc.get("controller.se3", DEFAULTS)
        self.kx, self.kv = np.array(gains["kx"]), np.array(gains["kv"])
        self.kR, self.kW = np.array(gains["kR"]), np.array(gains["kW"])
        self.tilt = sc["controller.tilt_limit"]
        self.floor = sc["controller.thrust_floor"]
        self.tmin = sc.get("controller.thrust_min", None)
        self.tmax = sc.get("controller.thrust_max", None)

    def __call__(self, s: np.ndarray, ref: dict) -> tuple[float, np.ndarray]:
        pos, att, vel, w = s[0:3], s[3:6], s[7:10], s[10:13]
        e_x, e_v = pos - ref["pos"], vel - ref["vel"]
        f = self.mt * (-self.kx * e_x - self.kv * e_v + ref["acc"] + np.array([0, 0, self.g]))
        r = rotation(*att)
        u1 = float(f @ r[:, 2])
        if self.tmin is not None:
            u1 = max(u1, self.tmin)
        if self.tmax is not None:
            u1 = min(u1, self.tmax)
        # b3_d: along f, at most tilt_limit from the vertical, never below the horizon
        n = max(np.linalg.norm(f), self.floor)
        h = f[:2] / n
        sin_t = math.sin(self.tilt)
        h = h * sin_t / max(np.linalg.norm(h), sin_t)
        b3 = np.array([h[0], h[1], math.sqrt(max(1.0 - h @ h, 0.0))])
        c1 = np.array([math.cos(ref["psi"]), math.sin(ref["psi"]), 0.0])
        b2 = np.cross(b3, c1)
        b2 /= max(np.linalg.norm(b2), 1e-6)
        rd = np.column_stack([np.cross(b2, b3), b2, b3])
        e_r = 0.5 * vee(rd.T @ r - r.T @ rd)
        e_w = w - np.array([0.0, 0.0, ref["psi_dot"]])  # RotorPy's W_d = (0, 0, yaw_dot)
        tau = self.J @ (-self.kR * e_r - self.kW * e_w) + np.cross(w, self.J @ w)
        return u1, tau


def spring_rhs(sc: quadrs.Scenario):
    """ds/dt of the paper's 14-state plant (section 1), controls and wind held."""
    m, mc, g = sc["vehicle.mass"], sc["payload.mass"], sc["environment.gravity"]
    ixx, iyy, izz = np.array(sc["vehicle.inertia"]) + np.array(sc["vehicle.inertia_error"])
    kc = mc * (2 * math.pi * sc["payload.natural_frequency"]) ** 2
    cc = sc["payload.damping"]
    half_rho = 0.5 * sc["gust.air_density"]
    k_lat = half_rho * sc["vehicle.lateral_drag_area"]
    k_z = half_rho * sc["vehicle.drag_area"]
    k_c = half_rho * sc["payload.drag_area"]

    def drag(k: float, v: float, w: float) -> float:
        return -k * (v - w) * abs(v - w)

    def f(s: np.ndarray, u1: float, tau: np.ndarray, wind: np.ndarray) -> np.ndarray:
        _, _, z, phi, th, psi, zc, vx, vy, vz, p, q, r, vzc = s
        rz = rotation(phi, th, psi)[:, 2]
        fs = kc * (z - zc) + cc * (vz - vzc)
        return np.array(
            [
                vx,
                vy,
                vz,
                p,
                q,
                r,
                vzc,
                (rz[0] * u1 + drag(k_lat, vx, wind[0])) / (m + mc),
                (rz[1] * u1 + drag(k_lat, vy, wind[1])) / (m + mc),
                (rz[2] * u1 - fs + drag(k_z, vz, wind[2])) / m - g,
                (q * r * (iyy - izz) + tau[0]) / ixx,
                (p * r * (izz - ixx) + tau[1]) / iyy,
                (p * q * (ixx - iyy) + tau[2]) / izz,
                (fs + drag(k_c, vzc, wind[2])) / mc - g,
            ]
        )

    return f


def min_jerk(sc: quadrs.Scenario, t: float) -> dict:
    """Section 3's reference for two waypoints, the first at the initial state at t = 0."""
    (_, *p0), (t1, *p1) = sc["trajectory.waypoints"]
    a, b = np.array(p0, dtype=float), np.array(p1, dtype=float)
    dur = sc["trajectory.transition"]
    tau = min(max((t - t1) / dur, 0.0), 1.0)
    s = tau**3 * (10 - 15 * tau + 6 * tau**2)
    ds = 30 * tau**2 * (1 - tau) ** 2 / dur if 0 < tau < 1 else 0.0
    dds = 60 * tau * (1 - 3 * tau + 2 * tau**2) / dur**2 if 0 < tau < 1 else 0.0
    p, v, acc = a + (b - a) * s, (b - a) * ds, (b - a) * dds
    return {"pos": p[:3], "vel": v[:3], "acc": acc[:3], "psi": p[3], "psi_dot": v[3]}


def step_ref(sc: quadrs.Scenario, t: float) -> dict:
    wps = sc["trajectory.waypoints"]
    now = [w for w in wps if w[0] <= t + 1e-9][-1] if t + 1e-9 >= wps[0][0] else wps[0]
    z = np.zeros(3)
    return {"pos": np.array(now[1:4], dtype=float), "vel": z, "acc": z, "psi": now[4],
            "psi_dot": 0.0}  # fmt: skip


def rest_state(sc: quadrs.Scenario) -> np.ndarray:
    s = np.zeros(14)
    s[0:3], s[3:6] = sc["initial.position"], sc["initial.attitude"]
    mc, g = sc["payload.mass"], sc["environment.gravity"]
    kc = mc * (2 * math.pi * sc["payload.natural_frequency"]) ** 2
    s[6] = s[2] - mc * g / kc
    return s


def fly(sc: quadrs.Scenario, reference, winds: np.ndarray):
    """Classical RK4, controls computed at each step's start and held over its four stages
    with the step's wind (section 5)."""
    law, rhs, dt = Se3Law(sc), spring_rhs(sc), sc["integrator.dt"]
    s = rest_state(sc)
    states, controls = [s], []
    for k in range(sc.steps):
        u1, tau = law(s, reference(sc, k * dt))
        w = winds[k]
        k1 = rhs(s, u1, tau, w)
        k2 = rhs(s + dt / 2 * k1, u1, tau, w)
        k3 = rhs(s + dt / 2 * k2, u1, tau, w)
        k4 = rhs(s + dt * k3, u1, tau, w)
        s = s + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        states.append(s)
        controls.append([u1, *tau])
    return np.array(states), np.array(controls)


# -- scenarios ---------------------------------------------------------------------------------
def lateral_move() -> quadrs.Scenario:
    """From a tilted, yawed hover, a 1 s min-jerk move 1 m forward, 0.5 m right, 0.5 m up and
    back to yaw 0 (acceleration fed forward), through three-axis turbulence."""
    return quadrs.Scenario.paper().override(
        {
            "initial.position": [0.0, 0.0, 2.0],
            "initial.attitude": [0.05, -0.03, 0.3],
            "trajectory.interpolation": "min_jerk",
            "trajectory.transition": 1.0,
            "trajectory.waypoints": [[0, 0, 0, 2, 0.3], [0.3, 1.0, -0.5, 2.5, 0.0]],
            "integrator.dt": 0.001,
            "integrator.duration": 2.0,
            "phases": [{"name": "all", "start": 0.0, "end": 2.0}],
            "gust.components": ["longitudinal", "lateral", "vertical"],
            "gust.start": 0.0,
            "gust.end": 2.0,
        }
    )


def tilted_step() -> quadrs.Scenario:
    """A 4 m lateral step with the tilt limit (0.3 rad) and a thrust ceiling in force."""
    return quadrs.Scenario.paper().override(
        {
            "initial.position": [0.0, 0.0, 2.0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.waypoints": [[0, 0, 0, 2, 0.0], [0.2, 4.0, 3.0, 2.0, 0.4]],
            "controller.tilt_limit": 0.3,
            "controller.thrust_max": 23.9,
            "integrator.dt": 0.001,
            "integrator.duration": 2.0,
            "phases": [{"name": "all", "start": 0.0, "end": 2.0}],
            "gust.enabled": False,
        }
    )


@pytest.mark.parametrize(
    ("make", "reference"), [(lateral_move, min_jerk), (tilted_step, step_ref)], ids=["move", "step"]
)
def test_a_flight_agrees_with_an_independent_closed_loop(make, reference) -> None:
    sc = make()
    flight = quadrs.simulate(sc, "se3", seed=4, record_every=1)
    assert flight.status == "ok"
    tr = flight.trace
    t = tr.index.to_numpy()
    # The reference the engine flew is the one written here.
    refs = [reference(sc, tk) for tk in t]
    np.testing.assert_allclose(
        tr[["x_ref", "y_ref", "z_ref"]], [r["pos"] for r in refs], atol=1e-12
    )
    np.testing.assert_allclose(tr["psi_ref"], [r["psi"] for r in refs], atol=1e-12)
    winds = tr[["wind_x", "wind_y", "wind_z"]].to_numpy()
    states, controls = fly(sc, reference, winds)
    err = np.abs(tr[STATES].to_numpy() - states).max(axis=0)
    assert err.max() < 1e-9, dict(zip(STATES, err, strict=True))
    ctrl = tr[["U1", "tau_phi", "tau_theta", "tau_psi"]].to_numpy()[:-1]
    assert np.abs(ctrl - controls).max() < 1e-9
    # It did something: moved, tilted, and (the step) hit its limits.
    assert np.abs(tr["x"].iloc[-1]) > 0.5 and np.abs(tr[["phi", "theta"]]).max().max() > 0.05
    if make is tilted_step:
        assert (tr["U1"] == 23.9).any()
        tilt = np.arccos(np.cos(tr["phi"]) * np.cos(tr["theta"]))
        assert 0.25 < tilt.max() < 0.3 + 0.05


def yaw_turn() -> quadrs.Scenario:
    """A 1 rad yaw turn in 2 s (min-jerk) at hover, in still air."""
    return quadrs.Scenario.paper().override(
        {
            "initial.position": [0.0, 0.0, 2.0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.interpolation": "min_jerk",
            "trajectory.transition": 2.0,
            "trajectory.waypoints": [[0, 0, 0, 2, 0.0], [0.5, 0, 0, 2, 1.0]],
            "integrator.dt": 0.001,
            "integrator.duration": 3.0,
            "phases": [{"name": "all", "start": 0.0, "end": 3.0}],
            "gust.enabled": False,
        }
    )


def test_a_yaw_turn_is_flown_with_rotorpys_yaw_rate_term() -> None:
    """The turn against the closed loop written here (W_d = (0, 0, psi_dot_ref)) to 1e-9, and
    the yaw lag it removes: with W_d = 0 the same loop trails the reference by 0.2 rad."""
    sc = yaw_turn()
    flight = quadrs.simulate(sc, "se3", record_every=1)
    assert flight.status == "ok"
    tr = flight.trace
    winds = tr[["wind_x", "wind_y", "wind_z"]].to_numpy()
    states, _ = fly(sc, min_jerk, winds)
    err = np.abs(tr[STATES].to_numpy() - states).max(axis=0)
    assert err.max() < 1e-9, dict(zip(STATES, err, strict=True))
    lag = np.abs(tr["psi"] - tr["psi_ref"]).max()

    def without_yaw_rate(sc: quadrs.Scenario, t: float) -> dict:
        return min_jerk(sc, t) | {"psi_dot": 0.0}

    old, _ = fly(sc, without_yaw_rate, winds)
    old_lag = np.abs(old[:, 5] - tr["psi_ref"].to_numpy()).max()
    assert old_lag > 0.15 and lag < old_lag / 3, (lag, old_lag)


def test_the_law_is_rotorpys_se3control() -> None:
    """RotorPy 3.0's own SE3Control (its gains set to these, its mass to the controller's) on
    the engine's states through the yaw turn: the same thrust and moments to 1e-9."""
    qc = pytest.importorskip("rotorpy.controllers.quadrotor_control")
    from scipy.spatial.transform import Rotation

    sc = yaw_turn()
    flight = quadrs.simulate(sc, "se3", record_every=1)
    tr = flight.trace
    law = Se3Law(sc)
    ixx, iyy, izz = sc["vehicle.inertia"]
    params = {"mass": law.mt, "Ixx": ixx, "Iyy": iyy, "Izz": izz, "Ixy": 0.0, "Ixz": 0.0,
              "Iyz": 0.0, "c_Dx": 0.0, "c_Dy": 0.0, "c_Dz": 0.0, "num_rotors": 4,
              "rotor_pos": {f"r{i}": np.array([math.cos(a), math.sin(a), 0.0]) * 0.17
                            for i, a in enumerate(np.radians([45, 135, 225, 315]))},
              "rotor_directions": np.array([1, -1, 1, -1]), "rotor_speed_min": 0.0,
              "rotor_speed_max": 3000.0, "k_eta": 8.5e-6, "k_m": 1.4e-7, "k_d": 0.0,
              "k_z": 0.0, "k_flap": 0.0, "tau_m": 0.03}  # fmt: skip
    ctrl = qc.SE3Control(params)
    ctrl.g = sc["environment.gravity"]
    ctrl.kp_pos, ctrl.kd_pos = law.kx, law.kv
    ctrl.kp_att, ctrl.kd_att = law.kR, law.kW
    worst = 0.0
    for k in range(0, sc.steps, 7):
        row = tr.iloc[k]
        ref = min_jerk(sc, tr.index[k])
        q = Rotation.from_matrix(rotation(row["phi"], row["theta"], row["psi"])).as_quat()
        state = {"x": row[["x", "y", "z"]].to_numpy(float),
                 "v": row[["vx", "vy", "vz"]].to_numpy(float), "q": q,
                 "w": row[["p", "q", "r"]].to_numpy(float)}  # fmt: skip
        flat = {"x": ref["pos"], "x_dot": ref["vel"], "x_ddot": ref["acc"], "yaw": ref["psi"],
                "yaw_dot": ref["psi_dot"]}  # fmt: skip
        out = ctrl.update(0.0, state, flat)
        mine = row[["U1", "tau_phi", "tau_theta", "tau_psi"]].to_numpy(float)
        theirs = np.array([out["cmd_thrust"], *out["cmd_moment"]])
        worst = max(worst, float(np.max(np.abs(mine - theirs))))
    assert worst < 1e-9, worst


def test_the_linearisation_is_the_central_differences_of_the_closed_loop() -> None:
    """quadrs.linearize's A (dual numbers through the engine's law and plant) against central
    differences of the closed loop written above, at its equilibrium: two implementations."""
    sc = quadrs.Scenario.paper()
    lin = quadrs.linearize(sc, "se3")
    x0 = lin.equilibrium
    law, rhs = Se3Law(sc), spring_rhs(sc)
    ref = {"pos": np.array([0.0, 0.0, 2.0]), "vel": np.zeros(3), "acc": np.zeros(3), "psi": 0.0,
           "psi_dot": 0.0}  # fmt: skip

    def closed(s: np.ndarray) -> np.ndarray:
        u1, tau = law(s, ref)
        return rhs(s, u1, tau, np.zeros(3))

    assert np.abs(closed(x0)).max() < 1e-12  # hover is an equilibrium of both
    h = 1e-6
    fd = np.column_stack(
        [(closed(x0 + h * e) - closed(x0 - h * e)) / (2 * h) for e in np.eye(len(x0))]
    )
    assert np.abs(lin.A - fd).max() < 1e-6 * max(1.0, np.abs(fd).max())
    assert np.abs(lin.A).max() > 1.0  # a real Jacobian


@pytest.fixture(scope="module")
def delivery() -> quadrs.Scenario:
    return delivery_on_the_state()


def test_stable_at_hover_with_the_line_and_the_rotors(delivery) -> None:
    st = quadrs.stability(delivery, "se3")
    assert st.stable and (st.poles["real"] < -0.05).all(), st.poles
    # 12 of the body, 8 of the cable (the parcel's position and velocity, the line's length
    # and rate: a winch's servo holds it, a critically damped pair at -kw / 2 = -10 1/s), 4 of
    # the rotors
    assert len(st.poles) == 24 and {"swing x"} <= set(st.poles["mode"])
    assert np.isclose(st.poles["real"], -10.0, atol=1e-4).sum() == 2
    # and the paper's vehicle with its defaults too
    assert quadrs.stability(quadrs.Scenario.paper(), "se3").stable


def test_it_holds_the_drop_hover_in_turbulence(delivery) -> None:
    sc = delivery.override(DELIVERY_DROP)
    f = quadrs.simulate(sc, "se3", seed=2)
    assert f.status == "ok"
    start, end = sc.phase_windows["drop"]
    tr = f.trace[(f.trace.index >= start + 5.0) & (f.trace.index <= end)]
    # No integrator: the law holds off downwind (+y, the wind from the east) by the steady
    # drag over its position gain, about 1.6 m in the preset's 5 m/s; the turbulence moves it
    # by less than a metre about that.
    off = tr[["x", "y", "z"]].to_numpy() - [0.0, 0.0, 5.0]
    steady = off.mean(axis=0)
    assert 0.5 < steady[1] < 2.5 and np.abs(steady[[0, 2]]).max() < 0.3, steady
    assert np.linalg.norm(off - steady, axis=1).max() < 1.0


def test_it_flies_the_delivery_route_to_the_drop_point(delivery) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no step-size or stability warning either
        f = quadrs.simulate(delivery, "se3", seed=1)
    assert f.status == "ok"
    (drop,) = [s for s in delivery.route.segments if s.name == "drop"]
    tr = f.trace[(f.trace.index >= drop.start) & (f.trace.index <= drop.end)]
    assert len(tr) > 1000
    off = np.linalg.norm(tr[["x", "y", "z"]].to_numpy(dtype=float) - drop.target, axis=1)
    assert off.max() < 3.0, off.max()
    m = f.metrics.set_index("phase")
    # The line stays taut until the parcel is lowered onto the ground, and it is released there.
    assert (m.loc[["lift", "climb", "transit", "descent"], "slack_time"] == 0.0).all()
    assert m.loc["lower", "touchdown_miss"] < 3.0
    assert drop.start - 8.0 < m.loc["flight", "release_time"] < drop.end


def test_its_name_reaches_python_and_the_command_line(short) -> None:
    assert "se3" in _core.CONTROLLER_NAMES
    for key in ("kx", "kv", "kR", "kW"):
        assert f"controller.se3.{key}" in _core.KEY_UNITS
    # The presets give no table (the defaults fly); a table given is checked key by key.
    assert "se3" not in quadrs.Scenario.paper()["controller"]
    f = quadrs.simulate(short, "se3")
    assert f.status == "ok"
    bad = {**DEFAULTS, "kW": [1.0, -1.0, 1.0]}
    with pytest.raises(quadrs.ScenarioError, match=r"controller\.se3\.kW\[1\] must be >= 0"):
        quadrs.simulate(short.override({"controller.se3": bad}), "se3")
    run = [sys.executable, "-m", "quadrs.cli"]
    out = subprocess.run(
        [*run, "run", "--controller", "se3", "--set", "integrator.dt=0.002"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    # The mission command flies it paired with the PD (over the drop point, two gusts).
    drop = [f"{k}={v}" for k, v in DELIVERY_DROP_TOML.items()]
    sets = [a for kv in drop for a in ("--set", kv)]
    out = subprocess.run(
        [*run, "mission", "--preset", "delivery", "--controller", "pd,se3", "--runs", "2",
         "--workers", "1", "--no-progress", *sets],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert out.returncode == 0, out.stderr
    assert "se3 specific_force %" in out.stdout and "se3 track" in out.stdout


def test_one_gain_of_the_defaulted_table_can_be_set_and_dispersed(short) -> None:
    """The presets leave [controller.se3] out (the engine's defaults fly); setting one key
    starts from those defaults, as does a dispersion of it."""
    assert json.loads(_core.CONTROLLER_DEFAULTS["se3"]) == DEFAULTS
    # the paper's flight is vertical: a vertical gain shows in its metrics
    s = short.override({"controller.se3.kx": [1.0, 1.0, 3.0]})
    assert s["controller.se3"] == {**DEFAULTS, "kx": [1.0, 1.0, 3.0]}
    whole = short.override({"controller.se3": {**DEFAULTS, "kx": [1.0, 1.0, 3.0]}})
    assert quadrs.simulate(s, "se3").metrics.equals(quadrs.simulate(whole, "se3").metrics)
    assert not quadrs.simulate(s, "se3").metrics.equals(quadrs.simulate(short, "se3").metrics)
    d = short.override(
        {"dispersions": {"controller.se3.kv[2]": {"dist": "uniform", "low": 2.5, "high": 3.5}}}
    )
    mc = quadrs.monte_carlo(d, runs=2, seed=0, controllers=("se3",), progress=False)
    assert len(mc.runs) > 0 and (mc.runs["status"] == "ok").all()


def test_a_partial_table_takes_the_rest_from_the_defaults(tmp_path) -> None:
    """``[controller.se3]`` with one key (a user's own gain) flies the defaults for the
    rest; a key the law does not know is refused, naming it."""
    f = tmp_path / "mine.toml"
    f.write_text('base = "paper"\n[controller.se3]\nkR = [80.0, 80.0, 40.0]\n')
    s = quadrs.Scenario.from_toml(f)
    assert s["controller.se3"] == {**DEFAULTS, "kR": [80.0, 80.0, 40.0]}
    assert s == quadrs.Scenario.paper().override({"controller.se3.kR": [80.0, 80.0, 40.0]})
    f.write_text('base = "paper"\n[controller.se3]\nkQ = 1.0\n')
    with pytest.raises(quadrs.ScenarioError, match="kQ"):
        quadrs.Scenario.from_toml(f)
