"""quadrs.rare_event: subset simulation checked against limit states whose tail probability is
known exactly, in 1000 dimensions, over repeated seeds; its identities; its refusals."""

from __future__ import annotations

import math
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scipy import integrate, optimize
from scipy.stats import binom, chi2, norm

import quadrs
from quadrs import _core
from quadrs.io.integrity import CorruptRunError
from quadrs.io.parquet import read_frame, write_frame
from quadrs.rare import RareEventComparison, RareEventResult
from quadrs.rare.scenario_model import ScenarioModel
from quadrs.rare.subset import chain_gamma, pilot_size, subset_simulation

N_DIM = 1000


def linear(x: np.ndarray) -> np.ndarray:
    """u = sum(x) / sqrt(n) ~ N(0, 1): P(u > t) = Phi(-t)."""
    return x.sum(axis=1) / math.sqrt(x.shape[1])


def squares(x: np.ndarray) -> np.ndarray:
    """sum(x^2) ~ chi2(n)."""
    return (x * x).sum(axis=1)


KAPPA = 0.2


def parabolic(x: np.ndarray) -> np.ndarray:
    """u1 - KAPPA u2^2 with u1, u2 the normalised sums of the two halves (independent N(0, 1))."""
    h = x.shape[1] // 2
    u1 = x[:, :h].sum(axis=1) / math.sqrt(h)
    u2 = x[:, h:].sum(axis=1) / math.sqrt(x.shape[1] - h)
    return u1 - KAPPA * u2 * u2


def parabolic_p(t: float) -> float:
    """P(u1 - KAPPA u2^2 > t) = E[Phi(-(t + KAPPA u2^2))], by quadrature."""
    return float(integrate.quad(lambda u: norm.pdf(u) * norm.sf(t + KAPPA * u * u), -40, 40,
                                epsabs=0, epsrel=1e-10, limit=200)[0])  # fmt: skip


def parabolic_threshold(p: float) -> float:
    return float(optimize.brentq(lambda t: parabolic_p(t) - p, 0.0, 10.0, xtol=1e-13))


def repeated(
    f: Callable[[np.ndarray], np.ndarray],
    t: float,
    seeds: range,
    per_level: int = 500,
    dimension: int = N_DIM,
) -> list[RareEventResult]:
    out = []
    for s in seeds:
        r = quadrs.rare_event(limit_state=f, dimension=dimension, threshold=t,
                              per_level=per_level, p0=0.1, seed=s)  # fmt: skip
        assert isinstance(r, RareEventResult)
        out.append(r)
    return out


def check_centred(results: list[RareEventResult], truth: float) -> None:
    """The mean of the estimates within 3 standard errors of the truth, and the reported
    coefficient of variation close to the estimates' spread (so the interval is honest)."""
    est = np.array([r.probability for r in results], dtype=float)
    se = est.std(ddof=1) / math.sqrt(len(est))
    assert abs(est.mean() - truth) < 3 * se, (est.mean() / truth, se / truth)
    spread = est.std(ddof=1) / est.mean()
    reported = float(np.mean([r.cov for r in results]))
    assert 0.6 < reported / spread < 1.5, (reported, spread)


def check_covers(results: list[RareEventResult], truth: float) -> None:
    """The 95 % intervals cover the truth about 95 % of the time: the count of covering runs
    is not below the binomial(n, 0.95) 0.1 % quantile. (That they are not needlessly wide is
    :func:`check_centred`'s bound on the reported CoV against the estimates' spread.)"""
    inside = 0
    for r in results:
        assert r.interval is not None and r.probability is not None
        lo, hi = r.interval
        assert lo < r.probability < hi
        inside += lo <= truth <= hi
    assert inside >= binom.ppf(0.001, len(results), 0.95), inside


