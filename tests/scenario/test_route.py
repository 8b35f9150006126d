"""Routes (docs/model.md, "Routes"): the schedule Python sees, leg phases, the whole-flight
phase, a route flown in still air, and the route figures."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from matplotlib.figure import Figure

import quadrs
from quadrs import Scenario, ScenarioError, plots
from quadrs.scenario.route import Route
from quadrs.scenario.route_timing import lowering_time

POINTS = [[0.0, 0.0, 0.0], [0.0, 0.0, 3.0], [24.0, 7.0, 3.0], [24.0, 7.0, 1.0]]
SPEED, ACCEL = 3.0, 1.0


def route_scenario(**changes: object) -> Scenario:
    """The paper vehicle in still air flying POINTS (25 m transit) under phases = "legs"."""
    base = {
        "trajectory.interpolation": "route",
        "trajectory.waypoints": None,
        "trajectory.route": POINTS,
        "trajectory.speed": SPEED,
        "trajectory.acceleration": ACCEL,
        "trajectory.hold": [1.0, 0.0, 0.0, 0.0],
        "phases": "legs",
        "gust.enabled": False,
        "integrator.dt": 1e-3,
        "integrator.duration": 40.0,
    }
    base.update(changes)
    return Scenario.paper().override(base)


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    return route_scenario()


@pytest.fixture(scope="module")
def flight(scenario: Scenario) -> quadrs.Flight:
    return quadrs.simulate(scenario, "pd", seed=0, record_every=10)


def test_summary_times_lengths_and_phases(scenario: Scenario) -> None:
    route = scenario.route
    assert isinstance(route, Route)
    names = [s.name for s in route.segments]
    assert names == ["hold1", "leg1", "leg2", "leg3", "hold4"]
    assert scenario.phase_names == [*names, "flight"]
    assert scenario.scenario_phases == names
    # Closed forms (rust/src/config/route.rs): a leg of length L >= 2 V^2 / A lasts 2 V / A + L / V,
    # a shorter one sqrt(8 L / A).
    climb, transit = np.sqrt(8 * 3.0 / ACCEL), 2 * SPEED / ACCEL + 25.0 / SPEED
    legs = route.legs
    assert [leg.length for leg in legs] == pytest.approx([3.0, 25.0, 2.0], rel=1e-15)
    assert legs[0].start == 1.0 and legs[0].arrival == pytest.approx(1.0 + climb, rel=1e-15)
    assert legs[1].arrival - legs[1].start == pytest.approx(transit, rel=1e-15)
    assert legs[1].peak_speed == SPEED and legs[0].peak_speed < SPEED
    assert route.arrival == legs[-1].arrival
    assert route.length == pytest.approx(30.0)
    # The phases cover the flight without gaps, and are the schedule's segments.
    windows = scenario.phase_windows
    assert windows["flight"] == (0.0, 40.0)
    spans = [windows[n] for n in names]
    assert spans[0][0] == 0.0 and spans[-1][1] == 40.0
    assert all(a[1] == b[0] for a, b in itertools.pairwise(spans))
    # Interior boundaries sit on the step grid (within half a step of the schedule's times).
    dt = scenario["integrator.dt"]
    for (a, b), seg in zip(spans, route.segments, strict=True):
        assert abs(a - seg.start) <= dt / 2 and abs(b - seg.end) <= dt / 2
        assert abs(a / dt - round(a / dt)) < 1e-9
    assert list(route.table().index) == names
    assert Scenario.paper().route is None


def test_reference_arrives_at_rest_when_the_summary_says(scenario, flight) -> None:
    """On the trace's grid: the sample nearest the summary's arrival time, sigma s from it, is
    within the distance a rest-to-rest reference can cover in sigma (A sigma^2 / 2; A bounds
    the acceleration) of the target, its speed within A sigma (rust/src/config/route.rs tests the
    exact instant)."""
    tr = flight.trace
    times = tr.index.to_numpy(float)
    for leg in scenario.route.legs:
        i = int(np.argmin(abs(times - leg.arrival)))
        sigma, at = abs(times[i] - leg.arrival), tr.iloc[i]
        ref = np.array([at["x_ref"], at["y_ref"], at["z_ref"]])
        assert np.linalg.norm(ref - leg.target) <= ACCEL * sigma**2 / 2 + 1e-12
        before = tr.loc[: leg.arrival - 0.05].iloc[-1]
        moved = np.hypot(before["x_ref"] - leg.target[0], before["y_ref"] - leg.target[1])
        assert moved + abs(before["z_ref"] - leg.target[2]) > 0


def test_route_flight_ends_at_its_last_point(scenario, flight) -> None:
    """Still air, ideal actuators, spring payload, PD: after the last arrival the reference
    rests at the last point, and the closed loop's slowest pole (quadrs.stability) decays the
    error to a small fraction of its size by the end of the flight."""
    poles = quadrs.stability(scenario, "pd").poles
    slowest = -poles["real"][poles["real"] < 0].max()  # 1/s, least damped decay rate
    rest = 40.0 - scenario.route.arrival
    peak = flight.metrics.set_index("phase").loc["flight", "tracking_rms"] * 10
    tolerance = max(peak * np.exp(-slowest * rest), 1e-3)  # m
    end = flight.trace.iloc[-1]
    miss = np.linalg.norm([end["x"] - 24.0, end["y"] - 7.0, end["z"] - 1.0])
    assert miss < tolerance, (miss, tolerance)
    assert np.isnan(flight.diverged_at)


def test_whole_flight_phase_agrees_with_the_phases_that_tile_it(flight) -> None:
    """Two independent paths: the 'flight' row against the leg phases that cover the flight
    (adjacent phases share their boundary sample, half-weighted in each: the trapezoid sums
    add up)."""
    m = flight.metrics.set_index("phase")
    legs, whole = m.drop(index="flight"), m.loc["flight"]
    assert whole["iae"] == pytest.approx(legs["iae"].sum(), rel=1e-12)
    assert whole["itae"] == pytest.approx(legs["itae"].sum(), rel=1e-12)
    assert whole["max_abs"] == legs["max_abs"].max()
    assert whole["max_accel"] == legs["max_accel"].max()


def test_paper_results_carry_the_flight_phase() -> None:
    s = Scenario.paper().override({"integrator.duration": 6.0, "phases[2].end": 6.0,
                                   "phases[2].start": 4.0, "phases[1].end": 4.0,
                                   "phases[1].start": 2.0, "phases[0].end": 2.0})  # fmt: skip
    f = quadrs.simulate(s, "smc", seed=1)
    assert list(f.metrics["phase"]) == ["P1", "P2", "P3", "flight"]
    m = f.metrics.set_index("phase")
    assert m.loc["flight", "iae"] == pytest.approx(m.loc[["P1", "P2", "P3"], "iae"].sum())
    assert set(f.spectra) == {"P1", "P2", "P3", "flight"}


@pytest.mark.parametrize(
    ("changes", "key"),
    [
        ({"trajectory.speed": 0.0}, "trajectory.speed"),
        ({"trajectory.acceleration": -1.0}, "trajectory.acceleration"),
        ({"trajectory.route": [[0, 0, 0], [0, 0, 3], [0, 0, 3]], "trajectory.hold": None},
         "trajectory.route[2]"),
        ({"trajectory.route": [[0, 0, 0]], "trajectory.hold": None}, "trajectory.route"),
        ({"trajectory.hold": [1.0, 2.0]}, "trajectory.hold"),
        ({"integrator.duration": 15.0}, "integrator.duration"),
        ({"trajectory.names": ["a", "b"]}, "trajectory.names"),
        ({"trajectory.waypoints": [[0, 0, 0, 2, 0], [1, 0, 0, 0, 0]]}, "trajectory.waypoints"),
        ({"trajectory.interpolation": "step", "trajectory.waypoints": [[0, 0, 0, 2, 0],
          [1, 0, 0, 0, 0]]}, "trajectory.route"),
    ],
)  # fmt: skip
def test_unflyable_routes_name_their_key(changes: dict, key: str) -> None:
    with pytest.raises(ScenarioError) as e:
        route_scenario(**changes)
    assert e.value.key == key, str(e.value)
    assert key.split("[")[0] in str(e.value)


def test_legs_without_a_route_and_the_reserved_name() -> None:
    with pytest.raises(ScenarioError) as e:
        Scenario.paper().override({"phases": "legs"})
    assert e.value.key == "phases"
    with pytest.raises(ScenarioError) as e:
        Scenario.paper().override({"phases[0].name": "flight"})
    assert e.value.key == "phases[0].name"


def test_named_segments(scenario) -> None:
    names = ["lift", "climb", "transit", "descent", "drop"]
    s = route_scenario(**{"trajectory.names": names})
    assert s.scenario_phases == names
    assert [seg.name for seg in s.route.segments] == names


def test_route_figures(flight, tmp_path: Path) -> None:
    fig = plots.ground_track(flight, path=tmp_path / "track")
    assert isinstance(fig, Figure) and len(fig.axes) == 1
    ref, quad, payload = fig.axes[0].get_lines()[:3]
    tr = flight.trace
    np.testing.assert_array_equal(ref.get_xdata(), tr["x_ref"])
    np.testing.assert_array_equal(quad.get_ydata(), tr["y"])
    np.testing.assert_array_equal(payload.get_ydata(), tr["y"])  # spring: moves with it
    assert (tmp_path / "track.png").stat().st_size > 0 and (tmp_path / "track.svg").exists()
    fig = plots.altitude_profile(flight, path=tmp_path / "profile")
    ref, quad, payload = fig.axes[0].get_lines()[:3]
    np.testing.assert_array_equal(payload.get_ydata(), tr["zc"])
    # Along the track: 0 over the climb, 25 m (the transit's length) over the descent.
    d = np.asarray(ref.get_xdata())
    assert d[0] == 0.0 and d[-1] == pytest.approx(25.0)
    assert np.all(np.diff(d) >= -1e-9)  # the reference never moves back
    with pytest.raises(ValueError, match="need a route"):
        plots.ground_track(quadrs.simulate(Scenario.paper().override(
            {"integrator.duration": 1.0, "phases": [{"name": "A", "start": 0, "end": 1}]}
        ), "pd", seed=0))  # fmt: skip


def test_along_track_projects_onto_the_polyline() -> None:
    from quadrs.plots.route import along_track

    pts = np.array([[0, 0, 0], [0, 0, 5], [3, 4, 5], [3, 10, 5]], float)
    x = np.array([0.0, 1.5, 3.0, 4.0, 3.0])
    y = np.array([0.0, 2.0, 4.0, 7.0, 12.0])
    np.testing.assert_allclose(along_track(pts, x, y), [0.0, 2.5, 5.0, 8.0, 11.0])


def _cross_track_from_trace(scenario: Scenario, tr) -> np.ndarray:
    """Distance of each trace row's quadrotor from its segment's line, computed here from the
    route summary (independently of the engine's Trajectory::line)."""
    segs = scenario.route.segments
    starts = np.array([s.start for s in segs])
    out = np.empty(len(tr))
    for i, (t, row) in enumerate(tr.iterrows()):
        seg = segs[int(np.searchsorted(starts, t + 1e-9, side="right")) - 1]
        a, b = np.array(seg.origin), np.array(seg.target)
        p = row[["x", "y", "z"]].to_numpy(float)
        if seg.kind == "hold":
            out[i] = np.linalg.norm(p - b)
        else:
            u = (b - a) / np.linalg.norm(b - a)
            d = p - a
            out[i] = np.linalg.norm(d - d.dot(u) * u)
    return out


def test_cross_track_and_peak_tracking_metrics(scenario, flight) -> None:
    """The engine's cross-track metrics against the trace (recorded every 10th step, so its
    peak is at most the engine's and its RMS close), and two identities: the reference lies on
    the leg's line, so cross-track <= 3-D tracking error at every sample."""
    m = flight.metrics.set_index("phase")
    tr = flight.trace
    cross = _cross_track_from_trace(scenario, tr)
    whole = m.loc["flight"]
    assert cross.max() <= whole["max_cross_track"] * (1 + 1e-12)
    assert cross.max() >= 0.9 * whole["max_cross_track"]
    t = tr.index.to_numpy(float)
    rms = np.sqrt(np.trapezoid(cross**2, t) / (t[-1] - t[0]))
    assert rms == pytest.approx(whole["rms_cross_track"], rel=2e-2)
    err = np.linalg.norm(
        tr[["x_ref", "y_ref", "z_ref"]].to_numpy(float) - tr[["x", "y", "z"]].to_numpy(float),
        axis=1,
    )
    assert err.max() <= whole["max_tracking"] * (1 + 1e-12)
    assert (m["max_cross_track"] <= m["max_tracking"] * (1 + 1e-12)).all()
    assert (m["rms_cross_track"] <= m["tracking_rms"] * (1 + 1e-12)).all()
    assert (m["max_tracking"] >= m["tracking_rms"]).all()
    assert whole["max_cross_track"] > 0  # the transit turns: something to measure


def test_cross_track_of_a_vertical_flight_is_zero() -> None:
    """The paper flies up and down the z axis with x = y = 0 exactly: every leg is that axis."""
    s = Scenario.paper().override(
        {"integrator.duration": 4.0, "phases": [{"name": "A", "start": 0, "end": 4}]}
    )
    m = quadrs.simulate(s, "pd", seed=2).metrics.set_index("phase")
    assert (m["max_cross_track"] == 0).all() and (m["rms_cross_track"] == 0).all()
    assert (m["max_tracking"] > 0).all()


def test_a_dispersed_start_flies_its_own_cross_track_line() -> None:
    """Before the first waypoint the line runs from the flight's own initial position: each
    row of a batch that disperses the start equals the single flight of its drawn scenario,
    cross-track included."""
    s = Scenario.paper().override(
        {
            "integrator.duration": 4.0,
            "integrator.dt": 2e-3,
            "gust.enabled": False,
            "phases": [{"name": "up", "start": 0.0, "end": 4.0}],
            "dispersions": {"initial.position[0]": {"dist": "uniform", "low": 0.0, "high": 0.5}},
        }
    )
    mc = quadrs.monte_carlo(s, runs=3, seed=4, controllers=["pd"], progress=False)
    for k in range(3):
        alone = quadrs.simulate(s, "pd", seed=4, realisation=k)
        row = mc.runs[(mc.runs["realisation"] == k) & (mc.runs["phase"] == "up")]
        for m in ("rms_cross_track", "max_cross_track", "iae", "tracking_rms"):
            assert row[m].iloc[0] == alone.metrics.set_index("phase").loc["up", m], (k, m)
    assert mc.runs["max_cross_track"].nunique() == 3  # the starts differ, so do the lines


def test_a_min_jerk_reference_refuses_a_dispersed_start() -> None:
    """A min-jerk reference starts from the initial state, which a batch's lanes share: a
    dispersed initial state is refused, naming the key, instead of flying the wrong reference."""
    with pytest.raises(ScenarioError, match=r"initial\.position\[2\].*min_jerk"):
        Scenario.paper().override(
            {
                "trajectory.interpolation": "min_jerk",
                "dispersions": {
                    "initial.position[2]": {"dist": "uniform", "low": 0.0, "high": 0.5}
                },
            }
        )


@pytest.mark.parametrize(("payout", "speed", "accel"), [(6.0, 0.5, 1.0), (4.5, 1.5, 0.4)])
def test_pythons_lowering_time_is_the_engines(payout: float, speed: float, accel: float) -> None:
    """The route files' and the route timing's bound read one lowering rule, the engine's
    schedule's: a lowering's span in the engine's route equals ``lowering_time``."""
    delivery = Scenario.preset("delivery").override(
        {"payload.winch_speed": speed, "payload.winch_acceleration": accel,
         "trajectory.route": [[0.0, 0.0, 5.0], [0.0, 0.0, 6.0]], "trajectory.hold": [6.0, 0.0],
         "trajectory.lower": [payout, 0.0], "initial.position": [0.0, 0.0, 5.0],
         # The rule without a final approach (with one, Python's is an upper bound).
         "payload.approach_height": None, "payload.approach_speed": None}
    )  # fmt: skip
    assert delivery.route is not None
    (lowering,) = delivery.route.lowerings
    assert lowering.end - lowering.start == pytest.approx(lowering_time(payout, speed, accel))
    assert lowering_time(payout, speed, accel) == payout / speed + 2 * speed / accel
