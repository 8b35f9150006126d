"""Lane operations the flight loops call out of line (docs/performance.md, "Lane operations in
the loop's line").

A function the optimiser leaves out of the flight loop's line (a closure, an array's ``map``,
an iterator's ``fold``) is compiled without the lane type's instruction set, so every SIMD
intrinsic in it becomes a call. This lists, from the engine's disassembly, the functions the
flight loops (``fly_avx2``, ``fly_avx2_fma``, ``fly_avx512``) and the navigation's step
(``sense_avx2``, ...) reach that make such calls, with
how many: per-flight setup (``gather``, ``new``, ``finish``, the trace) is harmless, anything
called per step is not.

    python benches/outlined_lane_calls.py            # the installed engine
    python benches/outlined_lane_calls.py path/to/_core.abi3.so

Needs ``objdump`` (binutils).
"""

from __future__ import annotations

import collections
import re
import shutil
import subprocess
import sys
from pathlib import Path


def engine_path() -> Path:
    import quadrs._core

    return Path(quadrs._core.__file__)


def outlined_calls(so: Path) -> tuple[int, collections.Counter[str], collections.Counter[str]]:
    """From ``so``'s disassembly: how many flight loops and navigation steps there are, and per
    function name they reach that calls lane intrinsics out of line, the calls and the copies."""
    text = subprocess.run(["objdump", "-d", "--no-show-raw-insn", "-C", str(so)],
                          capture_output=True, text=True, check=True).stdout  # fmt: skip
    name: dict[int, str] = {}
    calls: dict[int, list[int]] = collections.defaultdict(list)
    intrinsic: collections.Counter[int] = collections.Counter()
    here = None
    for line in text.splitlines():
        if m := re.match(r"^([0-9a-f]+) <(.*)>:$", line):
            here = int(m.group(1), 16)
            name[here] = m.group(2)
        elif here is not None and (m := re.search(r"\tcall\s+([0-9a-f]+) <(.*)>", line)):
            calls[here].append(int(m.group(1), 16))
            intrinsic[here] += "core_arch" in m.group(2)
    # The flight loops and the navigation's step, each compiled apart for its instruction set.
    loops = [a for a, n in name.items()
             if re.search(r"::(fly|sense)_avx(512|2)(_fma)?$", n)]  # fmt: skip
    reached: set[int] = set()
    todo = list(loops)
    while todo:
        for target in calls.get(todo.pop(), []):
            if target in name and target not in reached:
                reached.add(target)
                todo.append(target)
    sites: collections.Counter[str] = collections.Counter()
    functions: collections.Counter[str] = collections.Counter()
    for a in reached:
        if intrinsic[a]:
            sites[name[a]] += intrinsic[a]
            functions[name[a]] += 1
    return len(loops), sites, functions


def main() -> None:
    so = Path(sys.argv[1]) if len(sys.argv) > 1 else engine_path()
    if shutil.which("objdump") is None:
        sys.exit("objdump (binutils) is needed")
    loops, sites, functions = outlined_calls(so)
    print(f"{so.name}: {loops} flight loops and navigation steps reach "
          f"{sum(functions.values())} functions with {sum(sites.values())} lane-intrinsic "
          "calls out of line")  # fmt: skip
    for n, count in sites.most_common(20):
        print(f"{count:6d} calls in {functions[n]:3d} x {n[:110]}")


if __name__ == "__main__":
    main()
