"""Checkpointed Monte Carlo output: a Parquet dataset directory that grows chunk by chunk.

Layout of ``DIR``::

    DIR/_quadrs.json                 what the run is: scenario, seed, controllers, version,
                                     spectra on/off and the run identity they hash to
    DIR/part-<lo>-<hi>-<id>.parquet  the rows of some finished realisations, with the run
                                     identity in the file's metadata and the name, hash and
                                     counts of their spectrum table
    DIR/spectra-<lo>-<hi>-<hash>.parquet  that table (:func:`quadrs.chunk.save_spectra`)

A part is written to a hidden temporary file and renamed into place, so a killed process
leaves either a whole part or none. The manifest is created exclusively: of two runs started
at once on one directory, one proceeds and the other is refused. Every part is stamped with
the run identity (:mod:`quadrs.integrity`) and checked on reading: a part from another run
(another seed, scenario, controllers or version) is refused, never counted. Because a
realisation's numbers depend only on (scenario, seed, index), resuming computes exactly the
realisations no part holds yet.
"""

from __future__ import annotations

import json
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from quadrs.chunk import Chunk, SpectrumSums, load_spectra, save_spectra
from quadrs.integrity import CorruptRunError, RunRecord, check_rows
from quadrs.parquet import atomic_create, read_frame, read_meta, write_frame
from quadrs.scenario import Scenario

MANIFEST = "_quadrs.json"
_PART_KEY = b"quadrs_part"


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

    def create(
        self,
        scenario: Scenario,
        seed: int,
        controllers: tuple[str, ...],
        spectra: bool = True,
        design: dict[str, Any] | None = None,
        arithmetic: str = "exact",
    ) -> None:
        """Start a new run; refuses to overwrite an existing one (FileExistsError), also when
        another process creates one at the same moment. ``design``: how dispersed values are
        drawn (``sampling``, and for lhs/sobol the batch ``first``, ``runs``)."""
        if self.exists() or self.parts():
            raise FileExistsError(
                f"{self.path} already holds a run: resume it, or choose another output"
            )
        self.path.mkdir(parents=True, exist_ok=True)
        for leftover in self.path.glob(".*.partial"):  # a write cut short by a kill
            leftover.unlink()
        record = RunRecord(scenario, seed, tuple(controllers), bool(spectra), "design",
                           _design(design), arithmetic=arithmetic)  # fmt: skip
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
            text = self.manifest_path.read_text()
        except FileNotFoundError:
            raise FileNotFoundError(f"{self.path} is not a quadrs run (no {MANIFEST})") from None
        try:
            m = json.loads(text)
        except ValueError:
            raise CorruptRunError(f"{str(self.manifest_path)!r} is not valid JSON") from None
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

    def check_matches(
        self,
        scenario: Scenario,
        seed: int,
        controllers: tuple[str, ...],
        spectra: bool = True,
        design: dict[str, Any] | None = None,
        arithmetic: str = "exact",
    ) -> None:
        """Resuming must continue the same experiment, or its rows would not belong together
        (a random-sampled run may be extended; a design (lhs, sobol) is fixed by its batch)."""
        m = self.manifest()
        for what, ours, saved in (
            ("scenario", scenario, self.record.scenario),
            ("seed", seed, m["seed"]),
            ("controllers", list(controllers), m["controllers"]),
            ("spectra setting", bool(spectra), m["spectra"]),
            ("sampling design", _design(design), _design(m.get("design"))),
            ("arithmetic (fused or exact)", arithmetic, self.record.arithmetic),
        ):
            if ours != saved:
                raise ValueError(f"cannot resume {self.path}: its {what} differs from this run's")

    def write_part(self, chunk: Chunk) -> None:
        """Append the rows of a chunk's finished realisations (no-op if none finished): its
        spectrum table first, then the part that names it, so a part is never without it."""
        runs = chunk.runs
        if runs.empty:
            return
        real = runs["realisation"]
        span = f"{real.min():09d}-{real.max():09d}"
        part = self.path / f"part-{span}-{uuid.uuid4().hex[:8]}.parquet"
        spectra = None
        if chunk.spectra is not None:
            spectra = save_spectra(chunk.spectra, part, f"spectra-{span}", self.record)
        write_frame(runs, part, _PART_KEY, {"run": self.run, "spectra": spectra})

    def _part_meta(self, part: Path) -> dict[str, Any]:
        """A part's metadata, refused unless it carries this run's identity."""
        try:
            meta = read_meta(part, _PART_KEY)
        except (OSError, ValueError) as e:
            raise CorruptRunError(f"{str(part)!r}: not a readable part ({e})") from None
        if not isinstance(meta, dict) or meta.get("run") != self.run:
            raise CorruptRunError(
                f"{str(part)!r} does not belong to the run in {str(self.path)!r} (another "
                "seed, scenario, controllers or quadrs version): remove it, or resume "
                "into a fresh directory"
            )
        return meta

    def parts(self) -> list[Path]:
        """The finished parts (temporary files of interrupted writes are never read)."""
        return sorted(self.path.glob("part-*.parquet"))

    def load(self) -> tuple[pd.DataFrame | None, SpectrumSums | None]:
        """All rows so far (sorted by realisation, duplicates dropped) and the summed spectra."""
        frames: list[pd.DataFrame] = []
        sums: SpectrumSums | None = None
        record = self.record
        for part in self.parts():
            self._part_meta(part)
            frame, meta = read_frame(part, _PART_KEY)
            check_rows(frame, part, record.controllers, record.scenario.phase_names)
            frames.append(frame)
            raw = meta.get("spectra") if isinstance(meta, dict) else None
            s = load_spectra(raw, part, record)
            if s is not None:
                sums = s if sums is None else sums + s
        if not frames:
            return None, sums
        runs = pd.concat(frames, ignore_index=True)
        # Identical by construction (same seed and index): a duplicate can only come from a
        # part written twice, and either copy will do.
        runs = runs.drop_duplicates(["realisation", "controller", "phase"])
        runs = runs.sort_values("realisation", kind="stable").reset_index(drop=True)
        return runs, sums

    def done_realisations(self) -> set[int]:
        done: set[int] = set()
        for part in self.parts():
            self._part_meta(part)
            col = pq.read_table(part, columns=["realisation"]).column("realisation")
            done.update(np.unique(col.to_numpy()).tolist())
        return done


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
