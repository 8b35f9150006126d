"""Containment ([volume]): a hovering flight pushed off its point by a constant crosswind,
started at rest, counts as leaving the flight geography exactly at the step its horizontal
offset passes the corridor's half-width, and its margins are the corridor less the offsets."""

from __future__ import annotations

import numpy as np
import pytest

import quadrs
from quadrs.scenario.keys import ScenarioError

DT = 0.002
DURATION = 3.0


@pytest.fixture(scope="module")
def pushed() -> quadrs.Scenario:
    """Hover at (0, 0, 2) in a 6 m/s wind toward +y, started level as in still air."""
    return quadrs.Scenario.paper().override({
        "gust.enabled": False,
        "wind.speed": 6.0,
        "wind.heading": 90.0,
        "initial.trim": "rest",
        "initial.position": [0.0, 0.0, 2.0],
        "trajectory.waypoints": [[0.0, 0.0, 0.0, 2.0, 0.0], [1.0, 0.0, 0.0, 2.0, 0.0]],
        "integrator.dt": DT,
        "integrator.duration": DURATION,
        "phases": [{"name": "P1", "start": 0.0, "end": DURATION}],
    })  # fmt: skip


def _offsets(scenario: quadrs.Scenario) -> np.ndarray:
    """The horizontal offset from the hover point at every step (the trace keeps each)."""
    trace = quadrs.simulate(scenario, "pd", seed=0).trace
    assert len(trace) == round(DURATION / DT) + 1
    return np.hypot(trace["x"].to_numpy(), trace["y"].to_numpy())


def _split(scenario: quadrs.Scenario, last_of_a: int, width: float) -> dict[str, dict]:
    """The phases A = steps [0, last_of_a], B = the rest, flown in a corridor of ``width``."""
    s = scenario.override({
        "phases": [{"name": "A", "start": 0.0, "end": last_of_a * DT},
                   {"name": "B", "start": (last_of_a + 1) * DT, "end": DURATION}],
        "volume": {"flight_geography": width, "flight_height_band": 50.0, "contingency": 0.25},
    })  # fmt: skip
    m = quadrs.simulate(s, "pd", seed=0).metrics.set_index("phase")
    return {p: m.loc[p].to_dict() for p in ("A", "B", "flight")}


def test_leaving_the_corridor_is_counted_at_the_step_it_happens(pushed) -> None:
    d = _offsets(pushed)
    assert d[0] == 0.0 and d.max() > 0.05  # the wind pushes it off its point
    width = 0.5 * d.max()
    k = int(np.argmax(d > width))  # the first step outside
    assert 10 < k < len(d) - 10
    before = _split(pushed, k - 1, width)  # A ends the step before it leaves
    assert before["A"]["left_geography"] == 0.0 and before["B"]["left_geography"] == 1.0
    assert before["flight"]["left_geography"] == 1.0
    at = _split(pushed, k, width)  # one step later, A holds the step it left at
    assert at["A"]["left_geography"] == 1.0
    # The margins: the corridor less the largest offset, step by step (the height band is
    # far; the buffer adds 0.25 m to the volume's).
    a = before["A"]
    assert a["geography_margin"] == pytest.approx(width - d[:k].max(), abs=1e-12)
    assert a["volume_margin"] == pytest.approx(a["geography_margin"] + 0.25, abs=1e-12)
    assert before["flight"]["geography_margin"] == pytest.approx(width - d.max(), abs=1e-12)
    # The buffer keeps it in the operational volume while it is outside the geography.
    if d.max() < width + 0.25:
        assert before["flight"]["left_volume"] == 0.0


def test_without_a_volume_the_margins_are_nan_and_nothing_leaves(pushed) -> None:
    m = quadrs.simulate(pushed, "pd", seed=0).metrics.set_index("phase").loc["flight"]
    assert np.isnan(m["geography_margin"]) and np.isnan(m["volume_margin"])
    assert np.isnan(m["left_geography"]) and np.isnan(m["left_volume"])


@pytest.mark.parametrize(
    ("volume", "key"),
    [
        ({"flight_geography": 10.0}, "volume.flight_height_band"),
        ({"flight_geography": -1.0, "flight_height_band": 5.0}, "volume.flight_geography"),
        (
            {"flight_geography": 1.0, "flight_height_band": 5.0, "contingency": -2.0},
            "volume.contingency",
        ),
        ({"flight_geography": 1.0, "flight_height_band": 5.0, "width": 2.0}, "volume.width"),
    ],
)
def test_a_bad_volume_is_refused_naming_the_key(pushed, volume, key) -> None:
    with pytest.raises(ScenarioError) as e:
        pushed.override({"volume": volume})
    assert key in str(e.value)


def test_a_volume_key_cannot_be_dispersed(pushed) -> None:
    s = pushed.override({"volume": {"flight_geography": 2.0, "flight_height_band": 5.0}})
    with pytest.raises(ScenarioError, match="cannot be dispersed"):
        s.override({"dispersions": {"volume.flight_geography":
                                    {"dist": "uniform", "low": 1.0, "high": 3.0}}})  # fmt: skip
