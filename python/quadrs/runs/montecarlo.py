"""Monte Carlo batches: paired gust realisations in parallel, results as tidy pandas tables."""

from __future__ import annotations

import contextlib
import functools
import operator
import warnings
from collections.abc import Callable, Generator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pandas as pd

from quadrs.engine.calls import (
    I64_MAX,
    MAX_WORKERS,
    check_controller,
    check_int,
    check_labels,
    check_memory,
    default_workers,
    deferred_signals,
)
from quadrs.hover.stability import warn_before_running
from quadrs.runs.chunk import (
    Chunk,
    Design,
    SpectrumSums,
    arithmetic_of,
    batch_identity,
    fly_chunk,
    run_range,
)
from quadrs.runs.montecarlo_result import MonteCarloResult, empty_runs
from quadrs.runs.store import RunStore, checkpoint_record, missing_ranges
from quadrs.scenario.scenario import Scenario

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

__all__ = [
    "Design",
    "MonteCarloResult",
    "SpectrumSums",
    "default_workers",
    "monte_carlo",
    "run_range",
]

#: Chunks are rounded to whole lane-sets: 8 realisations fill one AVX-512 set or two AVX2 and
#: SSE2 ones, so no path flies a half-empty set at a chunk's end (results never depend on it).
LANES = 8
#: Memory (bytes) one row of ``runs`` takes while a batch is assembled: the engine's arrays,
#: the tidy frame and the copies made concatenating and sorting it.
ROW_BYTES = 400


