"""Wind over the whole flight (docs/model.md, "Wind over the whole flight"): the flight against
an independent integration of the paper's equations, the keys' checks, the figures."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import quadrs
from quadrs import Scenario, ScenarioError, plots
from quadrs.plots.wind import gust_spectra, mean_wind, wind_met

Z0 = 0.0457
GUSTS = [
    {"start": 3.0, "duration": 2.0, "amplitude": [1.0, -0.5, 0.4], "shape": "ramp"},
    {"start": 9.0, "duration": 1.5, "amplitude": [0.0, 1.2, -0.6], "shape": "pulse"},
]
WIND = {"speed": 3.0, "heading": 30.0, "shear": "log", "roughness": Z0, "gusts": GUSTS}


def climb(**wind: object) -> Scenario:
    """The paper's vehicle climbing from 0 to 15 m through the whole-flight wind (the
    turbulence off: every wind source here is deterministic)."""
    return Scenario.from_dict(
        {
            "base": "paper",
            "trajectory": {
                "interpolation": "min_jerk",
                "waypoints": [[0.0, 0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 15.0, 0.0]],
                "transition": 10.0,
            },
            "integrator": {"dt": 1e-3, "duration": 14.0},
            "phases": [{"name": "climb", "start": 0.0, "end": 14.0}],
            "gust": {"enabled": False},
            "wind": {**WIND, **wind},
        }
    )


def expected_wind(t: np.ndarray, z: np.ndarray) -> np.ndarray:
    """The wind of the climb, written here from MIL-F-8785C, not through the engine."""
    chi = math.radians(WIND["heading"])  # type: ignore[arg-type]
    with np.errstate(divide="ignore", invalid="ignore"):
        f = np.where(z > Z0, np.log(z / Z0) / math.log(6.096 / Z0), 0.0)
    w = np.outer(3.0 * f, [math.cos(chi), math.sin(chi), 0.0])
    for g in GUSTS:
        tau, d = t - g["start"], g["duration"]
        inside = np.clip(tau / d, 0.0, 1.0)
        if g["shape"] == "ramp":
            shape = 0.5 * (1 - np.cos(np.pi * inside))
        else:
            shape = np.where(tau <= d, 0.5 * (1 - np.cos(2 * np.pi * inside)), 0.0)
        shape = np.where(tau < 0, 0.0, shape)
        w += np.outer(shape, g["amplitude"])
    return w


def held(rows: np.ndarray) -> np.ndarray:
    """The wind each trace row holds: step k's at row k; the closing row, which no step
    follows, holds the last step's (MODEL.md section 12)."""
    rows = rows.copy()
    rows[-1] = rows[-2]
    return rows


def derivative(s: list[float], u: list[float], w: list[float], p: dict[str, float]) -> list[float]:
    """docs/model.md section 1, the spring payload and ideal actuators, by hand."""
    _x, _y, z, phi, th, psi, zc, vx, vy, vz, pp, q, r, vzc = s
    u1, tphi, tth, tpsi = u
    m, mc, g = p["m"], p["mc"], p["g"]
    sphi, cphi, sth, cth = math.sin(phi), math.cos(phi), math.sin(th), math.cos(th)
    spsi, cpsi = math.sin(psi), math.cos(psi)

    def drag(k: float, v: float, wind: float) -> float:
        return -k * (v - wind) * abs(v - wind)

    fs = p["kc"] * (z - zc) + p["cc"] * (vz - vzc)
    ax = ((cphi * sth * cpsi + spsi * sphi) * u1 + drag(p["klat"], vx, w[0])) / (m + mc)
    ay = ((cphi * sth * spsi - sphi * cpsi) * u1 + drag(p["klat"], vy, w[1])) / (m + mc)
    az = (-m * g + cphi * cth * u1 - fs + drag(p["kq"], vz, w[2])) / m
    azc = (-mc * g + fs + drag(p["kp"], vzc, w[2])) / mc
    ixx, iyy, izz = p["ixx"], p["iyy"], p["izz"]
    dp = ((iyy - izz) * q * r + tphi) / ixx
    dq = ((izz - ixx) * pp * r + tth) / iyy
    dr = ((ixx - iyy) * pp * q + tpsi) / izz
    return [vx, vy, vz, pp, q, r, vzc, ax, ay, az, dp, dq, dr, azc]


