"""The last metres (docs/delivery.md, "The last metres"; docs/model.md): the winch's variable-
length line against an independent integration, a lowering in still air touching down at the
commanded rate on the drop point, the hook's release, and bad input named."""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import quadrs

DROP = (3.0, 4.0)
V, A = 0.5, 0.5  # the winch's speed (m/s) and acceleration (m/s^2)


def lowering(payout: float, **extra: Any) -> quadrs.Scenario:
    """The slung preset hovering at 6 m over DROP, lowering ``payout`` m of line at once, then
    holding 8 s and climbing 1 m; a firm ground at 0, no wind."""
    changes: dict[str, Any] = {
        "trajectory.interpolation": "route",
        "trajectory.waypoints": None,
        "trajectory.route": [[*DROP, 6.0], [*DROP, 7.0]],
        "trajectory.speed": 1.0,
        "trajectory.acceleration": 1.0,
        "trajectory.lower": [payout, 0.0],
        "trajectory.hold": [8.0, 0.0],
        "initial.position": [*DROP, 6.0],
        "payload.cable_length": 8.0,
        "payload.length_min": 1.0,
        "payload.winch_speed": V,
        "payload.winch_acceleration": A,
        "payload.release": "touchdown",
        "ground.stiffness": 2.0e4,
        "ground.dissipation": 5.0,
        "ground.friction": 0.5,
        "gust.enabled": False,
        "phases": "legs",
        "integrator.dt": 0.0005,
        "integrator.duration": payout / V + 2 * V / A + 8.0 + 3.0,
    }
    changes.update(extra)
    return quadrs.Scenario.preset("slung").override(changes)


def fly(sc: quadrs.Scenario, **kw: Any) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StabilityWarning)
        return quadrs.simulate(sc, "pd", **kw)


# -- the line's length as a function of time, derived from the winch's law ---------------------
# L'' = clamp(kw (r - L'), -a, a), r = min(kp e, sqrt(a e), v) paying out (e = L* - L),
# kw = 20 1/s, kp = kw / 4, from rest at L0 with e > v^2 / a and e > v / kp (r = v):
# L'' = a while kw (v - L') >= a, i.e. until L' = v - a / kw at t1 = (v - a / kw) / a; then
# L' = v - (a / kw) exp(-kw (t - t1)).
KW = 20.0


def line_length(t: float, l0: float) -> tuple[float, float]:
    kw = KW
    t1 = (V - A / kw) / A
    if t <= t1:
        return l0 + 0.5 * A * t * t, A * t
    tau = t - t1
    l1 = l0 + 0.5 * A * t1 * t1
    decay = math.exp(-kw * tau)
    return l1 + V * tau - (A / kw**2) * (1 - decay), V - (A / kw) * decay


def rotation(phi: float, theta: float, psi: float) -> np.ndarray:
    c, s = math.cos, math.sin
    rx = np.array([[1, 0, 0], [0, c(phi), -s(phi)], [0, s(phi), c(phi)]])
    ry = np.array([[c(theta), 0, s(theta)], [0, 1, 0], [-s(theta), 0, c(theta)]])
    rz = np.array([[c(psi), -s(psi), 0], [s(psi), c(psi), 0], [0, 0, 1]])
    return rz @ ry @ rx


