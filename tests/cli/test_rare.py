"""``quadrs rare`` end to end: in a subprocess for what only a real process shows (exit status,
stderr, a real Ctrl-C), in process for bad input. The scenario is the short one of
tests/cli/test_main.py (1000 innovations a flight)."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import signal
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

import quadrs
from quadrs.cli.main import main
from quadrs.rare import RareEventResult
from quadrs.rare.scenario_model import ScenarioModel
from tests.cli.test_main import SHORT, one_error_line, run_cli

RARE = ["rare", *SHORT, "--metric", "max_accel", "--phase", "P2"]


def test_rare_prints_its_table_and_writes_the_result(tmp_path: Path) -> None:
    out = tmp_path / "rare.parquet"
    proc = run_cli(*RARE, "--threshold", "3.5", "--per-level", "100", "--seed", "2",
                   "--workers", "1", "--out", str(out))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    # stderr is no terminal: no progress lines, only where the file went (after the
    # announcement of what the run costs, which a loaded machine's calibration may print).
    lines = proc.stderr.strip().splitlines()
    assert lines[-1] == f"wrote {out}"
    assert all(line.startswith("quadrs rare: ") for line in lines[:-1]), lines
    r = RareEventResult.read_parquet(out)
    assert r.probability is not None and r.cov is not None and r.interval is not None
    model = r.model
    assert isinstance(model, ScenarioModel)
    assert (model.controller, model.metric, model.phase) == ("pd", "max_accel", "P2")
    assert (r.seed, r.threshold, r.run.per_level, r.run.p0) == (2, 3.5, 100, 0.1)
    # "  label   value" rows: the label and the value are two or more spaces apart.
    rows = dict(line.strip().split("  ", 1) for line in proc.stdout.splitlines()[1:])
    rows = {label: value.strip() for label, value in rows.items()}
    assert proc.stdout.startswith("P(max_accel in P2 > 3.5 m/s²), pd, seed 2, 1000 innovations")
    assert rows["estimate"] == f"{r.probability:.3g}"
    assert rows["coefficient of variation"] == f"{r.cov:.3f}"
    assert rows["95 % interval"] == f"[{r.interval[0]:.3g}, {r.interval[1]:.3g}]"
    assert rows["levels"] == str(len(r.levels)) and rows["flights"] == str(r.flights)
    need = (1 - r.probability) / (r.probability * r.cov**2)
    assert rows["Monte Carlo flights, same CoV"].startswith(f"{need:.3g} (")


def test_paired_controllers_print_both_and_their_ratio(tmp_path: Path) -> None:
    """--controller pd,smc: the same gusts for both, a table each, the ratio with its
    interval, and one file per controller beside --out."""
    out = tmp_path / "rare.parquet"
    proc = run_cli(*RARE, "--threshold", "3.5", "--per-level", "100", "--seed", "2",
                   "--workers", "1", "--controller", "pd,smc", "--out", str(out))  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    results = {c: RareEventResult.read_parquet(tmp_path / f"rare-{c}.parquet")
               for c in ("pd", "smc")}  # fmt: skip
    assert not out.exists()
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("P(max_accel in P2 > 3.5 m/s²), pd, seed 2, 1000 innovations")
    heads = [line for line in lines if line.startswith("P(")]
    assert [h.split(", ")[1] for h in heads] == ["pd", "smc"]
    pd_, smc = results["pd"], results["smc"]
    assert pd_.probability is not None and smc.probability is not None
    # Level 0 flew the same gusts: the same innovations in any failure both found there.
    assert pd_.levels["flights"].iloc[0] == smc.levels["flights"].iloc[0] == 100
    ratio = [line for line in lines if line.startswith("ratio smc / pd: ")]
    assert len(ratio) == 1 and f"{smc.probability / pd_.probability:.3g}" in ratio[0]
    assert "95 % [" in ratio[0] and "first-level correlation" in ratio[0]


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (["--threshold", "nan"], ["--threshold", "'nan'"]),
        (["--threshold", "3", "--p0", "0.3"], ["--p0", "0.3"]),
        (["--threshold", "3", "--per-level", "105"], ["--per-level", "105"]),
        (["--threshold", "3", "--per-level", "50"], ["--per-level", "50"]),
        (["--threshold", "3", "--max-levels", "0"], ["--max-levels", "0"]),
        (["--threshold", "3", "--seed", "-1"], ["--seed", "-1"]),
        (["--threshold", "3", "--workers", "0"], ["--workers", "0"]),
        (["--threshold", "3", "--out", "r.csv"], ["--out", "r.csv"]),
        (["--threshold", "3", "--phase", "P9"], ["--phase", "P9"]),
        (["--threshold", "3", "--metric", "accel"], ["--metric", "accel"]),
        (["--threshold", "3", "--controller", "lqr"], ["--controller", "lqr"]),
        (["--threshold", "3", "--set", "gust.enabled=false"], ["gust.enabled"]),
        (["--threshold", "3", "--controller", "pd,pd"], ["--controller", "pd,pd"]),
        (["--threshold", "3", "--workers", "1", "--scheduler", "tcp://x:1"], ["--scheduler"]),
        (["--threshold", "3", "--set", "integrator.dt=-1"], ["integrator.dt", "-1"]),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    args: list[str], needles: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*RARE, *args]) == 2
    captured = capsys.readouterr()
    one_error_line(captured.err, "quadrs rare", *needles)
    assert captured.out == ""


def test_a_missing_required_option_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["rare", *SHORT, "--metric", "max_accel", "--phase", "P2"]) == 2
    one_error_line(capsys.readouterr().err, "--threshold")


def test_real_sigint_keeps_the_levels_done(tmp_path: Path) -> None:
    """A real Ctrl-C after the first level: exit 130, one line saying how far it got, and
    the finished levels saved. stderr is a pseudo-terminal, so the level lines are drawn."""
    out = tmp_path / "cut.parquet"
    master, terminal = pty.openpty()
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    # A threshold no flight reaches in a few levels, and levels long enough (1000 flights)
    # that a fast build cannot finish them all before the signal lands: stopped mid-way.
    command = [sys.executable, "-m", "quadrs.cli", *RARE, "--threshold", "40",
               "--per-level", "1000", "--workers", "1", "--out", str(out)]  # fmt: skip
    # The child starts with Ctrl-C at its default, as from a terminal: a test process whose
    # SIGINT is ignored (something imported during collection sets that) would pass SIG_IGN on.
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=terminal,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    os.close(terminal)
    seen = b""
    try:
        while b"level 0 done" not in seen:
            ready, _, _ = select.select([master], [], [], 60)
            assert ready, f"no level line within 60 s: {seen!r}"
            chunk = os.read(master, 4096)
            assert chunk, seen
            seen += chunk
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
        while True:  # the rest of stderr
            ready, _, _ = select.select([master], [], [], 1)
            if not ready:
                break
            try:
                chunk = os.read(master, 4096)
            except OSError:  # the terminal closed with the process
                break
            if not chunk:
                break
            seen += chunk
    finally:
        proc.kill()
        os.close(master)
    assert proc.returncode == 130, seen
    text = seen.decode()
    assert re.search(r"quadrs rare: interrupted after [1-9]\d* finished levels? \(\d+ flights\)",
                     text), text  # fmt: skip
    assert "Traceback" not in text
    r = RareEventResult.read_parquet(out)
    assert r.interrupted and len(r.levels) >= 1 and r.probability is None
    assert r.upper_bound is not None and 0 < r.upper_bound <= 0.1 ** (len(r.levels) - 1)


@pytest.fixture
def no_calibration(monkeypatch: pytest.MonkeyPatch) -> None:
    """quadrs rare's announcement flies 20 calibration flights: not needed here."""
    import quadrs.cli.rare as cr

    monkeypatch.setattr(cr, "_announce", lambda *a: float("nan"))


