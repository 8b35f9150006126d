"""Where the engine's time goes, function by function, from a `perf record` of a build with
line tables (docs/performance.md, "Where the delivery batch's time goes").

The flight loop is one function with everything inlined into it, so `perf report` charges
almost every sample to it. This charges each sample to the innermost function of `rust/src`
(outside `rust/src/lane/`, whose lane operations every model function calls) that the
sampled instruction was inlined from (`addr2line -i`), and prints the shares:

    CARGO_TARGET_DIR=target/prof CARGO_PROFILE_DEV_OPT_DEBUG=line-tables-only \\
        MATURIN_PEP517_ARGS="--profile dev-opt" pip wheel --no-deps -w target/prof-wheel .
    # unpack that wheel's quadrs/ into DIR (beside python/quadrs' sources), then:
    PYTHONPATH=DIR perf record -F 2000 -o perf.data python benches/instructions.py delivery
    python benches/perf_by_function.py perf.data DIR/quadrs/_core.abi3.so

Needs `perf`, `readelf` and `addr2line` (binutils).
"""

from __future__ import annotations

import argparse
import collections
import re
import subprocess
import sys
from pathlib import Path


def load_base(data: Path, library: Path) -> tuple[int, int]:
    """Where perf saw ``library``'s executable mapping: (start address, file offset)."""
    events = subprocess.run(["perf", "script", "-i", str(data), "--show-mmap-events"],
                            capture_output=True, text=True, check=True).stdout  # fmt: skip
    pattern = re.compile(r"\[(0x[0-9a-f]+)\((0x[0-9a-f]+)\) @ (0x[0-9a-f]+) .*r-xp (\S+)")
    for line in events.splitlines():
        m = pattern.search(line)
        if m and Path(m.group(4)).resolve() == library.resolve():
            return int(m.group(1), 16), int(m.group(3), 16)
    raise SystemExit(f"{library}: not mapped executable in {data}")


def exec_segment(library: Path) -> tuple[int, int]:
    """The executable LOAD segment's (file offset, virtual address)."""
    out = subprocess.run(["readelf", "-lW", str(library)], capture_output=True, text=True,
                         check=True).stdout  # fmt: skip
    for line in out.splitlines():
        parts = line.split()
        if parts[:1] == ["LOAD"] and parts[-2] == "E":
            return int(parts[1], 16), int(parts[2], 16)
    raise SystemExit(f"{library}: no executable segment")


def plain(function: str) -> str:
    """``a::b::<impl X<T>>::f<L>`` -> ``f``: the name without its path and type arguments."""
    while True:
        shorter = re.sub(r"<[^<>]*>", "", function)
        if shorter == function:
            return function.split("::")[-1] or function
        function = shorter


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("data", type=Path, help="perf.data of the run")
    parser.add_argument("library", type=Path, help="the _core.abi3.so it ran (with line tables)")
    parser.add_argument("--top", type=int, default=30)
    args = parser.parse_args()
    start, pgoff = load_base(args.data, args.library)
    seg_offset, seg_vaddr = exec_segment(args.library)
    samples = subprocess.run(["perf", "script", "-i", str(args.data), "-F", "ip,dso"],
                             capture_output=True, text=True, check=True).stdout  # fmt: skip
    name = args.library.name
    ips = [int(line.split()[0], 16) for line in samples.splitlines() if name in line]
    if not ips:
        raise SystemExit(f"no sample in {name}")
    vaddr = collections.Counter(ip - start + pgoff - seg_offset + seg_vaddr for ip in ips)
    lines = subprocess.run(["addr2line", "-a", "-i", "-f", "-C", "-e", str(args.library),
                            *map(hex, vaddr)], capture_output=True, text=True,
                           check=True).stdout.splitlines()  # fmt: skip
    charged: collections.Counter[str] = collections.Counter()
    address, picked = None, None
    for i, line in enumerate(lines):
        if line.startswith("0x"):
            if address is not None:
                charged[picked or "(outside rust/src)"] += vaddr[address]
            address, picked = int(line, 16), None
        elif picked is None and "/rust/src/" in line and "/rust/src/lane/" not in line:
            picked = plain(lines[i - 1])
    if address is not None:
        charged[picked or "(outside rust/src)"] += vaddr[address]
    total = sum(charged.values())
    print(f"{total} samples in {name}, by the innermost rust/src function (lane/ excluded):")
    for function, n in charged.most_common(args.top):
        print(f"{100 * n / total:6.1f} %  {function}")


if __name__ == "__main__":
    sys.exit(main())
