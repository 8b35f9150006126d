"""Run the keystream kernels of a built quadrs extension in an emulated CPU that has AVX-512.

The AVX-512 keystream kernel (`lane::random::keystream::blocks16`) runs only on CPUs with AVX-512F,
where `cargo test` checks it against rand_chacha (`wide_matches_fill_bytes`). On a CPU without
it, this script runs the kernel's machine code, as built, in Bochs' x86 emulator (which
implements AVX-512) and compares every word with ChaCha8 computed here from RFC 8439, and
with the AVX2 kernel (`blocks8`, held to rand_chacha by the same Rust test) run the same way;
and the ziggurat's candidates of the AVX-512 pass (`normal::mark8`) with the AVX2 one
(`mark4`, held to rand_distr by `ahead_matches_rand_distr`) on the same words:

    pip install bochscpu-python
    python scripts/emulated_kernels.py python/quadrs/_core.abi3.so

The extension must keep its symbols (a `maturin develop --profile dev-opt` build does). Both
kernels are leaf functions with the C calling convention, so each runs alone: the extension's
loadable segments are mapped at their addresses, the arguments set in registers, and the
return address points at a `hlt`. Exit status 0 when every block of every case agrees.

The bochscpu-python wheel wants glibc 2.38 (`__isoc23_strtoull`, `__isoc23_sscanf`); on an
older glibc, preload a library defining those two as `strtoull` and `vsscanf`.
"""

from __future__ import annotations

import argparse
import random
import re
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

MASK = 0xFFFF_FFFF
CONSTANTS = (0x6170_7865, 0x3320_646E, 0x7962_2D32, 0x6B20_6574)
BASE = 0x5555_0000_0000  # where the extension's segments are mapped
DATA = 0x7000_0000_0000  # arguments, output, stack, and the return trap
PAGE = 0x1000


def chacha8_words(key: list[int], stream: int, block: int) -> list[int]:
    """Block `block` of ChaCha8 as rand_chacha lays it out: the 64-bit block counter in
    words 12-13, the stream in 14-15; returned as the block's eight little-endian u64s."""

    def rotl(v: int, n: int) -> int:
        return ((v << n) | (v >> (32 - n))) & MASK

    def quarter(x: list[int], a: int, b: int, c: int, d: int) -> None:
        x[a] = (x[a] + x[b]) & MASK
        x[d] = rotl(x[d] ^ x[a], 16)
        x[c] = (x[c] + x[d]) & MASK
        x[b] = rotl(x[b] ^ x[c], 12)
        x[a] = (x[a] + x[b]) & MASK
        x[d] = rotl(x[d] ^ x[a], 8)
        x[c] = (x[c] + x[d]) & MASK
        x[b] = rotl(x[b] ^ x[c], 7)

    block %= 1 << 64
    state = [*CONSTANTS, *key, block & MASK, block >> 32, stream & MASK, stream >> 32]
    x = list(state)
    for _ in range(4):
        for a, b, c, d in ((0, 4, 8, 12), (1, 5, 9, 13), (2, 6, 10, 14), (3, 7, 11, 15)):
            quarter(x, a, b, c, d)
        for a, b, c, d in ((0, 5, 10, 15), (1, 6, 11, 12), (2, 7, 8, 13), (3, 4, 9, 14)):
            quarter(x, a, b, c, d)
    out = [(v + s) & MASK for v, s in zip(x, state, strict=True)]
    return [out[2 * k] | out[2 * k + 1] << 32 for k in range(8)]


def load_segments(path: Path) -> list[tuple[int, bytes]]:
    """The ELF64 file's PT_LOAD segments as (virtual address, bytes padded to memsz)."""
    raw = path.read_bytes()
    if raw[:4] != b"\x7fELF" or raw[4] != 2:
        raise SystemExit(f"{path}: not an ELF64 file")
    (phoff,) = struct.unpack_from("<Q", raw, 0x20)
    phentsize, phnum = struct.unpack_from("<HH", raw, 0x36)
    segments = []
    for i in range(phnum):
        p_type, _flags, offset, vaddr, _paddr, filesz, memsz, _align = struct.unpack_from(
            "<IIQQQQQQ", raw, phoff + i * phentsize
        )
        if p_type == 1:
            segments.append((vaddr, raw[offset : offset + filesz].ljust(memsz, b"\0")))
    return segments


