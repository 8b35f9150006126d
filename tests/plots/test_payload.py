"""Slung-payload figures: they render the flight's own data, with plain labels and units."""

import warnings
from pathlib import Path

import numpy as np
import pytest

import quadrs
from quadrs import plots
from tests.plots.test_figures import assert_images


@pytest.fixture(scope="module")
def swinging() -> dict[str, quadrs.Flight]:
    """8 s of the slung preset: a lateral step from hover at 2 m, so the load swings."""
    sc = quadrs.Scenario.preset("slung").override(
        {
            "initial.position": [0.0, 0.0, 2.0],
            "trajectory.waypoints": [[0, 0, 0, 2, 0], [1, 2, 1, 2, 0]],
            "integrator.duration": 8.0,
            "integrator.dt": 0.002,
            "gust.start": 3.0,
            "gust.end": 6.0,
            "phases": [{"name": "all", "start": 0, "end": 8}],
        }
    )
    # The paper's PD lets the slung load's swing grow slowly (docs/model.md): a warning that
    # does not concern the figures.
    # The coarse step (a fast figure) warns too; the figures do not depend on it.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StepSizeWarning)
        with pytest.warns(quadrs.StabilityWarning, match="swing"):
            pd_flight = quadrs.simulate(sc, "pd", seed=1)
        return {"pd": pd_flight, "smc": quadrs.simulate(sc, "smc", seed=1)}


def test_payload_path_shows_both_bodies_from_the_side_and_above(swinging, tmp_path: Path) -> None:
    fig = plots.payload_path(swinging, tmp_path / "path")
    assert_images(tmp_path / "path")
    side, top = fig.axes[:2]
    assert len(fig.axes) == 4  # two views per flight
    assert side.get_xlabel() == "forward x (m)" and side.get_ylabel() == "height z (m)"
    assert top.get_ylabel() == "sideways y (m)"
    tr = swinging["pd"].trace
    vehicle, payload = side.get_lines()[:2]
    np.testing.assert_array_equal(vehicle.get_xdata(), tr["x"].to_numpy())
    np.testing.assert_array_equal(payload.get_ydata(), tr["zc"].to_numpy())
    np.testing.assert_array_equal(top.get_lines()[1].get_ydata(), tr["yc"].to_numpy())


def test_swing_and_tension_over_time(swinging, tmp_path: Path) -> None:
    fig = plots.swing_tension(swinging, tmp_path / "swing")
    assert_images(tmp_path / "swing")
    angle, pull = fig.axes
    assert angle.get_ylabel() == "cable angle from vertical (deg)"
    assert pull.get_ylabel() == "cable tension (N)"
    tr = swinging["smc"].trace
    np.testing.assert_array_equal(angle.get_lines()[1].get_ydata(), np.degrees(tr["swing"]))
    np.testing.assert_array_equal(pull.get_lines()[1].get_ydata(), tr["tension"].to_numpy())
    assert tr["swing"].max() > np.radians(1.0)  # the step swung the load
