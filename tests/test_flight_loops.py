"""The flight loop is compiled once per (lane entry, vehicle), the law chosen inside it
(docs/architecture.md, "What a kind costs the compiler"): the engine's size against a stated
bound, so a change that makes the law (or anything else) a type parameter of the loop again,
multiplying the loops, fails here."""

from __future__ import annotations

from pathlib import Path

from quadrs import _core

#: Bytes. With the law a type parameter of the loop (144 loops) the optimised engine without LTO
#: (the test command's `dev-opt` build) was 14.1 MB; with the law chosen per step (36 loops)
#: 9.8 MB (docs/performance.md, "The law out of the loop's type"); 11.6 MB with this round's
#: sensors and estimator, each law's closed-loop start (Newton on the closed loop, per law) and
#: the downwash. The bound leaves room for that, not for the loops to multiply again (36 more
#: loops would add about 4 MB).
LIMIT = 12_500_000


def test_the_engine_is_one_flight_loop_per_lane_entry_and_vehicle_in_size() -> None:
    size = Path(_core.__file__).stat().st_size
    assert size < LIMIT, f"the engine is {size / 1e6:.1f} MB, over {LIMIT / 1e6:.1f} MB"
