"""Where `quadrs mission`'s wall time goes: before the engine's first call (the interpreter, the
imports, the scenario, the cost calibration's set-up), inside the engine's calls (the flights),
between them and after the last (the tables and the report), each run in a fresh process.

    python benches/mission_timeline.py --runs 200 --repeat 3

Prints per repeat, and their medians: seconds from the process's start to the first engine
call, in engine calls, between them, and after the last, and the whole. The engine's calls
are `quadrs.runs.chunk.run_range` (every batch of flights goes through it: the calibration's
and the mission's); the process's start is read from /proc (Linux), so the interpreter's own
start-up is counted.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys

CHILD = """
import json, os, sys, time
ticks = os.sysconf("SC_CLK_TCK")
with open("/proc/self/stat") as f:
    started = int(f.read().rsplit(")", 1)[1].split()[19]) / ticks
with open("/proc/uptime") as f:
    since_start = float(f.read().split()[0]) - started
t0 = time.perf_counter() - since_start
import quadrs.runs.chunk as chunk
calls = []
real = chunk.run_range
def timed(*args, **kwargs):
    begin = time.perf_counter() - t0
    try:
        return real(*args, **kwargs)
    finally:
        calls.append((begin, time.perf_counter() - t0))
chunk.run_range = timed
from quadrs.cli.main import main
sys.stdout = open(os.devnull, "w")
try:
    main(["mission", "--preset", "delivery", "--runs", "{runs}", "--no-progress"])
except SystemExit:
    pass
end = time.perf_counter() - t0
sys.stderr.write(json.dumps([calls, end]) + "\\n")
"""

PARTS = ("before", "engine", "between", "after", "whole")


def run(runs: int) -> dict[str, float]:
    """One mission in a fresh process: its parts' seconds."""
    out = subprocess.run([sys.executable, "-c", CHILD.replace("{runs}", str(runs))],
                         capture_output=True, text=True, check=True)  # fmt: skip
    calls, end = json.loads(out.stderr.strip().splitlines()[-1])
    engine = sum(b - a for a, b in calls)
    return {
        "before": calls[0][0],
        "engine": engine,
        "between": calls[-1][1] - calls[0][0] - engine,
        "after": end - calls[-1][1],
        "whole": end,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    rows = [run(args.runs) for _ in range(args.repeat)]
    print(f"quadrs mission --preset delivery --runs {args.runs}: seconds, {args.repeat} runs")
    print("        " + "".join(f"{p:>9}" for p in PARTS))
    for i, row in enumerate(rows, 1):
        print(f"run {i:<4}" + "".join(f"{row[p]:9.2f}" for p in PARTS))
    print("median  " + "".join(f"{statistics.median(r[p] for r in rows):9.2f}" for p in PARTS))


if __name__ == "__main__":
    main()