def rk4(
    s: list[float], u: list[float], w: list[float], p: dict[str, float], h: float
) -> list[float]:
    def at(base: list[float], k: list[float], c: float) -> list[float]:
        return [b + c * d for b, d in zip(base, k, strict=True)]

    k1 = derivative(s, u, w, p)
    k2 = derivative(at(s, k1, h / 2), u, w, p)
    k3 = derivative(at(s, k2, h / 2), u, w, p)
    k4 = derivative(at(s, k3, h), u, w, p)
    return [
        x + h / 6 * (a + 2 * b + 2 * c + d) for x, a, b, c, d in zip(s, k1, k2, k3, k4, strict=True)
    ]


def test_a_climb_in_sheared_wind_with_gusts_matches_an_independent_integration() -> None:
    s = climb()
    flight = quadrs.simulate(s, "pd", seed=1, record_every=1)
    assert flight.status == "ok"
    tr = flight.trace
    t, z = tr.index.to_numpy(float), tr["z"].to_numpy(float)
    wind = tr[["wind_x", "wind_y", "wind_z"]].to_numpy(float)
    # The wind the engine held at each step is the formula at that step's t and z.
    assert np.max(np.abs(wind - held(expected_wind(t, z)))) < 1e-12
    assert z[-1] > 14.0 and wind[:, 0].max() > 3.0 and wind[:, 2].min() < -0.19
    inertia = s["vehicle.inertia"]
    error = s["vehicle.inertia_error"]
    rho = s["gust.air_density"]
    p = {
        "m": s["vehicle.mass"], "mc": s["payload.mass"], "g": s["environment.gravity"],
        "kc": s.stiffness, "cc": s["payload.damping"],
        "klat": 0.5 * rho * s["vehicle.lateral_drag_area"],
        "kq": 0.5 * rho * s["vehicle.drag_area"], "kp": 0.5 * rho * s["payload.drag_area"],
        "ixx": inertia[0] + error[0], "iyy": inertia[1] + error[1], "izz": inertia[2] + error[2],
    }  # fmt: skip
    names = s.state_names
    assert names == ["x", "y", "z", "phi", "theta", "psi", "zc",
                     "vx", "vy", "vz", "p", "q", "r", "vzc"]  # fmt: skip
    states = tr[names].to_numpy(float)
    controls = tr[["U1", "tau_phi", "tau_theta", "tau_psi"]].to_numpy(float)
    h = float(s["integrator.dt"])
    x = list(states[0])
    worst = 0.0
    for k in range(len(tr) - 1):
        x = rk4(x, list(controls[k]), list(wind[k]), p, h)
        worst = max(worst, float(np.max(np.abs(np.asarray(x) - states[k + 1]))))
    assert worst < 1e-9, worst
    # The flight went somewhere: the wind pushed it off the vertical.
    assert np.max(np.abs(states[:, 0])) > 1e-3


def test_mean_wind_is_w20_at_20_ft_and_zero_at_or_below_z0() -> None:
    s = climb(heading=0.0)
    w = mean_wind(s, [6.096, Z0, 0.01, -1.0])
    assert w[0].tolist() == [3.0, 0.0, 0.0]
    assert np.all(w[1:] == 0.0)
    turned = mean_wind(climb(heading=90.0, shear="none"), [0.0, 100.0])
    assert np.allclose(turned, [[0.0, 3.0, 0.0]] * 2, atol=1e-15)


