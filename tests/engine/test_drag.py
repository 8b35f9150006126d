"""The trace's ``drag_z``: the vertical drag on the quadrotor the engine's dynamics use."""

import numpy as np

import quadrs
from quadrs import Scenario


def test_drag_z_is_the_drag_formula_on_the_trace(short: Scenario) -> None:
    """Fdz = -1/2 rho CdA (vz - wind_z)|vz - wind_z| (docs/model.md section 1), by hand from the
    trace's own columns, through a gust: the column is the formula, row by row."""
    f = quadrs.simulate(short, "pd", seed=3)
    tr = f.trace
    rel = tr["vz"] - tr["wind_z"]
    rho, cda = short["gust.air_density"], short["vehicle.drag_area"]
    np.testing.assert_allclose(tr["drag_z"], -0.5 * rho * cda * rel * rel.abs(), rtol=1e-12)
    gusty = tr["wind_z"] != 0.0
    assert gusty.sum() > 100 and (tr.loc[gusty, "drag_z"].abs() > 1e-3).any()


def test_drag_z_vanishes_at_hover_without_wind(still_hover: Scenario) -> None:
    for controller in ("pd", "smc"):
        tr = quadrs.simulate(still_hover, controller, record_every=50).trace
        assert (tr["wind_z"] == 0.0).all()
        assert np.abs(tr["drag_z"].to_numpy()).max() < 1e-15


def test_drag_off_with_no_air(short: Scenario) -> None:
    """rho = 0 switches drag off: the column is exactly zero even in the gust."""
    tr = quadrs.simulate(short.override({"gust.air_density": 0.0}), "pd", seed=3).trace
    assert (tr["wind_z"] != 0.0).any()
    assert (tr["drag_z"] == 0.0).all()
