"""The swing-damping PD (docs/model.md, "The swing-damping PD"): a law that sees the payload.
Its keys are the PD's, off by default (then the recorded paper and delivery bits hold:
tests/engine/test_paper_bits.py); on, the parcel's swing after a step and along the delivery
route is smaller; bad values are refused by name."""

from __future__ import annotations

import math
import re
import warnings
from typing import Any

import pytest

import quadrs
from quadrs.scenario.units import label, unit
from tests.engine import delivery_on_the_state

KEYS = ("controller.pd.swing_gain", "controller.pd.swing_damping")


def fly(sc: quadrs.Scenario, seed: int = 0) -> Any:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StabilityWarning)
        return quadrs.simulate(sc, "pd", seed, record_every=1000)


def swing(sc: quadrs.Scenario, damping: float, seed: int = 0) -> Any:
    """Per phase, the peak and RMS swing of a PD flight with ``swing_damping`` = ``damping``."""
    f = fly(sc.override({"controller.pd.swing_damping": damping}), seed)
    assert math.isnan(f.diverged_at)
    return f.metrics.set_index("phase")[["max_swing", "rms_swing"]]


@pytest.fixture(scope="module")
def step() -> quadrs.Scenario:
    """The delivery vehicle (1 m line) hovering at 10 m in still air, its reference stepping
    2 m forward at 1 s; the swing measured from 4 s, once the vehicle has arrived."""
    return delivery_on_the_state().override(
        {
            "trajectory.interpolation": "step",
            "trajectory.route": None,
            "trajectory.lower": None,
            "trajectory.hold": None,
            "trajectory.speed": None,
            "trajectory.acceleration": None,
            "trajectory.names": None,
            "trajectory.waypoints": [[0.0, 0.0, 0.0, 10.0, 0.0], [1.0, 2.0, 0.0, 10.0, 0.0]],
            "initial.position": [0.0, 0.0, 10.0],
            "gust.enabled": False,
            "wind.speed": 0.0,
            "integrator.duration": 12.0,
            "phases": [{"name": "after", "start": 4.0, "end": 12.0}],
        }
    )


def test_the_keys_are_the_pds_and_left_out_by_the_presets() -> None:
    """No preset gives them (off: the presets' TOML is unchanged); set, they are written out
    and read back like the PD's other gains."""
    for preset in ("paper", "slung", "delivery"):
        sc = quadrs.Scenario.preset(preset)
        assert not any(k in sc for k in KEYS)
        assert "swing_" not in sc.to_toml()
    assert [unit(k) for k in KEYS] == ["m/s^2", "m/s"]
    assert all(label(k).startswith("PD swing") for k in KEYS)
    sc = delivery_on_the_state().override({KEYS[0]: 0.5, KEYS[1]: 2.0})
    back = quadrs.Scenario.from_toml_string(sc.to_toml())
    assert back == sc and [back[k] for k in KEYS] == [0.5, 2.0]


def test_zero_gains_fly_the_same_numbers_as_none(step: quadrs.Scenario) -> None:
    plain = fly(step)
    zero = fly(step.override({KEYS[0]: 0.0, KEYS[1]: 0.0}))
    assert plain.trace.equals(zero.trace)
    assert plain.metrics.equals(zero.metrics)


def test_damping_shrinks_the_swing_after_a_step(step: quadrs.Scenario) -> None:
    off, on = swing(step, 0.0), swing(step, 1.0)
    # Undamped, the parcel still swings 5 degrees and more 3 s after the vehicle arrived
    # (measured: 9.6 deg peak, 4.8 RMS; damped 1.5 and 0.5).
    assert off.loc["after", "max_swing"] > math.radians(5)
    assert on.loc["after", "max_swing"] < 0.3 * off.loc["after", "max_swing"]
    assert on.loc["after", "rms_swing"] < 0.3 * off.loc["after", "rms_swing"]


@pytest.mark.parametrize("seed", [0, 1])
def test_damping_shrinks_the_swing_of_the_delivery_lift(seed: int) -> None:
    """The delivery preset's whole flight through the same gusts: over the 2 s settle before
    the climb (the parcel let go in the breeze) the swing is about half (measured, seed 0:
    peak 11.2 -> 5.9 deg, RMS 5.7 -> 3.1); no phase's peak grows by more than a degree."""
    # From rest (the trimmed start is the law's equilibrium in the wind, the parcel already at
    # its steady angle: nothing to damp in the settle).
    sc = delivery_on_the_state().override({"initial.trim": "rest"})
    off, on = swing(sc, 0.0, seed), swing(sc, 2.0, seed)
    assert on.loc["lift", "max_swing"] < 0.7 * off.loc["lift", "max_swing"]
    assert on.loc["lift", "rms_swing"] < 0.7 * off.loc["lift", "rms_swing"]
    assert (on["max_swing"] < off["max_swing"] + math.radians(1)).all()


@pytest.mark.parametrize("key", KEYS)
@pytest.mark.parametrize("bad", [-1.0, -1e-9])
def test_negative_gains_are_refused_by_name(key: str, bad: float) -> None:
    with pytest.raises(quadrs.ScenarioError, match=rf"{re.escape(key)} must be >= 0, got"):
        delivery_on_the_state().override({key: bad})


@pytest.mark.parametrize("key", KEYS)
@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_non_finite_gains_are_refused_by_name(key: str, bad: float) -> None:
    with pytest.raises(quadrs.ScenarioError, match=re.escape(key)):
        delivery_on_the_state().override({key: bad})
