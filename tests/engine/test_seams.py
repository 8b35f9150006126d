"""The engine's seams as the Python side sees them: the state layout of a scenario, why each
flight ended, and flights driven by explicit innovations (docs/architecture.md)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs import _core


def test_the_layout_names_states_trace_and_linear_outputs(short):
    states = short.state_names
    assert states == list(_core.STATE_NAMES)
    assert states[:6] == ["x", "y", "z", "phi", "theta", "psi"] and "vzc" in states
    assert short.trace_columns[: len(states)] == states
    f = quadrs.simulate(short, "pd", seed=0)
    assert list(f.trace.columns) == short.trace_columns
    lin = quadrs.linearize(short, "pd", outputs=states)
    assert lin.output_names == tuple(states) and lin.A.shape == (len(states), len(states))


def _tight(scenario: quadrs.Scenario, key: str, value: float) -> quadrs.Scenario:
    return scenario.override({key: value, "gust.enabled": False})


@pytest.mark.parametrize(
    ("key", "value", "status"),
    [
        ("divergence.max_distance", 0.5, "distance"),
        ("divergence.max_speed", 0.05, "speed"),
        ("divergence.max_rate", 1e-3, "rate"),
        ("controller.pd.kp[2]", 1e308, "non_finite"),
    ],
)
@pytest.mark.filterwarnings(
    "ignore::quadrs.hover.stability.StabilityWarning"
)  # kp = 1e308: NaN poles
@pytest.mark.filterwarnings("ignore::quadrs.hover.stability.StepSizeWarning")
def test_status_names_the_bound_that_ended_the_flight(short, key, value, status):
    s = _tight(short.override({"initial.attitude": [0.02, -0.01, 0.5]}), key, value)
    f = quadrs.simulate(s, "pd", seed=0)
    assert f.diverged and f.status == status, (f.diverged_at, f.status)
    assert status in repr(f)
    mc = quadrs.monte_carlo(s, runs=5, seed=0, controllers=("pd",), progress=False)
    assert set(mc.runs["status"]) == {status}
    assert mc.runs["diverged"].all()


def test_status_is_ok_exactly_where_the_flight_did_not_diverge(short):
    s = short.override(
        {
            "gust.components": ["lateral", "vertical"],
            "gust.w20": 23.0,
            "gust.start": 0.5,
            "gust.end": 6.0,
            "divergence.max_tilt": 0.2,
        }
    )
    with pytest.warns(quadrs.StabilityWarning, match="EXCITES"):
        mc = quadrs.monte_carlo(s, runs=12, seed=3, progress=False)
    runs = mc.runs
    assert set(runs["status"]) <= set(_core.EXIT_STATUSES)
    assert ((runs["status"] == "ok") == ~runs["diverged"]).all()
    # the paper's SMC is laterally unstable: a lateral gust sets it off, and says why
    assert (runs.loc[runs["controller"] == "smc", "status"] != "ok").any()
    assert len(_core.EXIT_MESSAGES) == len(_core.EXIT_STATUSES)


def test_innovations_count_is_the_filters_orders_over_the_window(short):
    # vertical Dryden: two normals at onset and at each later step of the window
    steps = round((short["gust.end"] - short["gust.start"]) / short["integrator.dt"])
    assert _core.innovations_dimension(short.to_json()) == 2 * steps
    three = short.override({"gust.components": ["longitudinal", "lateral", "vertical"]})
    assert _core.innovations_dimension(three.to_json()) == (1 + 2 + 2) * steps
    # a window past the end of the flight counts the steps flown (the closing row, which
    # holds the last step's wind, draws none)
    late = short.override({"gust.start": 5.0, "gust.end": 9.0})
    n = round((6.0 - 5.0) / short["integrator.dt"])
    assert _core.innovations_dimension(late.to_json()) == 2 * n
    assert _core.innovations_dimension(short.override({"gust.enabled": False}).to_json()) == 0


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_a_flight_given_its_seeds_innovations_is_the_seeded_flight(short, controller):
    s = short.override({"gust.components": ["longitudinal", "lateral", "vertical"]})
    xi = _core.innovations(s.to_json(), 7, 4)
    seeded = _core.simulate(s.to_json(), controller, 7, 4, 3)
    given = _core.simulate_innovations(s.to_json(), controller, xi, 3)
    for key in ("trace", "metrics"):
        np.testing.assert_array_equal(given[key], seeded[key])
    assert given["diverged_at"] == seeded["diverged_at"] or (
        np.isnan(given["diverged_at"]) and np.isnan(seeded["diverged_at"])
    )
    # ... and different innovations fly a different gust
    other = _core.simulate_innovations(s.to_json(), controller, xi[::-1].copy(), 3)
    assert not np.array_equal(other["metrics"], seeded["metrics"])


def test_batches_of_innovations_equal_the_seeded_batch_rows(short):
    cfg = short.to_json()
    runs = 7  # not a multiple of any lane-set: the last set is padded
    xi = np.stack([_core.innovations(cfg, 2, i) for i in range(runs)])
    for workers in (1, 2):
        got = _core.run_innovations(cfg, "pd", xi, workers=workers)
        mc = quadrs.monte_carlo(short, runs=runs, seed=2, controllers=("pd",), progress=False)
        want = (
            mc.runs.sort_values(["realisation", "phase"], key=_phase_order(short))
            .loc[:, list(_core.METRIC_NAMES)]
            .to_numpy()
            .reshape(runs, len(short.phase_names), -1)
        )
        np.testing.assert_array_equal(got, want)


def _phase_order(s: quadrs.Scenario):
    order = {p: i for i, p in enumerate(s.phase_names)}

    def key(col: pd.Series) -> pd.Series:
        return col.map(order) if col.name == "phase" else col

    return key


def test_bad_innovations_are_refused_by_name(short):
    cfg = short.to_json()
    n = _core.innovations_dimension(cfg)
    with pytest.raises(ValueError, match=f"xi must hold {n} standard normals"):
        _core.run_innovations(cfg, "pd", np.zeros((2, n + 1)))
    with pytest.raises(ValueError, match="xi must hold"):
        _core.simulate_innovations(cfg, "pd", np.zeros(n - 1))
    # non-finite innovations end the flight as non-finite, never a silent number
    xi = np.zeros((1, n))
    xi[0, n // 2] = np.nan
    out = _core.simulate_innovations(cfg, "pd", xi[0])
    assert out["status"] == "non_finite"
