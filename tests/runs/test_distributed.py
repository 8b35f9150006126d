"""Past one machine: Dask chunks equal the local run; checkpointed runs survive kills."""

import contextlib
import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs import MonteCarloResult, Scenario
from quadrs.runs.store import RunStore, missing_ranges


def test_missing_ranges() -> None:
    assert missing_ranges(0, 10, set()) == [(0, 10)]
    assert missing_ranges(5, 10, {5, 6, 9, 14}) == [(7, 2), (10, 4)]
    assert missing_ranges(0, 4, {0, 1, 2, 3}) == []


def test_chunked_checkpointed_run_equals_one_batch(short: Scenario, tmp_path) -> None:
    whole = quadrs.monte_carlo(short, runs=10, seed=4, progress=False)
    chunked = quadrs.monte_carlo(short, runs=10, seed=4, progress=False, chunk=3)
    pd.testing.assert_frame_equal(chunked.runs, whole.runs)
    pd.testing.assert_frame_equal(chunked.spectra, whole.spectra, rtol=1e-12)
    stored = quadrs.monte_carlo(short, runs=10, seed=4, progress=False, out=tmp_path / "r", chunk=4)
    pd.testing.assert_frame_equal(stored.runs, whole.runs)
    assert len(RunStore(tmp_path / "r").parts()) == 3
    back = MonteCarloResult.read_parquet(tmp_path / "r")
    pd.testing.assert_frame_equal(back.runs, whole.runs)
    assert back.scenario == short and back.seed == 4


def test_store_refuses_to_mix_runs(short: Scenario, tmp_path) -> None:
    out = tmp_path / "r"
    quadrs.monte_carlo(short, runs=4, seed=1, progress=False, out=out)
    with pytest.raises(FileExistsError, match="already holds a run"):
        quadrs.monte_carlo(short, runs=4, seed=1, progress=False, out=out)
    with pytest.raises(ValueError, match="seed differs"):
        quadrs.monte_carlo(short, runs=4, seed=2, progress=False, out=out, resume=True)
    with pytest.raises(ValueError, match="scenario differs"):
        other = short.override({"gust.w20": 5.0})
        quadrs.monte_carlo(other, runs=4, seed=1, progress=False, out=out, resume=True)
    # resuming a complete run flies nothing new and returns it
    again = quadrs.monte_carlo(short, runs=4, seed=1, progress=False, out=out, resume=True)
    assert again.runs["realisation"].nunique() == 4
    assert len(RunStore(out).parts()) == 1


KILLED_RUN = textwrap.dedent(
    """
    import sys, quadrs
    s = quadrs.Scenario.paper().override({"integrator.dt": 0.001})
    quadrs.monte_carlo(s, runs=200, seed=9, workers=2, progress=False, out=sys.argv[1], chunk=8)
    """
)


@pytest.mark.parametrize("kill_after", [0.2, 1.1, 2.3, "2 parts"])
def test_killed_run_resumes_exactly(paper: Scenario, tmp_path, kill_after) -> None:
    """SIGKILL at an arbitrary moment (before the store exists, mid-chunk, mid-write...):
    resuming gives exactly the uninterrupted run, no duplicates, none missing."""
    out = tmp_path / "killed"
    proc = subprocess.Popen([sys.executable, "-c", KILLED_RUN, str(out)])
    try:
        if kill_after == "2 parts":
            deadline = time.monotonic() + 120
            while len(list(out.glob("part-*.parquet"))) < 2:
                assert proc.poll() is None, "the run ended before it could be killed"
                assert time.monotonic() < deadline
                time.sleep(0.05)
        else:
            time.sleep(kill_after)
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait()
    s = paper.override({"integrator.dt": 0.001})
    if kill_after == "2 parts":
        assert 16 <= len(RunStore(out).done_realisations()) < 200
    resumed = quadrs.monte_carlo(s, runs=24, seed=9, progress=False, out=out, resume=True)
    fresh = quadrs.monte_carlo(s, runs=24, seed=9, progress=False)
    got = resumed.runs[resumed.runs["realisation"] < 24].reset_index(drop=True)
    pd.testing.assert_frame_equal(got, fresh.runs)
    assert not resumed.runs.duplicated(["realisation", "controller", "phase"]).any()
    assert set(range(24)) <= RunStore(out).done_realisations()