def test_rare_writes_a_safety_case_page_with_its_mode_rate_bound_and_verdict(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], no_calibration: None
) -> None:
    """--safety-case from quadrs rare: the page names the mode (the parcel over its limit,
    the metric's exceedance), the rate per flight hour and its one-sided 95 % bound as the
    table printed them, and the target's verdict."""
    page, saved = tmp_path / "case.md", tmp_path / "rare.parquet"
    code = main([*RARE, "--threshold", "3.5", "--per-level", "100", "--seed", "2", "--workers",
                 "1", "--target", "parcel=1", "--safety-case", str(page), "--out",
                 str(saved)])  # fmt: skip
    assert code == 0
    out = capsys.readouterr().out
    rows = {ln[2:36].strip(): ln[37:] for ln in out.splitlines() if ln.startswith("  ")}
    rate = rows["per flight hour [95 % interval]"].split(" [")[0]
    bound = rows["upper bound per flight hour"].split(" (")[0]
    assert rows["upper bound per flight hour"].endswith("(one-sided 95 %, Garwood (Poisson))")
    assert "parcel <= 1 per flight hour: NOT MET" in out
    text = page.read_text()
    assert text.startswith("# Safety case summary: PD")
    modes = text.split("## Failure modes", 1)[1].split("##", 1)[0]
    row = next(ln for ln in modes.splitlines() if ln.startswith("| Parcel over its limit"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[0] == "Parcel over its limit (max_accel in P2 > 3.5 m/s², or diverged)"
    assert cells[3].split(" [")[0] == rate and cells[4] == bound
    assert f"| parcel | 1 | not met | {bound} |" in text
    assert "plain Monte Carlo (level 0 of subset simulation reached the threshold)" in text
    assert "| seed | 2 |" in text
    # quadrs report rebuilds the page from the saved result, the target given again.
    again = tmp_path / "again.md"
    assert main(["report", str(saved), "--safety-case", str(again), "--target", "parcel=1"]) == 0
    assert again.read_text() == text
    assert "parcel <= 1 per flight hour: NOT MET" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--target", "containment=1e-4"], "--target containment: quadrs rare --metric "
                                           "max_accel estimates the parcel mode only"),
        (["--metric", "touchdown_miss", "--safety-case", "case.md"],
         "--safety-case: an exceedance of touchdown_miss is none of the failure modes"),
    ],
)  # fmt: skip
def test_rare_refuses_a_target_of_another_mode_before_flying(
    args: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    no_calibration: None,
) -> None:  # fmt: skip
    args = [str(tmp_path / a) if a.endswith(".md") else a for a in args]
    assert main([*RARE, "--threshold", "3.5", *args]) == 2
    assert words in one_error_line(capsys.readouterr().err)


