"""Monte Carlo: determinism, pairing, confidence intervals, divergence, persistence, Ctrl-C."""

import functools
import os
import signal
import threading
import time

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs import MonteCarloResult, Scenario
from quadrs.present.table3 import ratio_ci, summarise

#: The metric columns, as the engine defines them (rust/src/metrics.rs).
METRICS = list(quadrs._core.METRIC_NAMES)
#: The paper's flights have no touchdown or release: those metrics are NaN, the others finite.
EVENTS = list(quadrs._core.EVENT_METRICS)
MEASURED = [m for m in METRICS if m not in EVENTS]


def test_runs_table_layout(short: Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=6, seed=1, workers=2, progress=False)
    r = mc.runs
    assert list(r.columns) == ["realisation", "controller", "phase", *METRICS, "diverged",
                               "diverged_at", "status"]  # fmt: skip
    assert ((r["status"] == "ok") == ~r["diverged"]).all()
    assert len(r) == 6 * 2 * 4  # P1, P2, P3 and the whole flight
    assert sorted(r["realisation"].unique()) == list(range(6))
    assert set(r["controller"]) == {"pd", "smc"}
    assert not r["diverged"].any()
    assert np.isfinite(r[MEASURED].to_numpy()).all()
    assert r[EVENTS].isna().all().all()
    assert not mc.interrupted


def test_results_depend_only_on_seed_and_index(short: Scenario) -> None:
    one = quadrs.monte_carlo(short, runs=10, seed=3, workers=1, progress=False).runs
    two = quadrs.monte_carlo(short, runs=10, seed=3, workers=2, progress=False).runs
    pd.testing.assert_frame_equal(one, two)
    inner = quadrs.monte_carlo(short, runs=5, seed=3, workers=2, progress=False, first=3).runs
    pd.testing.assert_frame_equal(
        inner, one[one["realisation"].between(3, 7)].reset_index(drop=True)
    )
    # runs 0..99 alone equal the same runs inside 0..199
    alone = quadrs.monte_carlo(short, runs=100, seed=3, progress=False, spectra=False).runs
    inside = quadrs.monte_carlo(short, runs=200, seed=3, progress=False, spectra=False).runs
    pd.testing.assert_frame_equal(alone, inside[inside["realisation"] < 100])
    other_seed = quadrs.monte_carlo(short, runs=10, seed=4, workers=2, progress=False).runs
    assert not np.array_equal(other_seed["iae"], one["iae"])


def test_flown_chunks_are_taken_not_flown_again(short: Scenario, tmp_path) -> None:
    """A batch given chunks of itself already flown (the command line's calibration: the
    batch's first realisations) equals the batch flown whole, bit for bit, and stores them
    in its checkpoint; chunks that are not whole new parts of the batch are refused."""
    from quadrs.runs.chunk import Design, fly_chunk

    s = short.override({"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.18,
                                                          "high": 0.26}}})  # fmt: skip
    whole = quadrs.monte_carlo(s, runs=13, seed=5, progress=False, spectra=False).runs

    def chunk(first: int, count: int, controllers=("pd", "smc"), spectra=False, seed=5, of=s):
        return fly_chunk(of, controllers, seed, first, count, 2, spectra,
                         Design("random", 0, count))  # fmt: skip

    flown = [chunk(0, 4), chunk(9, 2)]
    taken = quadrs.monte_carlo(s, runs=13, seed=5, progress=False, spectra=False, flown=flown)
    pd.testing.assert_frame_equal(taken.runs, whole)
    stored = quadrs.monte_carlo(s, runs=13, seed=5, progress=False, spectra=False, flown=flown,
                                out=tmp_path / "run")  # fmt: skip
    pd.testing.assert_frame_equal(stored.runs, whole)
    bad = {
        "not a whole new part": [chunk(0, 4), chunk(2, 3)],
        "not a whole new part ": [chunk(10, 4)],
        "another batch": [chunk(0, 2, controllers=("pd",))],
        "another batch ": [chunk(0, 2, seed=6)],
        "another batch  ": [chunk(0, 2, of=s.override({"payload.damping": 0.5}))],
    }
    for match, chunks in bad.items():
        with pytest.raises(ValueError, match=match.strip()):
            quadrs.monte_carlo(s, runs=13, seed=5, progress=False, spectra=False, flown=chunks)
    with pytest.raises(ValueError, match="another batch"):
        quadrs.monte_carlo(s, runs=13, seed=5, progress=False, spectra=True, flown=flown[:1])
    with pytest.raises(ValueError, match="sampling='random'"):
        quadrs.monte_carlo(s, runs=13, seed=5, progress=False, spectra=False, flown=flown,
                           sampling="lhs")  # fmt: skip


