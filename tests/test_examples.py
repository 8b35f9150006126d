"""The scripts in examples/ run as a user would run them, with small arguments."""

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


@pytest.mark.parametrize(
    ("script", "args", "expect"),
    [
        ("one_flight.py", ["{tmp}"], "figures in"),
        ("monte_carlo.py", ["3"], "P = SMC/PD %"),
        ("sweep.py", ["2"], "payload.natural_frequency"),
    ],
)
def test_example_runs(script: str, args: list[str], expect: str, tmp_path: Path) -> None:
    argv = [a.format(tmp=tmp_path) for a in args]
    proc = subprocess.run(
        [sys.executable, str(EXAMPLES / script), *argv],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert expect in proc.stdout


def test_the_paper_example_runs(paper_example: tuple[Path, str]) -> None:
    """examples/paper.py, run once per session by the ``paper_example`` fixture (the check of
    every table and figure it writes is tests/cli/test_main.py's)."""
    out, stdout = paper_example
    assert "report.md" in stdout and (out / "report.md").exists()
