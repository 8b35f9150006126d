"""Nothing lies, aborts or is lost, third round: the design-loop commands and saved files.

One test (or a few) per class of failure; each failed before the fix it proves
(docs/guarantees.md lists them beside their promise)."""

from __future__ import annotations

import fcntl
import json
import os
import pty
import re
import select
import shutil
import signal
import struct
import subprocess
import sys
import termios
import threading
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import quadrs
from quadrs import MonteCarloResult, Scenario, ScenarioError
from quadrs.io.integrity import CorruptRunError
from quadrs.runs.flight import METRIC_COLUMNS
from quadrs.runs.store import RunStore, checkpoint_record
from tests.guarantees.test_guarantees import TINY, run_cli

pytestmark = pytest.mark.filterwarnings(
    "ignore::quadrs.StabilityWarning", "ignore::quadrs.StepSizeWarning"
)

#: The same, as --set options of the command line.
TINY_CLI = [
    "--set", "integrator.duration=2", "--set", "integrator.dt=0.01",
    "--set", "trajectory.waypoints=[[0,0,0,2,0],[1,0,0,1,0]]",
    "--set", 'phases=[{name="P1",start=0.0,end=1.0},{name="P2",start=1.0,end=2.0}]',
    "--set", "gust.start=0.5", "--set", "gust.end=1.5",
]  # fmt: skip
MASS = {"dist": "uniform", "low": 0.15, "high": 0.3}


@pytest.fixture(scope="module")
def tiny(paper: Scenario) -> Scenario:
    return paper.override(TINY)


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def rewrite(path: Path, frame: pd.DataFrame | None = None, **meta_changes) -> None:
    """Edit a saved file as a user with pyarrow could: other rows and/or metadata fields,
    every other byte of the file kept (the content digest is not recomputed)."""
    table = pq.read_table(path)
    md = dict(table.schema.metadata)
    key = next(k for k in (b"quadrs", b"quadrs_sweep", b"quadrs_flight") if k in md)
    meta = json.loads(md[key])
    meta.update(meta_changes)
    md[key] = json.dumps(meta).encode()
    if frame is not None:
        table = pa.Table.from_pandas(frame, preserve_index=False)
    pq.write_table(table.replace_schema_metadata(md), path)


# -- a resumed checkpoint counts each realisation once ----------------------------------------
def test_a_copied_or_twice_written_part_is_not_counted_twice(tiny: Scenario, tmp_path: Path):
    out = tmp_path / "run"
    whole = quadrs.monte_carlo(tiny, runs=16, seed=1, chunk=8, progress=False, out=out)
    parts = RunStore(out).parts()
    assert len(parts) == 2
    shutil.copy(parts[0], out / parts[0].name.replace(".parquet", "0.parquet"))  # a copy
    back = MonteCarloResult.read_parquet(out)
    assert back.spectrum_sums.count.tolist() == whole.spectrum_sums.count.tolist()
    assert len(back.runs) == len(whole.runs)
    pd.testing.assert_frame_equal(back.spectra, whole.spectra)
    # What a concurrent resume with another chunking would leave: parts overlapping in part.
    other = tmp_path / "other"
    quadrs.monte_carlo(tiny, runs=12, seed=1, first=4, chunk=12, progress=False, out=other)
    (overlapping,) = RunStore(other).parts()
    (out / "part-x.parquet").write_bytes(overlapping.read_bytes())
    with pytest.raises(CorruptRunError, match="hold some of the same realisations"):
        MonteCarloResult.read_parquet(out)


def test_two_processes_cannot_write_one_checkpoint_at_once(tiny: Scenario, tmp_path: Path):
    out = tmp_path / "run"
    quadrs.monte_carlo(tiny, runs=4, seed=1, progress=False, out=out)
    with RunStore(out).writing():  # another process resuming it right now
        with pytest.raises(BlockingIOError, match="another quadrs process is writing"):
            quadrs.monte_carlo(tiny, runs=8, seed=1, progress=False, out=out, resume=True)
    done = quadrs.monte_carlo(tiny, runs=8, seed=1, progress=False, out=out, resume=True)
    assert done.spectrum_sums.count.tolist() == [8, 8] and done.realisations.tolist() == list(
        range(8)
    )


