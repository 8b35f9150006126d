"""The compiled engine handle (``_core.Engine``, ``Scenario.engine``): built once per
scenario, and every method gives the numbers of the module's function of the same name (which
re-reads the scenario's JSON at each call), bit for bit."""

from __future__ import annotations

import copy
import pickle

import numpy as np
import pytest

import quadrs
from quadrs import _core
from quadrs.engine.compiled import compiled
from tests.conftest import SHORT


@pytest.fixture(scope="module")
def scenario() -> quadrs.Scenario:
    return quadrs.Scenario.preset("paper_stable_lateral").override(
        {**SHORT, "gust.components": ["longitudinal", "lateral", "vertical"]}
    )


def same(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.shape == b.shape and a.tobytes() == b.tobytes()


def test_validating_a_scenario_builds_no_engine() -> None:
    before = compiled.cache_info()
    s = quadrs.Scenario.paper().override({"payload.mass": 0.3125})
    assert "_engine" not in s.__dict__
    assert compiled.cache_info().misses == before.misses


def test_the_engine_is_built_once_and_shared(scenario: quadrs.Scenario) -> None:
    e = scenario.engine
    assert scenario.engine is e
    # An equal scenario, built separately (as a Dask worker unpickles one): the same engine.
    twin = quadrs.Scenario.from_dict(scenario.to_dict())
    assert twin is not scenario and twin.engine is e
    assert e.steps == scenario.steps


def test_a_scenario_pickles_without_its_engine(scenario: quadrs.Scenario) -> None:
    _ = scenario.engine
    for back in (pickle.loads(pickle.dumps(scenario)), copy.deepcopy(scenario)):
        assert back == scenario and "_engine" not in back.__dict__
        assert back.engine is scenario.engine  # found again in the cache


def test_a_refused_scenario_is_a_scenario_error() -> None:
    with pytest.raises(quadrs.ScenarioError, match=r"payload\.mass"):
        _core.Engine(quadrs.Scenario.paper().to_json().replace('"mass": 0.22', '"mass": -1.0'))


def test_simulate_and_batch_equal_the_functions(scenario: quadrs.Scenario) -> None:
    js, e = scenario.to_json(), scenario.engine
    a = _core.simulate(js, "smc", 7, 3, 5)
    b = e.simulate("smc", 7, 3, 5)
    assert same(a["trace"], b["trace"]) and same(a["metrics"], b["metrics"])
    assert a["status"] == b["status"] and a["trace_columns"] == b["trace_columns"]
    x = _core.run_batch(js, ["pd", "smc"], 11, 2, 9, 2)
    y = e.run_batch(["pd", "smc"], 11, 2, 9, 2)
    for key in ("metrics", "diverged_at", "status", "done"):
        assert same(x[key], y[key]), key
    for p, q in zip(x["spectrum_sum"], y["spectrum_sum"], strict=True):
        assert same(p, q)


def test_a_dispersed_batch_on_the_handle_equals_the_function(scenario: quadrs.Scenario) -> None:
    js, e = scenario.to_json(), scenario.engine
    values = np.array([[0.2, 8.0], [0.25, 9.5], [0.3, 7.0]])
    keys = ["payload.mass", "payload.natural_frequency"]
    x = _core.run_batch(js, ["pd"], 1, 0, 3, 1, False, None, keys, values)
    y = e.run_batch(["pd"], 1, 0, 3, 1, False, None, keys, values)
    assert same(x["metrics"], y["metrics"])


def test_stability_linearize_and_innovations_equal_the_functions(
    scenario: quadrs.Scenario,
) -> None:
    js, e = scenario.to_json(), scenario.engine
    s1, s2 = _core.stability(js, "pd"), e.stability("pd")
    assert same(s1["real"], s2["real"]) and same(s1["jacobian"], s2["jacobian"])
    l1, l2 = _core.linearize(js, "smc", [0.5, 0, 0]), e.linearize("smc", [0.5, 0, 0])
    for k in "ABCD":
        assert same(l1[k], l2[k]), k
    assert e.innovations_dimension() == _core.innovations_dimension(js) > 0
    xi = e.innovations(4, 2)
    assert same(xi, _core.innovations(js, 4, 2))
    # The seeded flight, driven by its own innovations through the handle.
    seeded = e.simulate("pd", 4, 2)
    driven = e.simulate_innovations("pd", xi)
    assert same(seeded["metrics"], driven["metrics"])
    rows = e.run_innovations("pd", np.stack([xi, e.innovations(4, 3)]), workers=1)
    assert same(rows[0], seeded["metrics"])


def test_the_handle_reports_bad_arguments_as_the_functions_do(scenario: quadrs.Scenario) -> None:
    e = scenario.engine
    with pytest.raises(ValueError, match="record_every"):
        e.simulate("pd", 0, 0, 0)
    with pytest.raises(ValueError, match="runs must be >= 1"):
        e.run_batch(["pd"], 0, 0, 0, 1)
    with pytest.raises(ValueError, match="xi must hold"):
        e.simulate_innovations("pd", np.zeros(3))
    with pytest.raises(ValueError, match="controller"):
        e.stability("lqr")


def test_the_module_functions_compile_and_call(scenario: quadrs.Scenario) -> None:
    """Each module function is the method of a freshly compiled engine: same numbers, the
    scenario positional or by keyword, and its signature for introspection."""
    import inspect

    js = scenario.to_json()
    by_keyword = _core.stability(config_json=js, controller="smc")
    assert same(by_keyword["real"], scenario.engine.stability("smc")["real"])
    assert list(inspect.signature(_core.run_batch).parameters)[:3] == [
        "config_json",
        "controllers",
        "seed",
    ]
    with pytest.raises(TypeError, match="config_json"):
        _core.innovations_dimension()


def test_validation_refuses_what_the_engine_could_not_build() -> None:
    """A Scenario that exists is one the engine accepts: an altitude so small that the gust
    filters cannot be discretised (the step in scale lengths overflows) is refused when the
    scenario is made, naming ``gust``, not at its first flight."""
    with pytest.raises(quadrs.ScenarioError, match="length_scale") as e:
        quadrs.Scenario.paper().override({"gust.altitude": 5e-324})
    assert e.value.key == "gust"