def symbol(path: Path, name: str) -> int:
    """The address of the one defined function whose (mangled) name contains `name`."""
    out = subprocess.run(
        ["nm", "--defined-only", str(path)], check=True, capture_output=True, text=True
    ).stdout
    # A Rust symbol mangles `path::name` as `...<len>name17h<hash>E`; closures add more.
    pattern = re.compile(rf"{len(name)}{name}17h[0-9a-f]{{16}}E$")
    hits = [line.split() for line in out.splitlines()]
    hits = [h for h in hits if len(h) == 3 and h[1] in "tT" and pattern.search(h[2])]
    if len(hits) != 1:
        raise SystemExit(
            f"{path}: {len(hits)} functions match {name!r} (a build with symbols is needed)"
        )
    return int(hits[0][0], 16)


class Machine:
    """One emulated CPU in 64-bit mode, user level, with AVX-512 state enabled, and the
    extension's segments mapped."""

    def __init__(self, segments: list[tuple[int, bytes]]) -> None:
        import bochscpu
        import bochscpu.cpu
        import bochscpu.memory

        self.bochs = bochscpu
        # The session first: the emulator's memory is set up with it.
        self.session = bochscpu.Session()

        def missing(gpa: int) -> None:
            raise RuntimeError(f"the kernel touched unmapped memory at {gpa:#x}")

        self.session.missing_page_handler = missing
        # Kept: the table owns the pages its entries are committed to.
        self.table = table = bochscpu.memory.PageMapLevel4Table()
        regions = [(BASE + vaddr, len(data)) for vaddr, data in segments] + [(DATA, 16 * PAGE)]
        gpa = 0x1000_0000
        for start, size in regions:
            first, last = start & ~(PAGE - 1), (start + size + PAGE - 1) & ~(PAGE - 1)
            for page in range(first, last, PAGE):
                if table.translate(page) is None:
                    bochscpu.memory.page_insert(gpa, bochscpu.memory.allocate_host_page())
                    table.insert(page, gpa, 1)
                    gpa += PAGE
        self.pml4 = 0x10_0000
        for hva, table_gpa in table.commit(self.pml4):
            bochscpu.memory.page_insert(table_gpa, hva)
        for vaddr, data in segments:
            # Fresh pages hold zeros already.
            self.write(BASE + vaddr, data, skip_zeros=True)

    def write(self, gva: int, data: bytes, skip_zeros: bool = False) -> None:
        """Copy `data` to `gva`, page by page (bochscpu's `virt_write` does not cross pages),
        with `skip_zeros` leaving out the pieces that are all zero."""
        at = 0
        while at < len(data):
            n = min(len(data) - at, PAGE - (gva + at) % PAGE)
            chunk = data[at : at + n]
            if not skip_zeros or chunk.strip(b"\0"):
                if not self.bochs.memory.virt_write(self.pml4, gva + at, list(chunk)):
                    raise RuntimeError(f"cannot write {n} bytes at {gva + at:#x}")
            at += n

    def read(self, gva: int, n: int) -> bytes:
        """`n` bytes from `gva`, page by page as `write`."""
        out = b""
        while len(out) < n:
            k = min(n - len(out), PAGE - (gva + len(out)) % PAGE)
            out += bytes(self.bochs.memory.virt_read(self.pml4, gva + len(out), k))
        return out

    def call(self, entry: int, args: list[int]) -> int:
        """Run the C function at `entry` with up to four integer arguments; it must return to
        the trap (a `hlt`, which faults at user level and stops the run). Returns the
        instructions it executed."""
        bochscpu = self.bochs
        trap, stack = DATA, DATA + 16 * PAGE - 64
        self.write(trap, b"\xf4")
        self.write(stack, struct.pack("<Q", trap))
        state = bochscpu.State()
        bochscpu.cpu.set_long_mode(state)
        state.cr3 = self.pml4
        # CR4: PAE, OSFXSR, OSXMMEXCPT, OSXSAVE; XCR0: x87, SSE, AVX, opmask, ZMM (0xe7).
        state.cr4 = int(state.cr4) | 1 << 5 | 1 << 9 | 1 << 10 | 1 << 18
        state.xcr0 = 0xE7
        state.mxcsr = 0x1F80  # floating-point exceptions masked, round to nearest (the default)
        state.rip, state.rsp = entry, stack
        for reg, value in zip(("rdi", "rsi", "rdx", "rcx")[: len(args)], args, strict=True):
            setattr(state, reg, value)
        cs = bochscpu.Segment()
        cs.present, cs.selector, cs.base, cs.limit, cs.attr = True, 0x33, 0, 0xFFFF_FFFF, 0x22FB
        ds = bochscpu.Segment()
        ds.present, ds.selector, ds.base, ds.limit, ds.attr = True, 0x2B, 0, 0xFFFF_FFFF, 0xCF3
        state.cs = cs
        state.ds = state.ss = state.es = state.fs = state.gs = ds
        session = self.session
        session.cpu.state = state
        faults: list[tuple[int, int]] = []
        hook = bochscpu.Hook()

        def exception(sess: Any, _cpu: int, vector: Any, code: Any) -> None:
            faults.append((int(vector), int(code)))
            sess.stop()

        executed = [0]

        def after(_sess: Any, _cpu: int, _insn: Any) -> None:
            executed[0] += 1

        hook.exception = exception
        hook.after_execution = after
        session.run([hook])
        rip = session.cpu.state.rip
        if rip not in (trap, trap + 1) or faults != [(13, 0)]:
            raise SystemExit(
                f"the kernel did not return: stopped at {rip:#x} (entry {entry:#x}) with "
                f"exceptions {faults} (6: invalid opcode, 13: the trap's fault)"
            )
        return executed[0] - 1  # the trap's


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("extension", type=Path, help="a quadrs _core .so built with symbols")
    args = parser.parse_args()
    kernels = {
        "blocks8": (symbol(args.extension, "blocks8"), 8),
        "blocks16": (symbol(args.extension, "blocks16"), 16),
    }
    machine = Machine(load_segments(args.extension))
    key_at, out_at = DATA + PAGE, DATA + 2 * PAGE
    cases = [
        (list(range(8)), 0, 0),
        ([0x0123_4567 * (i + 1) & MASK for i in range(8)], 77, 5),
        ([MASK] * 8, (1 << 64) - 1, 1 << 40),
        ([0xDEAD_BEEF ^ i for i in range(8)], 3, (1 << 64) - 9),  # the counter wraps
    ]
    failures = 0
    for key, stream, block in cases:
        for name, (entry, blocks) in kernels.items():
            machine.write(key_at, struct.pack("<8I", *key))
            machine.write(out_at, bytes(8 * 8 * blocks))
            executed = machine.call(BASE + entry, [key_at, stream, block, out_at])
            got = struct.unpack(f"<{8 * blocks}Q", machine.read(out_at, 64 * blocks))
            want = [w for b in range(blocks) for w in chacha8_words(key, stream, block + b)]
            bad = [k for k in range(len(want)) if got[k] != want[k]]
            status = "ok" if not bad else f"{len(bad)} words differ, first at {bad[0]}"
            print(
                f"{name:>8}  stream {stream:#018x}  block {block:#018x}: {status}"
                f"  ({executed / (8 * blocks):.2f} instructions per u64)"
            )
            failures += bool(bad)
    failures += compare_marks(machine, args.extension)
    print("all kernels agree" if not failures else f"{failures} cases differ")
    return 1 if failures else 0


