"""Monte Carlo batches: paired gust realisations in parallel, results as tidy pandas tables."""

from __future__ import annotations

import functools
import operator
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from quadrs import _core
from quadrs.flight import check_controller
from quadrs.guard import (
    I64_MAX,
    MAX_WORKERS,
    check_int,
    check_labels,
    check_memory,
    run_cancellable,
)
from quadrs.results import MonteCarloResult, SpectrumSums, runs_frame, sums_from_raw
from quadrs.scenario import Scenario

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

__all__ = ["MonteCarloResult", "SpectrumSums", "default_workers", "monte_carlo", "run_range"]

#: Realisations the engine flies at once on its AVX2 and SSE2 paths; chunks are rounded to
#: this (the AVX-512 path flies 8: a chunk then may end in one half-filled lane-set).
LANES = 4
#: Memory (bytes) one row of ``runs`` takes while a batch is assembled: the engine's arrays,
#: the tidy frame and the copies made concatenating and sorting it.
ROW_BYTES = 400


def default_workers() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass(frozen=True)
class Design:
    """How a batch's dispersed values are drawn: the sampling scheme and, for the designs
    (lhs, sobol), the batch they stratify (``runs`` realisations from ``first``)."""

    sampling: str = "random"
    first: int = 0
    runs: int = 1

    def record(self) -> dict[str, Any]:
        """What fixes the values, for a checkpoint's manifest: a random-sampled run may be
        extended, a design is tied to its batch."""
        if self.sampling == "random":
            return {"sampling": "random"}
        return {"sampling": self.sampling, "first": self.first, "runs": self.runs}

    def values(self, scenario: Scenario, seed: int, first: int, count: int) -> pd.DataFrame:
        """The dispersed values of realisations first..first+count (no columns if fixed)."""
        from quadrs.dispersion import draw

        return draw(
            scenario, seed, first, count, runs=self.runs, sampling=self.sampling, offset=self.first
        )


def run_range(
    scenario: Scenario,
    controllers: Sequence[str],
    seed: int,
    first: int,
    count: int,
    workers: int,
    spectra: bool = True,
    on_progress: Callable[[int], None] | None = None,
    values: pd.DataFrame | None = None,
    streams: np.ndarray | None = None,
    fused: bool = False,
) -> tuple[dict[str, Any], bool]:
    """Run realisations first..first+count in the engine (GIL released, on a worker thread)
    while this thread polls progress and turns Ctrl-C into a cancel. ``values``: the
    dispersed keys' values, one row per realisation; ``streams``: the gust stream each one
    flies (default its own index). Returns the engine's arrays and whether it was
    interrupted. A failing ``on_progress`` cancels the batch and re-raises (see
    :func:`quadrs.guard.run_cancellable`)."""
    progress = _core.Progress()
    config_json = scenario.to_json()
    keys, table = dispersion_arrays(values)

    def work() -> dict[str, Any]:
        return _core.run_batch(
            config_json,
            list(controllers),
            seed,
            first,
            count,
            workers,
            spectra,
            progress,
            dispersion_keys=keys,
            dispersion_values=table,
            streams=streams,
            fused=fused,
        )

    poll = None if on_progress is None else lambda: on_progress(progress.done())
    out, interrupted = run_cancellable(work, progress, poll)
    if on_progress is not None:
        on_progress(progress.done())
    return out, interrupted