# -- one spelling per key ---------------------------------------------------------------------
def test_two_spellings_of_one_key_are_one_key(tiny: Scenario) -> None:
    with pytest.raises(ScenarioError, match=r"kp\[2\]'.*kp\[02\]'.*same key"):
        tiny.override({"dispersions": {"controller.pd.kp[2]": MASS, "controller.pd.kp[02]": MASS}})
    with pytest.raises(ScenarioError, match="same key"):
        tiny.override({"controller.pd.kp[2]": 1.0, "controller.pd.kp[02]": 2.0})
    spelled = tiny.override({"dispersions": {"controller.pd.kp[02]": MASS | {"low": 1, "high": 2}}})
    assert list(spelled.dispersions) == ["controller.pd.kp[2]"]
    mc = quadrs.monte_carlo(spelled, runs=2, progress=False, spectra=False)
    assert "controller.pd.kp[2]" in mc.runs.columns
    sw = quadrs.sweep(tiny, {"payload.mass": [0.2], "controller.pd.kp[02]": [3.0]}, runs=1,
                      progress=False)  # fmt: skip
    assert "controller.pd.kp[2]" in sw.runs.columns
    with pytest.raises(ScenarioError, match="same key"):
        quadrs.sweep(tiny, {"controller.pd.kp[2]": [1.0], "controller.pd.kp[002]": [2.0]}, runs=1)


def test_disperse_on_the_command_line_replaces_a_files_dispersion_of_the_same_key(
    tmp_path: Path, capsys
) -> None:
    src = tmp_path / "s.toml"
    src.write_text('base = "paper"\n[dispersions]\n"controller.pd.kp[2]" = '
                   '{dist = "uniform", low = 1.0, high = 2.0}\n')  # fmt: skip
    code, out, err = run_cli("scenario", "show", "--scenario", str(src), "--disperse",
                             "controller.pd.kp[02]=uniform(3,4)", capsys=capsys)  # fmt: skip
    assert code == 0, err
    assert Scenario.from_toml_string(out).dispersions == {
        "controller.pd.kp[2]": {"dist": "uniform", "low": 3, "high": 4}
    }


# -- a design-loop key is not also dispersed, nor given twice ---------------------------------
def test_tuned_or_swept_keys_cannot_be_dispersed_or_repeated(
    tiny: Scenario, tmp_path: Path, capsys, monkeypatch
) -> None:
    import importlib

    opt_module = importlib.import_module("quadrs.design.optimize")
    flown = []
    real = opt_module.monte_carlo
    monkeypatch.setattr(opt_module, "monte_carlo", lambda *a, **k: flown.append(1) or real(*a, **k))
    dispersed = tiny.override({"dispersions": {"payload.mass": MASS}})
    with pytest.raises(ScenarioError, match=r"payload\.mass is also dispersed"):
        quadrs.optimize(dispersed, "pd", {"payload.mass": (0.1, 0.3)}, phases=("P1",), runs=2)
    with pytest.raises(ScenarioError, match="same key"):
        quadrs.optimize(tiny, "pd", {"payload.mass,gust.w20": (0.1, 0.3),
                                     "gust.w20": (1, 2)}, phases=("P1",), runs=2)  # fmt: skip
    with pytest.raises(ScenarioError, match="also dispersed"):
        quadrs.sweep(dispersed, {"payload.mass": [0.2, 0.3]}, runs=1, progress=False)
    assert flown == []
    code, _, err = run_cli("sweep", *TINY_CLI, "--param", "payload.mass", "--values", "0.2,0.3",
                           "--disperse", "payload.mass=uniform(0.15,0.3)", "--runs", "1",
                           "--no-progress", capsys=capsys)  # fmt: skip
    assert code == 2 and "also dispersed" in one_line(err)
    code, _, err = run_cli("tune", *TINY_CLI, "--param", "payload.mass=0.1:0.3", "--disperse",
                           "payload.mass=uniform(0.15,0.3)", "--out", str(tmp_path / "t.toml"),
                           capsys=capsys)  # fmt: skip
    assert code == 2 and "also dispersed" in one_line(err)


