"""A dispersed batch solves each flight's start for the laws it flies alone (each a Newton solve
on the closed loop: `Realisation::for_laws`), and flies the start `simulate` flies: a batch row
is the single flight bit for bit, for each of two laws flown in the same batch, in a steady
crosswind where the starts are the laws' own closed-loop equilibria (not the plant's trim)."""

from __future__ import annotations

import numpy as np

import quadrs
from quadrs.runs.flight import METRIC_COLUMNS

#: The delivery vehicle hovering 3 s at 2 m in a steady 8 m/s crosswind (6.2 m/s at 2 m), on
#: its state, its parcel's mass dispersed: every flight its own vehicle, so its own starts.
HOVER = {
    "trajectory.route": [[0.0, 0.0, 2.0], [0.0, 0.0, 2.5]],
    "trajectory.hold": [3.0, 0.0],
    "trajectory.lower": [0.0, 0.0],
    "trajectory.names": None,
    "integrator.duration": 5.5,
    "wind.speed": 8.0,
    "gust.enabled": False,
    "navigation.mode": "truth",
    "dispersions": {"payload.mass": {"dist": "uniform", "low": 0.3, "high": 0.7}},
}


def test_a_dispersed_batch_row_is_its_single_flight_for_each_law() -> None:
    sc = quadrs.Scenario.preset("delivery").override(HOVER)
    laws = ("pd", "smc")
    mc = quadrs.monte_carlo(sc, runs=5, seed=2, controllers=laws, progress=False,
                            spectra=False)  # fmt: skip
    metrics = list(METRIC_COLUMNS)
    for law in laws:
        for i in (0, 4):
            alone = quadrs.simulate(sc, law, seed=2, realisation=i)
            rows = mc.runs[(mc.runs["realisation"] == i) & (mc.runs["controller"] == law)]
            want = alone.metrics[metrics].to_numpy()
            np.testing.assert_array_equal(want, rows[metrics].to_numpy(), err_msg=f"{law} {i}")
    # Each realisation's start is its own closed-loop equilibrium (its own parcel's mass), not
    # the nominal vehicle's: hovering from it, the swing holds within 1e-3 rad of its start.
    for law in laws:
        for i in (0, 4):
            t = quadrs.simulate(sc, law, seed=2, realisation=i, record_every=10).trace
            swing = t.swing[t.index <= 3.0].to_numpy()
            assert np.max(np.abs(swing - swing[0])) < 1e-3, (law, i, swing[0])