def test_local_path_does_not_import_dask(tmp_path) -> None:
    code = textwrap.dedent(
        """
        import sys, quadrs
        s = quadrs.Scenario.paper().override({"integrator.duration": 2.0, "integrator.dt": 0.01,
            "phases": [{"name": "all", "start": 0.0, "end": 2.0}]})
        quadrs.monte_carlo(s, runs=2, progress=False)
        assert "dask" not in sys.modules and "distributed" not in sys.modules
        """
    )
    subprocess.run([sys.executable, "-c", code], check=True)


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of two worker processes (one thread each), started by the test."""
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as c:
        yield c


def test_dask_local_cluster_equals_local_run(short: Scenario, cluster) -> None:
    from dask.distributed import Client

    with Client(cluster) as client:
        remote = quadrs.monte_carlo(short, runs=12, seed=6, progress=False, client=client, chunk=4)
        swept = quadrs.sweep(
            short, {"payload.mass": [0.2, 0.4]}, runs=4, seed=6, progress=False, client=client
        )
    local = quadrs.monte_carlo(short, runs=12, seed=6, progress=False)
    pd.testing.assert_frame_equal(remote.runs, local.runs)
    np.testing.assert_allclose(remote.spectra["mean"], local.spectra["mean"], rtol=1e-12)
    local_sweep = quadrs.sweep(short, {"payload.mass": [0.2, 0.4]}, runs=4, seed=6, progress=False)
    pd.testing.assert_frame_equal(swept.runs, local_sweep.runs)


def test_rare_event_on_dask_equals_the_local_run(short: Scenario, cluster) -> None:
    """rare_event(client=): each batch's rows flown on the cluster's worker processes, for a
    scenario with a dispersed key (its values travel with the rows): the same estimate,
    levels and failure samples as on one machine, bit for bit."""
    from dask.distributed import Client

    from quadrs.rare import RareEventResult

    s = short.override({"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.15,
                                                         "high": 0.35}}})  # fmt: skip
    # p0 = 0.2: 9 batches in the main run's two levels and as many in the pilot's (each a
    # round trip to the cluster).
    kwargs = dict(metric="max_accel", phase="P2", threshold=3.6, per_level=50, p0=0.2, seed=2,
                  max_levels=2)  # fmt: skip
    local = quadrs.rare_event(s, **kwargs)  # type: ignore[arg-type]
    with Client(cluster) as client:
        remote = quadrs.rare_event(s, client=client, **kwargs)  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="workers= or client="):
            quadrs.rare_event(s, client=client, workers=1, **kwargs)  # type: ignore[arg-type]
    assert isinstance(local, RareEventResult) and isinstance(remote, RareEventResult)
    assert local.probability is not None
    assert remote.probability == local.probability and remote.cov == local.cov
    pd.testing.assert_frame_equal(remote.levels, local.levels)
    pd.testing.assert_frame_equal(remote.failures, local.failures)
    assert np.array_equal(remote.xi, local.xi)


def test_dask_fused_run_equals_local_fused_run(short: Scenario, cluster) -> None:
    """The fused mode reaches the workers (and their task keys): on one machine's CPU its
    chunks are the local fused run's, and differ from the exact run's."""
    from dask.distributed import Client

    if quadrs._core.simd_path() == "baseline":
        pytest.skip("the baseline path has no fused mode")
    with Client(cluster) as client:
        exact = quadrs.monte_carlo(short, runs=8, seed=6, progress=False, client=client, chunk=4)
        fused = quadrs.monte_carlo(short, runs=8, seed=6, progress=False, client=client, chunk=4,
                                   fused=True)  # fmt: skip
    local = quadrs.monte_carlo(short, runs=8, seed=6, progress=False, fused=True)
    assert (exact.arithmetic, fused.arithmetic) == ("exact", "fused")
    pd.testing.assert_frame_equal(fused.runs, local.runs)
    assert not exact.runs.equals(fused.runs)


def test_cli_scheduler_and_checkpoint(cluster, tmp_path) -> None:
    from quadrs.cli.main import main
    from tests.cli.test_main import SHORT

    remote, local = tmp_path / "remote.parquet", tmp_path / "local.parquet"
    args = ["mc", "--runs", "8", "--seed", "2", "--no-progress", *SHORT]
    assert main([*args, "--scheduler", cluster.scheduler_address, "--out", str(remote)]) == 0
    assert main([*args, "--checkpoint", str(tmp_path / "ck"), "--out", str(local)]) == 0
    a, b = MonteCarloResult.read_parquet(remote), MonteCarloResult.read_parquet(local)
    pd.testing.assert_frame_equal(a.runs, b.runs)
    pd.testing.assert_frame_equal(MonteCarloResult.read_parquet(tmp_path / "ck").runs, b.runs)
    # the checkpoint exists: running again needs --resume, which then flies nothing new
    assert main([*args, "--checkpoint", str(tmp_path / "ck")]) == 2
    assert main([*args, "--checkpoint", str(tmp_path / "ck"), "--resume"]) == 0
    assert main([*args, "--scheduler", "tcp://127.0.0.1:1"]) == 2


def test_concurrent_dask_calls_do_not_share_tasks(short: Scenario, cluster) -> None:
    """Two calls on one client that differ only in controllers (or spectra) get their own
    rows: every input of a chunk is in its task key."""
    from dask.distributed import Client

    from quadrs.runs.distributed import run_on_dask
    from quadrs.runs.montecarlo import Design

    with Client(cluster) as client:
        ranges, d = [(0, 4), (4, 4)], Design()
        pd_tasks = run_on_dask(client, short, ("pd",), 0, ranges, True, d)
        rows = next(pd_tasks).runs  # submitted, and still held
        smc = list(run_on_dask(client, short, ("smc",), 0, ranges, True, d))
        no_spectra = list(run_on_dask(client, short, ("pd",), 0, ranges, False, d))
        rest = list(pd_tasks)
    assert set(rows["controller"]) == {"pd"}
    assert all(set(c.runs["controller"]) == {"smc"} for c in smc)
    assert all(c.spectra is None for c in no_spectra)
    assert all(c.spectra is not None for c in rest)


def _whole_vehicle() -> Scenario:
    """The third round's vehicle in 3 s: a cable payload on rotors, a sheared mean wind and
    three-component turbulence at the vehicle's altitude and airspeed, the line's length and
    the rotors' lag dispersed per realisation."""
    return Scenario.preset("slung").override(
        {
            "actuator.model": "rotors",
            "initial.attitude": [0.0, 0.0, 0.0],
            "wind.speed": 3.0,
            "wind.shear": "log",
            "gust.start": 0.5,
            "gust.end": 3.0,
            "gust.altitude": "vehicle",
            "gust.airspeed": "relative",
            "integrator.duration": 3.0,
            "integrator.dt": 1e-3,
            "phases": [{"name": "all", "start": 0.0, "end": 3.0}],
            "dispersions": {
                "payload.cable_length": {"dist": "uniform", "low": 0.8, "high": 1.2},
                "actuator.time_constant": {"dist": "uniform", "low": 0.02, "high": 0.04},
            },
        }
    )


