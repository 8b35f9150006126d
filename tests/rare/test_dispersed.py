"""Subset simulation over gusts AND dispersed parameters: a scenario's ``[dispersions]`` join
the standard-normal space through their inverse CDF (theta = F^-1(Phi(z))), the engine flies
per-row parameter values (``dispersion_keys``/``dispersion_values`` of ``run_innovations``,
``simulate_innovations``) exactly as the overridden fixed scenario, and refuses what it
cannot honour. (The Dask path, ``client=``: tests/runs/test_distributed.py.)"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import kstest, norm

import quadrs
from quadrs import _core
from quadrs.rare import RareEventResult
from quadrs.rare.scenario_model import ScenarioModel, parameters_of_normals
from quadrs.scenario.dispersion import distribution

METRIC, PHASE = "max_accel", "P2"
#: One key per kind of distribution, a gust key among them (its filters are rebuilt per row).
DISPERSIONS = {
    "payload.mass": {"dist": "uniform", "low": 0.15, "high": 0.35},
    "payload.natural_frequency": {
        "dist": "truncnorm",
        "mean": 2.0,
        "std": 0.3,
        "low": 1.5,
        "high": 2.5,
    },
    "payload.drag_area": {"dist": "lognormal", "mu": -2.3, "sigma": 0.2},
    "gust.w20": {"dist": "normal", "mean": 10.0, "std": 1.0},
    "vehicle.mass": {"dist": "triangular", "low": 2.0, "mode": 2.2, "high": 2.5},
}


@pytest.fixture(scope="module")
def dispersed(short: quadrs.Scenario) -> quadrs.Scenario:
    return short.override({"dispersions": DISPERSIONS})


def test_parameters_are_the_inverse_cdf_of_standard_normals(dispersed: quadrs.Scenario) -> None:
    """theta_j = F_j^-1(Phi(z_j)) with monte_carlo's own distributions (scipy ppf); z ~ N(0, 1)
    gives theta ~ F_j (Kolmogorov-Smirnov), and extreme z stay finite inside the support."""
    keys = sorted(DISPERSIONS)
    z = np.random.default_rng(3).standard_normal((4000, len(keys)))
    theta = parameters_of_normals(dispersed, z)
    for j, key in enumerate(keys):
        dist = distribution(DISPERSIONS[key])
        assert np.array_equal(theta[:, j], dist.ppf(np.clip(norm.cdf(z[:, j]), 1e-16, 1 - 1e-16)))
        assert kstest(theta[:, j], dist.cdf).pvalue > 1e-3, key
    far = parameters_of_normals(dispersed, np.array([[-40.0] * 5, [40.0] * 5]))
    assert np.isfinite(far).all()
    mass = keys.index("payload.mass")
    assert 0.15 <= far[0, mass] < far[1, mass] <= 0.35


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_given_values_fly_the_overridden_scenario_bit_for_bit(
    dispersed: quadrs.Scenario, controller: str
) -> None:
    """Row j of a batch with parameter values equals the fixed scenario with row j's values
    set by override, flown on the same innovations: every metric of every phase, and the
    single flight's trace."""
    keys = sorted(DISPERSIONS)
    n = _core.innovations_dimension(dispersed.to_json())
    rng = np.random.default_rng(8)
    xi = rng.standard_normal((5, n))
    values = parameters_of_normals(dispersed, rng.standard_normal((5, len(keys))))
    batch = _core.run_innovations(dispersed.to_json(), controller, xi, None, 2, keys, values)
    for j in range(5):
        fixed = dispersed.fixed(dict(zip(keys, map(float, values[j]), strict=True)))
        alone = _core.run_innovations(fixed.to_json(), controller, xi[j : j + 1], None, 1)
        np.testing.assert_array_equal(batch[j], alone[0])
    one = _core.simulate_innovations(dispersed.to_json(), controller, xi[2], 5, None, keys,
                                     values[2])  # fmt: skip
    ref = _core.simulate_innovations(fixed_of(dispersed, keys, values[2]).to_json(), controller,
                                     xi[2], 5)  # fmt: skip
    for field in ("trace", "metrics"):
        np.testing.assert_array_equal(one[field], ref[field])
    np.testing.assert_array_equal(one["metrics"], batch[2])
    # The values reached the flights: rows with other values differ.
    assert not np.array_equal(batch[0], batch[1])


