"""One chunk of a Monte Carlo batch: realisations first .. first + count flown in the engine, and
the record they yield, :class:`Chunk`, the same whether the chunk ran here or on a Dask worker.

A chunk's rows depend only on (scenario, seed, realisation index), so chunks can run anywhere,
in any order, and add up to the batch a single call gives: the rows bit for bit, the
:class:`SpectrumSums` to within rounding (floating-point sums depend on their order).
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from quadrs import _core
from quadrs.engine.calls import deferred_signals, run_cancellable
from quadrs.io.integrity import CorruptRunError, RunRecord, run_identity
from quadrs.io.parquet import frame_bytes, read_frame
from quadrs.runs.flight import METRIC_COLUMNS
from quadrs.scenario.scenario import Scenario

__all__ = [
    "Chunk",
    "Design",
    "SpectrumSums",
    "check_spectrum_counts",
    "fly_chunk",
    "load_spectra",
    "run_range",
    "runs_frame",
    "spectra_attachment",
]

#: The schema-metadata key of a spectrum table: in the table's own bytes it holds the run
#: identity; in a result or part file, the embedded table.
SPECTRA_KEY = b"quadrs_spectra"


@dataclass
class SpectrumSums:
    """Ensemble sums of amplitude spectra, per phase an array (n_controllers, bins): they add
    across chunks and machines (equal to within rounding, not bit for bit, whatever the
    chunking) and give the mean and spread."""

    frequencies: list[np.ndarray]
    total: list[np.ndarray]
    total_sq: list[np.ndarray]
    count: np.ndarray  # per controller

    def __add__(self, other: SpectrumSums) -> SpectrumSums:
        return SpectrumSums(
            self.frequencies,
            [a + b for a, b in zip(self.total, other.total, strict=True)],
            [a + b for a, b in zip(self.total_sq, other.total_sq, strict=True)],
            self.count + other.count,
        )

    def frame(self, controllers: Sequence[str], phases: Sequence[str]) -> pd.DataFrame:
        """Tidy: controller, phase, frequency (Hz), mean and std of the amplitude (m), n."""
        parts = []
        for p, phase in enumerate(phases):
            for c, ctrl in enumerate(controllers):
                n = int(self.count[c])
                mean = self.total[p][c] / max(n, 1)
                var = np.maximum(self.total_sq[p][c] / max(n, 1) - mean**2, 0.0)
                std = np.sqrt(var * n / (n - 1)) if n > 1 else np.full_like(mean, np.nan)
                parts.append(
                    pd.DataFrame(
                        {
                            "controller": ctrl,
                            "phase": phase,
                            "frequency": self.frequencies[p],
                            "mean": mean if n else np.full_like(mean, np.nan),
                            "std": std,
                            "n": n,
                        }
                    )
                )
        return pd.concat(parts, ignore_index=True)

    def table(self, controllers: Sequence[str], phases: Sequence[str]) -> pd.DataFrame:
        """The sums as a tidy table, one row per (phase, controller, frequency bin), the form
        they are saved in; the counts (:attr:`count`) go beside it. :meth:`from_table` reads
        it back exactly."""
        parts = [
            pd.DataFrame(
                {
                    "phase": phase,
                    "controller": ctrl,
                    "frequency": np.asarray(self.frequencies[p], dtype=np.float64),
                    "total": np.asarray(self.total[p][c], dtype=np.float64),
                    "total_sq": np.asarray(self.total_sq[p][c], dtype=np.float64),
                }
            )
            for p, phase in enumerate(phases)
            for c, ctrl in enumerate(controllers)
        ]
        return pd.concat(parts, ignore_index=True)

    @classmethod
    def from_table(
        cls,
        table: pd.DataFrame,
        count: Sequence[int],
        controllers: Sequence[str],
        phases: Sequence[str],
        frequencies: Sequence[np.ndarray],
    ) -> SpectrumSums:
        """The inverse of :meth:`table`, on the run's own frequency grid ``frequencies`` (per
        phase); ValueError saying what does not fit (columns, names, bins, counts)."""
        missing = sorted({"phase", "controller", "frequency", "total", "total_sq"} - set(table))
        if missing:
            raise ValueError(f"the spectrum table lacks the columns {missing}")
        if len(count) != len(controllers) or any(
            isinstance(n, bool) or not isinstance(n, int) or n < 0 for n in count
        ):
            raise ValueError(f"spectrum counts must be one whole number >= 0 per controller, "
                             f"got {count!r}")  # fmt: skip
        keys = [table["phase"].astype(str), table["controller"].astype(str)]
        groups = dict(list(table.groupby(keys, sort=False)))
        if set(groups) - {(p, c) for p in phases for c in controllers}:
            raise ValueError("the spectrum table names phases or controllers the run does not")
        empty = table.iloc[:0]
        total, total_sq = [], []
        for phase, grid in zip(phases, frequencies, strict=True):
            rows = [groups.get((phase, ctrl), empty) for ctrl in controllers]
            for ctrl, g in zip(controllers, rows, strict=True):
                if not np.array_equal(g["frequency"].to_numpy(dtype=np.float64), grid):
                    raise ValueError(f"the spectrum of {ctrl} in phase {phase!r} is not on "
                                     "the run's frequency grid")  # fmt: skip
            total.append(np.stack([g["total"].to_numpy(dtype=np.float64) for g in rows]))
            total_sq.append(np.stack([g["total_sq"].to_numpy(dtype=np.float64) for g in rows]))
        return cls(
            [np.asarray(f, dtype=np.float64) for f in frequencies],
            total,
            total_sq,
            np.asarray(count, dtype=np.int64),
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "frequencies": [f.tolist() for f in self.frequencies],
            "total": [t.tolist() for t in self.total],
            "total_sq": [t.tolist() for t in self.total_sq],
            "count": self.count.tolist(),
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SpectrumSums:
        """Spectra as files written before quadrs saved them as a table hold them."""
        return cls(
            [np.asarray(f) for f in d["frequencies"]],
            [np.asarray(t) for t in d["total"]],
            [np.asarray(t) for t in d["total_sq"]],
            np.asarray(d["count"], dtype=np.int64),
        )


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
        from quadrs.scenario.dispersion import draw

        return draw(
            scenario, seed, first, count, runs=self.runs, sampling=self.sampling, offset=self.first
        )


@dataclass(frozen=True)
class Chunk:
    """What one chunk of realisations produced, wherever it ran: ``count`` realisations from
    ``first`` were asked for; ``runs`` holds the rows of those that finished (all of them
    unless ``interrupted``) and ``spectra`` their spectrum sums (None without spectra);
    ``run``: the run identity of the batch it is part of (:func:`fly_chunk`'s), "" if unknown."""

    first: int
    count: int
    runs: pd.DataFrame
    spectra: SpectrumSums | None
    interrupted: bool = False
    run: str = ""


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
    streams: npt.NDArray[np.uint64] | None = None,
    fused: bool = False,
) -> tuple[_core.BatchResult, bool]:
    """Run realisations first..first+count in the engine (GIL released, on a worker thread)
    while this thread polls progress and turns Ctrl-C into a cancel. ``values``: the
    dispersed keys' values, one row per realisation; ``streams``: the gust stream each one
    flies (default its own index); ``fused``: the opt-in fused arithmetic (not bit-identical
    across instruction sets). Returns the engine's arrays and whether it was
    interrupted. A failing ``on_progress`` cancels the batch and re-raises (see
    :func:`quadrs.engine.calls.run_cancellable`)."""
    progress = _core.Progress()
    engine = scenario.engine
    keys, table = dispersion_arrays(values)

    def work() -> _core.BatchResult:
        return engine.run_batch(
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

    def poll() -> None:
        if on_progress is not None:
            on_progress(progress.done())

    out, interrupted = run_cancellable(work, progress, None if on_progress is None else poll)
    with deferred_signals(deliver=False) as held:  # the flights are done: keep them
        poll()
    return out, interrupted or bool(held)


def dispersion_arrays(
    values: pd.DataFrame | None,
) -> tuple[list[str], npt.NDArray[np.float64] | None]:
    """The engine's form of a values table: its keys and a C-contiguous (rows, keys) array."""
    if values is None or values.shape[1] == 0:
        return [], None
    return list(values.columns), np.ascontiguousarray(values.to_numpy(dtype=np.float64))


def fly_chunk(
    scenario: Scenario,
    controllers: Sequence[str],
    seed: int,
    first: int,
    count: int,
    workers: int,
    spectra: bool,
    design: Design,
    on_progress: Callable[[int], None] | None = None,
    fused: bool = False,
) -> Chunk:
    """Fly one chunk (its dispersed values drawn from (seed, design), so on any machine the
    same) and return its record."""
    values = design.values(scenario, seed, first, count)
    # (before the flights: a Ctrl-C while it was hashed after them lost the finished chunk)
    run = batch_identity(scenario, seed, tuple(controllers), spectra, design, fused)
    raw, interrupted = run_range(
        scenario, controllers, seed, first, count, workers, spectra, on_progress, values,
        fused=fused,
    )  # fmt: skip
    # The flights are done: a Ctrl-C (or SIGTERM) while their rows are assembled must not
    # throw them away. It is held and only marks the chunk interrupted (the batch stops
    # after it, keeping it).
    with deferred_signals(deliver=False) as held:
        rows = runs_frame(raw, controllers, scenario.phase_names, first, values)
        sums = spectrum_sums(raw, scenario)
    return Chunk(first, count, rows, sums, interrupted or bool(held), run)


def arithmetic_of(fused: bool) -> str:
    """The name a run records for its arithmetic: "fused" or "exact" (the default)."""
    return "fused" if fused else "exact"


def batch_identity(
    scenario: Scenario,
    seed: int,
    controllers: tuple[str, ...],
    spectra: bool,
    design: Design,
    fused: bool,
) -> str:
    """The run identity (:func:`quadrs.io.integrity.run_identity`) of the batch a chunk of
    ``design`` belongs to: what ``fly_chunk`` stamps and ``monte_carlo(flown=)`` checks."""
    return run_identity(scenario, seed, controllers, spectra, extra=design.record(),
                        arithmetic=arithmetic_of(fused))  # fmt: skip


def runs_frame(
    raw: _core.BatchResult,
    controllers: Sequence[str],
    phases: Sequence[str],
    first: int,
    values: pd.DataFrame | None = None,
) -> pd.DataFrame:
    """The engine's arrays -> the tidy table (finished realisations only), with a column per
    dispersed key holding the value each realisation flew (``values``, one row each)."""
    metrics = raw["metrics"]  # (count, n_ctrl, n_phase, n_metric)
    done = np.asarray(raw["done"], dtype=bool)
    count, n_ctrl, n_phase, _ = metrics.shape
    real = first + np.arange(count)
    shape = (count, n_ctrl, n_phase)
    diverged_at = np.broadcast_to(raw["diverged_at"][:, :, None], shape)
    keep = np.broadcast_to(done[:, None, None], shape).reshape(-1)

    def flat(a: np.ndarray) -> np.ndarray:
        return np.broadcast_to(a, shape).reshape(-1)

    # The columns gathered first and the table made once (a column at a time, pandas copied
    # its blocks per column: 20 ms a batch call).
    columns: dict[str, np.ndarray] = {
        "realisation": flat(real[:, None, None]).astype(np.int64),
        "controller": flat(np.asarray(controllers)[None, :, None]),
        "phase": flat(np.asarray(phases)[None, None, :]),
    }
    for k, name in enumerate(METRIC_COLUMNS):
        columns[name] = metrics[..., k].reshape(-1)
    columns["diverged"] = ~np.isnan(diverged_at.reshape(-1))
    columns["diverged_at"] = diverged_at.reshape(-1)
    status = flat(np.asarray(raw["status"])[:, :, None])
    columns["status"] = np.asarray(_core.EXIT_STATUSES, dtype=object)[status]
    if values is not None:
        for key in values.columns:
            columns[key] = flat(values[key].to_numpy(dtype=np.float64)[:, None, None])
    return pd.DataFrame(columns)[keep].reset_index(drop=True)


def spectrum_sums(raw: _core.BatchResult, scenario: Scenario) -> SpectrumSums | None:
    """The engine's spectrum arrays -> SpectrumSums on the scenario's frequency grid (known
    since the scenario was validated: no second call into the engine); None without spectra."""
    if "spectrum_sum" not in raw:
        return None
    return SpectrumSums(
        list(scenario.spectrum_frequencies),
        list(raw["spectrum_sum"]),
        list(raw["spectrum_sum_sq"]),
        np.asarray(raw["spectrum_count"], dtype=np.int64),
    )


def spectra_attachment(sums: SpectrumSums, record: RunRecord) -> tuple[dict[str, Any], bytes]:
    """``sums`` as a Parquet table (:meth:`SpectrumSums.table`) stamped with the run identity,
    to embed in the file of the rows they belong to (one result, one file). Returns the
    reference that file keeps in its metadata under ``spectra`` (the table's SHA-256 and the
    counts) and the table's bytes."""
    table = sums.table(record.controllers, record.scenario.phase_names)
    data = frame_bytes(table, SPECTRA_KEY, {"run": record.run})
    ref = {"sha256": hashlib.sha256(data).hexdigest(), "count": [int(n) for n in sums.count]}
    return ref, data


def load_spectra(
    ref: Any, path: str | Path, record: RunRecord, attachments: dict[bytes, bytes]
) -> SpectrumSums | None:
    """The spectrum sums embedded in the file ``path`` of run ``record`` (``attachments``: its
    embedded tables), as its ``spectra`` metadata ``ref`` describes them: checked against the
    SHA-256 and run identity, and against the run's frequency grid. None if it has none.
    CorruptRunError naming the file otherwise."""
    phases = record.scenario.phase_names
    if ref is None or ref is False:
        return None

    def fail(what: str) -> CorruptRunError:
        return CorruptRunError(f"{str(path)!r}: {what}; refusing to read it")

    if not (isinstance(ref, dict) and isinstance(ref.get("sha256"), str)
            and isinstance(ref.get("count"), list)):  # fmt: skip
        raise fail("its spectra metadata is malformed")
    data = attachments.get(SPECTRA_KEY)
    if data is None:
        raise fail("its spectrum table is missing")
    if hashlib.sha256(data).hexdigest() != ref["sha256"]:
        raise fail("its spectrum table is not the one it was written with")
    try:
        frame, meta = read_frame(data, SPECTRA_KEY)
    except (OSError, ValueError) as e:
        raise fail(f"its spectrum table is unreadable ({e})") from None
    if not isinstance(meta, dict) or meta.get("run") != record.run:
        raise fail("its spectrum table belongs to another run")
    try:
        return SpectrumSums.from_table(
            frame, ref["count"], record.controllers, phases, record.scenario.spectrum_frequencies
        )
    except ValueError as e:
        raise fail(f"its spectrum table does not fit it ({e})") from None


def check_spectrum_counts(
    sums: SpectrumSums | None, runs: pd.DataFrame, controllers: Sequence[str], path: str | Path
) -> None:
    """The spectra of a run count, per controller, exactly its finished realisations that did
    not diverge under it (the engine's rule): anything else (a part counted twice, an edited
    count) is refused, naming ``path``."""
    if sums is None:
        return
    if "diverged" in runs and len(runs):
        flown = runs.drop_duplicates(["realisation", "controller"])
        ok = flown[~flown["diverged"].astype(bool)]
        expected = [int((ok["controller"].astype(str) == c).sum()) for c in controllers]
    else:
        expected = [0] * len(controllers)
    got = [int(n) for n in sums.count]
    if got != expected:
        raise CorruptRunError(
            f"{str(path)!r}: its spectra count {got} flights per controller ({list(controllers)})"
            f" but its rows hold {expected} that did not diverge; refusing to read it"
        )