def test_batch_rows_equal_single_flights(short: Scenario) -> None:
    """Realisation i of the batch is `simulate(seed, realisation=i)` (SIMD vs scalar path),
    and both controllers of a realisation fly the very same gust."""
    mc = quadrs.monte_carlo(short, runs=5, seed=11, workers=2, progress=False)
    for i in (0, 4):
        flights = {c: quadrs.simulate(short, c, seed=11, realisation=i) for c in ("pd", "smc")}
        np.testing.assert_array_equal(
            flights["pd"].trace["wind_z"].to_numpy(), flights["smc"].trace["wind_z"].to_numpy()
        )
        for c, f in flights.items():
            rows = mc.runs[(mc.runs["realisation"] == i) & (mc.runs["controller"] == c)]
            np.testing.assert_allclose(
                rows[METRICS].to_numpy(), f.metrics[METRICS].to_numpy(), rtol=1e-9, atol=1e-15
            )


def test_confidence_interval_shrinks_like_one_over_sqrt_n(paper: Scenario) -> None:
    mc = quadrs.monte_carlo(paper, runs=64, seed=5, workers=2, progress=False)
    phases = paper.phase_names
    small = summarise(mc.runs[mc.runs["realisation"] < 16], mc.controllers, phases)
    large = summarise(mc.runs, mc.controllers, phases)
    from scipy import stats

    def half_width(summary, c: str) -> float:
        row = summary.loc[("iae", "P2")]
        return (row[f"{c}_ci_high"] - row[f"{c}_ci_low"]) / 2

    for c in ("pd", "smc"):
        hw = functools.partial(half_width, c=c)
        ratio = (hw(small) / stats.t.ppf(0.975, 15)) / (hw(large) / stats.t.ppf(0.975, 63))
        assert 1.3 < ratio < 3.0, ratio
        assert large.loc[("iae", "P2"), f"{c}_n"] == 64


def test_paired_ratio_interval_is_tighter_than_unpaired() -> None:
    rng = np.random.default_rng(0)
    common = rng.lognormal(0.0, 0.5, 400)  # gust severity shared by both controllers
    pd_ = common * 1.0 + rng.normal(0, 0.01, 400)
    smc = common * 0.3 + rng.normal(0, 0.01, 400)
    p, lo, hi = ratio_ci(smc, pd_, 0.95)
    assert lo < p < hi
    assert p == pytest.approx(30.0, abs=1.0)
    assert hi - lo < 2.0  # shuffled pairs give an interval several times wider
    _, lo2, hi2 = ratio_ci(smc, rng.permutation(pd_), 0.95)
    assert hi2 - lo2 > 3 * (hi - lo)


def test_unstable_scenario_flags_divergence_and_keeps_the_rest(paper: Scenario) -> None:
    # The paper's SMC lateral loop is unstable (MODEL.md section 2): a sideways waypoint
    # excites it and it tips past divergence.max_tilt. PD flies the same realisations fine.
    s = paper.override(
        {"integrator.dt": 0.002, "trajectory.waypoints": [[0, 1.0, 0, 2, 0], [60, 1.0, 0, 0, 0]]}
    )
    with pytest.warns(quadrs.StabilityWarning, match=r"EXCITES them"):
        mc = quadrs.monte_carlo(s, runs=4, seed=0, workers=2, progress=False)
    smc = mc.runs[mc.runs["controller"] == "smc"]
    pd_rows = mc.runs[mc.runs["controller"] == "pd"]
    assert smc["diverged"].all()
    assert smc[METRICS].isna().all().all()
    assert (smc["diverged_at"] > 0).all()
    assert not pd_rows["diverged"].any()
    assert np.isfinite(pd_rows[MEASURED].to_numpy()).all()
    summary = mc.summary()
    assert (summary["diverged"] == 4).all()
    assert np.isfinite(summary.loc[("iae", "P1"), "pd_mean"])


