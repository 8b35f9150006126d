"""Nothing lies, nothing aborts, nothing is lost: one test per promise of docs/guarantees.md."""

import errno
import json
import os
import signal
import subprocess
import sys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import quadrs
from quadrs import MonteCarloResult, Scenario, ScenarioError, _core
from quadrs.cli.main import main
from quadrs.runs.montecarlo import run_range
from quadrs.runs.store import RunStore, checkpoint_record

TINY = {
    "integrator.duration": 2.0,
    "integrator.dt": 0.01,
    "trajectory.waypoints": [[0, 0, 0, 2, 0], [1, 0, 0, 1, 0]],
    "phases": [{"name": "P1", "start": 0, "end": 1}, {"name": "P2", "start": 1, "end": 2}],
    "gust.start": 0.5,
    "gust.end": 1.5,
}


@pytest.fixture(scope="module")
def tiny(paper: Scenario) -> Scenario:
    return paper.override(TINY)


def run_cli(*args: str, capsys) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


# -- silent wrong results ---------------------------------------------------------------------
@pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")  # coarse dt on purpose
def test_checkpoint_refuses_a_foreign_part(tiny: Scenario, tmp_path: Path, capsys) -> None:
    ours, theirs = tmp_path / "ours", tmp_path / "theirs"
    quadrs.monte_carlo(tiny, runs=4, seed=1, progress=False, out=ours)
    quadrs.monte_carlo(tiny, runs=4, seed=2, progress=False, out=theirs, first=4)
    (part,) = RunStore(theirs).parts()
    (ours / part.name).write_bytes(part.read_bytes())
    from quadrs.io.integrity import CorruptRunError

    with pytest.raises(CorruptRunError, match="does not belong to the run"):
        MonteCarloResult.read_parquet(ours)
    with pytest.raises(CorruptRunError):
        quadrs.monte_carlo(tiny, runs=8, seed=1, progress=False, out=ours, resume=True)
    code, out, err = run_cli("report", str(ours), capsys=capsys)
    assert code == 2 and "does not belong" in err and out == ""


def test_two_runs_cannot_both_create_one_checkpoint(
    tiny: Scenario, tmp_path: Path, monkeypatch
) -> None:
    """The check-then-create window: even if both runs saw an empty directory, only one
    manifest can be created."""
    RunStore(tmp_path).create(checkpoint_record(tiny, 1, ("pd",)))
    monkeypatch.setattr(RunStore, "exists", lambda self: False)
    monkeypatch.setattr(RunStore, "parts", lambda self: [])
    with pytest.raises(FileExistsError, match="already holds a run"):
        RunStore(tmp_path).create(checkpoint_record(tiny, 2, ("pd",)))
    assert RunStore(tmp_path).manifest()["seed"] == 1


@pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")  # coarse dt on purpose
def test_report_refuses_tampered_metadata(tiny: Scenario, tmp_path: Path, capsys) -> None:
    mc = quadrs.monte_carlo(tiny, runs=4, seed=0, progress=False)
    path = tmp_path / "runs.parquet"
    mc.to_parquet(path)
    assert MonteCarloResult.read_parquet(path).seed == 0
    table = pq.read_table(path)
    meta = json.loads(table.schema.metadata[b"quadrs"])
    for key, value in (("interrupted", "false"), ("seed", 7), ("controllers", ["pd", "pd"])):
        bad = {**meta, key: value}
        schema = {**table.schema.metadata, b"quadrs": json.dumps(bad).encode()}
        pq.write_table(table.replace_schema_metadata(schema), tmp_path / "bad.parquet")
        code, out, err = run_cli("report", str(tmp_path / "bad.parquet"), capsys=capsys)
        assert code == 2 and (key in err or "run identity" in err), (key, err)
        assert out == ""


def test_diverged_trace_stops_at_divergence(tiny: Scenario) -> None:
    with pytest.warns(quadrs.PlausibilityWarning, match="400 Hz"):  # too stiff on purpose
        s = tiny.override({"payload.natural_frequency": 400.0, "integrator.dt": 0.002})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        f = quadrs.simulate(s, "pd", record_every=1)
    assert f.diverged
    assert f.trace.index.max() < f.diverged_at
    assert np.isfinite(f.trace.to_numpy()).all()
    # The state it recorded never comes back to the initial one after lift-off.
    assert len(f.trace) == round(f.diverged_at / 0.002)


@pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")  # coarse dt on purpose
def test_unstable_step_is_flagged_by_the_speed_bound(tiny: Scenario) -> None:
    """SMC eta = 200 at dt = 10 ms: the step is unstable, vertical speeds reach ~1e3 m/s while
    positions stay within max_distance."""
    s = tiny.override({"controller.smc.eta": [0.4, 0.4, 200.0], "integrator.dt": 0.01})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flagged = quadrs.simulate(s, "smc")
        loose = s.override({"divergence.max_speed": 1e300, "divergence.max_rate": 1e300})
        unflagged = quadrs.simulate(loose, "smc")
    assert flagged.diverged
    assert not unflagged.diverged
    assert np.abs(unflagged.trace["vz"]).max() > 100.0  # absurd, and now caught
    healthy = quadrs.simulate(tiny, "smc")  # the defaults never flag a healthy flight
    assert not healthy.diverged and np.abs(healthy.trace["vz"]).max() < 10.0


def test_scenario_equality_and_hash_agree(paper: Scenario) -> None:
    reordered = Scenario(dict(reversed(list(paper.to_dict().items()))))
    as_int = paper.override({"gust.w20": 10})
    for other in (reordered, as_int):
        assert other == paper
        assert hash(other) == hash(paper)
    assert len({paper, reordered, as_int}) == 1


# -- aborts -----------------------------------------------------------------------------------
def test_huge_allocations_are_refused_not_aborted(tiny: Scenario, capsys) -> None:
    with pytest.raises(MemoryError, match="steps \\* realisations"):
        quadrs.gust_series(steps=10**12, realisations=1)
    with pytest.raises(MemoryError, match="runs = 1000000000000"):
        quadrs.monte_carlo(tiny, runs=10**12, progress=False)
    long = tiny.override({"integrator.duration": 1e8, "integrator.dt": 0.1})
    with pytest.raises(MemoryError, match="trace"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        quadrs.simulate(long, "pd")
    code, _, err = run_cli("mc", "--runs", str(10**12), "--set", "integrator.dt=0.01",
                             capsys=capsys)  # fmt: skip
    assert code == 2 and "runs = 1000000000000" in err and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('base = "paper"\n[gust]\nw20 = 1979-05-27\n', "gust.w20"),
        ('base = "paper"\n[gust]\nw20 = 07:32:00\n', "gust.w20"),
        ('base = "paper"\n[gust]\nw20 = ' + "[" * 40 + "]" * 40 + "\n", "nested"),
        ("x = " + "[" * 100_000 + "]" * 100_000, "nested too deeply"),
        ('base = "paper"\n[gust]\nw20 = 18446744073709551616\n', "gust.w20"),
    ],
)
def test_toml_values_outside_the_model_name_their_key(
    text: str, key: str, tmp_path: Path, capsys
) -> None:
    with pytest.raises(ScenarioError, match=key):
        Scenario.from_toml_string(text)
    path = tmp_path / "s.toml"
    path.write_text(text)
    code, _, err = run_cli("scenario", "show", "--scenario", str(path), capsys=capsys)
    assert code == 2 and len(err.strip().splitlines()) == 1


def test_binary_and_endless_scenario_files(tmp_path: Path, capsys) -> None:
    with pytest.raises(ScenarioError, match="larger than"):
        Scenario.from_toml("/dev/zero")
    binary = tmp_path / "b.toml"
    binary.write_bytes(bytes(range(256)))
    with pytest.raises(ScenarioError, match="not UTF-8"):
        Scenario.from_toml(binary)
    code, _, err = run_cli("run", "--scenario", "/dev/zero", capsys=capsys)
    assert code == 2 and "larger than" in err


def test_base_chains_resolve_and_cycles_are_refused(monkeypatch) -> None:
    s = Scenario.from_toml_string('base = "paper_stable_lateral"\n[gust]\nw20 = 3.0\n')
    assert s["gust.w20"] == 3.0
    assert (
        s["controller.smc.lambda"]
        == Scenario.preset("paper_stable_lateral")["controller.smc.lambda"]
    )
    from quadrs.scenario import scenario as mod

    texts = {"a": 'base = "b"\n', "b": 'base = "a"\n'}
    monkeypatch.setattr(mod, "_preset_text", lambda name: texts[name])
    with pytest.raises(ScenarioError, match="cycle: a -> b -> a"):
        Scenario.from_toml_string('base = "a"\n')


