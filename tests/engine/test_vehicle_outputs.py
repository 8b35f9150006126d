"""Whole-vehicle outputs (docs/model.md section 11): every metric recomputed from a trace
recorded at every step, in a 3-D flight; the ground plane; the exit statuses."""

import math

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs import Scenario


@pytest.fixture(scope="module")
def lateral(short: Scenario) -> Scenario:
    """The short flight through three-component turbulence: the vehicle moves in 3-D."""
    return Scenario.preset("paper_stable_lateral").override(
        {
            **{k: short[k] for k in ("integrator.duration", "integrator.dt", "phases")},
            "trajectory.waypoints": short["trajectory.waypoints"],
            "gust.start": 1.0,
            "gust.end": 5.0,
            "gust.w20": 25.0,
            "gust.components": ["longitudinal", "lateral", "vertical"],
            "payload.damping": 0.3,
        }
    )


def inside(t: np.ndarray, phase: dict, dt: float) -> np.ndarray:
    return (t >= phase["start"] - dt / 2) & (t <= phase["end"] + dt / 2)


def trapezoid_rms(x: np.ndarray, t: np.ndarray, span: float) -> float:
    return math.sqrt(np.trapezoid(x**2, t) / span)


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_metrics_recomputed_from_the_trace_of_a_3d_flight(lateral: Scenario, controller: str):
    f = quadrs.simulate(lateral, controller, seed=4, record_every=1)
    assert f.status == "ok"
    tr = f.trace
    t = tr.index.to_numpy()
    dt = float(lateral["integrator.dt"])
    err = np.sqrt(
        (tr["x_ref"] - tr["x"]) ** 2 + (tr["y_ref"] - tr["y"]) ** 2 + (tr["z_ref"] - tr["z"]) ** 2
    ).to_numpy()
    # The flight really is 3-D: the lateral error is a real part of the tracking error.
    assert np.abs(tr["x"]).max() > 1e-3 and np.abs(tr["y"]).max() > 1e-3
    # The spring payload moves laterally with the vehicle: its acceleration has lateral parts.
    vertical_only = np.abs(np.gradient(tr["vzc"].to_numpy(), t))
    assert (tr["accel_c"] > vertical_only + 1e-3).any()
    tension = tr["tension"].to_numpy()
    for phase in lateral["phases"]:
        m = f.metrics.set_index("phase").loc[phase["name"]]
        ins = inside(t, phase, dt)
        span = phase["end"] - phase["start"]
        assert m["tracking_rms"] == pytest.approx(trapezoid_rms(err[ins], t[ins], span), rel=1e-9)
        a = tr["accel_c"].to_numpy()[ins]
        assert m["max_accel"] == pytest.approx(a.max(), rel=1e-12)
        assert m["rms_accel"] == pytest.approx(trapezoid_rms(a, t[ins], span), rel=1e-9)
        # The spring hangs straight: no swing; its tension is the spring force.
        assert m["max_swing"] == 0.0 and m["rms_swing"] == 0.0
        assert m["max_tension"] == tension[ins].max()
        assert m["min_tension"] == tension[ins].min()
        assert m["slack_time"] == pytest.approx(np.count_nonzero(tension[ins] <= 0) * dt)
        assert m["saturated_time"] == 0.0  # ideal actuators never saturate


def test_the_spring_tension_is_its_force_and_it_goes_slack_when_the_payload_is_thrown_up(
    short: Scenario,
) -> None:
    # An undamped spring and a 10 m drop: the payload overshoots its hook (Fs <= 0) landing.
    s = short.override(
        {"payload.damping": 0.0, "trajectory.waypoints": [[0, 0, 0, 10, 0], [4, 0, 0, 0, 0]]}
    )
    f = quadrs.simulate(s, "pd", seed=1, record_every=1)
    tr = f.trace
    kc = s["payload.mass"] * (2 * math.pi * s["payload.natural_frequency"]) ** 2
    cc = s["payload.damping"]
    force = kc * (tr["z"] - tr["zc"]) + cc * (tr["vz"] - tr["vzc"])
    np.testing.assert_allclose(tr["tension"], force, rtol=1e-9, atol=1e-9)
    own = f.metrics[f.metrics["phase"] != "flight"]  # the scenario's phases (not the whole)
    total_slack = own["slack_time"].sum()
    assert total_slack == pytest.approx(
        sum(
            np.count_nonzero(force.to_numpy()[inside(tr.index.to_numpy(), p, 0.002)] <= 0)
            for p in s["phases"]
        )
        * 0.002
    )
    assert total_slack > 0


def test_a_vehicle_below_the_ground_ends_its_flight_with_status_ground(still_hover: Scenario):
    # Hover at 2 m, then a commanded descent to 0.5 m through a ground plane at 1 m.
    s = still_hover.override(
        {
            "trajectory.waypoints": [[0, 0, 0, 2.0, 0.0], [1.0, 0, 0, 0.5, 0.0]],
            "ground.enabled": True,
            "ground.altitude": 1.0,
        }
    )
    f = quadrs.simulate(s, "pd", record_every=1)
    assert f.status == "ground"
    assert 1.0 < f.diverged_at < 5.0
    z = f.trace["z"].to_numpy()
    assert z.min() >= 1.0  # the trace stops before the first state below the ground
    assert math.isnan(f.metrics["iae"].iloc[0])  # the phase did not finish
    # Off, the same flight runs to the end.
    assert quadrs.simulate(s.override({"ground.enabled": False}), "pd").status == "ok"
    # And in a batch, the status reaches mc.runs.
    mc = quadrs.monte_carlo(s, runs=2, seed=0, controllers=("pd",), progress=False)
    assert set(mc.runs["status"]) == {"ground"}
    assert "ground" in quadrs._core.EXIT_STATUSES


def test_a_start_below_the_ground_is_a_scenario_error(still_hover: Scenario) -> None:
    with pytest.raises(quadrs.ScenarioError, match=r"ground\.altitude"):
        still_hover.override({"ground.enabled": True, "ground.altitude": 3.0})
    with pytest.raises(quadrs.ScenarioError, match=r"ground\.altitude"):
        still_hover.override({"ground.altitude": float("nan")})


def test_new_metrics_reach_runs(short: Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=3, seed=0, progress=False)
    for col in ("max_swing", "rms_swing", "max_tension", "min_tension", "slack_time"):
        assert col in mc.runs
    assert isinstance(mc.runs, pd.DataFrame)
    assert (mc.runs["max_tension"] >= mc.runs["min_tension"]).all()