def test_parquet_round_trip(short: Scenario, tmp_path) -> None:
    mc = quadrs.monte_carlo(short, runs=4, seed=2, workers=2, progress=False)
    path = tmp_path / "runs.parquet"
    mc.to_parquet(path)
    back = MonteCarloResult.read_parquet(path)
    pd.testing.assert_frame_equal(back.runs, mc.runs)
    assert back.scenario == short and back.seed == 2 and back.controllers == ("pd", "smc")
    pd.testing.assert_frame_equal(back.spectra, mc.spectra)
    pd.testing.assert_frame_equal(back.summary(), mc.summary())
    import pyarrow.parquet as pq

    meta = pq.read_schema(path).metadata[b"quadrs"]
    assert quadrs.__version__.encode() in meta
    assert not list(tmp_path.glob(".*partial"))


def test_ensemble_spectra(short: Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=8, seed=0, workers=2, progress=False)
    sp = mc.spectra
    assert list(sp.columns) == ["controller", "phase", "frequency", "mean", "std", "n"]
    assert (sp["n"] == 8).all()
    one = quadrs.simulate(short, "pd", seed=0, realisation=0).spectra["P1"]
    pd_p1 = sp[(sp["controller"] == "pd") & (sp["phase"] == "P1")]
    np.testing.assert_allclose(pd_p1["frequency"].to_numpy(), one["frequency"].to_numpy())


def test_summary_layout(short: Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=6, seed=0, workers=2, progress=False)
    s = mc.summary()
    assert s.index.names == ["metric", "phase"]
    for col in ("pd_mean", "pd_ci_low", "pd_ci_high", "smc_mean", "P", "P_ci_low", "P_ci_high"):
        assert col in s.columns
    row = s.loc[("iae", "P1")]
    assert row["pd_ci_low"] <= row["pd_mean"] <= row["pd_ci_high"]
    manual = mc.runs.query("phase == 'P1'").groupby("controller")["iae"].mean()
    assert row["P"] == pytest.approx(100 * manual["smc"] / manual["pd"], rel=1e-12)
    only_smc = quadrs.monte_carlo(short, runs=3, controllers=("smc",), progress=False)
    assert "P" not in only_smc.summary().columns


def test_cancel_keeps_what_finished(paper: Scenario) -> None:
    progress = quadrs._core.Progress()

    def cancel_after_first_lane_set() -> None:
        while progress.done() == 0:
            time.sleep(0.01)
        progress.cancel()

    watcher = threading.Thread(target=cancel_after_first_lane_set)
    watcher.start()
    out = quadrs._core.run_batch(paper.to_json(), ["pd", "smc"], 0, 0, 400, 2, False, progress)
    watcher.join()
    done = out["done"]
    assert 0 < done.sum() < 400
    assert done.sum() == progress.done()
    measured = [METRICS.index(m) for m in MEASURED]
    assert np.isfinite(out["metrics"][done][..., measured]).all()
    assert np.isnan(out["metrics"][~done]).all()


def interrupt_when(condition) -> threading.Thread:
    """SIGINT this process (as Ctrl-C does) once `condition()` holds."""

    def watch() -> None:
        while not condition():
            time.sleep(0.02)
        os.kill(os.getpid(), signal.SIGINT)

    t = threading.Thread(target=watch, daemon=True)
    t.start()
    return t


