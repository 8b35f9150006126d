"""``--scheduler`` is bounded (docs/guarantees.md): an address that accepts and never answers,
or answers in another protocol, is one line and exit 2 within the connect timeout, for every
command that takes it; a Ctrl-C just after the save with a scheduler is exit 130, no
traceback."""

from __future__ import annotations

import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.guarantees.test_design_loop_and_files import TINY_CLI, one_line, run_cli

pytest.importorskip("dask.distributed")

#: Each command with --scheduler and the arguments that make it fly a tiny batch.
COMMANDS = {
    "mc": ["--runs", "2"],
    "rare": ["--metric", "max_accel", "--phase", "P2", "--threshold", "1e3", "--per-level",
             "100", "--max-levels", "2"],
    "mission": ["--runs", "2", "--preset", "paper"],
    "sweep": ["--param", "payload.mass", "--values", "0.2,0.3", "--runs", "2"],
    "sensitivity": ["--disperse", "payload.mass=uniform(0.15,0.3)", "--runs", "2"],
    "tune": ["--controller", "pd", "--param", "controller.pd.kp[2]=1:2", "--runs", "2",
             "--maxiter", "1", "--popsize", "2"],
}  # fmt: skip


def _server(answer: bytes | None) -> Iterator[str]:
    """A TCP server on 127.0.0.1 that accepts every connection and never answers (``answer``
    None) or answers once with ``answer``; yields its address."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(16)
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            held.append(conn)
            if answer is not None:
                conn.settimeout(1.0)
                try:
                    conn.recv(4096)
                    conn.sendall(answer)
                except OSError:
                    pass

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    finally:
        stop.set()
        thread.join(2)
        for conn in held:
            conn.close()
        server.close()


@pytest.fixture
def silent() -> Iterator[str]:
    yield from _server(None)


@pytest.fixture
def http() -> Iterator[str]:
    yield from _server(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_scheduler_that_never_answers_times_out_in_one_line(
    command: str, silent: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """Before: the command hung (Dask's timeout covers the TCP connect, not its handshake)."""
    import quadrs.cli.common as common

    monkeypatch.setattr(common, "CONNECT_TIMEOUT", 1.0)
    tune = command == "tune"  # tune writes a scenario and draws no progress bar
    out = ["--out", str(tmp_path / "tuned.toml")] if tune else ["--no-progress"]
    workers = [] if command == "rare" else ["--workers", "1"]  # rare: one or the other
    start = time.monotonic()
    code, _, err = run_cli(command, *TINY_CLI, *COMMANDS[command], *out, *workers,
                           "--scheduler", silent, capsys=capsys)  # fmt: skip
    assert code == 2, err
    assert time.monotonic() - start < 30
    assert f"--scheduler {silent}: no answer within 1 s" in one_line(err)


def test_a_scheduler_address_that_speaks_http_says_so(http: str, capsys) -> None:
    """Before: "Unable to allocate 3.07 EiB" (Dask read the HTTP answer as a frame length)."""
    code, _, err = run_cli("mc", *TINY_CLI, "--runs", "1", "--no-progress", "--scheduler",
                           http, capsys=capsys)  # fmt: skip
    assert code == 2, err
    line = one_line(err)
    assert "not a Dask scheduler" in line and "EiB" not in line


def test_a_ctrl_c_as_the_process_exits_after_a_cluster_run_is_130(tmp_path: Path) -> None:
    """Before: a Ctrl-C just after the save, while Dask closed at the process's exit, printed
    a KeyboardInterrupt traceback and the process exited 0. The console command (main() with
    the process's own arguments) against an in-process cluster; an exit handler registered
    after the command's raises SIGINT as Dask's close would meet it."""
    import subprocess
    import sys

    out = tmp_path / "runs.parquet"
    code = f"""
import atexit, signal, sys
from dask.distributed import LocalCluster
cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                       dashboard_address=None)
sys.argv = ["quadrs", "mc", *{TINY_CLI!r}, "--runs", "2", "--workers", "1", "--no-progress",
            "--scheduler", cluster.scheduler_address, "--out", {str(out)!r}]
from quadrs.cli.main import main
status = main()
atexit.register(lambda: signal.raise_signal(signal.SIGINT))  # a Ctrl-C at exit
sys.exit(status)
"""
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)  # fmt: skip
    assert out.is_file(), run.stderr
    assert "Traceback" not in run.stderr, run.stderr
    assert run.returncode == 130, run.stderr
