"""What a Monte Carlo batch produced: the tidy runs table, ensemble spectra, persistence."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from quadrs.io.integrity import RunRecord, check_rows
from quadrs.io.parquet import read_file, write_frame
from quadrs.runs.chunk import (
    SPECTRA_KEY,
    SpectrumSums,
    check_spectrum_counts,
    load_spectra,
    runs_frame,
    spectra_attachment,
)
from quadrs.runs.store import RunStore
from quadrs.scenario.scenario import Scenario
from quadrs.stats.groups import Group, RunTables

__all__ = ["MonteCarloResult", "SpectrumSums", "runs_frame"]

_META_KEY = b"quadrs"


def empty_runs(scenario: Scenario) -> pd.DataFrame:
    """A runs table with every column (those of the dispersed keys too) and no rows."""
    from quadrs.runs.flight import METRIC_COLUMNS
    from quadrs.scenario.dispersion import dispersed_keys

    columns = {"realisation": "int64", "controller": "object", "phase": "object"}
    columns |= {m: "float64" for m in METRIC_COLUMNS}
    columns |= {"diverged": "bool", "diverged_at": "float64"}
    columns |= {k: "float64" for k in dispersed_keys(scenario)}
    return pd.DataFrame({c: pd.Series(dtype=t) for c, t in columns.items()})


@dataclass
class MonteCarloResult(RunTables):
    """Everything a batch produced.

    ``runs``: one row per (realisation, controller, phase) with the metric columns, the
    whole flight's phase ``flight`` included (for every scenario, the paper's too: it is not
    one more phase, so summing a metric over a realisation's rows counts the flight twice;
    :meth:`phases_only` gives the scenario's phases alone), with
    ``diverged`` and ``diverged_at`` (s, NaN if it did not), on every row of the flight. The
    phases that ended before a flight diverged keep their metrics; the one in progress and
    the later ones are NaN (:func:`quadrs.present.table3.phase_diverged`, docs/model.md section 6).
    ``interrupted``: the batch was stopped (Ctrl-C) and ``runs`` holds what had finished.
    """

    scenario: Scenario
    seed: int
    controllers: tuple[str, ...]
    runs: pd.DataFrame
    spectrum_sums: SpectrumSums | None = field(default=None, repr=False)
    interrupted: bool = False
    #: How the dispersed values were drawn ("random", "lhs", "sobol").
    sampling: str = "random"
    #: The engine's arithmetic: "exact" (default; bit-identical on every machine) or "fused"
    #: (``monte_carlo(fused=True)``: fused multiply-adds, faster, not bit-identical).
    arithmetic: str = "exact"
    #: The question a command asked of these runs and saves with them (``quadrs mission``:
    #: ``metric``, ``limit`` in the results' unit, ``track_limit``, ``cross_track_limit``,
    #: ``quantile``), which ``quadrs report`` asks again; None when none was.
    question: dict[str, Any] | None = None

    def phases_only(self) -> pd.DataFrame:
        """``runs`` without the whole flight's ``flight`` rows: the scenario's phases alone."""
        from quadrs.scenario.route import FLIGHT_PHASE

        return self.runs[self.runs["phase"] != FLIGHT_PHASE].reset_index(drop=True)

    @property
    def dispersed_keys(self) -> list[str]:
        """The keys that carried a distribution (a column each in ``runs``)."""
        from quadrs.scenario.dispersion import dispersed_keys

        return dispersed_keys(self.scenario)

    def dispersions(self) -> pd.DataFrame:
        """Per dispersed key: its distribution, how it was sampled, and the range and mean of
        the values the realisations flew."""
        from quadrs.scenario.dispersion import describe

        one = self.runs.drop_duplicates("realisation")
        rows = []
        for key, line in zip(self.dispersed_keys, describe(self.scenario), strict=True):
            v = one[key]
            rows.append(
                {
                    "key": key,
                    "distribution": line.split(" ~ ", 1)[1],
                    "sampling": self.sampling,
                    "min": v.min(),
                    "mean": v.mean(),
                    "max": v.max(),
                }
            )
        return pd.DataFrame(rows, columns=["key", "distribution", "sampling", "min", "mean", "max"])

    def scenario_of(self, realisation: int) -> Scenario:
        """The fixed scenario realisation ``realisation`` flew (its dispersed values set)."""
        rows = self.runs[self.runs["realisation"] == realisation]
        if rows.empty:
            raise KeyError(f"realisation {realisation} is not in this result")
        return self.scenario.fixed({k: float(rows[k].iloc[0]) for k in self.dispersed_keys})

    def __repr__(self) -> str:
        """A summary, not the tables: what ran, how many, how many diverged."""
        n = len(self.realisations)
        diverged = int(self.runs.groupby("realisation")["diverged"].any().sum()) if n else 0
        note = ", interrupted" if self.interrupted else ""
        return (
            f"<MonteCarloResult {n} realisations x {'/'.join(self.controllers)}, seed "
            f"{self.seed}, {diverged} diverged{note}; {self.scenario!r}>"
        )

    def _repr_html_(self) -> str:
        """In a notebook: Table 3 (IAE and ITAE) with its counts, as HTML."""
        from quadrs.present.html import monte_carlo

        return monte_carlo(self)

    @property
    def realisations(self) -> np.ndarray:
        """Indices of the realisations present, sorted."""
        return np.unique(self.runs["realisation"].to_numpy())

    @property
    def spectra(self) -> pd.DataFrame | None:
        """Ensemble amplitude spectra of e_o (mean and std over non-diverged realisations)."""
        if self.spectrum_sums is None:
            return None
        return self.spectrum_sums.frame(self.controllers, self.scenario.phase_names)

    def _groups(self) -> Iterator[Group]:
        yield {}, self.runs, self.scenario.phase_names

    def summary(self, confidence: float = 0.95) -> pd.DataFrame:
        """The paper's Table 3 and more: for each (metric, phase), per controller the mean and
        its confidence interval, and P = 100 * mean(SMC) / mean(PD) with a paired CI. A
        dispersed batch lists its dispersions in ``.attrs["dispersions"]``."""
        table = super().summary(confidence)
        if self.dispersed_keys:
            from quadrs.scenario.dispersion import describe

            table.attrs["dispersions"] = describe(self.scenario)
            table.attrs["sampling"] = self.sampling
        return table

    # -- persistence ----------------------------------------------------------------------
    @property
    def record(self) -> RunRecord:
        """What this run is, as its files record it (the sampling fixes the dispersed values)."""
        return RunRecord(
            self.scenario,
            self.seed,
            self.controllers,
            self.spectrum_sums is not None,
            "sampling",
            self.sampling,
            arithmetic=self.arithmetic,
        )

    def to_parquet(self, path: str | Path) -> None:
        """Write ``runs`` with the scenario, seed, controllers and quadrs version in the file's
        metadata and the ensemble spectra embedded as a table: one result, one file (copy it
        alone). The metadata holds a digest of everything in the file, checked on reading.
        Written to a temporary file, then renamed: never half-written."""
        record = self.record
        spectra, attachments = None, {}
        if self.spectrum_sums is not None:
            spectra, data = spectra_attachment(self.spectrum_sums, record)
            attachments = {SPECTRA_KEY: data}
        asked = {} if self.question is None else {"question": _question(self.question, path)}
        write_frame(self.runs, path, _META_KEY,
                    record.metadata(interrupted=self.interrupted, spectra=spectra, **asked),
                    attachments=attachments)  # fmt: skip

    @classmethod
    def from_store(cls, store: RunStore, interrupted: bool = False) -> MonteCarloResult:
        """Everything a run directory (``monte_carlo(..., out=DIR)``) holds so far."""
        record = store.record
        runs, sums = store.load()
        if runs is None:
            runs = empty_runs(record.scenario)
        sampling = str(record.extra.get("sampling", "random"))
        return cls(record.scenario, record.seed, record.controllers, runs, sums, interrupted,
                   sampling, arithmetic=record.arithmetic)  # fmt: skip

    @classmethod
    def read_parquet(cls, path: str | Path) -> MonteCarloResult:
        """Read a file written by :meth:`to_parquet`, or a run directory written by
        ``monte_carlo(..., out=DIR)`` (complete or not). A file whose rows, metadata or spectra
        were changed, or that lacks the content digest (written before quadrs kept one), is
        refused (:class:`quadrs.io.integrity.CorruptRunError`)."""
        if Path(path).is_dir():
            return cls.from_store(RunStore(path))

        def validate(meta: Any) -> None:
            if meta is None:
                raise ValueError(f"{path} was not written by quadrs (no 'quadrs' metadata)")
            # Types, required keys and the run identity: a foreign or edited file is refused.
            RunRecord.read(meta, path, "sampling", {"interrupted": bool, "sampling": str})

        saved = read_file(path, _META_KEY, validate=validate)
        runs, meta = saved.frame, saved.meta
        record = RunRecord.read(meta, path, "sampling", {"interrupted": bool, "sampling": str})
        check_rows(runs, path, record.controllers, record.scenario.phase_names)
        sums = load_spectra(meta.get("spectra"), path, record, saved.attachments)
        check_spectrum_counts(sums, runs, record.controllers, path)
        return cls(
            scenario=record.scenario,
            seed=record.seed,
            controllers=record.controllers,
            runs=runs,
            spectrum_sums=sums,
            interrupted=meta["interrupted"],
            sampling=meta["sampling"],
            arithmetic=meta.get("arithmetic", "exact"),
            question=_question(meta["question"], path) if "question" in meta else None,
        )


def _question(asked: Any, path: str | Path) -> dict[str, Any]:
    """A saved question checked: a table with a metric the engine names and a finite limit,
    the other entries numbers or None."""
    from quadrs import _core
    from quadrs.io.integrity import CorruptRunError

    def number(v: Any) -> bool:
        return isinstance(v, int | float) and not isinstance(v, bool) and bool(np.isfinite(v))

    def targets(v: Any) -> bool:  # mode -> rate per flight hour (quadrs mission --target)
        return isinstance(v, dict) and all(isinstance(k, str) and number(r) for k, r in v.items())

    ok = (isinstance(asked, dict) and asked.get("metric") in _core.METRIC_NAMES
          and all(v is None or number(v) or (k == "targets" and targets(v))
                  for k, v in asked.items() if k != "metric")
          and isinstance(asked.get("limit"), int | float))  # fmt: skip
    if not ok:
        raise CorruptRunError(f"{path}: its metadata 'question' must be a table with a metric "
                              f"and a finite limit, got {asked!r}")  # fmt: skip
    return dict(asked)
