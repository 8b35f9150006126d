"""Past one machine: realisation chunks as Dask tasks.

Each task is one Rust batch over a contiguous range of realisations on a Dask worker; its
rows depend only on (scenario, seed, index), so a task Dask recomputes after losing a worker
gives the very same rows, and the gathered result equals a local run. Dask is an optional
extra (``pip install quadrs[dask]``): nothing here imports it at module level.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
import pandas as pd

from quadrs import _core
from quadrs.runs.chunk import Chunk, Design, fly_chunk
from quadrs.scenario.scenario import Scenario

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client


def run_chunk(
    scenario_toml: str,
    controllers: Sequence[str],
    seed: int,
    first: int,
    count: int,
    workers: int,
    spectra: bool,
    design: Design,
    fused: bool = False,
) -> Chunk:
    """One chunk on whichever machine runs it: the very record a local run makes of it
    (:func:`quadrs.runs.chunk.fly_chunk`), dispersed values drawn from the same (seed, design)."""
    scenario = Scenario.from_toml_string(scenario_toml)
    return fly_chunk(scenario, controllers, seed, first, count, workers, spectra, design,
                     fused=fused)  # fmt: skip


def worker_threads(client: Client) -> int:
    """Threads of the smallest worker: each task's Rust batch uses that many."""
    info = client.scheduler_info()["workers"]
    if not info:
        raise RuntimeError("the Dask cluster has no workers")
    return max(1, min(int(w.get("nthreads", 1)) for w in info.values()))


def total_threads(client: Client) -> int:
    return sum(int(w.get("nthreads", 1)) for w in client.scheduler_info()["workers"].values())


def run_on_dask(
    client: Client,
    scenario: Scenario,
    controllers: Sequence[str],
    seed: int,
    ranges: Sequence[tuple[int, int]],
    spectra: bool,
    design: Design,
    fused: bool = False,
) -> Generator[Chunk, None, None]:
    """Submit one task per (first, count) range; yield each chunk's record as it finishes.
    Closing the iterator early (Ctrl-C) cancels the tasks not yet finished."""
    from dask.base import tokenize
    from dask.distributed import as_completed

    threads = worker_threads(client)
    toml = scenario.to_toml()
    futures = []
    for first, count in ranges:
        # Every input of the chunk is in its key: two calls that differ in anything (scenario,
        # controllers, seed, range, threads, spectra, sampling design, arithmetic) never share
        # a task. Fused chunks may run on workers with other instruction sets: fused numbers
        # are not bit-identical across them (docs/performance.md).
        args = (toml, list(controllers), seed, first, count, threads, spectra, design, fused)
        key = f"quadrs-chunk-{first}-{count}-{tokenize(_core.__version__, *args)}"
        futures.append(client.submit(run_chunk, *args, key=key, pure=True, retries=2))
    try:
        for future in as_completed(futures):
            yield future.result()
    finally:
        client.cancel([f for f in futures if not f.done()])


def run_rows(
    scenario_toml: str,
    controllers: Sequence[str],
    seed: int,
    first: int,
    count: int,
    workers: int,
    values: pd.DataFrame,
    streams: npt.NDArray[np.uint64],
) -> pd.DataFrame:
    """Rows ``first .. first + count`` of a design given row by row (each row's dispersed
    values and gust stream: ``values`` and ``streams`` hold this chunk's rows only), flown on
    whichever machine runs it: the very rows a local run of the whole design makes of them."""
    from quadrs.runs.chunk import run_range, runs_frame

    scenario = Scenario.from_toml_string(scenario_toml)
    raw, _ = run_range(scenario, controllers, seed, first, count, workers, False, None, values,
                       streams)  # fmt: skip
    return runs_frame(raw, controllers, scenario.phase_names, first, values)


def rows_on_dask(
    client: Client,
    scenario: Scenario,
    controllers: Sequence[str],
    seed: int,
    values: pd.DataFrame,
    streams: npt.NDArray[np.uint64],
    chunk: int,
    on_progress: Callable[[int], None] | None = None,
) -> pd.DataFrame:
    """Every row of a given design (``values``, ``streams``: one per row) flown as Dask tasks of
    ``chunk`` rows, gathered in row order: the frame a local run gives, bit for bit (a row's
    numbers depend only on its values, stream and the seed). A task lost with its worker is run
    again (``retries``) and gives the same rows."""
    from dask.base import tokenize
    from dask.distributed import as_completed

    threads = worker_threads(client)
    toml = scenario.to_toml()
    total = len(streams)
    futures = {}
    for first in range(0, total, chunk):
        count = min(chunk, total - first)
        part = values.iloc[first : first + count].reset_index(drop=True)
        args = (toml, list(controllers), seed, first, count, threads, part,
                np.asarray(streams[first : first + count]))  # fmt: skip
        key = f"quadrs-rows-{first}-{count}-{tokenize(_core.__version__, *args)}"
        futures[client.submit(run_rows, *args, key=key, pure=True, retries=2)] = (first, count)
    parts: dict[int, pd.DataFrame] = {}
    try:
        done = 0
        for future in as_completed(list(futures)):
            first, count = futures[future]
            parts[first] = future.result()
            done += count
            if on_progress is not None:
                on_progress(done)
    finally:
        client.cancel([f for f in futures if not f.done()])
    return pd.concat([parts[k] for k in sorted(parts)], ignore_index=True)