def dispersion_arrays(values: pd.DataFrame | None) -> tuple[list[str], Any]:
    """The engine's form of a values table: its keys and a C-contiguous (rows, keys) array."""
    if values is None or values.shape[1] == 0:
        return [], None
    return list(values.columns), np.ascontiguousarray(values.to_numpy(dtype=np.float64))


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
) -> MonteCarloResult:
    """Fly realisations ``first .. first + runs`` of the gust under every controller.

    Each realisation flies all controllers through the very same gust (a paired comparison).
    A realisation's numbers depend only on (scenario, seed, realisation index): not on
    ``workers``, chunking, or the machine that ran it. A diverged realisation is flagged in
    ``runs.diverged`` and the batch goes on. Ctrl-C stops promptly and returns what finished
    (``result.interrupted`` is then True).

    ``out``: a directory that receives each chunk's rows as a Parquet part as soon as it
    finishes (see :mod:`quadrs.store`); a killed run loses at most the chunks in flight.
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
    metadata and the run identity). Not yet with ``out=`` or ``client=``. See
    docs/performance.md.
    """
    from tqdm.auto import tqdm

    from quadrs.stability import warn_before_running
    from quadrs.store import RunStore, missing_ranges

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
    from quadrs.dispersion import SAMPLINGS

    if sampling not in SAMPLINGS:
        raise ValueError(f"sampling must be one of {SAMPLINGS}, got {sampling!r}")
    design = Design(sampling, first, runs)
    if not isinstance(fused, bool):
        raise ValueError(f"fused must be True or False, got {fused!r}")
    if fused and (out is not None or client is not None):
        raise ValueError(
            "fused=True is not supported with out= or client= (checkpointed and Dask runs "
            "record only the default arithmetic); drop one of them"
        )

    # Say so before a long batch starts on gains that cannot hold hover (MODEL.md section 6)
    # or on a step too coarse for the fastest mode.
    warn_before_running(scenario, controllers, gains=True, stacklevel=2)

    todo = [(first, runs)]
    store = RunStore(out) if out is not None else None
    if store is not None:
        if store.exists() and resume:
            store.check_matches(scenario, seed, controllers, spectra, design.record())
            todo = missing_ranges(first, runs, store.done_realisations())
        else:
            store.create(scenario, seed, controllers, spectra, design.record())
    if client is not None:
        from quadrs.distributed import total_threads

        threads = total_threads(client)
    else:
        threads = workers
    size = chunk or default_chunk(runs, threads, store is not None, client is not None)
    ranges = split_ranges(todo, size)
    config_json, phases = scenario.to_json(), scenario.phase_names
    parts: list[tuple[Any, SpectrumSums | None]] = []
    pending: list[tuple[Any, SpectrumSums | None]] = []

    def flush() -> None:
        """Hand finished chunks to the store (or the in-memory list). An item leaves `pending`
        only once written, so a Ctrl-C landing mid-write is retried from `finally`."""
        while pending:
            rows, sums = pending[0]
            if store is not None:
                store.write_part(rows, sums)
            else:
                parts.append((rows, sums))
            pending.pop(0)

    remaining = sum(c for _, c in ranges)
    bar = tqdm(
        total=runs,
        initial=runs - remaining,
        unit="run",
        desc="quadrs mc",
        delay=1.0,
        disable=not progress,
    )
    interrupted = False
    try:
        if client is None:
            for f, c in ranges:
                base = bar.n
                values = design.values(scenario, seed, f, c)
                raw, interrupted = run_range(
                    scenario,
                    controllers,
                    seed,
                    f,
                    c,
                    workers,
                    spectra,
                    on_progress=lambda done, base=base: bar.update(base + done - bar.n),
                    values=values,
                    fused=fused,
                )
                pending.append(
                    (
                        runs_frame(raw, controllers, phases, f, values),
                        sums_from_raw(raw, config_json),
                    )
                )
                flush()
                if interrupted:
                    break
        else:
            from quadrs.distributed import run_on_dask

            tasks = run_on_dask(client, scenario, controllers, seed, ranges, spectra, design)
            try:
                for count, rows, sums in tasks:
                    pending.append((rows, SpectrumSums.from_json(sums) if sums else None))
                    flush()
                    bar.update(count)
            finally:
                tasks.close()
    except KeyboardInterrupt:
        # Between chunks (inside one, run_range already turned Ctrl-C into a cancel).
        interrupted = True
    finally:
        bar.close()
        flush()
    if interrupted:
        warnings.warn(
            "Monte Carlo interrupted: the result holds only the realisations that finished"
            + (f" (saved in {out}; resume=True continues it)" if out is not None else ""),
            RuntimeWarning,
            stacklevel=2,
        )
    if store is not None:
        return store.result(interrupted)
    frames = [rows for rows, _ in parts]
    table = pd.concat(frames, ignore_index=True) if len(frames) > 1 else frames[0]
    if len(frames) > 1:
        table = table.sort_values("realisation", kind="stable").reset_index(drop=True)
    sums = [s for _, s in parts if s is not None]
    return MonteCarloResult(
        scenario=scenario,
        seed=seed,
        controllers=controllers,
        runs=table,
        spectrum_sums=functools.reduce(operator.add, sums) if sums else None,
        interrupted=interrupted,
        sampling=sampling,
        arithmetic="fused" if fused else "exact",
    )