# -- a saved result is bound to its contents --------------------------------------------------
def test_saved_results_are_bound_to_their_rows_spectra_and_metadata(
    tiny: Scenario, tmp_path: Path
) -> None:
    a = quadrs.monte_carlo(tiny, runs=6, seed=1, progress=False)
    b = quadrs.monte_carlo(tiny, runs=6, seed=2, progress=False)
    path = tmp_path / "a.parquet"

    def fresh() -> Path:
        a.to_parquet(path)
        return path

    assert not MonteCarloResult.read_parquet(fresh()).interrupted
    rewrite(fresh(), interrupted=True)
    with pytest.raises(CorruptRunError, match="not those it was written with"):
        MonteCarloResult.read_parquet(path)
    edited = a.runs.copy()
    edited.loc[0, "iae"] *= 2
    rewrite(fresh(), frame=edited)
    with pytest.raises(CorruptRunError, match="not those it was written with"):
        MonteCarloResult.read_parquet(path)
    spectra = json.loads(pq.read_schema(fresh()).metadata[b"quadrs"])["spectra"]
    rewrite(path, spectra=spectra | {"count": [5, 6]})
    with pytest.raises(CorruptRunError, match="not those it was written with"):
        MonteCarloResult.read_parquet(path)
    rewrite(fresh(), frame=b.runs)  # run A's metadata with run B's rows
    with pytest.raises(CorruptRunError, match="not those it was written with"):
        MonteCarloResult.read_parquet(path)
    # One result, one file: copied alone, it reads back whole.
    alone = tmp_path / "elsewhere" / "copy.parquet"
    alone.parent.mkdir()
    shutil.copy(fresh(), alone)
    assert sorted(p.name for p in tmp_path.rglob("*.parquet")) == ["a.parquet", "copy.parquet"]
    back = MonteCarloResult.read_parquet(alone)
    pd.testing.assert_frame_equal(back.spectra, a.spectra)
    pd.testing.assert_frame_equal(back.runs, a.runs)


def test_trace_and_sweep_files_are_bound_to_their_contents(tiny: Scenario, tmp_path: Path):
    flight = quadrs.simulate(tiny, "pd", seed=1)
    path = tmp_path / "trace.parquet"
    columns = list(METRIC_COLUMNS)
    for change in ({"metrics": (flight.metrics[columns] * 0).to_numpy()
                    .tolist()}, {"diverged_at": 1.0}):  # fmt: skip
        flight.to_parquet(path)
        rewrite(path, **change)
        with pytest.raises(CorruptRunError, match="not those it was written with"):
            quadrs.Flight.read_parquet(path)
    from quadrs.runs.sweep import SweepResult

    sw = quadrs.sweep(tiny, {"gust.w20": [5.0]}, runs=2, progress=False)
    sw.to_parquet(path)
    rewrite(path, interrupted=True)
    with pytest.raises(CorruptRunError, match="not those it was written with"):
        SweepResult.read_parquet(path)


def test_a_file_without_a_content_digest_is_refused_clearly(tiny: Scenario, tmp_path: Path):
    """Files of the previous format (no digest) cannot be told from edited ones."""
    a = quadrs.monte_carlo(tiny, runs=2, seed=1, progress=False, spectra=False)
    path = tmp_path / "old.parquet"
    table = pa.Table.from_pandas(a.runs, preserve_index=False)
    meta = a.record.metadata(interrupted=False, spectra=None)
    pq.write_table(table.replace_schema_metadata({b"quadrs": json.dumps(meta).encode()}), path)
    with pytest.raises(CorruptRunError, match=r"no content digest .* run it again"):
        MonteCarloResult.read_parquet(path)


# -- linearize never returns non-finite matrices ----------------------------------------------
def test_linearize_refuses_a_wind_it_cannot_linearise_about(paper: Scenario, capsys) -> None:
    with pytest.raises(ValueError, match=r"wind = \[0.0, 0.0, 1e\+200\].*no finite"):
        quadrs.linearize(paper, "smc", wind=(0.0, 0.0, 1e200))
    lin = quadrs.linearize(paper, "smc", wind=(0.0, 0.0, 1.0))
    assert all(np.all(np.isfinite(getattr(lin, m))) for m in "ABCD")
    code, _, err = run_cli("linearize", "--wind", "1e200", capsys=capsys)
    assert code == 2 and "no finite linearisation" in one_line(err)