def test_linear_limit_state_in_1000_dimensions_centres_and_covers() -> None:
    truth = 1e-4
    results = repeated(linear, float(norm.isf(truth)), range(100))
    check_centred(results, truth)
    check_covers(results, truth)
    # A few thousand evaluations, against 1/(p cov^2) ~ 1e5 for plain Monte Carlo.
    assert max(r.flights for r in results) <= 3300  # the pilot (a fifth) included
    assert np.mean([r.monte_carlo_flights for r in results]) > 10 * np.mean(
        [r.flights for r in results]
    )


def test_chi2_tail_in_1000_dimensions_centres_and_covers() -> None:
    # Nonlinear in every direction: the failure set is the outside of a sphere.
    truth = 1e-4
    results = repeated(squares, float(chi2.isf(truth, N_DIM)), range(100))
    check_centred(results, truth)
    check_covers(results, truth)


@pytest.mark.parametrize(
    ("name", "truth"),
    [("linear", 1e-3), ("linear", 1e-6), ("squares", 1e-6), ("parabolic", 1e-5)],
)
def test_other_probabilities_centre_on_the_truth(name: str, truth: float) -> None:
    f, t = {
        "linear": (linear, float(norm.isf(truth))),
        "squares": (squares, float(chi2.isf(truth, N_DIM))),
        "parabolic": (parabolic, parabolic_threshold(truth)),
    }[name]
    results = repeated(f, t, range(200, 230))
    check_centred(results, truth)
    check_covers(results, truth)


def test_parabolic_reference_is_right() -> None:
    """The quadrature truth against plain Monte Carlo at a probability it can reach."""
    t = parabolic_threshold(0.02)
    rng = np.random.default_rng(5)
    u1, u2 = rng.standard_normal((2, 200_000))
    hits = int((u1 - KAPPA * u2 * u2 > t).sum())
    assert abs(hits / 200_000 - 0.02) < 4 * math.sqrt(0.02 * 0.98 / 200_000)


class Counting:
    """A model that records the rows of every call."""

    def __init__(self, f: Callable[[np.ndarray], np.ndarray]) -> None:
        self.f = f
        self.calls: list[int] = []

    def __call__(self, x: np.ndarray) -> np.ndarray:
        self.calls.append(x.shape[0])
        return self.f(x)


@pytest.mark.parametrize(("p0", "per_level"), [(0.1, 1000), (0.2, 500), (0.5, 200)])
def test_levels_flights_and_failures_identities(p0: float, per_level: int) -> None:
    model = Counting(linear)
    t = float(norm.isf(1e-5))
    r = quadrs.rare_event(limit_state=model, dimension=300, threshold=t, per_level=per_level,
                          p0=p0, seed=3)  # fmt: skip
    assert isinstance(r, RareEventResult) and r.probability is not None
    levels = r.levels
    m = len(levels)
    seeds = round(p0 * per_level)
    pilot = r.run.pilot_flights
    pilot_seeds = round(p0 * pilot_size(per_level, p0))
    # Flights: the pilot's, then level 0 plain Monte Carlo and every later level
    # (1 - p0) * per_level new ones.
    assert 0 < pilot < r.flights
    assert r.flights == pilot + per_level + (m - 1) * (per_level - seeds)
    assert r.flights == pilot + int(levels["flights"].sum()) == sum(model.calls)
    # Every call is one step of all chains (level 0 in blocks of the same size).
    assert set(model.calls) == {seeds, pilot_seeds}
    # The levels the pilot placed: fixed cuts rising to the threshold; each level's
    # conditional probability is the fraction of its samples above its cut.
    assert (levels["conditional_p"] == levels["above"] / per_level).all()
    assert (levels["above"] > 0).all()
    assert levels["threshold"].iloc[-1] == t
    assert (np.diff(levels["threshold"]) > 0).all()
    assert r.probability == pytest.approx(float(np.prod(levels["conditional_p"])), rel=1e-12)
    # The coefficient of variation is at least Au & Beck's (the levels' variances summed).
    assert r.cov >= math.sqrt(float((levels["cov"] ** 2).sum())) * (1 - 1e-12)
    lo, hi = r.interval
    assert 0 < lo < r.probability < hi <= 1
    assert levels["acceptance_rate"].iloc[1:].between(0, 1).all()
    # Failures: the last level's samples above the threshold, each state once with its
    # copies; values are the model's own at the stored xi, bit for bit.
    fails = r.failures
    assert int(fails["copies"].sum()) == levels["above"].iloc[-1]
    assert (fails["limit_state"] > t).all()
    assert r.xi.shape == (len(fails), 300)
    again = linear(r.xi)
    assert np.array_equal(again, fails["limit_state"].to_numpy())
    for k in range(min(5, len(fails))):
        assert linear(r.xi[k : k + 1])[0] == fails["limit_state"].iloc[k]


