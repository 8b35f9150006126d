"""Peak memory of a Monte Carlo batch against the number of realisations.

Each size runs in a fresh process (peak RSS is per process). A short, coarse scenario keeps the
flying cheap: the engine's working memory does not depend on the flight length (per lane-set a
few kB of state plus the spectrum buffer), so what grows with N is only the result table.

    python benches/memory.py --runs 1000 10000 100000
"""

from __future__ import annotations

import argparse
import subprocess
import sys

CHILD = """
import resource, sys, time
import quadrs
s = quadrs.Scenario.paper().override({
    "integrator.duration": 2.0, "integrator.dt": 0.01, "gust.start": 0.5, "gust.end": 1.5,
    "phases": [{"name": "P1", "start": 0.0, "end": 1.0}, {"name": "P2", "start": 1.0, "end": 2.0}],
})
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.perf_counter()
mc = quadrs.monte_carlo(s, runs=int(sys.argv[1]), progress=False)
mc.summary()
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
table = mc.runs.memory_usage(deep=True).sum()
print(f"{int(sys.argv[1])},{before / 1024:.1f},{peak / 1024:.1f},{table / 2**20:.1f},"
      f"{time.perf_counter() - t:.2f}")
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, nargs="+", default=[1_000, 10_000, 100_000])
    args = parser.parse_args()
    print("runs,rss_after_import_MiB,peak_rss_MiB,runs_table_MiB,seconds")
    for n in args.runs:
        out = subprocess.run(
            [sys.executable, "-W", "ignore", "-c", CHILD, str(n)],
            check=True,
            capture_output=True,
            text=True,
        )
        print(out.stdout.strip(), flush=True)


if __name__ == "__main__":
    main()