# -- a dispersed realisation flown alone is the batch's row, bit for bit ----------------------
def test_numbers_reach_the_engine_correctly_rounded(paper: Scenario) -> None:
    """A value handed over as JSON text is the float it was: 2,000 random ones, 17 digits and
    wide exponents included."""
    from quadrs import _core

    rng = np.random.default_rng(0)
    data = paper.override({"payload.stiffness": 30.0}).to_dict()
    values = np.concatenate([rng.uniform(10, 60, 1000), 10 ** rng.uniform(-3, 6, 1000)])
    off = 0
    for v in values:
        data["payload"]["stiffness"] = float(v)
        off += _core.describe(json.dumps(data))["stiffness"] != v
    assert off == 0, f"{off} of {len(values)} values parsed off by an ulp or more"


def test_single_flight_of_a_dispersed_realisation_equals_its_batch_row(tiny: Scenario) -> None:
    """Values reach the engine as text for a single flight and as floats for a batch: the text
    must parse to the very same floats (correctly rounded parsing)."""
    dispersed = tiny.override({"dispersions": {
        "payload.mass": MASS,
        "vehicle.mass": {"dist": "normal", "mean": 1.2, "std": 0.01},
        "controller.pd.kp[2]": {"dist": "uniform", "low": 4.0, "high": 8.0},
    }})  # fmt: skip
    runs = 48
    mc = quadrs.monte_carlo(dispersed, runs=runs, seed=7, controllers=["pd"], progress=False)
    metrics = list(METRIC_COLUMNS)
    for i in range(runs):
        alone = quadrs.simulate(dispersed, "pd", seed=7, realisation=i)
        row = mc.runs[mc.runs["realisation"] == i][metrics].to_numpy()
        np.testing.assert_array_equal(alone.metrics[metrics].to_numpy(), row, err_msg=f"row {i}")


# -- a second Ctrl-C never loses the batch ----------------------------------------------------
def _read_until(master: int, pattern: bytes, seen: bytes = b"") -> bytes:
    """What the pseudo-terminal ``master`` shows until ``pattern`` (a regex) appears in it."""
    while re.search(pattern, seen) is None:
        ready, _, _ = select.select([master], [], [], 120)
        assert ready, f"no {pattern!r} within 120 s: {seen[-500:]!r}"
        chunk = os.read(master, 4096)
        assert chunk, seen
        seen += chunk
    return seen


def _read_rest(master: int, seen: bytes, proc: subprocess.Popen, timeout: float) -> bytes:
    """The rest of what the terminal shows, read while ``proc`` runs (so that its writes
    never block on a full terminal) and after it exits."""
    deadline = time.monotonic() + timeout
    while True:
        running = proc.poll() is None
        assert time.monotonic() < deadline, f"still running after {timeout} s: {seen[-500:]!r}"
        if select.select([master], [], [], 0.2)[0]:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # the terminal closed with the process
                chunk = b""
            seen += chunk
            if chunk or running:
                continue
        if not running:
            return seen


