"""What a long command will fly and roughly how long it will take, said before it starts.

:func:`calibrate` flies a few realisations of the scenario (as many as the engine flies at
once, so the measurement is of a full batch step) and times them; :func:`announce` turns the
count of flights a command will make into one line for stderr, and :class:`Eta` the elapsed
and remaining time of a job made of counted pieces (levels, candidates) for its progress lines.
The estimate is rough: the same flights in another wind can end early (a divergence) or not.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from quadrs.runs.chunk import Chunk

__all__ = [
    "ANNOUNCE_AFTER",
    "Calibration",
    "Eta",
    "announce",
    "announce_batch",
    "calibrate",
    "duration",
    "say",
]

#: A job estimated to take at least this long (s) is announced before it starts; a shorter
#: one just runs.
ANNOUNCE_AFTER = 10.0


@dataclass(frozen=True)
class Calibration:
    """``flights`` flown in ``seconds`` of wall clock with ``workers`` threads; ``chunk``: what
    they gave (the batch's first realisations, so a batch of the same scenario, seed,
    controllers and random sampling without spectra takes them rather than fly them again:
    :func:`quadrs.monte_carlo`'s ``flown``)."""

    flights: int
    seconds: float
    workers: int
    chunk: Chunk | None = field(default=None, compare=False, repr=False)

    @property
    def per_flight(self) -> float:
        """Seconds of wall clock per flight, at this machine's parallelism."""
        return self.seconds / max(self.flights, 1)

    def estimate(self, flights: int) -> float:
        """Seconds for ``flights`` more flights."""
        return flights * self.per_flight


def _workers(workers: int | None) -> int:
    from quadrs.engine.calls import default_workers

    return max(1, workers if workers is not None else default_workers())


def precheck(scenario: Any, controllers: Sequence[str], runs: int, workers: int | None,
             seed: int = 0) -> None:  # fmt: skip
    """The checks :func:`quadrs.monte_carlo` makes before it flies, with its messages: a batch
    that will be refused is neither calibrated nor announced (bad input stays one line)."""
    from quadrs.engine.calls import I64_MAX, MAX_WORKERS, check_int, check_memory, default_workers
    from quadrs.runs.montecarlo import ROW_BYTES

    runs = check_int("runs", runs, 1, I64_MAX)
    check_int("seed", seed)
    check_int("workers", default_workers() if workers is None else workers, 1, MAX_WORKERS)
    rows = runs * len(controllers) * len(scenario.phase_names)
    check_memory(f"the result table of runs = {runs} ({rows} rows)", rows * ROW_BYTES)


def calibrate(
    scenario: Any,
    controllers: Sequence[str] = ("pd",),
    workers: int | None = None,
    seed: int = 0,
    flights: int | None = None,
    at_most: int | None = None,
) -> Calibration:
    """Fly ``flights`` realisations (default: one lane-set per thread, the least that keeps
    every thread busy, so the time is the machine's; at most ``at_most``, the batch's size)
    of ``scenario`` with ``controllers`` in the engine and time them: the batch's own first
    realisations (with random sampling of any dispersions), so that a draw the scenario
    refuses is refused naming a realisation the batch has. Ctrl-C raises
    KeyboardInterrupt."""
    from quadrs import _core
    from quadrs.runs.chunk import Design, fly_chunk

    n_workers = _workers(workers)
    count = flights if flights is not None else _core.lanes_per_set() * n_workers
    if at_most is not None:
        count = max(1, min(count, at_most))
    # Random sampling: realisation i's values depend on (seed, i) only, so these are the
    # batch's whatever its size.
    design = Design("random", 0, count)
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        chunk = fly_chunk(scenario, tuple(controllers), seed, 0, count, n_workers,
                          spectra=False, design=design)  # fmt: skip
    if chunk.interrupted:  # Ctrl-C in the calibration stops the command
        raise KeyboardInterrupt
    seconds = time.perf_counter() - start
    # One flight per controller: a paired batch of c controllers is c flights per realisation.
    return Calibration(count * len(controllers), seconds, n_workers, chunk)


def duration(seconds: float) -> str:
    """``"40 s"``, ``"7 min"``, ``"2.5 h"``: a rough duration for a person."""
    if not math.isfinite(seconds):
        return "unknown"
    if seconds < 90:
        return f"{max(1, round(seconds))} s"
    if seconds < 90 * 60:
        return f"{round(seconds / 60)} min"
    return f"{seconds / 3600:.1f} h"


#: How much longer a job may take than its calibration says when the machine gets busier
#: while it runs (measured: tune announced 36 s took 70 s beside other builds on 2 cores).
LOADED = 2.0


def announce(command: str, what: str, flights: int, calibration: Calibration) -> str:
    """One line: ``quadrs tune: 336 candidates of 200 flights (67,200 flights): about 5.4 h
    (0.29 s a flight on 2 threads, from 8 calibration flights)``."""
    total = calibration.estimate(flights)
    return (
        f"quadrs {command}: {what} ({flights:,} flights): about {duration(total)} "
        f"({calibration.per_flight:.2g} s a flight on {calibration.workers} thread"
        f"{'s' * (calibration.workers != 1)}, from {calibration.flights} calibration flights; "
        f"up to {duration(LOADED * total)} if the machine gets busier, the progress bar's rate "
        "updates it); Ctrl-C keeps what finished"
    )


def say(line: str, seconds: float) -> None:
    """Print ``line`` to stderr (now: before the work) if the job it announces is long."""
    from quadrs.cli.common import note

    if seconds >= ANNOUNCE_AFTER:
        note(line)


class Eta:
    """Elapsed and remaining time of ``total`` pieces of work done one after another."""

    def __init__(self, total: int | None) -> None:
        self.total = total
        self.start = time.perf_counter()
        self.done = 0

    def step(self, pieces: int = 1) -> str:
        """Count ``pieces`` done; ``"3 of 12 after 1 min, about 3 min left"``."""
        self.done += pieces
        elapsed = time.perf_counter() - self.start
        text = f"{self.done}" + (f" of {self.total}" if self.total else "")
        text += f" after {duration(elapsed)}"
        if self.total and self.done < self.total:
            left = elapsed / self.done * (self.total - self.done)
            text += f", about {duration(left)} left"
        return text


def announce_batch(
    command: str,
    scenario: Any,
    controllers: Sequence[str],
    runs: int,
    workers: int | None,
    seed: int,
    extra: int = 0,
    what: str = "",
) -> None:
    """Say on stderr what a long batch flies and roughly how long: ``runs`` realisations of
    each controller, plus ``extra`` flights (``mc``, ``paper``)."""
    precheck(scenario, controllers, runs, workers, seed)
    cal = calibrate(scenario, controllers, workers, seed, at_most=runs)
    flights = runs * len(controllers) + extra
    names = " and ".join(c.upper() for c in controllers)
    what = what or f"{runs} realisations x {names}"
    say(announce(command, what, flights, cal), cal.estimate(flights))
