"""Checkpointed Monte Carlo output: a Parquet dataset directory that grows chunk by chunk.

Layout of ``DIR``::

    DIR/_quadrs.json                 what the run is: scenario, seed, controllers, version
    DIR/part-<lo>-<hi>-<id>.parquet  the rows of some finished realisations, with their
                                     spectrum sums in the file's metadata

A part is written to a hidden temporary file and renamed into place, so a killed process
leaves either a whole part or none. Because a realisation's numbers depend only on
(scenario, seed, index), resuming computes exactly the realisations no part holds yet.
"""

from __future__ import annotations

import json
import uuid
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq

from quadrs import _core
from quadrs.parquet import atomic_write_bytes, read_frame, write_frame
from quadrs.results import MonteCarloResult, SpectrumSums
from quadrs.scenario import Scenario

MANIFEST = "_quadrs.json"
_SPECTRA_KEY = b"quadrs_spectra"


class RunStore:
    """The dataset directory of one Monte Carlo run (see the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

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
        design: dict[str, Any] | None = None,
    ) -> None:
        """Start a new run; refuses to overwrite an existing one. ``design``: how dispersed
        values are drawn (``sampling``, and for lhs/sobol the batch ``first``, ``runs``)."""
        if self.exists() or self.parts():
            raise FileExistsError(
                f"{self.path} already holds a run: resume it, or choose another output"
            )
        self.path.mkdir(parents=True, exist_ok=True)
        for leftover in self.path.glob(".*.partial"):  # a write cut short by a kill
            leftover.unlink()
        manifest = {
            "version": _core.__version__,
            "seed": seed,
            "controllers": list(controllers),
            "scenario": scenario.to_toml(),
            "design": design or {"sampling": "random"},
        }
        atomic_write_bytes(self.manifest_path, json.dumps(manifest, indent=1).encode())

    def manifest(self) -> dict[str, Any]:
        try:
            return json.loads(self.manifest_path.read_text())
        except FileNotFoundError:
            raise FileNotFoundError(f"{self.path} is not a quadrs run (no {MANIFEST})") from None

    def check_matches(
        self,
        scenario: Scenario,
        seed: int,
        controllers: tuple[str, ...],
        design: dict[str, Any] | None = None,
    ) -> None:
        """Resuming must continue the same experiment, or its rows would not belong together
        (a random-sampled run may be extended; a design (lhs, sobol) is fixed by its batch)."""
        m = self.manifest()
        theirs = Scenario.from_toml_string(m["scenario"], source=str(self.manifest_path))
        ours_design = design or {"sampling": "random"}
        saved_design = m.get("design", {"sampling": "random"})
        for what, ours, saved in (
            ("scenario", scenario, theirs),
            ("seed", seed, m["seed"]),
            ("controllers", list(controllers), m["controllers"]),
            ("sampling design", ours_design, saved_design),
        ):
            if ours != saved:
                raise ValueError(f"cannot resume {self.path}: its {what} differs from this run's")

    def write_part(self, runs: pd.DataFrame, spectra: SpectrumSums | None) -> None:
        """Append the rows of finished realisations (no-op for an empty frame)."""
        if runs.empty:
            return
        real = runs["realisation"]
        name = f"part-{real.min():09d}-{real.max():09d}-{uuid.uuid4().hex[:8]}.parquet"
        write_frame(runs, self.path / name, _SPECTRA_KEY, spectra.to_json() if spectra else None)

    def parts(self) -> list[Path]:
        """The finished parts (temporary files of interrupted writes are never read)."""
        return sorted(self.path.glob("part-*.parquet"))

    def load(self) -> tuple[pd.DataFrame | None, SpectrumSums | None]:
        """All rows so far (sorted by realisation, duplicates dropped) and the summed spectra."""
        frames, sums = [], None
        for part in self.parts():
            frame, raw = read_frame(part, _SPECTRA_KEY)
            frames.append(frame)
            if raw is not None:
                s = SpectrumSums.from_json(raw)
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
            col = pq.read_table(part, columns=["realisation"]).column("realisation")
            done.update(np.unique(col.to_numpy()).tolist())
        return done

    def result(self, interrupted: bool = False) -> MonteCarloResult:
        m = self.manifest()
        runs, sums = self.load()
        controllers = tuple(m["controllers"])
        scenario = Scenario.from_toml_string(m["scenario"], source=str(self.manifest_path))
        if runs is None:
            runs = pd.DataFrame(columns=["realisation", "controller", "phase"])
        sampling = str(m.get("design", {}).get("sampling", "random"))
        return MonteCarloResult(
            scenario, int(m["seed"]), controllers, runs, sums, interrupted, sampling
        )


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