def fixed_of(s: quadrs.Scenario, keys: list[str], row: np.ndarray) -> quadrs.Scenario:
    return s.fixed(dict(zip(keys, map(float, row), strict=True)))


def test_the_engine_refuses_what_it_cannot_honour(
    short: quadrs.Scenario, dispersed: quadrs.Scenario
) -> None:
    keys = sorted(DISPERSIONS)
    cfg = dispersed.to_json()
    n = _core.innovations_dimension(cfg)
    xi = np.zeros((2, n))
    good = np.tile([10.0, 0.1, 0.25, 2.0, 2.2], (2, 1))  # the sorted keys' order
    run = _core.run_innovations
    with pytest.raises(quadrs.ScenarioError, match=r"disperses .*payload\.mass.*none were given"):
        run(cfg, "pd", xi)
    with pytest.raises(quadrs.ScenarioError, match="disperses"):
        _core.simulate_innovations(cfg, "pd", xi[0])
    with pytest.raises(quadrs.ScenarioError, match="dispersed keys"):
        run(cfg, "pd", xi, None, 1, keys[:-1], good[:, :-1])
    with pytest.raises(quadrs.ScenarioError, match="dispersed keys"):
        run(short.to_json(), "pd", xi, None, 1, ["payload.mass"], good[:, :1])
    with pytest.raises(ValueError, match=r"dispersion_values must have shape \(2, 5\)"):
        run(cfg, "pd", xi, None, 1, keys, good[:1])
    with pytest.raises(ValueError, match="go together"):
        run(cfg, "pd", xi, None, 1, keys, None)
    bad = good.copy()
    bad[1, keys.index("payload.mass")] = -1.0
    with pytest.raises(quadrs.ScenarioError, match=r"payload\.mass must be > 0, got -1"):
        run(cfg, "pd", xi, None, 1, keys, bad)
    # A seeded flight of a dispersed scenario: the engine draws no parameter values.
    with pytest.raises(quadrs.ScenarioError, match="fixed scenario"):
        _core.simulate(cfg, "pd", 0)
    with pytest.raises(ValueError, match="go with xi"):
        _core.simulate(short.to_json(), "pd", 0, 0, 1, None, None, None, keys, good[0])
    # A gust key that moves the gust window changes the innovations: refused, naming the row.
    window = short.override({"dispersions": {"gust.end": {"dist": "uniform", "low": 3.4,
                                                          "high": 3.6}}})  # fmt: skip
    n_window = _core.innovations_dimension(window.to_json())
    with pytest.raises(quadrs.ScenarioError, match=r"row 1's gust values change the flight's "
                                                    r"innovations"):  # fmt: skip
        run(window.to_json(), "pd", np.zeros((2, n_window)), None, 1, ["gust.end"],
            np.array([[3.5], [3.6]]))  # fmt: skip


def test_rare_event_explores_gusts_and_parameters(dispersed: quadrs.Scenario) -> None:
    """The sampler's space is the gust's innovations then one normal per dispersed key; the
    failure samples report their parameter values, and each re-flies (r.flight(k), the fixed
    scenario of its values) to the value the sampler recorded, bit for bit."""
    model = ScenarioModel(dispersed, "pd", METRIC, PHASE)
    n = _core.innovations_dimension(dispersed.to_json())
    assert model.dimension == n + 5 and model.parameter_keys == tuple(sorted(DISPERSIONS))
    r = quadrs.rare_event(dispersed, metric=METRIC, phase=PHASE, threshold=4.2, per_level=100,
                          seed=5, max_levels=3)  # fmt: skip
    assert isinstance(r, RareEventResult) and r.probability is not None
    failures = r.failures
    theta = parameters_of_normals(dispersed, r.xi[:, n:])
    for j, key in enumerate(model.parameter_keys):
        np.testing.assert_array_equal(failures[key].to_numpy(), theta[:, j])
    value_column = failures.columns[1]
    for k in range(min(3, len(failures))):
        flight = r.flight(k)
        for j, key in enumerate(model.parameter_keys):
            assert flight.scenario[key] == theta[k, j]
        assert not flight.scenario.dispersed
        got = float(flight.metrics.set_index("phase").loc[PHASE, METRIC])
        assert got == failures[value_column].iloc[k] > 4.2
