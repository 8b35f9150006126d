"""How long ``import quadrs`` and ``quadrs --version`` take, against loading every public name
(what the package face did before it loaded them lazily), each in a fresh process.

    python benches/import_time.py --repeat 7

Prints, per case, the median and the fastest wall time of the child's work (measured inside
it, so the interpreter's own start-up is left out), whether pandas was loaded, and the ratio to
loading every name. ``python -X importtime -c "import quadrs"`` lists where the time goes.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys

CASES = {
    "import quadrs": "import quadrs",
    "quadrs --version": "from quadrs.cli.main import main; main(['--version'])",
    "every public name": "import quadrs\nfor name in quadrs.__all__: getattr(quadrs, name)",
}

CHILD = """
import contextlib, io, sys, time
t = time.perf_counter()
with contextlib.redirect_stdout(io.StringIO()):
{body}
print(time.perf_counter() - t, "pandas" in sys.modules)
"""


def run(body: str) -> tuple[float, bool]:
    code = CHILD.format(body="\n".join("    " + line for line in body.splitlines()))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    seconds, pandas = out.stdout.split()[-2:]
    return float(seconds), pandas == "True"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="fresh processes per case")
    args = parser.parse_args()
    results = {}
    for _ in range(args.repeat):  # interleaved, so a busy moment hits every case alike
        for name, body in CASES.items():
            results.setdefault(name, []).append(run(body))
    base = statistics.median(t for t, _ in results["every public name"])
    print(f"{'case':<20} {'median s':>9} {'fastest s':>10} {'pandas':>7} {'ratio':>7}")
    for name, rows in results.items():
        times = [t for t, _ in rows]
        median = statistics.median(times)
        print(f"{name:<20} {median:>9.3f} {min(times):>10.3f} {rows[0][1]!s:>7} "
              f"{median / base:>7.3f}")  # fmt: skip


if __name__ == "__main__":
    main()
