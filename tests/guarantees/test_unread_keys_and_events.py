"""Keys a scenario does not read are refused when given a value, and an event that never
happened is said, never read as safe (docs/guarantees.md): the rotors' aerodynamics on ideal
actuators, the paper body's drag areas on the rigid body (``--set``, ``--disperse``, sweeps,
``tune``); the mission's joint line, ``tune``'s objective, ``rare``'s levels and the
exceedance figure of an event metric without its event."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import quadrs
from tests.guarantees.test_design_loop_and_files import TINY_CLI, one_line, run_cli

RIGID = {"vehicle.body": "rigid"}
AERO = ("actuator.rotor_drag", "actuator.flapping", "actuator.translational_lift")


@pytest.mark.parametrize("key", ["vehicle.drag_area", "vehicle.lateral_drag_area"])
def test_the_paper_bodys_drag_areas_are_refused_on_the_rigid_body(key: str) -> None:
    delivery = quadrs.Scenario.preset("delivery")
    assert delivery["vehicle.body"] == "rigid" and delivery[key] > 0  # inherited: kept
    with pytest.raises(
        quadrs.ScenarioError,
        match=re.escape(key) + r" is read by vehicle\.body "
        r'= "paper" only',
    ) as e:
        delivery.override({key: 0.5})
    assert e.value.key == key
    with pytest.raises(quadrs.ScenarioError, match=re.escape(key)):
        delivery.override({"dispersions": {key: {"dist": "uniform", "low": 0.0, "high": 1.0}}})
    with pytest.raises(quadrs.ScenarioError, match=re.escape(key)):
        quadrs.sweep(delivery, {key: [0.1, 0.2]}, runs=1, progress=False)
    # On the paper body it is read.
    assert quadrs.Scenario.preset("paper").override({key: 0.5})[key] == 0.5


@pytest.mark.parametrize("key", AERO)
def test_rotor_aerodynamics_are_refused_on_ideal_actuators(key: str) -> None:
    ideal = quadrs.Scenario.preset("delivery").override({"actuator.model": "ideal"})
    value = [0.1, 0.1, 0.1] if key == "actuator.rotor_drag" else 0.1
    with pytest.raises(
        quadrs.ScenarioError,
        match=re.escape(key) + r" is read by actuator\.model"
        r' = "rotors" only',
    ):
        ideal.override({key: value})
    element = f"{key}[0]" if key == "actuator.rotor_drag" else key
    with pytest.raises(quadrs.ScenarioError, match=re.escape(element)):
        ideal.override({"dispersions": {element: {"dist": "uniform", "low": 0.0, "high": 1.0}}})


def test_the_cli_names_an_unread_key(capsys) -> None:
    code, _, err = run_cli("mc", "--preset", "delivery", "--runs", "1", "--no-progress",
                           "--set", "vehicle.drag_area=0.3", capsys=capsys)  # fmt: skip
    assert code == 2
    assert "vehicle.drag_area is read by vehicle.body" in one_line(err)


# -- an event that never happened ---------------------------------------------------------------
def test_a_touchdown_limit_without_a_touchdown_is_not_judged(capsys) -> None:
    """Before: "any phase: 0 of 2 flights ... exceeded" on a vehicle without a parcel that
    could touch down."""
    code, out, err = run_cli("mission", "--preset", "paper", *TINY_CLI, "--runs", "2",
                             "--workers", "1", "--no-progress", "--limit",
                             "touchdown_speed=1", capsys=capsys)  # fmt: skip
    assert code == 0, err
    text = " ".join(out.split())
    assert "any phase: not judged: none of the 2 flights has a value of the metric" in text
    assert "exceeded 1 m/s in at least one phase" not in text


def test_tune_on_an_event_metric_over_several_phases_is_refused_before_flying(
    tmp_path: Path, capsys
) -> None:
    code, _, err = run_cli("tune", *TINY_CLI, "--controller", "pd", "--param",
                           "controller.pd.kp[2]=1:2", "--objective", "touchdown_speed",
                           "--runs", "2", "--maxiter", "1", "--workers", "1", "--out",
                           str(tmp_path / "t.toml"), capsys=capsys)  # fmt: skip
    assert code == 2
    line = one_line(err)
    assert "objective touchdown_speed is an event's metric" in line and "--phase" in line


def test_rare_on_an_event_that_never_happens_says_so(capsys) -> None:
    code, _, err = run_cli("rare", *TINY_CLI, "--metric", "touchdown_speed", "--phase", "P2",
                           "--threshold", "1", "--per-level", "100", "--max-levels", "2",
                           "--workers", "1", "--no-progress", capsys=capsys)  # fmt: skip
    assert code == 2, err
    line = one_line(err)
    assert "the event too rarely happened" in line and "atom" not in line


def test_an_exceedance_figure_of_an_event_that_never_happened_is_not_drawn() -> None:
    from quadrs import plots

    runs = pd.DataFrame({"phase": ["P1", "P2"] * 3, "controller": "pd",
                         "realisation": np.repeat(np.arange(3), 2), "diverged": False,
                         "touchdown_speed": np.nan})  # fmt: skip
    with pytest.raises(
        ValueError,
        match=r"no flight has a value of touchdown_speed \(an event's "
        r"metric: the event never happened\) in any phase",
    ):
        plots.exceedance_curves(runs, "touchdown_speed", [1.0])
    # A phase with touchdowns draws; the one without says so and has no limit legend.
    runs.loc[runs["phase"] == "P2", "touchdown_speed"] = [0.5, 0.7, 0.9]
    fig = plots.exceedance_curves(runs, "touchdown_speed", [1.0])
    empty, full = fig.axes[0], fig.axes[1]
    assert empty.get_legend() is None and not empty.get_lines()
    assert any("never happened" in t.get_text() for t in empty.texts)
    assert full.get_legend() is not None


# -- the ground in the step-size check ----------------------------------------------------------
def test_a_ground_too_stiff_for_the_step_is_warned() -> None:
    """Before: no warning, a concrete-stiff ground ended flights "tilt" (blaming the vehicle)
    and an undamped stiff one doubled the touchdown's peak force."""
    from quadrs.hover.stability import contact_step_warning, warn_before_running

    delivery = quadrs.Scenario.preset("delivery")
    assert contact_step_warning(delivery) == ""  # 200 1/s at 2 ms: resolved
    concrete = delivery.override({"ground.stiffness": 1e8, "ground.dissipation": 0.0})
    message = contact_step_warning(concrete)
    assert "ground.stiffness = 1e+08 N/m" in message and "integrator.dt = 0.002 s" in message
    assert "|pole| = 1.414e+04 1/s" in message  # sqrt(1e8 / 0.5 kg)
    with pytest.warns(quadrs.StepSizeWarning, match=r"ground\.stiffness = 1e\+08"):
        warn_before_running(concrete, ("pd",), gains=False, stacklevel=1)
    # (At 10 ms the preset's 250 Hz attitude and 500 Hz inner loops are no whole number of
    # steps: every step.)
    coarse = {"integrator.dt": 0.01, "controller.attitude_rate": 0.0, "controller.inner_rate": 0.0}
    slippery = delivery.override({"ground.friction": 5.0, **coarse})
    assert "ground.friction = 5" in contact_step_warning(slippery)


