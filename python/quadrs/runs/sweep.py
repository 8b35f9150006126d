"""Parameter sweeps: a Monte Carlo batch at every point of a grid over one or two scenario keys.

Every grid point flies the same gust realisations (the same master seed): common random
numbers, so what differs between points is the parameter, not the luck of the draw.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from quadrs.io.integrity import CorruptRunError, RunRecord, check_rows
from quadrs.io.parquet import read_frame, read_meta, write_frame
from quadrs.runs.montecarlo import monte_carlo
from quadrs.scenario.scenario import Scenario, design_keys
from quadrs.stats.groups import Group, RunTables

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

_META_KEY = b"quadrs_sweep"
#: Columns of ``mc.runs`` that a swept key may not shadow.
_RESERVED = frozenset({"realisation", "controller", "phase", "diverged", "diverged_at"})


def column_value(value: Any) -> Any:
    """How a swept value appears in the tidy table: scalars as they are, arrays and tables as
    their JSON text (so the column stays groupable and Parquet-friendly)."""
    if isinstance(value, bool | int | float | str):
        return value
    return json.dumps(value)


def grid_points(grid: Mapping[str, Sequence[Any]]) -> list[dict[str, Any]]:
    """The Cartesian product of the grid, first key outermost: ``{"a": [1, 2], "b": [3]}`` ->
    ``[{"a": 1, "b": 3}, {"a": 2, "b": 3}]``."""
    keys = list(grid)
    return [dict(zip(keys, combo, strict=True)) for combo in itertools.product(*grid.values())]


def check_grid(grid: Mapping[str, Sequence[Any]]) -> dict[str, list[Any]]:
    """A validated copy of the grid: one or two keys, each with at least one value, no key
    that would shadow a column of the runs table."""
    if not 1 <= len(grid) <= 2:
        raise ValueError(f"a sweep takes one or two keys, got {list(grid)}")
    out: dict[str, list[Any]] = {}
    for key, values in grid.items():
        if key in _RESERVED:
            raise ValueError(f"{key}: cannot sweep a key named like a column of the runs")
        if isinstance(values, str | bytes) or not isinstance(values, Sequence):
            raise ValueError(f"{key}: sweep values must be a list, got {values!r}")
        if len(values) == 0:
            raise ValueError(f"{key}: sweep needs at least one value")
        out[key] = list(values)
    return out


@dataclass
class SweepResult(RunTables):
    """What a sweep produced.

    ``runs``: the tidy table of every grid point's Monte Carlo runs (one row per point,
    realisation, controller and phase) with one extra column per swept key, named by the
    key (e.g. ``payload.natural_frequency``). ``interrupted``: the sweep was stopped
    (Ctrl-C); ``runs`` holds every realisation that finished.
    """

    scenario: Scenario
    grid: dict[str, list[Any]]
    seed: int
    controllers: tuple[str, ...]
    runs: pd.DataFrame
    interrupted: bool = False

    @property
    def keys(self) -> list[str]:
        """The swept keys, outermost first."""
        return list(self.grid)

    def __repr__(self) -> str:
        """A summary, not the tables: the grid, the batch at each point, what diverged."""
        grid = ", ".join(f"{k} x{len(v)}" for k, v in self.grid.items())
        n = int(self.runs["realisation"].nunique()) if len(self.runs) else 0
        diverged = int(self.runs["diverged"].sum()) if "diverged" in self.runs else 0
        note = ", interrupted" if self.interrupted else ""
        return (
            f"<SweepResult {grid} points, {n} realisations x {'/'.join(self.controllers)} each, "
            f"seed {self.seed}, {diverged} diverged rows{note}; {self.scenario!r}>"
        )

    def _repr_html_(self) -> str:
        """In a notebook: the compact summary per grid point and phase, as HTML."""
        from quadrs.present.html import render

        if self.runs.empty:
            return render(repr(self), [], ["no grid point finished"])
        return render(repr(self), [("mean IAE and ITAE per controller, P = 100 SMC/PD (%)",
                                    self.compact())])  # fmt: skip

    @property
    def points(self) -> pd.DataFrame:
        """The grid, one row per point (values as they appear in ``runs``)."""
        rows = [{k: column_value(v) for k, v in p.items()} for p in grid_points(self.grid)]
        return pd.DataFrame(rows, columns=self.keys)

    def _group_keys(self) -> list[str]:
        return self.keys

    def _groups(self) -> Iterator[Group]:
        """One group per grid point that has finished runs, in grid order."""
        for _, point in self.points.iterrows():
            mask = np.ones(len(self.runs), dtype=bool)
            for k in self.keys:
                mask &= (self.runs[k] == point[k]).to_numpy()
            sub = self.runs[mask]
            if not sub.empty:
                yield {k: point[k] for k in self.keys}, sub, list(pd.unique(sub["phase"]))

    def compact(self, metrics: Sequence[str] = ("iae", "itae")) -> pd.DataFrame:
        """The summary in one screen: per point and phase, the mean of each metric per
        controller and P = 100 SMC/PD (percent)."""
        summ = self.summary()
        out = {}
        for metric in metrics:
            part = summ.xs(metric, level="metric")
            for c in self.controllers:
                out[f"{metric.upper()} {c.upper()}"] = part[f"{c}_mean"]
            if "P" in part:
                out[f"P_{metric.upper()} %"] = part["P"]
        part = summ.xs(metrics[0], level="metric")
        frame = pd.DataFrame(out)
        frame["n"] = part[[f"{c}_n" for c in self.controllers]].min(axis=1).astype(int)
        frame["diverged"] = part["diverged"]
        return frame

    # -- persistence ----------------------------------------------------------------------
    @property
    def record(self) -> RunRecord:
        """What this sweep is, as its file records it (the grid fixes its rows too)."""
        return RunRecord(self.scenario, self.seed, self.controllers, False, "grid", self.grid)

    def to_parquet(self, path: str | Path) -> None:
        """Write ``runs`` with the base scenario, grid, seed and quadrs version in the file's
        metadata (through a temporary file and a rename: never half-written)."""
        write_frame(self.runs, path, _META_KEY, self.metadata())

    @classmethod
    def read_parquet(cls, path: str | Path) -> SweepResult:
        """Read a file written by :meth:`to_parquet`."""

        def validate(meta: Any) -> None:
            if meta is None:
                raise ValueError(f"{path} was not written by quadrs sweep (no sweep metadata)")
            RunRecord.read(meta, path, "grid", {"interrupted": bool, "grid": dict})

        runs, meta = read_frame(path, _META_KEY, validate=validate)
        record = RunRecord.read(meta, path, "grid", {"interrupted": bool, "grid": dict})
        grid = meta["grid"]
        if not all(isinstance(v, list) for v in grid.values()):
            raise CorruptRunError(f"{str(path)!r}: metadata 'grid' must map keys to lists")
        check_rows(runs, path, record.controllers, record.scenario.phase_names)
        missing = sorted(set(grid) - set(runs.columns))
        if missing:
            raise CorruptRunError(f"{str(path)!r}: its rows lack the swept columns {missing}")
        return cls(
            scenario=record.scenario,
            grid={k: list(v) for k, v in grid.items()},
            seed=record.seed,
            controllers=record.controllers,
            runs=runs,
            interrupted=meta["interrupted"],
        )


def is_sweep_file(path: str | Path) -> bool:
    """True if ``path`` is a Parquet file written by :meth:`SweepResult.to_parquet`."""
    return read_meta(path, _META_KEY) is not None


def sweep(
    scenario: Scenario,
    grid: Mapping[str, Sequence[Any]],
    runs: int = 100,
    seed: int = 0,
    controllers: Sequence[str] = ("pd", "smc"),
    workers: int | None = None,
    progress: bool = True,
    *,
    client: Client | None = None,
) -> SweepResult:
    """A Monte Carlo batch of ``runs`` realisations at every point of ``grid``.

    ``grid`` maps one or two dotted scenario keys to their values, e.g.
    ``{"payload.natural_frequency": [1, 2, 4, 8]}``; with two keys every combination is flown
    (first key outermost). Every point is checked before anything runs, so a bad value fails
    fast with a :class:`quadrs.ScenarioError` naming the key.

    Common random numbers: every grid point uses the same master ``seed``, so realisation
    ``i`` meets the very same gust noise at every point. Differences between points are then
    due to the parameter, not to gust-to-gust scatter, and far fewer runs resolve them.

    Ctrl-C stops the sweep and returns what finished (``result.interrupted`` is then True).
    ``client``: a ``dask.distributed.Client``; each point's realisations then run as chunks
    on the cluster (see :func:`quadrs.monte_carlo`), with results identical to a local sweep.
    """
    checked = check_grid(grid)
    keys = design_keys(scenario, checked, "grid")
    swept = dict(zip(keys, checked.values(), strict=True))
    points = grid_points(swept)
    scenarios = [scenario.override(p) for p in points]  # validate all before running any
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    parts: list[pd.DataFrame] = []
    interrupted = False
    bar = _points_bar(len(points), progress)
    try:
        for point, sc in zip(points, scenarios, strict=True):
            mc = monte_carlo(
                sc,
                runs=runs,
                seed=seed,
                controllers=controllers,
                workers=workers,
                progress=progress,
                spectra=False,
                client=client,
            )
            frame = mc.runs
            for k in reversed(list(swept)):
                frame.insert(0, k, column_value(point[k]))
            parts.append(frame)
            bar.update(1)
            if mc.interrupted:
                interrupted = True
                break
    except KeyboardInterrupt:
        interrupted = True
    finally:
        bar.close()
    table = pd.concat(parts, ignore_index=True) if parts else _empty_runs(swept, controllers)
    return SweepResult(scenario, swept, seed, tuple(controllers), table, interrupted)


def _points_bar(total: int, progress: bool) -> Any:
    from quadrs.present.terminal import shows_progress, tqdm_class

    tqdm = tqdm_class()

    return tqdm(
        total=total,
        unit="point",
        desc="quadrs sweep",
        delay=1.0,
        disable=not shows_progress(progress),
    )


def _empty_runs(grid: Mapping[str, Any], controllers: Sequence[str]) -> pd.DataFrame:
    from quadrs.runs.flight import METRIC_COLUMNS

    cols = [*grid, "realisation", "controller", "phase", *METRIC_COLUMNS, "diverged"]
    return pd.DataFrame(columns=[*cols, "diverged_at"])