@pytest.mark.parametrize("delay", [0.0, 0.003, 0.007, 0.015, 0.05])
def test_a_second_ctrl_c_soon_after_the_first_keeps_the_batch(tmp_path: Path, delay: float):
    """The first Ctrl-C lands once the progress bar has counted a finished realisation (well
    into the batch, however loaded the machine), the second ``delay`` seconds after it, while
    the engine is being cancelled or the finished rows are assembled. stderr is a
    pseudo-terminal, so the progress bar is drawn."""
    out = tmp_path / "runs.parquet"
    master, terminal = pty.openpty()
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    proc = subprocess.Popen(
        [sys.executable, "-m", "quadrs.cli", "mc", "--runs", "200000", "--workers", "1",
         "--controllers", "pd", *TINY_CLI, "--out", str(out)],
        stdout=subprocess.DEVNULL, stderr=terminal,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    os.close(terminal)
    try:
        seen = _read_until(master, rb"quadrs mc.*\| *[1-9][0-9]*/200000")
        proc.send_signal(signal.SIGINT)
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        err = _read_rest(master, seen, proc, timeout=120).decode(errors="replace")
    finally:
        proc.kill()
        os.close(master)
    assert proc.returncode == 130, err
    assert "Traceback" not in err and "IndexError" not in err, err
    saved = MonteCarloResult.read_parquet(out)
    assert saved.interrupted and len(saved.realisations) > 0


def test_a_ctrl_c_while_the_batch_is_saved_keeps_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A Ctrl-C that lands after the batch is over (a second one, after the one that stopped
    it) but before its file is written waits for the file: written whole, then status 130."""
    write = MonteCarloResult.to_parquet

    def interrupted_while_saving(self: MonteCarloResult, path: Path) -> None:
        signal.raise_signal(signal.SIGINT)
        write(self, path)

    monkeypatch.setattr(MonteCarloResult, "to_parquet", interrupted_while_saving)
    out = tmp_path / "runs.parquet"
    code, _, err = run_cli("mc", "--runs", "4", "--workers", "1", "--controllers", "pd",
                           "--no-progress", *TINY_CLI, "--out", str(out),
                           capsys=capsys)  # fmt: skip
    assert code == 130 and "interrupted" in err, err
    assert len(MonteCarloResult.read_parquet(out).realisations) == 4
    # and the mission command alike (its batch, then its file with the saved question)
    mission_out = tmp_path / "mission.parquet"
    code, _, err = run_cli("mission", "--preset", "paper", "--runs", "4", "--workers", "1",
                           "--no-progress", *TINY_CLI, "--out", str(mission_out),
                           capsys=capsys)  # fmt: skip
    assert code == 130, err
    kept = MonteCarloResult.read_parquet(mission_out)
    assert len(kept.realisations) == 4 and kept.question is not None


#: Each batch command that saves a result: (its result's class, its arguments after
#: TINY_CLI, how to tell that what it saved holds the result).
SAVING_COMMANDS = {
    "sweep": ("SweepResult",
              ["--param", "payload.mass", "--values", "0.2,0.3", "--runs", "2"],
              lambda r: len(r.runs) > 0),
    "sensitivity": ("SensitivityResult",
                    ["--disperse", "payload.mass=uniform(0.15,0.3)", "--runs", "2"],
                    lambda r: len(r.indices) > 0),
    "rare": ("RareEventResult",
             ["--metric", "max_accel", "--phase", "P2", "--threshold", "1e3", "--per-level",
              "100", "--max-levels", "2"],
             lambda r: r.flights > 0),
}  # fmt: skip


@pytest.mark.parametrize("command", sorted(SAVING_COMMANDS))
def test_a_ctrl_c_after_any_batch_waits_for_its_file(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """As `mc` and `mission` (above): a Ctrl-C after the batch is over but before its file is
    written waits for the file, written whole, then status 130."""
    name, args, holds = SAVING_COMMANDS[command]
    cls = getattr(quadrs, name)
    write = cls.to_parquet

    def interrupted_while_saving(self, path: Path) -> None:
        signal.raise_signal(signal.SIGINT)
        write(self, path)

    monkeypatch.setattr(cls, "to_parquet", interrupted_while_saving)
    out = tmp_path / f"{command}.parquet"
    code, _, err = run_cli(command, *TINY_CLI, *args, "--workers", "1", "--no-progress",
                           "--out", str(out), capsys=capsys)  # fmt: skip
    assert code == 130, err
    assert holds(cls.read_parquet(out))


def test_a_ctrl_c_after_the_search_waits_for_the_tuned_files(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """tune alike: a Ctrl-C as its history is written waits for it and for the tuned file."""
    import quadrs.io.files as files

    write = files.atomic_write_frame

    def interrupted_while_saving(*a, **k) -> None:
        signal.raise_signal(signal.SIGINT)
        write(*a, **k)

    monkeypatch.setattr(files, "atomic_write_frame", interrupted_while_saving)
    out, history = tmp_path / "tuned.toml", tmp_path / "history.csv"
    code, _, err = run_cli("tune", *TINY_CLI, "--controller", "pd", "--param",
                           "controller.pd.kp[2]=1:2", "--runs",
                           "2", "--maxiter", "1", "--popsize", "2", "--workers", "1",
                           "--out", str(out), "--history", str(history),
                           capsys=capsys)  # fmt: skip
    assert code == 130, err
    assert 1.0 <= Scenario.from_toml(out)["controller.pd.kp"][2] <= 2.0
    assert len(pd.read_csv(history)) > 0


# -- no traceback, one line -------------------------------------------------------------------
def test_design_loop_bad_input_is_one_line(tiny: Scenario, tmp_path: Path, capsys) -> None:
    disperse = ["--disperse", "payload.mass=uniform(0.15,0.3)", "--runs", "2", "--no-progress"]
    for seed in (str(2**64), "-1"):
        code, _, err = run_cli("sensitivity", *TINY_CLI, *disperse, "--seed", seed,
                               capsys=capsys)  # fmt: skip
        assert code == 2 and "--seed" in one_line(err), err
    code, _, err = run_cli("sensitivity", *TINY_CLI, *disperse, "--workers", "1000000",
                           capsys=capsys)  # fmt: skip
    assert code == 2 and "--workers" in one_line(err) and "spectrum" not in err
    deep = "[" * 5000 + "]" * 5000
    code, _, err = run_cli("run", "--set", f"gust.w20={deep}", capsys=capsys)
    assert code == 2 and "nested" in one_line(err)
    loop = tmp_path / "loop.toml"
    loop.symlink_to(loop)
    (tmp_path / "s.toml").write_text(f'base = "{loop.name}"\n')
    code, _, err = run_cli("run", "--scenario", str(tmp_path / "s.toml"), capsys=capsys)
    assert code == 2 and "loop.toml" in one_line(err)


def test_report_on_odd_saved_files_is_one_line_or_a_summary(
    tiny: Scenario, tmp_path: Path, capsys
) -> None:
    from quadrs.io.parquet import write_frame

    mc = quadrs.monte_carlo(tiny, runs=2, seed=1, progress=False, spectra=False)
    nested = tmp_path / "nested.parquet"
    table = pa.Table.from_pandas(mc.runs, preserve_index=False)
    deep = ("[" * 100_000 + "]" * 100_000).encode()
    pq.write_table(table.replace_schema_metadata({b"quadrs": deep}), nested)
    code, _, err = run_cli("report", str(nested), capsys=capsys)
    assert code == 2 and "nested" in one_line(err)
    # a checkpoint killed before its first chunk: a manifest, no part
    empty = tmp_path / "empty"
    RunStore(empty).create(checkpoint_record(tiny, 1, ("pd", "smc")))
    code, out, err = run_cli("report", str(empty), capsys=capsys)
    assert code == 0 and "0 realisations" in out and "Traceback" not in err
    # a (sealed) file with zero rows, and one lacking a metric column
    zero = tmp_path / "zero.parquet"
    write_frame(mc.runs.iloc[:0], zero, b"quadrs", mc.record.metadata(interrupted=True))
    code, out, err = run_cli("report", str(zero), capsys=capsys)
    assert code == 0 and "0 realisations" in out and "Traceback" not in err
    lacking = tmp_path / "lacking.parquet"
    write_frame(mc.runs.drop(columns=["iae"]), lacking, b"quadrs",
                mc.record.metadata(interrupted=False))  # fmt: skip
    code, _, err = run_cli("report", str(lacking), capsys=capsys)
    assert code == 2 and "iae" in one_line(err)


def test_repr_of_a_sensitivity_result_without_any_index(tiny: Scenario) -> None:
    from quadrs.design.sensitivity import INDEX_COLUMNS, SensitivityResult

    rows = pd.DataFrame([["pd", "P1", "iae", "payload.mass"] + [np.nan] * 4], columns=INDEX_COLUMNS)
    sa = SensitivityResult(tiny, 0, 4, ("payload.mass",), rows, pd.DataFrame())
    assert "1 parameters" in repr(sa)


# -- nothing is read without bound ------------------------------------------------------------
def test_devices_and_fifos_are_refused_not_read(tiny: Scenario, tmp_path: Path, capsys) -> None:
    zero = tmp_path / "zero.parquet"
    zero.symlink_to("/dev/zero")
    fifo = tmp_path / "fifo.parquet"
    os.mkfifo(fifo)
    run = tmp_path / "run"
    quadrs.monte_carlo(tiny, runs=2, seed=1, progress=False, out=run)
    manifest = run / "_quadrs.json"
    manifest.unlink()
    manifest.symlink_to("/dev/zero")
    results: list[tuple[int, str]] = []

    def report(path: Path) -> None:
        code, _, err = run_cli("report", str(path), capsys=capsys)
        results.append((code, err))

    for path in (zero, fifo, run):
        worker = threading.Thread(target=report, args=(path,), daemon=True)
        worker.start()
        worker.join(timeout=20)
        assert not worker.is_alive(), f"reading {path} did not return"
    for code, err in results:
        assert code == 2 and "not a regular file" in one_line(err)


# -- work is not lost to an output that fails -------------------------------------------------
def test_bad_outputs_of_design_commands_are_refused_before_flying(tmp_path: Path, capsys):
    folder = tmp_path / "dir.parquet"
    folder.mkdir()
    dispersed = [*TINY_CLI, "--disperse", "payload.mass=uniform(0.15,0.3)", "--no-progress"]
    start = time.monotonic()
    code, out, err = run_cli("sensitivity", *dispersed, "--runs", "4096", "--out", str(folder),
                             capsys=capsys)  # fmt: skip
    assert code == 2 and "is a directory" in one_line(err) and out == ""
    tune = ["tune", *TINY_CLI, "--param", "payload.mass=0.1:0.3", "--phase", "P1", "--runs",
            "512", "--maxiter", "50"]  # fmt: skip
    folder_toml = tmp_path / "f.toml"
    folder_toml.mkdir()
    code, out, err = run_cli(*tune, "--out", str(folder_toml), capsys=capsys)
    assert code == 2 and "is a directory" in one_line(err) and out == ""
    code, out, err = run_cli(*tune, "--out", str(tmp_path / "t.toml"), "--history", str(folder),
                             capsys=capsys)  # fmt: skip
    assert code == 2 and "is a directory" in one_line(err) and out == ""
    assert time.monotonic() - start < 30, "refused only after the flights"


def test_sensitivity_on_a_full_disk_keeps_a_recovery_copy(tmp_path: Path, monkeypatch, capsys):
    import errno

    from quadrs.design.sensitivity import SensitivityResult

    target = tmp_path / "sa.parquet"
    real = SensitivityResult.to_parquet

    def full(self, path):
        if Path(path) == target:
            raise OSError(errno.ENOSPC, "No space left on device", str(path))
        real(self, path)

    monkeypatch.setattr(SensitivityResult, "to_parquet", full)
    code, out, err = run_cli("sensitivity", *TINY_CLI, "--disperse",
                             "payload.mass=uniform(0.15,0.3)", "--runs", "4", "--no-progress",
                             "--out", str(target), capsys=capsys)  # fmt: skip
    assert code == 1 and "Sobol" in out
    spare = Path(err.split("saved to ")[1].split(" instead")[0])
    assert SensitivityResult.read_parquet(spare).parameters[0] == "payload.mass"


@pytest.mark.parametrize(
    ("setup", "param", "seed"),
    [
        ("", "phases[1].end=1.5:1.9", "0"),  # a phase key (inside an array of tables)
        # --set payload.stiffness over a base that gives natural_frequency
        ("[payload]\nnatural_frequency = 2.0\n", "payload.mass=0.1:0.3", "0"),
        ("", "payload.mass=0.1:0.3", str(2**64 - 1)),  # the held-out seed wraps
        ("txt", "payload.mass=0.1:0.3", "0"),  # a scenario file not ending in .toml
    ],
)
def test_tune_writes_a_readable_file_whatever_it_tuned(
    tmp_path: Path, capsys, setup: str, param: str, seed: str
) -> None:
    src = tmp_path / ("start.txt" if setup == "txt" else "start.toml")
    src.write_text('base = "paper"\n' + ("" if setup == "txt" else setup))
    out = tmp_path / "tuned.toml"
    stiff = ["--set", "payload.stiffness=30"] if "natural" in setup else []
    code, stdout, err = run_cli("tune", "--scenario", str(src), *TINY_CLI, *stiff, "--param", param,
                                "--controller", "pd", "--phase", "P1", "--runs", "2",
                                "--maxiter", "1", "--popsize", "2", "--seed", seed,
                                "--method", "nelder-mead", "--out", str(out),
                                capsys=capsys)  # fmt: skip
    assert code == 0, err
    tuned = Scenario.from_toml(out)
    key, _, _ = param.partition("=")
    value = float(stdout.split(f"{key} = ")[1].split()[0])
    assert tuned[key] == pytest.approx(value, rel=1e-5)


# -- files are written through the one atomic writer ------------------------------------------
def test_linearize_out_never_follows_a_planted_symlink(tmp_path: Path, capsys) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("keep me")
    out = tmp_path / "lin.npz"
    out.symlink_to(victim)
    code, _, err = run_cli("linearize", "--controller", "pd", "--out", str(out), capsys=capsys)
    assert code == 0, err
    assert victim.read_text() == "keep me" and not out.is_symlink()
    assert set(np.load(out)) == {"pd_A", "pd_B", "pd_C", "pd_D"}
    code, _, err = run_cli("linearize", "--controller", "pd", "--out", str(tmp_path / "m"),
                           capsys=capsys)  # fmt: skip
    assert code == 0 and f"wrote {tmp_path / 'm.npz'}" in err
    assert (tmp_path / "m.npz").is_file() and not (tmp_path / "m").exists()


# -- scenario strings cannot drive the terminal -----------------------------------------------
def test_control_characters_in_scenario_strings_are_escaped(tmp_path: Path, capsys) -> None:
    evil = tmp_path / "evil.toml"
    evil.write_text(
        'base = "paper"\n[integrator]\nduration = 2.0\ndt = 0.01\n'
        '[[phases]]\nname = "P\\u001b]0;owned\\u0007\\u001b[2J"\nstart = 0.0\nend = 2.0\n'
    )
    code, out, err = run_cli("run", "--scenario", str(evil), "--controller", "pd", capsys=capsys)
    assert code == 0, err
    assert "\x1b" not in out + err and "\x07" not in out + err
    assert "\\x1b]0;owned" in out
    code, out, err = run_cli("tune", "--scenario", str(evil), "--param", "payload.mass=0.1:0.3",
                             "--controller", "pd", "--runs", "1", "--maxiter", "1", "--method",
                             "nelder-mead", "--out", str(tmp_path / "t.toml"),
                             capsys=capsys)  # fmt: skip
    assert code == 0 and "\x1b" not in out + err, err
    code, _, err = run_cli("run", "--set", "gust.w20\x1b[2J=3", capsys=capsys)
    assert code == 2 and "\x1b" not in err and "\\x1b" in one_line(err)


# -- figures: one without data does not cost the others ---------------------------------------
def test_mc_plots_of_an_all_diverged_batch_draw_what_they_can(tmp_path: Path, capsys) -> None:
    code, _, err = run_cli("mc", *TINY_CLI, "--runs", "4", "--no-progress", "--controllers",
                           "pd", "--set", "divergence.max_speed=0.01", "--plots",
                           str(tmp_path), capsys=capsys)  # fmt: skip
    assert code == 0, err
    assert (tmp_path / "exceedance_max_accel.png").is_file(), err
    assert "Traceback" not in err and "error" not in err


def test_tune_of_a_dispersed_scenario_writes_its_dispersions(tmp_path: Path, capsys) -> None:
    out = tmp_path / "tuned.toml"
    code, _, err = run_cli("tune", *TINY_CLI, "--disperse", "payload.mass=uniform(0.15,0.3)",
                           "--param", "controller.pd.kp[2]=4:8", "--controller", "pd", "--phase",
                           "P1", "--runs", "2", "--maxiter", "1", "--popsize", "2", "--method",
                           "nelder-mead", "--out", str(out), capsys=capsys)  # fmt: skip
    assert code == 0, err
    assert list(Scenario.from_toml(out).dispersions) == ["payload.mass"]
