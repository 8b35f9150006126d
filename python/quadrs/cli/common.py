"""What every ``quadrs`` subcommand module shares: the bad-input error and the Dask client
of ``--scheduler``. Imported by :mod:`quadrs.cli.main` and the other command modules beside it
alike, so that none of them imports another."""

from __future__ import annotations

import argparse
import contextlib
from collections.abc import Iterator
from typing import Any

__all__ = [
    "EXIT_FAIL",
    "EXIT_INTERRUPT",
    "EXIT_OK",
    "EXIT_TERMINATED",
    "EXIT_USAGE",
    "BadInput",
    "dask_client",
    "scheduler_option",
    "seed_and_workers",
]

#: Exit statuses of every subcommand: done; done but a check failed (or nothing was saved);
#: bad input (one line on stderr); interrupted (Ctrl-C, what finished is saved); terminated.
EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPT, EXIT_TERMINATED = 0, 1, 2, 130, 143


class BadInput(ValueError):
    """Bad command-line input caught by the CLI itself (not by the scenario)."""


@contextlib.contextmanager
def dask_client(address: str | None) -> Iterator[Any]:
    """A Dask client for ``--scheduler`` (None without it): Dask is imported only then."""
    if address is None:
        yield None
        return
    try:
        from dask.distributed import Client
    except ImportError:
        raise BadInput("--scheduler needs Dask: pip install 'quadrs[dask]'") from None
    try:
        client = Client(address, timeout="10s")
    except Exception as e:
        # (a bad port, an unknown protocol, TLS without a context, inproc:// from outside)
        why = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise BadInput(f"--scheduler {address}: cannot connect ({why})") from None
    with client:
        yield client


def scheduler_option(p: argparse.ArgumentParser) -> None:
    """``--scheduler ADDRESS``: the command's flights as tasks on a Dask cluster."""
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="fly on a Dask cluster, e.g. tcp://10.0.0.5:8786, with the same result as here "
        "(needs pip install quadrs[dask])",
    )


def seed_and_workers(p: argparse.ArgumentParser) -> None:
    """The options every batch command takes: ``--seed`` and ``--workers``."""
    p.add_argument("--seed", type=int, default=0, metavar="S", help="master seed (default: 0)")
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="W",
        help="worker threads (default: every core this process may use)",
    )


def limit_option(text: str) -> tuple[str, float]:
    """``--limit METRIC=X`` (any metric the engine names) or a bare ``X`` for max_accel, in
    ``quadrs mc``, ``sweep``, ``report`` and ``mission`` alike; X in the unit the tables show
    (degrees for swing; for an acceleration m/s², or g with a ``g`` suffix: ``2g``), returned
    in the results' unit (radians, m/s²)."""
    from quadrs.present.labels import metric_value
    from quadrs.stats.risk import parse_limit

    if "=" not in text:
        text = f"max_accel={text}"
    name, _, raw = text.partition("=")
    try:
        metric, _ = parse_limit(f"{name}=0")  # the metric's name checked
        return metric, metric_value(metric, raw.strip() or "?")
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None
