"""Each loop at its own rate (docs/model.md, "Loop rates", docs/model.md "Loop rates"): the wind at
`gust.rate`, the laws' loops at `controller.*_rate`, what is refused, and what the stability
analysis and the linear model say of a sampled law."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import quadrs
from quadrs import Scenario, ScenarioError
from quadrs.engine.calls import is_sampled, loop_rates

SEED, REALISATION = 7, 3


def gusty_hover(rate: float) -> Scenario:
    """The paper flight through its vertical gust (25 to 40 s) at dt = 1 ms, the
    wind evaluated at ``rate`` Hz."""
    return Scenario.paper().override({"integrator.dt": 1e-3, "gust.rate": rate})


def wind_z(s: Scenario) -> np.ndarray:
    flight = quadrs.simulate(s, "smc", SEED, realisation=REALISATION, record_every=1)
    return flight.trace["wind_z"].to_numpy()


def test_the_wind_at_its_rate_is_the_exact_series_at_that_period_interpolated_between() -> None:
    """At the updates, the flight's turbulence is the exactly discretised Dryden filter at the
    update period (`gust_series` at that dt: its variance and autocorrelation are the
    spectrum's at every lag, tests/engine/test_gust*.py); between them it runs linearly to the
    next update's value; 0 Hz is every step, as before."""
    rate, dt = 100.0, 1e-3
    every = round(1.0 / (rate * dt))
    s = gusty_hover(rate)
    w = wind_z(s)
    start, end = round(25.0 / dt), round(40.0 / dt)
    updates = w[start:end:every]
    scales = quadrs.gust_scales(2.0, 10.0)["vertical"]
    series = quadrs.gust_series(
        "vertical", *scales, airspeed=10.0, dt=1.0 / rate, steps=len(updates) - 1,
        seed=SEED, first=REALISATION,
    )[0]  # fmt: skip
    # The last row of the trace is the closing one (it holds the last step's wind).
    np.testing.assert_allclose(updates[: len(series)], series, rtol=1e-13, atol=1e-15)
    # Between updates: a first-order hold (linear interpolation) to the next update.
    body = w[start : start + every * (len(series) - 1)].reshape(-1, every)
    frac = np.arange(every) / every
    want = series[:-1, None] + (series[1:, None] - series[:-1, None]) * frac
    np.testing.assert_allclose(body, want, rtol=1e-12, atol=1e-14)
    # Before the window, no turbulence; the step before it already ramps toward the onset's.
    assert np.all(w[: start - every] == 0.0)
    # Every step (0 Hz): the series at the step itself, not held.
    every_step = wind_z(gusty_hover(0.0))[start : start + 50]
    np.testing.assert_allclose(
        every_step,
        quadrs.gust_series(
            "vertical", *scales, airspeed=10.0, dt=dt, steps=50, seed=SEED, first=REALISATION
        )[0],
        rtol=1e-13,
        atol=1e-15,
    )


def test_the_wind_at_its_rate_draws_a_tenth_of_the_innovations() -> None:
    every_step = gusty_hover(0.0).engine.innovations_dimension()
    at_rate = gusty_hover(100.0).engine.innovations_dimension()
    # 15 s of the vertical Dryden filter (second order): 2 x 15,000 draws every step,
    # 2 x 1,500 at 100 Hz (one per update of the window).
    assert every_step == 30_000
    assert at_rate == 3_000


@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("gust.rate", 300.0),
        ("controller.position_rate", 3000.0),
        ("controller.attitude_rate", 333.0),
        ("controller.inner_rate", 1500.0),
    ],
)
def test_a_rate_whose_period_is_not_whole_steps_is_refused_naming_its_key(
    key: str, value: float
) -> None:
    with pytest.raises(ScenarioError, match=key.replace(".", r"\.")) as e:
        gusty_hover(0.0).override({key: value}).engine  # noqa: B018
    assert "integrator.dt" in str(e.value)


def test_a_laws_own_rates_round_to_whole_steps_where_the_keys_are_refused() -> None:
    """PX4's own 50, 250 and 1000 Hz on a 3 ms step: 7 steps (21 ms), 1 and 1 (no loop runs
    faster than the step); the same rates set as keys are refused."""
    s = Scenario.paper().override({"integrator.dt": 3e-3})
    assert s.engine.loop_steps("px4") == [7, 1, 1]
    assert s.engine.loop_steps("pd") == [1, 1, 1]
    assert is_sampled(s, "px4")
    with pytest.raises(ScenarioError, match=r"controller\.position_rate: 50\.0 Hz"):
        s.override({"controller.position_rate": 50.0})