@pytest.mark.parametrize(
    "args",
    [
        ["mc", "--seed", str(2**64)],
        ["mc", "--runs", str(2**64)],
        ["mc", "--workers", str(2**64)],
        ["run", "--realisation", str(2**64)],
        ["run", "--seed", str(2**70)],
    ],
)
def test_integers_beyond_64_bits_are_bad_input(args: list[str], capsys) -> None:
    code, out, err = run_cli(*args, capsys=capsys)
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    assert args[1].lstrip("-") in err


@pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")  # coarse dt on purpose
def test_first_near_2_63_keeps_labels_non_negative(tiny: Scenario) -> None:
    with pytest.raises(ValueError, match="first \\+ runs - 1"):
        quadrs.monte_carlo(tiny, runs=8, first=2**63 - 4, progress=False)
    mc = quadrs.monte_carlo(tiny, runs=4, first=2**63 - 4, controllers=("pd",), progress=False)
    assert (mc.runs["realisation"] >= 2**63 - 4).all()


# -- finished work lost -----------------------------------------------------------------------
def test_unwritable_out_is_refused_before_running(tmp_path: Path, capsys) -> None:
    target = tmp_path / "dir.parquet"
    target.mkdir()
    code, out, err = run_cli("mc", "--runs", "4", "--set", "integrator.dt=0.01",
                             "--out", str(target), capsys=capsys)  # fmt: skip
    assert code == 2 and out == "" and "directory" in err
    trace = tmp_path / "trace.parquet"
    trace.mkdir()
    code, out, err = run_cli("run", "--trace", str(trace), capsys=capsys)
    assert code == 2 and out == "" and "directory" in err