def test_the_whole_vehicle_checkpointed_and_on_dask_equals_one_batch(cluster, tmp_path) -> None:
    """Every round-2 guarantee for the new models: chunks, a checkpointed store read back, and
    a Dask cluster give the one local batch's rows exactly."""
    from dask.distributed import Client

    s = _whole_vehicle()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the paper PD's lateral margin with rotors: known
        whole = quadrs.monte_carlo(s, runs=6, seed=2, progress=False, spectra=False)
        stored = quadrs.monte_carlo(
            s, runs=6, seed=2, progress=False, spectra=False, out=tmp_path / "r", chunk=4
        )
        with Client(cluster) as client:
            remote = quadrs.monte_carlo(
                s, runs=6, seed=2, progress=False, spectra=False, client=client, chunk=2
            )
    assert whole.runs["max_tension"].gt(0).all() and whole.runs["max_swing"].gt(0).all()
    assert whole.runs["payload.cable_length"].nunique() == 6
    pd.testing.assert_frame_equal(stored.runs, whole.runs)
    pd.testing.assert_frame_equal(MonteCarloResult.read_parquet(tmp_path / "r").runs, whole.runs)
    pd.testing.assert_frame_equal(remote.runs, whole.runs)


def test_mission_tune_and_sensitivity_on_dask_equal_the_local_run(
    short: Scenario, cluster, tmp_path
) -> None:
    """``mission``, ``tune`` and ``sens`` with ``--scheduler`` (the library calls' ``client=``)
    give the local run's numbers, bit for bit."""
    from dask.distributed import Client

    from quadrs.cli.main import main
    from quadrs.design.optimize import optimize
    from quadrs.design.sensitivity import sensitivity
    from tests.cli.test_main import SHORT

    # mission, through the command line (the paper preset's short flight: quick).
    remote, local = tmp_path / "remote.parquet", tmp_path / "local.parquet"
    args = ["mission", "--preset", "paper", *SHORT, "--runs", "4", "--seed", "3",
            "--no-progress"]  # fmt: skip
    assert main([*args, "--scheduler", cluster.scheduler_address, "--out", str(remote)]) == 0
    assert main([*args, "--out", str(local)]) == 0
    a, b = MonteCarloResult.read_parquet(remote), MonteCarloResult.read_parquet(local)
    assert len(b.runs) > 0
    pd.testing.assert_frame_equal(a.runs, b.runs)
    assert main([*args, "--scheduler", "tcp://127.0.0.1:1"]) == 2

    s = short.override({"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.15,
                                                         "high": 0.35}}})  # fmt: skip
    tune = dict(controller="pd", params={"controller.pd.kp[2]": (1.0, 3.0)}, objective="iae",
                phases=("P2",), runs=3, seed=5, maxiter=1, popsize=2)  # fmt: skip
    with Client(cluster) as client:
        sens_remote = sensitivity(s, runs=4, seed=1, controllers=("pd",), progress=False,
                                  client=client, chunk=5)  # fmt: skip
        tuned_remote = optimize(s, **tune, client=client)  # type: ignore[arg-type]
    sens_local = sensitivity(s, runs=4, seed=1, controllers=("pd",), progress=False)
    assert sens_local.samples["row"].nunique() == 4 * (1 + 2 + 1)  # N (k + 2), k = mass, gust
    pd.testing.assert_frame_equal(sens_remote.samples, sens_local.samples)
    pd.testing.assert_frame_equal(sens_remote.indices, sens_local.indices)
    tuned_local = optimize(s, **tune)  # type: ignore[arg-type]
    pd.testing.assert_frame_equal(tuned_remote.history, tuned_local.history)
    assert tuned_remote.best == tuned_local.best
    assert tuned_remote.objective == tuned_local.objective


def test_sensitivity_rows_survive_a_lost_worker(short: Scenario) -> None:
    """A worker killed while it holds a chunk of the design: Dask runs that chunk again
    elsewhere (its key is pure, its rows depend only on its inputs) and the result is the
    local run's."""
    distributed = pytest.importorskip("dask.distributed")
    from quadrs.design.sensitivity import sensitivity

    s = short.override({"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.15,
                                                         "high": 0.35}}})  # fmt: skip
    local = sensitivity(s, runs=8, seed=2, controllers=("pd",), progress=False)
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    with cluster, distributed.Client(cluster) as client:
        killed: list[str] = []

        def kill_one(done: int) -> None:
            # After the first chunk: the other worker is busy with (or queued for) the rest.
            if not killed and done > 0:
                victim = next(iter(client.scheduler_info()["workers"]))
                killed.append(victim)
                with contextlib.suppress(Exception):  # the worker dies before it answers
                    client.run(os._exit, 1, workers=[victim], wait=False)

        remote = sensitivity(s, runs=8, seed=2, controllers=("pd",), progress=False,
                             client=client, chunk=4, on_progress=kill_one)  # fmt: skip
    assert killed
    pd.testing.assert_frame_equal(remote.samples, local.samples)