def rhs(sc: quadrs.Scenario, u1: float, tau: np.ndarray, l0: float):
    """ds/dt of the quadrotor and a point mass on an elastic line whose unstretched length is
    the given L(t): tension k (l - L) + c (l' - L') while l > L (the strain and its rate)."""
    m, mc, g = sc["vehicle.mass"], sc["payload.mass"], sc["environment.gravity"]
    inertia = np.array(sc["vehicle.inertia"]) + np.array(sc["vehicle.inertia_error"])
    rho = sc["gust.air_density"]
    k = mc * (2 * math.pi * sc["payload.natural_frequency"]) ** 2
    c, h = sc["payload.damping"], sc["payload.attachment_offset"]
    cda_v, cda_lat, cda_c = (sc["vehicle.drag_area"], sc["vehicle.lateral_drag_area"],
                             sc["payload.drag_area"])  # fmt: skip
    e3, hb = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, -h])

    def f(t: float, s: np.ndarray) -> np.ndarray:
        pos, att, pc = s[0:3], s[3:6], s[6:9]
        v, w, vc = s[9:12], s[12:15], s[15:18]
        length_now, rate = line_length(t, l0)
        r = rotation(*att)
        a = pos + r @ hb
        va = v + r @ np.cross(w, hb)
        d = pc - a
        dist = np.linalg.norm(d)
        u = d / dist
        strain_rate = u @ (vc - va) - rate
        tension = max(0.0, k * (dist - length_now) + c * strain_rate) if dist > length_now else 0.0
        fdc = -0.5 * rho * cda_c * np.linalg.norm(vc) * vc
        fd = -0.5 * rho * np.array([cda_lat, cda_lat, cda_v]) * v * np.abs(v)
        dvc = (-tension * u + fdc) / mc - g * e3
        dv = (u1 * r @ e3 + tension * u + fd) / m - g * e3
        torque = tau + np.cross(hb, r.T @ (tension * u))
        p, q, rr = w
        dw = np.array([
            ((inertia[1] - inertia[2]) * q * rr + torque[0]) / inertia[0],
            ((inertia[2] - inertia[0]) * p * rr + torque[1]) / inertia[1],
            ((inertia[0] - inertia[1]) * p * q + torque[2]) / inertia[2],
        ])  # fmt: skip
        return np.concatenate([v, w, vc, dv, dw, dvc])

    return f


STATES = ["x", "y", "z", "phi", "theta", "psi", "xc", "yc", "zc",
          "vx", "vy", "vz", "p", "q", "r", "vxc", "vyc", "vzc"]  # fmt: skip


