"""Checkpointed Monte Carlo output: a Parquet dataset directory that grows chunk by chunk.

Layout of ``DIR``::

    DIR/_quadrs.json                 what the run is: scenario, seed, controllers, version,
                                     spectra on/off and the run identity they hash to
    DIR/part-<lo>-<hi>-<id>.parquet  the rows of some finished realisations and their
                                     spectrum sums (embedded), with the run identity and a
                                     digest of the part's contents in its metadata
    DIR/_quadrs.lock                 held (flock) by the one process writing the run

A part is written to a hidden temporary file and renamed into place, so a killed process
leaves either a whole part or none. The manifest is created exclusively: of two runs started
at once on one directory, one proceeds and the other is refused. Every part is stamped with
the run identity (:mod:`quadrs.io.integrity`) and checked on reading: a part from another run
(another seed, scenario, controllers or version) is refused, never counted. Because a
realisation's numbers depend only on (scenario, seed, index), resuming computes exactly the
realisations no part holds yet. Only one process writes a run at a time (a second one is
refused while the first holds the lock), and reading never counts a realisation twice: a part
whose realisations are all in larger parts already read (a copy, or a part written twice) is
skipped, and parts that overlap only in part are refused, naming both.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import os
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd

from quadrs.io.files import MAX_JSON_BYTES, atomic_create, loads_json, read_regular
from quadrs.io.integrity import CorruptRunError, RunRecord, check_rows
from quadrs.io.parquet import read_file, write_frame
from quadrs.runs.chunk import (
    SPECTRA_KEY,
    Chunk,
    SpectrumSums,
    check_spectrum_counts,
    load_spectra,
    spectra_attachment,
)
from quadrs.scenario.scenario import Scenario

MANIFEST = "_quadrs.json"
LOCK = "_quadrs.lock"
_PART_KEY = b"quadrs_part"


@dataclass(frozen=True)
class _Part:
    """A part read and checked: its file, rows, spectra and realisations."""

    path: Path
    runs: pd.DataFrame
    spectra: SpectrumSums | None
    realisations: frozenset[int]


class RunStore:
    """The dataset directory of one Monte Carlo run (see the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._checked: dict[str, Any] | None = None  # the manifest, once validated
        self._record: RunRecord | None = None  # what it says, once validated

    @property
    def manifest_path(self) -> Path:
        return self.path / MANIFEST

    def exists(self) -> bool:
        return self.manifest_path.exists()

    def create(self, record: RunRecord) -> None:
        """Start a new run, the experiment ``record`` (:func:`checkpoint_record`); refuses to
        overwrite an existing one (FileExistsError), also when another process creates one at
        the same moment."""
        if self.exists() or self.parts():
            raise FileExistsError(
                f"{self.path} already holds a run: resume it, or choose another output"
            )
        self.path.mkdir(parents=True, exist_ok=True)
        for leftover in self.path.glob(".*.partial"):  # a write cut short by a kill
            leftover.unlink()
        manifest = record.metadata()
        try:
            atomic_create(self.manifest_path, json.dumps(manifest, indent=1).encode())
        except FileExistsError:
            raise FileExistsError(
                f"{self.path} already holds a run (another process just started one there)"
            ) from None
        self._checked = None

    def manifest(self) -> dict[str, Any]:
        """The manifest, validated (types, keys and its run identity)."""
        if self._checked is not None:
            return self._checked
        try:
            text = read_regular(self.manifest_path, MAX_JSON_BYTES)
        except FileNotFoundError:
            raise FileNotFoundError(f"{self.path} is not a quadrs run (no {MANIFEST})") from None
        try:
            m = loads_json(text, self.manifest_path)
        except ValueError as e:
            raise CorruptRunError(f"{e}; refusing to read it") from None
        self._record = RunRecord.read(m, self.manifest_path, "design",
                                      {"spectra": bool, "design": dict})  # fmt: skip
        self._checked = m
        return m

    @property
    def record(self) -> RunRecord:
        """What the run is (from the validated manifest)."""
        self.manifest()
        assert self._record is not None
        return self._record

    @property
    def run(self) -> str:
        """The run identity every part must carry."""
        return str(self.manifest()["run"])

    def check_matches(self, record: RunRecord) -> None:
        """Resuming must continue the same experiment (``record``: :func:`checkpoint_record`),
        or its rows would not belong together (a random-sampled run may be extended; a design
        (lhs, sobol) is fixed by its batch)."""
        m = self.manifest()
        for what, ours, saved in (
            ("scenario", record.scenario, self.record.scenario),
            ("seed", record.seed, m["seed"]),
            ("controllers", list(record.controllers), m["controllers"]),
            ("spectra setting", record.spectra, m["spectra"]),
            ("sampling design", _design(record.extra), _design(m.get("design"))),
            ("arithmetic (fused or exact)", record.arithmetic, self.record.arithmetic),
        ):
            if ours != saved:
                raise ValueError(f"cannot resume {self.path}: its {what} differs from this run's")

    @contextlib.contextmanager
    def writing(self) -> Iterator[None]:
        """Hold the run's lock while writing parts: a second process that tries to write the
        same run at the same time (two ``--resume`` of one checkpoint) is refused with
        BlockingIOError naming the directory, so no realisation is flown and counted twice."""
        flags = os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_CLOEXEC", 0)
        fd = os.open(self.path / LOCK, flags, 0o666)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                raise BlockingIOError(
                    errno.EWOULDBLOCK, "another quadrs process is writing this run now (wait "
                    "for it to finish, then resume)", str(self.path),
                ) from None  # fmt: skip
            yield
        finally:
            os.close(fd)  # releases the lock

    def write_part(self, chunk: Chunk) -> None:
        """Append the rows of a chunk's finished realisations and their spectrum sums, as one
        file (no-op if none finished)."""
        runs = chunk.runs
        if runs.empty:
            return
        real = runs["realisation"]
        span = f"{real.min():09d}-{real.max():09d}"
        part = self.path / f"part-{span}-{uuid.uuid4().hex[:8]}.parquet"
        spectra, attachments = None, {}
        if chunk.spectra is not None:
            spectra, data = spectra_attachment(chunk.spectra, self.record)
            attachments = {SPECTRA_KEY: data}
        write_frame(runs, part, _PART_KEY, {"run": self.run, "spectra": spectra},
                    attachments=attachments)  # fmt: skip

    def _read_part(self, part: Path) -> _Part:
        """A part, refused unless whole, unedited and carrying this run's identity."""
        record = self.record

        def ours(meta: Any) -> None:
            if not isinstance(meta, dict) or meta.get("run") != self.run:
                raise CorruptRunError(
                    f"{str(part)!r} does not belong to the run in {str(self.path)!r} (another "
                    "seed, scenario, controllers or quadrs version): remove it, or resume "
                    "into a fresh directory"
                )

        try:
            saved = read_file(part, _PART_KEY, validate=ours)
        except CorruptRunError:
            raise
        except (OSError, ValueError) as e:
            raise CorruptRunError(f"{str(part)!r}: not a readable part ({e})") from None
        meta = saved.meta
        check_rows(saved.frame, part, record.controllers, record.scenario.phase_names)
        sums = load_spectra(meta.get("spectra"), part, record, saved.attachments)
        check_spectrum_counts(sums, saved.frame, record.controllers, part)
        done = frozenset(int(i) for i in pd.unique(saved.frame["realisation"]))
        return _Part(part, saved.frame, sums, done)

    def parts(self) -> list[Path]:
        """The finished parts (temporary files of interrupted writes are never read)."""
        return sorted(self.path.glob("part-*.parquet"))

    def _selected(self) -> list[_Part]:
        """The parts that hold each realisation once: larger parts first; a part whose
        realisations are all held already (a copy, a part written twice) is skipped, rows and
        spectra alike; one that overlaps the held ones only in part is refused."""
        parts = [self._read_part(p) for p in self.parts()]
        parts.sort(key=lambda p: (-len(p.realisations), min(p.realisations), p.path.name))
        chosen: list[_Part] = []
        held: set[int] = set()
        for part in parts:
            common = held & part.realisations
            if not common:
                chosen.append(part)
                held |= part.realisations
            elif common != part.realisations:
                other = next(c.path for c in chosen if c.realisations & part.realisations)
                raise CorruptRunError(
                    f"{str(part.path)!r} and {str(other)!r} hold some of the same realisations "
                    "(written by two runs at once?): remove one of them, then resume"
                )
        return chosen

    def load(self) -> tuple[pd.DataFrame | None, SpectrumSums | None]:
        """All rows so far (sorted by realisation), each realisation once, and the summed
        spectra of exactly those rows."""
        chosen = self._selected()
        if not chosen:
            return None, None
        sums: SpectrumSums | None = None
        for part in sorted(chosen, key=lambda p: min(p.realisations)):
            if part.spectra is not None:
                sums = part.spectra if sums is None else sums + part.spectra
        runs = pd.concat([p.runs for p in chosen], ignore_index=True)
        runs = runs.sort_values("realisation", kind="stable").reset_index(drop=True)
        check_spectrum_counts(sums, runs, self.record.controllers, self.path)
        return runs, sums

    def done_realisations(self) -> set[int]:
        done: set[int] = set()
        for part in self._selected():
            done |= part.realisations
        return done


def checkpoint_record(
    scenario: Scenario,
    seed: int,
    controllers: tuple[str, ...],
    spectra: bool = True,
    design: dict[str, Any] | None = None,
    arithmetic: str = "exact",
) -> RunRecord:
    """The experiment a checkpoint holds: the scenario, seed, controllers, whether spectra are
    kept, ``design`` (how dispersed values are drawn: ``sampling``, and for lhs/sobol the
    batch ``first``, ``runs``) and the arithmetic; what :meth:`RunStore.create` starts and
    :meth:`RunStore.check_matches` resumes."""
    return RunRecord(scenario, seed, tuple(controllers), bool(spectra), "design",
                     _design(design), arithmetic=arithmetic)  # fmt: skip


def _design(design: dict[str, Any] | None) -> dict[str, Any]:
    """A run's sampling design in one form (older manifests have none: random)."""
    return dict(design) if design else {"sampling": "random"}


def missing_ranges(first: int, runs: int, done: set[int]) -> list[tuple[int, int]]:
    """Contiguous (first, count) ranges of first..first+runs that are not in ``done``."""
    out: list[tuple[int, int]] = []
    start = None
    for i in range(first, first + runs + 1):
        todo = i < first + runs and i not in done
        if todo and start is None:
            start = i
        elif not todo and start is not None:
            out.append((start, i - start))
            start = None
    return out