def test_full_disk_prints_the_table_and_keeps_a_recovery_file(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    target = tmp_path / "runs.parquet"
    real = MonteCarloResult.to_parquet

    def full(self, path):
        if Path(path) == target:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        real(self, path)

    monkeypatch.setattr(MonteCarloResult, "to_parquet", full)
    code, out, err = run_cli("mc", "--runs", "4", "--no-progress", "--set",
                             "integrator.duration=2", "--set", "integrator.dt=0.01", "--set",
                             'phases=[{name="a", start=0.0, end=2.0}]', "--out", str(target),
                             capsys=capsys)  # fmt: skip
    assert code == 1 and "IAE" in out.upper()
    spare = Path(err.split("saved to ")[1].split(" instead")[0])
    assert MonteCarloResult.read_parquet(spare).runs["realisation"].nunique() == 4
    assert not target.exists()


def test_sigterm_saves_what_finished(tmp_path: Path) -> None:
    out, ckpt = tmp_path / "runs.parquet", tmp_path / "ckpt"
    proc = subprocess.Popen(
        [sys.executable, "-m", "quadrs.cli", "mc", "--runs", "100000", "--chunk", "8",
         "--workers", "1", "--no-progress", "--controllers", "pd", "--set", "integrator.dt=0.002",
         "--set", "integrator.duration=2", "--set", 'phases=[{name="a", start=0.0, end=2.0}]',
         "--checkpoint", str(ckpt), "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip
    deadline = time.monotonic() + 60
    while not list(ckpt.glob("part-*.parquet")) and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    saved = MonteCarloResult.read_parquet(out)
    assert saved.interrupted and len(saved.realisations) >= 8
    assert not [p for p in tmp_path.rglob(".*") if p.is_file()], "no temporary file left"


def test_signals_the_process_ignores_stay_ignored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Started with Ctrl-C and SIGTERM ignored (``nohup``, a script's background job), a batch
    neither holds nor obeys them: both arriving while it flies leave it to finish, whole, with
    status 0, and the two still ignored after it."""
    import quadrs.runs.montecarlo as mc

    fly = mc.fly_chunk

    def fly_then_signal(*args: object, **kwargs: object) -> object:
        chunk = fly(*args, **kwargs)
        signal.raise_signal(signal.SIGINT)
        signal.raise_signal(signal.SIGTERM)
        return chunk

    monkeypatch.setattr(mc, "fly_chunk", fly_then_signal)
    out = tmp_path / "runs.parquet"
    ignored = (signal.SIGINT, signal.SIGTERM)
    before = {sig: signal.signal(sig, signal.SIG_IGN) for sig in ignored}
    try:
        code, _, err = run_cli("mc", "--runs", "6", "--chunk", "2", "--workers", "1",
                               "--controllers", "pd", "--no-progress", "--set",
                               "integrator.duration=2", "--set", "integrator.dt=0.01", "--set",
                               'phases=[{name="a", start=0.0, end=2.0}]', "--out", str(out),
                               capsys=capsys)  # fmt: skip
        still = [signal.getsignal(sig) for sig in ignored]
    finally:
        for sig, handler in before.items():
            signal.signal(sig, handler)
    assert code == 0 and "interrupted" not in err, err
    assert still == [signal.SIG_IGN, signal.SIG_IGN]
    saved = MonteCarloResult.read_parquet(out)
    assert not saved.interrupted and len(saved.realisations) == 6


def test_ctrl_c_during_a_write_is_delivered_after_it(tmp_path: Path) -> None:
    from quadrs.io.files import atomic_write

    target = tmp_path / "f.bin"

    def write(f) -> None:
        f.write(b"a" * 1000)
        os.kill(os.getpid(), signal.SIGINT)  # a second Ctrl-C, mid-save
        time.sleep(0.05)
        f.write(b"b" * 1000)

    # Python's own Ctrl-C handler, whatever an earlier test in this process left installed.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            atomic_write(target, write)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert target.read_bytes() == b"a" * 1000 + b"b" * 1000
    assert [p.name for p in tmp_path.iterdir()] == ["f.bin"]


def test_failing_progress_callback_cancels_the_batch(paper: Scenario) -> None:
    before = {t.ident for t in threading.enumerate()}

    def broken(done: int) -> None:
        raise BrokenPipeError(errno.EPIPE, "stderr is gone")

    long = paper.override({"integrator.dt": 0.002})
    with pytest.raises(BrokenPipeError):
        run_range(long, ("pd", "smc"), 0, 0, 4000, 1, on_progress=broken)
    left = [t for t in threading.enumerate() if t.ident not in before and t.is_alive()]
    assert left == [], "the batch must not keep running in the background"


def test_single_flight_polls_its_cancel_flag(paper: Scenario) -> None:
    progress = _core.Progress()
    progress.cancel()
    with pytest.raises(KeyboardInterrupt):
        _core.simulate(paper.to_json(), "pd", 0, 0, 1000, progress=progress)


def test_simulate_answers_ctrl_c(paper: Scenario) -> None:
    import _thread

    long = paper.override({"integrator.duration": 20000.0, "integrator.dt": 0.001,
                           "gust.end": 19000.0, "phases[2].end": 20000.0})  # fmt: skip
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        quadrs.simulate(long, "pd", record_every=10_000)
    timer.join()
    assert time.monotonic() - started < 10  # the whole flight would take minutes


def test_thread_pools_are_bounded() -> None:
    def threads() -> int:
        return len(os.listdir("/proc/self/task"))

    base = threads()
    for w in range(1, 41):
        quadrs.gust_series(steps=10, realisations=1, workers=w)
    deadline = time.monotonic() + 10
    while threads() > base + 2 * 40 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert threads() <= base + 2 * 40  # was base + 820 with a pool kept per size


# -- security ---------------------------------------------------------------------------------
@pytest.mark.filterwarnings("ignore::quadrs.StepSizeWarning")  # coarse dt on purpose
def test_a_planted_symlink_is_not_followed(tiny: Scenario, tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    target = tmp_path / "runs.parquet"
    (tmp_path / ".runs.parquet.partial").symlink_to(victim)  # the old predictable name
    quadrs.monte_carlo(tiny, runs=4, progress=False).to_parquet(target)
    assert victim.read_text() == "precious"
    assert MonteCarloResult.read_parquet(target).runs["realisation"].nunique() == 4