def test_rare_announces_its_memory_and_the_delivery_fits_four_gib(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before: the announcement gave the time only. The delivery preset at the default 1,000
    flights a level holds about 2 GiB (105,500 innovations a flight: its turbulence at 100 Hz);
    at every step of 1 ms it held 19 GiB."""
    import argparse

    import quadrs.cli.rare as cr
    from quadrs.cli.cost import Calibration
    from quadrs.rare.scenario_model import ScenarioModel
    from quadrs.rare.subset import subset_memory

    monkeypatch.setattr(cr, "calibrate_rare", lambda *a: Calibration(20, 20.0, 2))
    delivery = quadrs.Scenario.preset("delivery")
    args = argparse.Namespace(per_level=1000, metric="touchdown_speed", phase="lower")
    cr._announce(delivery, args, ("pd",), 0.1, 4)
    said = capsys.readouterr().err
    dimension = ScenarioModel(delivery, "pd", "touchdown_speed", "lower").dimension
    nbytes = subset_memory(dimension, 1000, 0.1)
    assert f"and about {nbytes / 2**30:.2g} GiB of memory;" in said, said
    assert nbytes < 4 * 2**30
    every_step = delivery.override({"gust.rate": 0.0})
    dense = ScenarioModel(every_step, "pd", "touchdown_speed", "lower").dimension
    assert subset_memory(dense, 1000, 0.1) > 4 * 2**30