@pytest.mark.parametrize("key", ["gust.rate", "controller.position_rate"])
def test_rates_cannot_be_dispersed(key: str) -> None:
    spread = {"dispersions": {key: {"dist": "uniform", "low": 10.0, "high": 20.0}}}
    with pytest.raises(ScenarioError, match=r"cannot be dispersed: the loops' rates"):
        gusty_hover(0.0).override(spread)


def test_each_law_flies_its_own_rates_unless_set() -> None:
    """The rates are the engine's schedule's (a loop run every step at the 0.2 ms step's 5 kHz)."""
    paper = Scenario.paper()
    assert loop_rates(paper, "px4") == (50.0, 250.0, 1000.0)
    assert loop_rates(paper, "pd") == (5000.0, 5000.0, 5000.0)
    assert is_sampled(paper, "px4") and not is_sampled(paper, "smc")
    flat = paper.override({"controller.position_rate": 0.0, "controller.attitude_rate": 0.0,
                           "controller.inner_rate": 0.0})  # fmt: skip
    assert loop_rates(flat, "px4") == (5000.0, 5000.0, 5000.0)
    assert not is_sampled(flat, "px4")
    set_all = paper.override({"controller.position_rate": 100.0})
    assert loop_rates(set_all, "smc") == (100.0, 5000.0, 5000.0)
    assert loop_rates(set_all, "px4") == (100.0, 250.0, 1000.0)


def test_the_rates_said_are_the_rates_flown() -> None:
    """On a 3 ms step PX4's own 50 Hz rounds to 7 steps: the loop flies at 1 / 21 ms, and
    its 250 and 1000 Hz loops at the step's 333 Hz (the rule is the engine's, read once)."""
    s = Scenario.paper().override({"integrator.dt": 3e-3})
    assert loop_rates(s, "px4") == pytest.approx((1 / 0.021, 1 / 0.003, 1 / 0.003), rel=1e-12)


def hover_offset(position_rate: float) -> Scenario:
    """The paper's flight from 0.2 m up at dt = 1 ms, its PD position loop at ``position_rate``
    Hz, in still air; a flight that leaves a 20 m ball around its start has run away."""
    return Scenario.paper().override(
        {
            "integrator.dt": 1e-3,
            "gust.enabled": False,
            "controller.position_rate": position_rate,
            "initial.position": [0.0, 0.0, 0.2],
            "divergence.max_distance": 20.0,
        }
    )


def test_a_position_loop_too_slow_for_the_hover_is_unstable_in_the_model_and_in_flight() -> None:
    """The sampled law's discrete-time model (its poles over one period of its schedule)
    against the flight: stable at 50 Hz, unstable at 0.5 Hz (a vertical pair at +0.81 +/-
    1.57j: the multiplier is negative, the error flips sign every period and grows), where the
    flight runs away."""
    for rate, stable in [(50.0, True), (0.5, False)]:
        s = hover_offset(rate)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            report = quadrs.stability(s, "pd")
            flight = quadrs.simulate(s, "pd", 0)
        assert report.period == pytest.approx(1.0 / rate)
        assert report.stable is stable, str(report)
        assert "sampled: the discrete-time model over" in str(report)
        assert flight.diverged is (not stable), (rate, flight)
    # Every step: the continuous model, as before.
    assert quadrs.stability(hover_offset(0.0), "pd").period is None


def test_a_period_too_long_to_model_is_the_continuous_laws_and_says_so() -> None:
    """A position loop at 1e-300 Hz (its period past any flight): the report is the continuous
    law's and says why, where the analysis flew the period for ever (and `simulate`, which
    analyses first, with it); the flight itself flies, its position loop updating once."""
    s = hover_offset(1e-300)
    report = quadrs.stability(s, "pd")
    assert report.period is None and report.unmodelled_period is not None
    assert report.unmodelled_period > quadrs._core.MAX_PERIOD_STEPS * 1e-3
    assert "too long to model sampled" in str(report)
    continuous = quadrs.stability(hover_offset(0.0), "pd")
    np.testing.assert_array_equal(report.jacobian, continuous.jacobian)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        quadrs.simulate(s.override({"integrator.duration": 1.0, "phases": [
            {"name": "P1", "start": 0.0, "end": 1.0}]}), "pd", record_every=100)  # fmt: skip


def test_the_linear_model_says_it_is_the_continuous_laws() -> None:
    s = hover_offset(50.0)
    said = r"continuous law's; its loops run at 50, 1000, 1000 Hz"  # the 1 ms step's rate
    with pytest.warns(quadrs.SampledLawNote, match=said):
        quadrs.linearize(s, "pd")
    with warnings.catch_warnings():
        warnings.simplefilter("error", quadrs.SampledLawNote)
        quadrs.linearize(hover_offset(0.0), "pd")