def test_memory_holds_a_few_chains_not_a_level() -> None:
    """A level of 2000 samples in 10000 dimensions is 160 MB; the sampler holds its 200
    chains, their candidates and the best 200, plus the last level's failure states (twice,
    while they are gathered into one array)."""
    n, per_level = 10_000, 2000
    t = float(norm.isf(1e-3))
    tracemalloc.start()
    try:
        r = subset_simulation(linear, n, t, per_level=per_level, p0=0.1, seed=1)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    seeds = per_level // 10
    failures = len(r.failure_values)
    assert peak < (6 * seeds + 2 * failures) * n * 8, (peak / (seeds * n * 8), failures)
    assert peak < 0.75 * per_level * n * 8


def test_same_seed_same_result_other_seed_other() -> None:
    t = float(norm.isf(1e-4))
    a, b, c = (subset_simulation(linear, 200, t, per_level=500, seed=s) for s in (7, 7, 8))
    assert a.probability == b.probability and np.array_equal(a.failure_xi, b.failure_xi)
    assert a.probability != c.probability


def test_paired_runs_share_their_first_level() -> None:
    """Two models on one seed see the same level-0 samples: shifting the model by 0.5 shifts
    the first cut by exactly 0.5; the ratio's interval covers the exact ratio."""
    t = float(norm.isf(1e-4))
    res = quadrs.rare_event(limit_state={"a": linear, "b": lambda x: linear(x) + 0.5},
                            dimension=N_DIM, threshold=t, seed=2)  # fmt: skip
    assert isinstance(res, RareEventComparison)
    cut_a, cut_b = (res[k].levels["threshold"].iloc[0] for k in ("a", "b"))
    assert cut_b - cut_a == pytest.approx(0.5, abs=1e-12)
    ratio = res.ratio("b", "a")
    exact = norm.sf(t - 0.5) / norm.sf(t)
    assert ratio["low"] < exact < ratio["high"]
    with pytest.raises(KeyError, match="'c'"):
        res.ratio("c", "a")


def test_no_failure_found_is_an_upper_bound_not_a_zero() -> None:
    """tanh(u) never exceeds 1: the result says so instead of estimating P = 0."""
    r = quadrs.rare_event(limit_state=lambda x: np.tanh(linear(x)), dimension=50,
                          threshold=1.0, per_level=200, max_levels=3, seed=0)  # fmt: skip
    assert isinstance(r, RareEventResult)
    assert not r.reached
    assert r.probability is None and r.cov is None
    # A 95 % upper confidence bound: the highest cut's probability (about 1e-2, three levels
    # in all) times the bound for none of the last level's 20 chains crossing (about 0.17).
    assert 1e-4 < r.upper_bound < 1e-2
    assert len(r.levels) == 3
    assert r.interval == (0.0, r.upper_bound)
    assert r.closest < 1.0 and len(r.failures) == 0
    assert f"no failure in {r.flights} flights" in repr(r)
    assert r.flights == r.run.pilot_flights + 200 + 2 * 180


def test_a_model_with_an_atom_is_refused_naming_the_threshold() -> None:
    with pytest.raises(ValueError, match=r"100 of 100 samples .* threshold = 1\.0"):
        quadrs.rare_event(limit_state=lambda x: np.zeros(len(x)), dimension=5, threshold=1.0,
                          per_level=100)  # fmt: skip
    # A metric that saturates below the threshold: the chains pile up at the cap.
    with pytest.raises(ValueError, match=r"atom: .* threshold = 2\.0"):
        quadrs.rare_event(limit_state=lambda x: np.minimum(linear(x), 1.0), dimension=5,
                          threshold=2.0, per_level=100)  # fmt: skip