def default_chunk(runs: int, threads: int, checkpointing: bool, distributed: bool) -> int:
    """Realisations per chunk. One Rust call is fastest, so a plain local run is one chunk;
    a checkpointed run saves about every twentieth of the work (and at least a few lane-sets
    per thread, so chunk tails do not idle the cores); on Dask, about four tasks per thread
    balance the load."""
    lane_sets = lambda n: -(-n // LANES) * LANES  # noqa: E731  round up to whole lane-sets
    if distributed:
        return max(LANES, lane_sets(-(-runs // (4 * threads))))
    if checkpointing:
        return max(8 * LANES * threads, lane_sets(-(-runs // 20)))
    return runs


def split_ranges(ranges: Sequence[tuple[int, int]], chunk: int) -> list[tuple[int, int]]:
    """(first, count) ranges cut into pieces of at most ``chunk`` realisations."""
    return [(f + i, min(chunk, c - i)) for f, c in ranges for i in range(0, c, chunk)]


def monte_carlo(
    scenario: Scenario,
    runs: int = 1000,
    seed: int = 0,
    controllers: Sequence[str] = ("pd", "smc"),
    workers: int | None = None,
    progress: bool = True,
    *,
    first: int = 0,
    spectra: bool = True,
    out: str | Path | None = None,
    resume: bool = False,
    chunk: int | None = None,
    client: Client | None = None,
    sampling: str = "random",
    fused: bool = False,
    flown: Sequence[Chunk] | None = None,
) -> MonteCarloResult:
    """Fly realisations ``first .. first + runs`` of the gust under every controller.

    Each realisation flies all controllers through the very same gust (a paired comparison).
    A realisation's numbers depend only on (scenario, seed, realisation index): not on
    ``workers``, chunking, or the machine that ran it. A diverged realisation is flagged in
    ``runs.diverged`` and the batch goes on. Ctrl-C stops promptly and returns what finished
    (``result.interrupted`` is then True).

    ``out``: a directory that receives each chunk's rows as a Parquet part as soon as it
    finishes (see :mod:`quadrs.runs.store`); a killed run loses at most the chunks in flight.
    With ``resume=True`` an existing ``out`` is continued: only realisations it lacks are
    flown, and the result is everything it then holds. ``chunk``: realisations per chunk.
    ``client``: a ``dask.distributed.Client``; chunks then run as tasks on its workers
    (``workers`` is ignored: each task uses its worker's threads).

    A scenario with ``[dispersions]`` flies each realisation with its own values of the
    dispersed keys (a column each in ``runs``), drawn by ``sampling``: ``"random"`` (values of
    realisation i depend only on (seed, i)), ``"lhs"`` or ``"sobol"`` (one stratified design
    over the batch's ``runs`` realisations from (seed, runs)). Every controller of a
    realisation flies the same values and the same gust; see docs/dispersions.md.

    ``fused=True``: the opt-in fused mode, faster on CPUs with FMA (AVX2+FMA or AVX-512): the
    engine fuses multiply-adds, so its numbers differ from the default mode's in the last
    digits (about 1e-12 relative on the paper preset) and are not bit-identical across
    instruction sets. The result says so (``result.arithmetic == "fused"``, also in saved
    metadata, a checkpoint's manifest and the run identity, so a resumed run keeps its mode; on
    Dask each worker fuses on its own instruction set). See docs/performance.md.

    ``flown``: chunks of this very batch already flown (:func:`quadrs.runs.chunk.fly_chunk`
    with the same scenario, seed, controllers, spectra and ``sampling = "random"``, as the
    command line's calibration flies the batch's first realisations): taken as they are, not
    flown again. They must lie inside the batch and not overlap.
    """
    controllers = tuple(check_controller(c) for c in controllers)
    if len(set(controllers)) != len(controllers) or not controllers:
        raise ValueError(f"controllers must be distinct and non-empty, got {controllers}")
    runs = check_int("runs", runs, 1, I64_MAX)
    seed = check_int("seed", seed)
    first = check_int("first", first, 0, I64_MAX)
    check_labels(first, runs)
    workers = check_int("workers", default_workers() if workers is None else workers, 1,
                        MAX_WORKERS)  # fmt: skip
    if chunk is not None:
        chunk = check_int("chunk", chunk, 1, I64_MAX)
    # The result table is held in memory: refuse up front what cannot fit, rather than fail
    # (or be killed) after the work is done.
    rows = runs * len(controllers) * len(scenario.phase_names)
    check_memory(f"the result table of runs = {runs} ({rows} rows)", rows * ROW_BYTES)
    if resume and out is None:
        raise ValueError("resume=True needs out= (the directory of the run to continue)")
    from quadrs.scenario.dispersion import SAMPLINGS

    if sampling not in SAMPLINGS:
        raise ValueError(f"sampling must be one of {SAMPLINGS}, got {sampling!r}")
    design = Design(sampling, first, runs)
    if not isinstance(fused, bool):
        raise ValueError(f"fused must be True or False, got {fused!r}")
    arithmetic = arithmetic_of(fused)

    # Say so before a long batch starts on gains that cannot hold hover (docs/model.md section 8)
    # or on a step too coarse for the fastest mode.
    warn_before_running(scenario, controllers, gains=True, stacklevel=2)

    run = batch_identity(scenario, seed, controllers, spectra, design, fused) if flown else ""
    flown = _check_flown(flown or (), first, runs, sampling, run)
    store = RunStore(out) if out is not None else None
    experiment = checkpoint_record(scenario, seed, controllers, spectra, design.record(),
                                   arithmetic)  # fmt: skip
    with contextlib.ExitStack() as held:
        done: set[int] = set()
        if store is not None:
            if store.exists() and resume:
                held.enter_context(store.writing())  # one writer at a time
                store.check_matches(experiment)
                done = store.done_realisations()
            else:
                store.create(experiment)
                held.enter_context(store.writing())
        # A flown chunk the checkpoint holds already is not taken twice.
        flown = [c for c in flown if done.isdisjoint(range(c.first, c.first + c.count))]
        done |= {i for c in flown for i in range(c.first, c.first + c.count)}
        todo = missing_ranges(first, runs, done) if done else [(first, runs)]
        return _fly(scenario, controllers, seed, runs, workers, progress, spectra, out, store,
                    chunk, client, sampling, design, fused, arithmetic, todo,
                    flown)  # fmt: skip


def _check_flown(
    flown: Sequence[Chunk], first: int, runs: int, sampling: str, run: str
) -> list[Chunk]:
    """``monte_carlo``'s ``flown``, checked to be whole chunks of this batch (whose run
    identity is ``run``: the same scenario, seed, controllers, spectra, design and
    arithmetic)."""
    flown = list(flown)
    if not flown:
        return flown
    if sampling != "random":
        raise ValueError(f"flown= needs sampling='random' (a {sampling!r} design depends on runs)")
    seen: set[int] = set()
    for c in flown:
        span = set(range(c.first, c.first + c.count))
        if c.interrupted or c.first < first or c.first + c.count > first + runs or seen & span:
            last = c.first + c.count - 1
            raise ValueError(f"flown: realisations {c.first}..{last} are not a whole new part "
                             f"of the batch {first}..{first + runs - 1}")  # fmt: skip
        if c.run != run:
            raise ValueError("flown: a chunk of another batch (its scenario, seed, "
                             "controllers, spectra or arithmetic; or of none: fly it with "
                             "fly_chunk)")  # fmt: skip
        seen |= span
    return flown


def _fly(
    scenario: Scenario,
    controllers: tuple[str, ...],
    seed: int,
    runs: int,
    workers: int,
    progress: bool,
    spectra: bool,
    out: str | Path | None,
    store: RunStore | None,
    chunk: int | None,
    client: Client | None,
    sampling: str,
    design: Design,
    fused: bool,
    arithmetic: str,
    todo: list[tuple[int, int]],
    flown: list[Chunk],
) -> MonteCarloResult:
    """The batch of :func:`monte_carlo`, its arguments checked and its store (if any) ready."""
    from quadrs.present.terminal import shows_progress, tqdm_class

    tqdm = tqdm_class()

    if client is not None:
        from quadrs.runs.distributed import total_threads

        threads = total_threads(client)
    else:
        threads = workers
    size = chunk or default_chunk(runs, threads, store is not None, client is not None)
    ranges = split_ranges(todo, size)
    parts: list[Chunk] = []
    pending: list[Chunk] = list(flown)
    interrupted = False

    def flush() -> None:
        """Hand finished chunks to the store (or the in-memory list), Ctrl-C held back so each
        lands exactly once (a signal held here marks the batch interrupted)."""
        nonlocal interrupted
        with deferred_signals(deliver=False) as held:
            while pending:
                if store is not None:
                    store.write_part(pending[0])
                else:
                    parts.append(pending[0])
                pending.pop(0)
        interrupted = interrupted or bool(held)

    remaining = sum(c for _, c in ranges)
    bar = tqdm(
        total=runs,
        initial=runs - remaining,
        unit="run",
        desc="quadrs mc",
        delay=1.0,
        disable=not shows_progress(progress),
    )
    interrupted = False
    # Flown here, the batch holds Ctrl-C and SIGTERM from its first chunk to its last flush: a
    # signal cancels the engine call under way (run_cancellable's own handler) or, between
    # calls, stops the batch after the chunk in hand; it is never raised between a chunk's
    # flights and its landing in `pending`, where it would drop them. On Dask the wait for a
    # chunk is the client's, and a signal raises into it.
    holding: contextlib.AbstractContextManager[list[int]] = (
        deferred_signals(deliver=False) if client is None else contextlib.nullcontext([])
    )
    with holding as signalled:
        try:
            chunks = _chunks(scenario, controllers, seed, ranges, workers, spectra, design, bar,
                             fused, client)  # fmt: skip
            try:
                for done in chunks:
                    pending.append(done)
                    flush()
                    if client is not None:
                        bar.update(done.count)
                    # (a signal held while it was flown, assembled or saved)
                    if done.interrupted or interrupted or signalled:
                        interrupted = True
                        break
            finally:
                chunks.close()
        except KeyboardInterrupt:
            # Waiting for Dask (flown here, no KeyboardInterrupt is raised in the batch).
            interrupted = True
        finally:
            # Closing the bar draws on the terminal: a Ctrl-C meanwhile must not skip the flush.
            with deferred_signals(deliver=False) as closing:
                bar.close()
                flush()
            interrupted = interrupted or bool(closing)
    interrupted = interrupted or bool(signalled)
    # What finished is assembled whatever arrives meanwhile: a signal now only marks the
    # batch interrupted (the command line then saves it and exits 130).
    with deferred_signals(deliver=False) as held:
        interrupted = interrupted or bool(held)
        if interrupted:
            warnings.warn(
                "Monte Carlo interrupted: the result holds only the realisations that finished"
                + (
                    f" (saved in {out}; resume=True, or --resume on the command line, continues it)"
                    if out is not None
                    else ""
                ),
                RuntimeWarning,
                stacklevel=3,
            )
        if store is not None:
            return MonteCarloResult.from_store(store, interrupted or bool(held))
        return _in_memory(scenario, seed, controllers, parts, interrupted or bool(held),
                          sampling, arithmetic)  # fmt: skip


def _chunks(
    scenario: Scenario,
    controllers: tuple[str, ...],
    seed: int,
    ranges: Sequence[tuple[int, int]],
    workers: int,
    spectra: bool,
    design: Design,
    bar: Any,
    fused: bool,
    client: Client | None,
) -> Generator[Chunk, None, None]:
    """The batch's chunks as they finish: on Dask, or flown here one after the other, moving
    ``bar`` as realisations finish."""
    if client is not None:
        from quadrs.runs.distributed import run_on_dask

        return run_on_dask(client, scenario, controllers, seed, ranges, spectra, design, fused)

    def advance(base: int) -> Callable[[int], None]:
        return lambda done: bar.update(base + done - bar.n)

    return (fly_chunk(scenario, controllers, seed, first, count, workers, spectra, design,
                      on_progress=advance(bar.n), fused=fused)
            for first, count in ranges)  # fmt: skip


def _in_memory(
    scenario: Scenario,
    seed: int,
    controllers: tuple[str, ...],
    parts: list[Chunk],
    interrupted: bool,
    sampling: str,
    arithmetic: str,
) -> MonteCarloResult:
    """The result of the chunks ``parts`` kept in memory: their rows in realisation order."""
    frames = [part.runs for part in parts]
    if not frames:
        table = empty_runs(scenario)
    elif len(frames) == 1:
        table = frames[0]
    else:
        table = pd.concat(frames, ignore_index=True)
        table = table.sort_values("realisation", kind="stable").reset_index(drop=True)
    # Summed in realisation order, not arrival order (Dask): the same run gives the same bits.
    ordered = sorted(parts, key=lambda part: part.first)
    sums = [part.spectra for part in ordered if part.spectra is not None]
    return _result(scenario, seed, controllers, table, sums, interrupted, sampling, arithmetic)


def _result(
    scenario: Scenario,
    seed: int,
    controllers: tuple[str, ...],
    table: pd.DataFrame,
    sums: list[SpectrumSums],
    interrupted: bool,
    sampling: str,
    arithmetic: str,
) -> MonteCarloResult:
    return MonteCarloResult(
        scenario=scenario,
        seed=seed,
        controllers=controllers,
        runs=table,
        spectrum_sums=functools.reduce(operator.add, sums) if sums else None,
        interrupted=interrupted,
        sampling=sampling,
        arithmetic=arithmetic,
    )
