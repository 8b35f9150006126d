"""A level's flights over a Dask cluster: ``rare_event(..., client=client)``.

Each batch the sampler asks for (``p0 * per_level`` rows) is split into one block of rows per
Dask worker thread's share, and each block is one engine call on a worker. A row's flight
depends only on its innovations and parameter values (not on which rows fly beside it, nor on
the threads), so the gathered metrics equal a local run's bit for bit, and the sampler, which
runs here, makes the same decisions. Dask is an optional extra: imported only when used.
"""

from __future__ import annotations

from itertools import pairwise
from typing import TYPE_CHECKING

import numpy as np

from quadrs.rare.engine import run_rows
from quadrs.runs.distributed import total_threads, worker_threads

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

__all__ = ["evaluate_on_dask", "fly_rows"]


def fly_rows(
    config: str,
    controller: str,
    keys: list[str],
    gust: np.ndarray,
    values: np.ndarray | None,
    threads: int,
) -> np.ndarray:
    """One block of rows on whichever machine runs it: the engine's metrics
    (rows, phases, metrics), exactly what a local :class:`ScenarioModel` computes."""
    return run_rows(config, controller, keys, gust, values, threads)


def evaluate_on_dask(
    client: Client,
    engine_args: tuple[str, str, list[str]],
    gust: np.ndarray,
    values: np.ndarray | None,
) -> np.ndarray:
    """The metrics of every row, its blocks flown as Dask tasks (one block per worker thread,
    at most); Ctrl-C cancels the tasks not yet finished and raises KeyboardInterrupt."""
    threads = worker_threads(client)
    rows = len(gust)
    blocks = max(1, min(rows, total_threads(client)))
    bounds = np.linspace(0, rows, blocks + 1).round().astype(int)
    futures = []
    for a, b in pairwise(bounds):
        if b > a:
            part = None if values is None else values[a:b]
            futures.append(client.submit(fly_rows, *engine_args, gust[a:b], part, threads,
                                         pure=False, retries=2))  # fmt: skip
    try:
        parts = client.gather(futures)
    except KeyboardInterrupt:
        client.cancel(futures)
        raise
    return np.concatenate([np.asarray(p, dtype=np.float64) for p in parts], axis=0)