def test_chain_gamma_of_independent_and_frozen_chains() -> None:
    rng = np.random.default_rng(0)
    independent = rng.random((10, 5000)) < 0.3
    assert abs(chain_gamma(independent)) < 0.1
    frozen = np.repeat(rng.random((1, 5000)) < 0.3, 10, axis=0)
    # A chain that never moves: every lag correlation is 1, gamma = 2 sum (1 - k/L) = L - 1.
    assert chain_gamma(frozen) == pytest.approx(9.0)
    # Pairs of frozen chains started from one state: 2500 independent units of 2 L samples
    # each, 1 + gamma = 2 L; Au & Beck's along-chain sum alone would say L.
    pairs = np.repeat(rng.random((1, 2500)) < 0.3, 2, axis=1).repeat(10, axis=0)
    groups = np.repeat(np.arange(2500), 2)
    assert chain_gamma(pairs, groups) == pytest.approx(19.0, rel=0.05)
    assert chain_gamma(pairs) == pytest.approx(9.0)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"p0": 0.0}, "p0"),
        ({"p0": 0.6}, "p0"),
        ({"p0": float("nan")}, "p0"),
        ({"p0": True}, "p0"),
        ({"p0": 0.3}, "p0 must be 1/L"),
        ({"per_level": 50}, "5 seeds per level"),
        ({"per_level": 1005}, "per_level must be a multiple"),
        ({"per_level": 0}, "per_level"),
        ({"per_level": 100.5}, "per_level"),
        ({"threshold": float("nan")}, "threshold"),
        ({"threshold": float("inf")}, "threshold"),
        ({"threshold": None}, "threshold"),
        ({"threshold": "high"}, "threshold"),
        ({"dimension": 0}, "dimension"),
        ({"dimension": None}, "dimension"),
        ({"seed": -1}, "seed"),
        ({"max_levels": 0}, "max_levels"),
        ({"method": "importance"}, "method"),
        ({"metric": "max_accel"}, "metric"),
        ({"limit_state": 3.0}, "limit_state"),
        ({"limit_state": {}}, "limit_state"),
        ({"limit_state": lambda x: x}, r"shape \(20,\)"),
        ({"limit_state": lambda x: np.full(len(x), np.nan)}, "NaN"),
    ],
)
def test_bad_input_is_a_value_error_naming_it(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"limit_state": linear, "dimension": 10, "threshold": 3.0,
                               "per_level": 1000, "p0": 0.1}  # fmt: skip
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        quadrs.rare_event(**args)  # type: ignore[arg-type]


def test_flight_of_a_limit_state_result_says_it_has_none() -> None:
    r = quadrs.rare_event(limit_state=linear, dimension=20, threshold=2.0, per_level=200)
    assert isinstance(r, RareEventResult) and len(r.failures) > 0
    with pytest.raises(ValueError, match="limit_state function"):
        r.flight(0)
    with pytest.raises(IndexError, match="k must be"):
        r.flight(len(r.failures))
    assert "<table" in r._repr_html_()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"metric": "max_acc"}, "metric must be one of"),
        ({"phase": "P9"}, "phase must be one of"),
        ({"controller": "lqr"}, "controller must be one of"),
        ({"controllers": ("pd", "pd")}, "controllers must be distinct"),
        ({"metric": None}, "metric= and phase="),
        ({"dimension": 10}, "dimension is set by the scenario"),
        ({"limit_state": linear}, "not both"),
        ({"seed": -1}, "seed"),
        ({"threshold": float("nan")}, "threshold"),
        ({"p0": 0.3}, "p0"),
    ],
)
def test_scenario_arguments_are_checked(kwargs: dict[str, object], match: str) -> None:
    args: dict[str, object] = {"controller": "pd", "metric": "max_accel", "phase": "P2",
                               "threshold": 8.0}  # fmt: skip
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        quadrs.rare_event(quadrs.Scenario.paper(), **args)  # type: ignore[arg-type]