def compare_marks(machine: Machine, extension: Path) -> int:
    """The ziggurat's candidates (`mark4`, AVX2, held to rand_distr by `cargo test`, and
    `mark8`, AVX-512) on the same words: every candidate's bits and every accepted bit."""
    rng = random.Random(8)
    words_at, out_at, bits_at = DATA + 4 * PAGE, DATA + 8 * PAGE, DATA + 12 * PAGE
    passes = 40  # 640 words: every layer many times, and rejections
    n = 16 * passes
    words = [rng.getrandbits(64) for _ in range(n)]
    # The edges of the layers and the wedges: the top and bottom of the 52-bit fraction.
    for k in range(0, n, 7):
        words[k] = words[k] | 0xFFFF_F000_0000_0000 if k % 2 else words[k] & 0xFFF
    results, executed = {}, {}
    for name in ("mark4", "mark8"):
        machine.write(words_at, struct.pack(f"<{n}Q", *words))
        machine.write(out_at, bytes(8 * n))
        machine.write(bits_at, bytes(8 * (n // 64 + 1)))
        executed[name] = machine.call(
            BASE + symbol(extension, name), [words_at, passes, out_at, bits_at]
        )
        results[name] = (machine.read(out_at, 8 * n), machine.read(bits_at, 8 * (n // 64)))
    (x4, b4), (x8, b8) = results["mark4"], results["mark8"]
    accepted = sum(bin(b).count("1") for b in struct.unpack(f"<{n // 64}Q", b4))
    same = x4 == x8 and b4 == b8
    print(
        f"   mark8  {n} words, {accepted} accepted by mark4: {'ok' if same else 'differs'}"
        f"  ({executed['mark4'] / n:.2f} and {executed['mark8'] / n:.2f} instructions per u64)"
    )
    # Most accepted, and some rejected (the forced edges), or the comparison proves little.
    return 0 if same and n // 2 < accepted < n else 1


if __name__ == "__main__":
    sys.exit(main())