def test_ctrl_c_returns_finished_realisations(paper: Scenario, tmp_path) -> None:
    out = tmp_path / "run"
    watcher = interrupt_when(lambda: out.exists() and len(list(out.glob("part-*"))) >= 1)
    with pytest.warns(RuntimeWarning, match="interrupted"):
        mc = quadrs.monte_carlo(paper, runs=400, workers=2, progress=False, out=out, chunk=8)
    watcher.join()
    assert mc.interrupted
    n = mc.runs["realisation"].nunique()
    assert 0 < n < 400
    assert len(mc.runs) == n * 2 * 4  # P1-P3 and the whole flight
    assert np.isfinite(mc.runs[MEASURED].to_numpy()).all()
    # Resuming flies only what is missing, and equals an uninterrupted run.
    resumed = quadrs.monte_carlo(paper, runs=12, workers=2, progress=False, out=out, resume=True)
    fresh = quadrs.monte_carlo(paper, runs=12, workers=2, progress=False)
    pd.testing.assert_frame_equal(
        resumed.runs[resumed.runs["realisation"] < 12].reset_index(drop=True), fresh.runs
    )


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_between_a_chunks_flights_and_its_landing_keeps_it(
    short: Scenario, monkeypatch: pytest.MonkeyPatch, signum: int
) -> None:
    """A Ctrl-C (or SIGTERM) landing after a chunk's flights are done, before the batch has
    taken the chunk in, stops the batch after it and keeps it: it is held from the first chunk
    to the last save, never raised in that gap (before, it raised there and the chunk, flown
    and assembled, was lost: an empty result)."""
    import quadrs.runs.montecarlo as mc

    whole = quadrs.monte_carlo(short, runs=4, workers=1, progress=False)
    fly = mc.fly_chunk

    def fly_then_signal(*args: object, **kwargs: object) -> object:
        chunk = fly(*args, **kwargs)
        signal.raise_signal(signum)  # delivered before this function returns
        return chunk

    monkeypatch.setattr(mc, "fly_chunk", fly_then_signal)
    if signum == signal.SIGTERM:  # as the command line has it: SIGTERM stops like Ctrl-C
        previous = signal.signal(signal.SIGTERM, signal.default_int_handler)
    try:
        with pytest.warns(RuntimeWarning, match="interrupted"):
            result = quadrs.monte_carlo(short, runs=12, chunk=4, workers=1, progress=False)
    finally:
        if signum == signal.SIGTERM:
            signal.signal(signal.SIGTERM, previous)
    assert result.interrupted
    assert sorted(result.runs["realisation"].unique()) == [0, 1, 2, 3]
    pd.testing.assert_frame_equal(result.runs, whole.runs)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"runs": 0}, "runs"),
        ({"workers": 0}, "workers"),
        ({"controllers": ("pd", "pd")}, "distinct"),
        ({"controllers": ("lqr",)}, "controller"),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_arguments(short: Scenario, kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        quadrs.monte_carlo(short, progress=False, **kwargs)


def test_fused_mode_is_close_recorded_and_refused_where_it_cannot_run(
    short: Scenario, tmp_path
) -> None:
    from quadrs import _core

    if _core.simd_path() == "baseline":
        with pytest.raises(ValueError, match="fused=True needs fused multiply-add"):
            quadrs.monte_carlo(short, runs=4, progress=False, fused=True)
        pytest.skip("the baseline path has no fused mode")
    exact = quadrs.monte_carlo(short, runs=8, seed=2, progress=False)
    fused = quadrs.monte_carlo(short, runs=8, seed=2, progress=False, fused=True)
    assert (exact.arithmetic, fused.arithmetic) == ("exact", "fused")
    cols = list(_core.METRIC_NAMES)
    a, b = exact.runs[cols].to_numpy(), fused.runs[cols].to_numpy()
    # Fused multiply-adds change the last digits only; they do change them.
    np.testing.assert_allclose(b, a, rtol=1e-8, atol=1e-14)
    assert not np.array_equal(a, b)
    # The mode is in the saved metadata and the run identity (an exact run's is unchanged).
    fused.to_parquet(tmp_path / "f.parquet")
    back = MonteCarloResult.read_parquet(tmp_path / "f.parquet")
    assert back.arithmetic == "fused"
    assert fused.metadata()["run"] != exact.metadata()["run"]
    # A checkpoint records the mode: its rows are the in-memory run's, it reads back fused,
    # and resuming it in the other mode is refused (rows of two modes never mix).
    saved = quadrs.monte_carlo(short, runs=8, seed=2, progress=False, fused=True, chunk=4,
                               out=tmp_path / "d")  # fmt: skip
    assert saved.arithmetic == "fused"
    pd.testing.assert_frame_equal(saved.runs, fused.runs)
    assert MonteCarloResult.read_parquet(tmp_path / "d").arithmetic == "fused"
    with pytest.raises(ValueError, match="arithmetic"):
        quadrs.monte_carlo(short, runs=12, seed=2, progress=False, out=tmp_path / "d",
                           resume=True)  # fmt: skip
    more = quadrs.monte_carlo(short, runs=12, seed=2, progress=False, fused=True,
                              out=tmp_path / "d", resume=True)  # fmt: skip
    assert more.arithmetic == "fused" and more.runs["realisation"].nunique() == 12