def test_intensity_and_w20_are_exclusive() -> None:
    paper = Scenario.paper()
    severe = paper.override({"gust.intensity": "severe"})
    assert "w20" not in severe.to_dict()["gust"]
    assert severe.turbulence_w20 == pytest.approx(45 * 1852 / 3600, rel=1e-15)
    assert Scenario.from_toml_string(severe.to_toml()) == severe
    back = severe.override({"gust.w20": 4.0})
    assert "intensity" not in back.to_dict()["gust"] and back.turbulence_w20 == 4.0
    for level, knots in [("light", 15), ("moderate", 30)]:
        s = paper.override({"gust.intensity": level})
        assert s.turbulence_w20 == pytest.approx(knots * 1852 / 3600, rel=1e-15)
    with pytest.raises(ScenarioError, match=r"exactly one of gust\.w20 and gust\.intensity") as e:
        Scenario.from_dict({"base": "paper", "gust": {"intensity": "light"}})
    assert e.value.key == "gust.intensity"
    with pytest.raises(ScenarioError, match=r"gust\.intensity") as e:
        paper.override({"gust.intensity": "hurricane"})


@pytest.mark.parametrize(
    ("change", "key", "says"),
    [
        ({"wind.roughness": -0.1}, "wind.roughness", "must be > 0"),
        ({"wind.roughness": 7.0}, "wind.roughness", "reference height"),
        ({"wind.speed": -1.0}, "wind.speed", "must be >= 0"),
        ({"wind.gusts[0].duration": 0.0}, "wind.gusts[0].duration", "must be > 0"),
        ({"wind.gusts[1].start": -1.0}, "wind.gusts[1].start", "must be >= 0"),
        ({"wind.gusts[1].shape": "square"}, "wind.gusts[1].shape", "unknown variant"),
        ({"wind.shear": "power"}, "wind.shear", "unknown variant"),
        ({"gust.altitude": "ground"}, "gust.altitude", '"vehicle"'),
        ({"gust.airspeed": "ground"}, "gust.airspeed", '"relative"'),
        ({"gust.min_airspeed": 0.0}, "gust.min_airspeed", "must be > 0"),
    ],
)
def test_bad_wind_values_name_their_key(change: dict[str, object], key: str, says: str) -> None:
    with pytest.raises(ScenarioError, match=says) as e:
        climb().override(change)
    assert e.value.key == key, e.value


def test_wind_keys_disperse_per_realisation() -> None:
    s = climb().override(
        {
            "integrator.duration": 4.0,
            "phases[0].end": 4.0,
            "gust.enabled": True,
            "gust.start": 1.0,
            "gust.altitude": "vehicle",
            "gust.airspeed": "relative",
            "gust.components": ["longitudinal", "lateral", "vertical"],
            "dispersions": {
                "wind.speed": {"dist": "uniform", "low": 1.0, "high": 4.0},
                "wind.heading": {"dist": "uniform", "low": 0.0, "high": 90.0},
                "wind.gusts[0].amplitude[2]": {"dist": "normal", "mean": 0.0, "std": 0.5},
                "gust.min_airspeed": {"dist": "uniform", "low": 0.5, "high": 2.0},
            },
        }
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        mc = quadrs.monte_carlo(s, controllers=("pd",), runs=4, seed=3, progress=False)
        one = quadrs.simulate(mc.scenario_of(2), "pd", seed=3, realisation=2)
    own = mc.runs[mc.runs.phase == s.phase_names[0]]  # (the whole-flight phase aside)
    assert one.scenario["wind.speed"] == own["wind.speed"].iloc[2]
    row = own[own.realisation == 2]
    assert row["iae"].item() == one.metrics["iae"].iloc[0]
    assert own["wind.speed"].nunique() == 4 and own["iae"].nunique() == 4


def test_wind_figures_draw() -> None:
    flight = quadrs.simulate(climb(), "pd", seed=0)
    fig = wind_met(flight)
    assert len(fig.axes) == 3
    s = climb().override({"gust.enabled": True, "gust.altitude": "vehicle"})
    with pytest.raises(ValueError, match=r"gust\.altitude"):
        gust_spectra(scenario=s, steps=256, realisations=2)
    fig = gust_spectra(scenario=s, altitude=30.0, steps=512, realisations=4)
    assert len(fig.axes) == 3
    assert plots.wind_met is wind_met
