"""The flight loop is compiled once per (lane entry, vehicle), the law chosen inside it
(docs/architecture.md, "What a kind costs the compiler"), and so is the linear models' closed
loop once per vehicle ("What the library weighs"): the engine's size against a stated bound,
and the closed loops counted by name, so a change that makes the law (or anything else) a type
parameter of either loop again, multiplying the loops, fails here."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from quadrs import _core

#: Bytes. With the law a type parameter of the loop (144 loops) the optimised engine without LTO
#: (the test command's `dev-opt` build) was 14.1 MB; with the law chosen per step (36 loops)
#: 9.8 MB (docs/performance.md, "The law out of the loop's type"); 11.6 MB with this round's
#: sensors and estimator, each law's closed-loop start (Newton on the closed loop, per law) and
#: the downwash; 10.3 MB with the linear models' closed loop compiled once per vehicle, not per
#: vehicle and law (24 copies to 6: 1.45 MB less, docs/architecture.md "What the library
#: weighs"). The bound leaves 1.2 MB to grow, not for the loops to multiply again (36 more
#: flight loops would add about 4 MB, the closed loop generic over the law again 1.45 MB).
LIMIT = 11_500_000

#: The vehicles `model::dispatch` builds: the paper body with 2 payload kinds x 2 actuator
#: kinds, the rigid body with 1 x 2.
VEHICLES = 6

#: The lane entries (`integrate/entry.rs`): f64, F64x4, AVX2, AVX2 fused, AVX-512, AVX-512 fused
#: (x86-64 compiles 5 of them: no portable F64x4).
LANE_ENTRIES = 6

#: How a flight loop is named (`nm -C`): one per lane entry and vehicle.
FLIGHT_LOOP = "LoopEntry>::enter"

#: How a copy of the closed loop's evaluation on dual numbers is named (`nm -C`): one per
#: vehicle when the law is held as a value (`stability::closed_loop::Law`), one per vehicle and
#: law (24) when `Loop` is generic over it.
CLOSED_LOOP_EVAL = "ClosedLoop>::eval_dual"


def test_the_engine_is_one_flight_loop_per_lane_entry_and_vehicle_in_size() -> None:
    size = Path(_core.__file__).stat().st_size
    assert size < LIMIT, f"the engine is {size / 1e6:.1f} MB, over {LIMIT / 1e6:.1f} MB"


def engine_symbols() -> list[str]:
    """The engine's defined symbols, demangled; skips where they cannot be read (no `nm`, or
    the release profile's library, whose symbol table is stripped)."""
    nm = shutil.which("nm")
    if nm is None:
        pytest.skip("no nm on this machine")
    proc = subprocess.run(
        [nm, "--defined-only", "-C", _core.__file__], capture_output=True, text=True, check=False
    )
    if proc.returncode != 0 or not proc.stdout.strip():
        pytest.skip(f"no symbol table in the engine (a release build?): {proc.stderr.strip()}")
    return proc.stdout.splitlines()


def test_the_linear_models_closed_loop_is_compiled_once_per_vehicle() -> None:
    copies = sum(line.endswith(CLOSED_LOOP_EVAL) for line in engine_symbols())
    assert 0 < copies <= VEHICLES, (
        f"{copies} copies of the closed loop's evaluation (`{CLOSED_LOOP_EVAL}`), "
        f"expected one per vehicle ({VEHICLES}): is `stability::Loop` generic over the law again?"
    )


def test_the_flight_loop_is_compiled_once_per_lane_entry_and_vehicle() -> None:
    loops = sum(line.endswith(FLIGHT_LOOP) for line in engine_symbols())
    assert 0 < loops <= LANE_ENTRIES * VEHICLES, (
        f"{loops} flight loops (`{FLIGHT_LOOP}`), expected at most one per lane entry and "
        f"vehicle ({LANE_ENTRIES} x {VEHICLES}): is the law a type parameter of the loop again?"
    )


def test_no_closure_the_flight_loops_call_makes_lane_operations_out_of_line() -> None:
    """A closure the optimiser leaves out of the flight loop's line is compiled without the
    lane type's instruction set, so each lane operation in it becomes a call (docs/performance.md,
    "Lane operations in the loop's line"). One made the state's sines and cosines per step
    through `FnOnce::call_once`, 1,395 such calls, and the delivery flown on its state ran 1.5x
    slower. The flight loops' set-up closures are named by their function (`start::{{closure}}`,
    `Runaway::new::{{closure}}`, a dozen calls each); an anonymous one reached from the loops
    makes none."""
    if shutil.which("objdump") is None:
        pytest.skip("needs objdump (binutils)")
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benches"))
    try:
        from outlined_lane_calls import outlined_calls
    finally:
        sys.path.pop(0)
    loops, sites, _ = outlined_calls(Path(_core.__file__))
    assert loops > 0, "no flight loop found by name in the engine's disassembly"
    anonymous = {n: c for n, c in sites.items() if n.startswith("core::ops::function::Fn")}
    assert anonymous == {}, anonymous