def test_any_winch_acceleration_flies_and_a_coarse_step_is_refused() -> None:
    """Before: the servo's gain 4 a / v grew with the acceleration; past 1 / dt the line's
    length went negative and the flight ended "ok" (so 1000 m/s^2 was refused). Now its gain is
    a constant 20 1/s: any acceleration flies (the line never shorter than reeled in), and only
    a step too coarse for the servo is refused, naming integrator.dt."""
    from tests.engine.test_last_metres import fly, lowering

    flight = fly(lowering(6.0, **{"payload.winch_acceleration": 1000.0,
                                  "integrator.dt": 0.001}), record_every=10)  # fmt: skip
    assert flight.status == "ok"
    assert flight.trace["line"].min() >= 1.0 - 1e-9
    assert 5.0 < flight.trace["line"].max() <= 7.0 + 1e-9
    assert flight.metrics.set_index("phase").loc["flight", "release_time"] > 0  # it landed
    with pytest.raises(
        quadrs.ScenarioError,
        match=r"integrator\.dt is too coarse for the winch's speed servo .* got 0\.06",
    ):
        lowering(6.0, **{"integrator.dt": 0.06})


def test_a_touchdown_release_on_a_spring_is_named_as_given() -> None:
    """Before: "got NaN"."""
    with pytest.raises(
        quadrs.ScenarioError,
        match=r"payload\.release applies to payload\.model "
        r'= "cable" only, got "touchdown"',
    ):
        quadrs.Scenario.preset("paper").override({"payload.release": "touchdown"})