def test_the_paid_out_line_agrees_with_an_independent_integration() -> None:
    sc = lowering(2.0)
    flight = fly(sc, record_every=1)
    tr = flight.trace
    dt, steps = sc["integrator.dt"], 3000  # 1.5 s: through the winch's switch at 0.95 s
    t = tr.index.to_numpy()
    l0 = 1.0
    # The engine's line is the law's closed form.
    exact = np.array([line_length(x, l0) for x in t[: steps + 1]])
    np.testing.assert_allclose(tr["line"].to_numpy()[: steps + 1], exact[:, 0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(tr["line_rate"].to_numpy()[: steps + 1], exact[:, 1], rtol=0,
                               atol=1e-9)  # fmt: skip
    mine = tr[STATES].to_numpy()
    s = mine[0].copy()
    worst = 0.0
    for k in range(steps):
        u1 = tr["U1"].iloc[k]
        tau = tr[["tau_phi", "tau_theta", "tau_psi"]].iloc[k].to_numpy()
        sol = solve_ivp(rhs(sc, u1, tau, l0), (k * dt, (k + 1) * dt), s, method="DOP853",
                        rtol=1e-13, atol=1e-13)  # fmt: skip
        s = sol.y[:, -1]
        worst = max(worst, float(np.max(np.abs(s - mine[k + 1]))))
    assert worst < 1e-9, worst
    # The parcel went down with the line, and the vehicle felt it.
    assert tr["zc"].iloc[steps] < tr["zc"].iloc[0] - 0.4
    assert np.ptp(tr["z"].to_numpy()[:steps]) > 1e-5


def test_a_lowering_in_still_air_touches_down_at_the_commanded_rate_on_the_drop_point() -> None:
    # 6 m: the parcel reaches the ground 1 m before the winch's target, while the winch still
    # pays out at its full speed (it slows within v^2 / a = 0.5 m of the target).
    sc = lowering(6.0)
    flight = fly(sc, record_every=1)
    m, tr = flight.metrics.set_index("phase"), flight.trace
    assert not flight.diverged
    # The touchdown falls in the lowering, at the winch's speed: the line's axial bounce,
    # set off by the winch's start, has died down to well under 1 % by then.
    low = m.loc["lower1"]
    assert abs(low["touchdown_speed"] - V) < 0.01 * V, low["touchdown_speed"]
    assert low["touchdown_miss"] < 1e-6 and low["touchdown_drift"] < 1e-6, low
    assert m.loc["flight", "touchdown_speed"] == low["touchdown_speed"]
    assert math.isnan(m.loc["hold1", "touchdown_speed"])
    # It rests, the line goes slack, the hook opens 1 s (the default delay) later.
    first = tr.index[tr["zc"] < 0][0]
    release = m.loc["flight", "release_time"]
    assert 1.0 < release - first < 1.5, (first, release)
    slack = tr[(tr.index > first + 0.5) & (tr.index < release)]
    assert (slack["tension"] == 0).all() and (slack["zc"] < 0).all()
    # After it: no line force, the line reeled in, the vehicle climbs away, the parcel stays.
    after = tr[tr.index > release + 0.01]
    assert (after["tension"] == 0).all()
    assert after["line"].iloc[0] > 5.9 and 1.0 <= after["line"].iloc[-1] < 1.2
    assert after["z"].iloc[-1] > 6.9
    assert abs(after["zc"].iloc[-1]) < 1e-3 and math.dist(after[["xc", "yc"]].iloc[-1], DROP) < 1e-6
    # The law, compensating a mass no longer carried, settles the height it rose by once the
    # parcel rested.
    assert 0 < m.loc["flight", "release_height_change"] < 1.0


def test_bad_last_metres_values_name_their_key() -> None:
    cases = {
        "payload.winch_speed": {"payload.winch_speed": -1.0},
        "payload.release": {"payload.release": "landing"},
        "trajectory.lower[0]": {"trajectory.lower": [9.0, 0.0]},
        "ground.dissipation": {"ground.dissipation": -1.0},
    }
    for key, change in cases.items():
        with pytest.raises(quadrs.ScenarioError, match=re.escape(key)):
            lowering(5.0, **change)
    with pytest.raises(quadrs.ScenarioError, match=re.escape("trajectory.lower[0]")):
        lowering(5.0, **{"payload.winch_speed": None, "payload.winch_acceleration": None,
                         "payload.length_min": None})  # fmt: skip


# -- the route from a .plan: DO_WINCH and DO_GRIPPER -------------------------------------------
HOME = (47.3977419, 8.5455938, 488.0)


def _item(command: int, *params: Any, frame: int = 3) -> dict[str, Any]:
    p = [*params, *[0] * (7 - len(params))]
    return {"type": "SimpleItem", "command": command, "frame": frame, "params": p,
            "autoContinue": True}  # fmt: skip


def _plan(tmp_path: Path, items: list[dict[str, Any]]) -> Path:
    doc = {"fileType": "Plan", "version": 1,
           "mission": {"version": 2, "hoverSpeed": 1.0, "plannedHomePosition": list(HOME),
                       "items": items}}  # fmt: skip
    path = tmp_path / "drop.plan"
    path.write_text(json.dumps(doc))
    return path


def test_winch_and_gripper_items_become_the_route_written_by_hand(tmp_path: Path) -> None:
    from quadrs.scenario.route_files import RouteFileError, read_plan

    lat, lon = HOME[0], HOME[1]
    path = _plan(tmp_path, [
        _item(22, 0, 0, 0, None, None, None, 6.0),     # take off to 6 m, here
        _item(16, 8.0, 0, 0, None, lat, lon, 6.0),     # hold 8 s there, then its items
        _item(42600, 1, 1, 5.0, 0.5),                  # DO_WINCH: pay out 5 m at 0.5 m/s
        _item(211, 1, 0),                              # DO_GRIPPER: release
        _item(42600, 1, 6),                            # DO_WINCH: retract
        _item(16, 0, 0, 0, None, lat, lon, 7.0),       # climb away
    ])  # fmt: skip
    base = lowering(5.0)
    flown = read_plan(path, start_height=6.0).apply(base)
    by_hand = base.override({"trajectory.route": [[0.0, 0.0, 6.0], [0.0, 0.0, 7.0]],
                             "trajectory.lower": [5.0, 0.0], "trajectory.hold": [0.0, 0.0],
                             "trajectory.arrival_hold": [8.0, 0.0],
                             "payload.release": "touchdown", "payload.winch_speed": 0.5,
                             "initial.position": [0.0, 0.0, 6.0], "trajectory.speed": 1.0,
                             "integrator.duration": flown["integrator.duration"]})  # fmt: skip
    for key in ("trajectory.route", "trajectory.lower", "trajectory.hold",
                "trajectory.arrival_hold", "payload.release", "payload.winch_speed",
                "initial.position"):  # fmt: skip
        assert flown[key] == by_hand[key], key
    assert flown.route == by_hand.route
    # The flight is long enough for the hold (flown first, as PX4 does), the lowering and the
    # climb.
    segments = flown.route.segments
    assert [s.kind for s in segments][:3] == ["hold", "lower", "leg"]
    assert flown["integrator.duration"] >= segments[2].arrival
    # What is not understood is refused, naming the item.
    for bad, where in (([_item(42600, 1, 3)], "mission.items[2]: DO_WINCH action 3"),
                       ([_item(211, 1, 2)], "mission.items[2]: DO_GRIPPER action 2")):  # fmt: skip
        path = _plan(tmp_path, [_item(22, 0, 0, 0, None, None, None, 6.0),  # here
                                _item(16, 0, 0, 0, None, lat, lon, 6.0), *bad,
                                _item(16, 0, 0, 0, None, lat, lon, 7.0)])  # fmt: skip
        with pytest.raises(RouteFileError, match=re.escape(where)):
            read_plan(path, start_height=6.0)


# -- the mission's answer on the touchdown speed, confirmed by brute force ----------------------
@pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")  # dt = 2 ms: a count, not a metric
def test_the_missions_touchdown_answer_covers_a_brute_force_count() -> None:
    """A short lowering from 3 m with the winch's speed dispersed about 0.5 m/s: P(touchdown
    faster than 0.5 m/s) from 100 flights, its interval against the count over 300 others.
    (16 s: each realisation's slower winch times its own schedule, which must fit the flight.)"""
    from quadrs.design.mission import mission_report

    sc = lowering(3.0, **{
        "trajectory.route": [[*DROP, 3.0], [*DROP, 4.0]], "initial.position": [*DROP, 3.0],
        "trajectory.hold": [3.0, 0.0], "integrator.dt": 0.002, "integrator.duration": 16.0,
        "dispersions": {"payload.winch_speed": {"dist": "normal", "mean": 0.5, "std": 0.05}},
    })  # fmt: skip

    def batch(runs: int, seed: int) -> quadrs.MonteCarloResult:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", quadrs.StabilityWarning)
            return quadrs.monte_carlo(sc, runs=runs, seed=seed, controllers=("pd",),
                                      progress=False, spectra=False)  # fmt: skip

    report = mission_report(batch(100, seed=1), 10.0, touchdown_limit=0.5)
    row = report.last_metres.loc["flight"]
    assert int(row["touchdowns"]) == 100 and int(row["diverged"]) == 0
    assert "lower1" in report.last_metres.index
    assert report.last_metres_line().startswith("Last metres: touchdown faster than 0.5 m/s: p = ")
    runs = batch(300, seed=2).runs
    speed = runs[runs["phase"] == "flight"]["touchdown_speed"].to_numpy(float)
    assert np.isfinite(speed).all() and len(speed) == 300
    brute = float(np.mean(speed > 0.5))
    assert 0.2 < brute < 0.8, brute
    assert row["ci_low"] <= brute <= row["ci_high"], (brute, row["ci_low"], row["ci_high"])