def test_scenario_without_randomness_is_refused() -> None:
    still = quadrs.Scenario.paper().override({"gust.enabled": False})
    with pytest.raises(ValueError, match="gust is off"):
        quadrs.rare_event(still, metric="max_accel", phase="P2", threshold=8.0)


def test_scenario_run_without_the_engine_interface_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An engine built without the innovations interface: NotImplementedError naming it, not
    an AttributeError (the scenario path itself: tests/rare/test_scenario_model.py)."""
    monkeypatch.delattr(_core, "run_innovations")
    with pytest.raises(NotImplementedError, match="run_innovations"):
        quadrs.rare_event(quadrs.Scenario.paper(), controller="pd", metric="max_accel",
                          phase="P2", threshold=8.0, per_level=100)  # fmt: skip


def test_saved_result_reads_back_whole(tmp_path: Path) -> None:
    r = quadrs.rare_event(limit_state=linear, dimension=40, threshold=3.0, per_level=200, seed=4)
    assert isinstance(r, RareEventResult) and r.probability is not None
    path = tmp_path / "rare.parquet"
    r.to_parquet(path)
    back = RareEventResult.read_parquet(path)
    assert back.probability == r.probability and back.cov == r.cov
    assert back.interval == r.interval and back.flights == r.flights
    assert back.levels.equals(r.levels)
    assert back.failures.equals(r.failures)
    assert np.array_equal(back.xi, r.xi)  # bit for bit
    with pytest.raises(ValueError, match="limit_state function"):
        back.flight(0)
    # No failure found: still None after the round trip, not 0 or NaN.
    none = quadrs.rare_event(limit_state=lambda x: np.tanh(linear(x)), dimension=10,
                             threshold=1.0, per_level=100, max_levels=2)  # fmt: skip
    assert isinstance(none, RareEventResult)
    none.to_parquet(path)
    again = RareEventResult.read_parquet(path)
    assert again.probability is None and again.upper_bound == none.upper_bound
    assert again.xi.shape == (0, 10)


def test_saved_scenario_run_keeps_its_model_and_refuses_edits(
    tmp_path: Path,
) -> None:
    """A scenario run's file carries its run identity; read back, its model is the scenario's,
    so flight(k) re-flies; an edited file is refused. (The run itself is of a limit state, to
    be fast; the file only records what produced it. A real scenario run saved and re-flown:
    tests/rare/test_scenario_model.py.)"""
    s = quadrs.Scenario.paper()
    run = subset_simulation(linear, 30, 2.5, per_level=100, seed=1)
    r = RareEventResult(run, value_name="max_accel_P2",
                        model=ScenarioModel(s, "smc", "max_accel", "P2"))  # fmt: skip
    path = tmp_path / "scenario.parquet"
    r.to_parquet(path)
    back = RareEventResult.read_parquet(path)
    assert isinstance(back.model, ScenarioModel)
    assert (back.model.scenario, back.model.controller, back.model.metric, back.model.phase) == (
        s,
        "smc",
        "max_accel",
        "P2",
    )
    assert back.probability == r.probability and np.array_equal(back.xi, r.xi)
    frame, meta = read_frame(path, b"quadrs")
    assert isinstance(meta, dict)
    meta["threshold"] = 9.0
    write_frame(frame, path, b"quadrs", meta)
    with pytest.raises(CorruptRunError, match="disagree"):
        RareEventResult.read_parquet(path)
    meta["rare_event"]["threshold"] = 9.0
    write_frame(frame, path, b"quadrs", meta)
    with pytest.raises(CorruptRunError, match="run identity"):
        RareEventResult.read_parquet(path)
    write_frame(frame, path, b"quadrs", {"kind": "flight"})
    with pytest.raises(CorruptRunError, match="not a quadrs rare-event result"):
        RareEventResult.read_parquet(path)
