"""Subset simulation on real flights: the scenario path of ``quadrs.rare_event`` through the
engine's innovations interface (``_core.innovations_dimension``, ``run_innovations``,
``simulate_innovations``). The scenario is the short one of conftest.py (a 1 s gust at
dt = 2 ms: 1000 innovations a flight), so the whole file flies about 2500 flights."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import quadrs
from quadrs import _core
from quadrs.rare import RareEventComparison, RareEventResult
from quadrs.rare.scenario_model import ScenarioModel

METRIC, PHASE = "max_accel", "P2"
#: Near the 98th-99th percentile of max_accel in P2 under PD (subset runs of this scenario put
#: P(> 4.46) at about 1e-2; the 99.5th percentile of a 2000-flight pilot run is 4.63), so a
#: run takes two levels.
THRESHOLD = 4.2


def metric_of(flight: quadrs.Flight) -> float:
    return float(flight.metrics.set_index("phase").loc[PHASE, METRIC])


@pytest.fixture(scope="module")
def paired(short: quadrs.Scenario) -> RareEventComparison:
    cmp = quadrs.rare_event(short, controllers=("pd", "smc"), metric=METRIC, phase=PHASE,
                            threshold=THRESHOLD, per_level=200, seed=3)  # fmt: skip
    assert isinstance(cmp, RareEventComparison)
    return cmp


def test_dimension_is_the_gust_filters_innovations(short: quadrs.Scenario) -> None:
    """1 s of gust at 2 ms: 500 steps; the engine counts per active gust component its filter
    order at the onset and at every later step of the window."""
    n = _core.innovations_dimension(short.to_json())
    assert ScenarioModel(short, "pd", METRIC, PHASE).dimension == n
    assert 900 <= n <= 1600
    longer = short.override({"gust.end": 4.0})  # 1.5 s of gust: 250 more steps per state
    assert _core.innovations_dimension(longer.to_json()) - n == pytest.approx(n / 2, rel=0.02)


def test_seeded_innovations_fly_the_seeded_flight_bit_for_bit(short: quadrs.Scenario) -> None:
    """The innovations the seeded stream of (seed, realisation) draws, flown explicitly, give
    the metrics of quadrs.simulate(seed, realisation): batched and one at a time."""
    cfg = short.to_json()
    model = ScenarioModel(short, "smc", METRIC, PHASE)
    seed, realisations = 11, (0, 1, 7)
    xi = np.stack([_core.innovations(cfg, seed, i) for i in realisations])
    assert xi.shape == (3, model.dimension)
    # They are standard normals (1000 each: the mean within 5 standard errors, the variance
    # within 5 of its own).
    n = xi.size
    assert abs(xi.mean()) < 5 / math.sqrt(n) and abs(xi.var() - 1) < 5 * math.sqrt(2 / n)
    batch = model.evaluate(xi)
    for row, i in enumerate(realisations):
        seeded = quadrs.simulate(short, "smc", seed=seed, realisation=i)
        flown = model.fly(xi[row])
        assert flown.metrics.equals(seeded.metrics)  # every phase and metric, bit for bit
        assert batch[row] == metric_of(seeded)
        assert flown.status == seeded.status == "ok"
        assert list(flown.trace.columns) == short.trace_columns
        assert np.array_equal(flown.trace.to_numpy(), seeded.trace.to_numpy())


def test_threads_do_not_change_a_batch(short: quadrs.Scenario) -> None:
    xi = np.random.default_rng(5).standard_normal(
        (24, _core.innovations_dimension(short.to_json()))
    )
    one = ScenarioModel(short, "pd", METRIC, PHASE, workers=1).evaluate(xi)
    two = ScenarioModel(short, "pd", METRIC, PHASE, workers=2).evaluate(xi)
    assert np.array_equal(one, two) and np.isfinite(one).all()
    with pytest.raises(ValueError, match="workers"):
        ScenarioModel(short, "pd", METRIC, PHASE, workers=0)


def test_every_failure_re_flies_above_the_threshold_bit_for_bit(
    paired: RareEventComparison,
) -> None:
    r = paired["pd"]
    assert r.reached and r.probability is not None and len(r.levels) >= 2
    values = r.failures[r.value_name].to_numpy()
    assert len(values) > 0 and (values > THRESHOLD).all()
    for k in range(len(values)):
        flight = r.flight(k)
        assert metric_of(flight) == values[k]  # the very value the sampler recorded
        assert flight.controller == "pd" and flight.status == "ok"
    # The batch path agrees with the one-flight path on all of them at once.
    assert r.model is not None
    assert np.array_equal(r.model.evaluate(r.xi), values)


def test_paired_controllers_give_a_ratio(paired: RareEventComparison) -> None:
    pd_, smc = paired["pd"], paired["smc"]
    assert pd_.probability is not None and smc.probability is not None
    assert pd_.cov is not None and smc.cov is not None
    ratio = paired.ratio("smc", "pd")
    assert ratio["ratio"] == smc.probability / pd_.probability
    assert 0 < ratio["low"] < ratio["ratio"] < ratio["high"]
    width = math.log(ratio["high"] / ratio["low"]) / (2 * 1.959964)
    # Less the covariance of the two level-0 fractions (the same 200 flights).
    a, b = smc.run.first_above, pd_.run.first_above
    assert a is not None and b is not None and len(a) == len(b) == 200
    c0 = ((a & b).mean() - a.mean() * b.mean()) / (200 * a.mean() * b.mean())
    assert c0 > 0  # one gust, two controllers: the same flights are the worst
    independent = math.log1p(pd_.cov**2) + math.log1p(smc.cov**2)
    assert width == pytest.approx(math.sqrt(independent - 2 * c0))
    # Paired: one seed, so level 0 flew the same innovations under both controllers (that
    # paired runs share their first level is tested in rare/test_subset.py).
    assert pd_.seed == smc.seed == 3 and pd_.levels["flights"].iloc[0] == 200
    assert isinstance(pd_.model, ScenarioModel) and isinstance(smc.model, ScenarioModel)
    assert (pd_.model.controller, smc.model.controller) == ("pd", "smc")


def test_subset_agrees_with_plain_monte_carlo(short: quadrs.Scenario) -> None:
    """The cheap statistical check (the tight one, at p ~ 5e-3 with 40 000 flights, is
    benches/rare_vs_mc.py, its output in docs/rare-events.md): the threshold is the 95th
    percentile of 200 pilot flights; then 1000 other flights and one subset simulation
    estimate P(max_accel > threshold), and the two must agree within 3.5 standard deviations
    of their log-ratio (lognormal, from both coefficients of variation)."""
    mc = quadrs.monte_carlo(short, runs=1200, seed=21, controllers=("pd",), progress=False,
                            spectra=False)  # fmt: skip
    rows = mc.runs[mc.runs["phase"] == PHASE].sort_values("realisation")
    values = np.where(rows["diverged"], np.inf, rows[METRIC].to_numpy(np.float64))
    threshold = float(np.quantile(values[:200], 0.95))
    rest = values[200:]
    k = int((rest > threshold).sum())
    assert 10 <= k <= 200, k  # p in the regime the test is about
    p_mc = k / len(rest)
    cov_mc = math.sqrt((1 - p_mc) / (len(rest) * p_mc))
    r = quadrs.rare_event(short, controller="pd", metric=METRIC, phase=PHASE,
                          threshold=threshold, per_level=200, seed=8)  # fmt: skip
    assert isinstance(r, RareEventResult) and r.probability is not None and r.cov is not None
    z = math.log(r.probability / p_mc) / math.sqrt(math.log1p(r.cov**2) + math.log1p(cov_mc**2))
    assert abs(z) < 3.5, (r.probability, p_mc, r.cov, cov_mc)
    assert r.flights == r.run.pilot_flights + 200 + (len(r.levels) - 1) * 180


def test_saved_scenario_run_re_flies_after_reading(
    paired: RareEventComparison, tmp_path: Path
) -> None:
    r = paired["smc"]
    path = tmp_path / "smc.parquet"
    r.to_parquet(path)
    back = RareEventResult.read_parquet(path)
    assert back.probability == r.probability and np.array_equal(back.xi, r.xi)
    assert metric_of(back.flight(0)) == r.failures[r.value_name].iloc[0]


def test_ctrl_c_keeps_the_levels_done(tmp_path: Path) -> None:
    """A KeyboardInterrupt from the model (what run_cancellable raises on Ctrl-C) stops the
    run: the finished levels, no estimate, and the file says so."""
    calls = 0
    stop_at = 0

    def f(x: np.ndarray) -> np.ndarray:
        nonlocal calls
        calls += 1
        if calls == stop_at:
            raise KeyboardInterrupt
        return np.asarray(x.sum(axis=1) / math.sqrt(x.shape[1]))

    # The pilot (which places the levels) makes the first calls: count them once.
    whole = quadrs.rare_event(limit_state=f, dimension=50, threshold=4.0, per_level=100)
    assert isinstance(whole, RareEventResult)
    pilot = whole.run.pilot_flights
    # The main run's level 0 is 10 calls of 10 rows; stop at level 1's fifth step.
    calls, stop_at = 0, pilot // 10 + 15
    seen: list[int] = []
    r = quadrs.rare_event(limit_state=f, dimension=50, threshold=4.0, per_level=100,
                          on_level=lambda level: seen.append(level.level))  # fmt: skip
    assert isinstance(r, RareEventResult)
    assert r.interrupted and seen == [0] and len(r.levels) == 1
    assert r.probability is None and r.cov is None
    assert r.upper_bound == r.levels["conditional_p"].iloc[0]
    assert r.flights == pilot + 140  # the pilot, level 0 and four steps of ten chains
    assert "interrupted after 1 levels" in repr(r)
    path = tmp_path / "cut.parquet"
    r.to_parquet(path)
    back = RareEventResult.read_parquet(path)
    assert back.interrupted and back.upper_bound == r.upper_bound and len(back.levels) == 1
    assert back.closest == r.closest
    # Stopped before the first level: nothing to report but that.
    calls, stop_at = 0, 15
    # (p0 = 0.05: level 0 is 20 calls of 10 rows, so the 15th is inside it.)
    early = quadrs.rare_event(limit_state=f, dimension=50, threshold=4.0, per_level=200, p0=0.05)
    assert isinstance(early, RareEventResult) and early.interrupted
    assert len(early.levels) == 0 and early.upper_bound is None and early.flights == 140
    early.to_parquet(path)
    again = RareEventResult.read_parquet(path)
    assert again.interrupted and again.upper_bound is None and again.closest == -math.inf
