"""Monte Carlo batches: paired gust realisations in parallel, results as tidy pandas tables."""

from __future__ import annotations

import json
import os
import threading
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from quadrs import _core
from quadrs.flight import METRIC_COLUMNS, check_controller
from quadrs.report import summarise
from quadrs.scenario import Scenario

#: Seconds between progress polls (the main thread also answers Ctrl-C at this pace).
POLL_SECONDS = 0.2
_META_KEY = b"quadrs"


def default_workers() -> int:
    """Cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


@dataclass
class SpectrumSums:
    """Ensemble sums of amplitude spectra, per phase an array (n_controllers, bins): they add
    exactly across chunks and machines, and give the mean and spread."""

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

    def to_json(self) -> dict[str, Any]:
        return {
            "frequencies": [f.tolist() for f in self.frequencies],
            "total": [t.tolist() for t in self.total],
            "total_sq": [t.tolist() for t in self.total_sq],
            "count": self.count.tolist(),
        }

    @classmethod
    def from_json(cls, d: dict[str, Any]) -> SpectrumSums:
        return cls(
            [np.asarray(f) for f in d["frequencies"]],
            [np.asarray(t) for t in d["total"]],
            [np.asarray(t) for t in d["total_sq"]],
            np.asarray(d["count"], dtype=np.int64),
        )


@dataclass
class MonteCarloResult:
    """Everything a batch produced.

    ``runs``: one row per (realisation, controller, phase) with the metric columns,
    ``diverged`` and ``diverged_at`` (s, NaN if it did not). Diverged rows keep NaN metrics.
    ``interrupted``: the batch was stopped (Ctrl-C) and ``runs`` holds what had finished.
    """

    scenario: Scenario
    seed: int
    controllers: tuple[str, ...]
    runs: pd.DataFrame
    spectrum_sums: SpectrumSums | None = field(default=None, repr=False)
    interrupted: bool = False

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

    def summary(self, confidence: float = 0.95) -> pd.DataFrame:
        """The paper's Table 3 and more: for each (metric, phase), per controller the mean and
        its confidence interval, and P = 100 * mean(SMC) / mean(PD) with a paired CI."""
        return summarise(self.runs, self.controllers, self.scenario.phase_names, confidence)

    # -- persistence ----------------------------------------------------------------------
    def metadata(self) -> dict[str, Any]:
        return {
            "version": _core.__version__,
            "seed": self.seed,
            "controllers": list(self.controllers),
            "scenario": self.scenario.to_toml(),
            "interrupted": self.interrupted,
            "spectra": self.spectrum_sums.to_json() if self.spectrum_sums else None,
        }

    def to_parquet(self, path: str | Path) -> None:
        """Write ``runs`` with the scenario, seed, controllers, spectra and quadrs version in
        the file's metadata (written to a temporary file, then renamed: never half-written)."""
        path = Path(path)
        table = pa.Table.from_pandas(self.runs, preserve_index=False)
        meta = dict(table.schema.metadata or {})
        meta[_META_KEY] = json.dumps(self.metadata()).encode()
        tmp = path.with_name(f".{path.name}.partial")
        pq.write_table(table.replace_schema_metadata(meta), tmp)
        os.replace(tmp, path)

    @classmethod
    def read_parquet(cls, path: str | Path) -> MonteCarloResult:
        """Read a file written by :meth:`to_parquet`."""
        table = pq.read_table(path)
        raw = (table.schema.metadata or {}).get(_META_KEY)
        if raw is None:
            raise ValueError(f"{path} was not written by quadrs (no 'quadrs' metadata)")
        meta = json.loads(raw)
        spectra = meta.get("spectra")
        return cls(
            scenario=Scenario.from_toml_string(meta["scenario"], source=str(path)),
            seed=int(meta["seed"]),
            controllers=tuple(meta["controllers"]),
            runs=table.to_pandas(),
            spectrum_sums=SpectrumSums.from_json(spectra) if spectra else None,
            interrupted=bool(meta.get("interrupted", False)),
        )


def runs_frame(
    raw: dict[str, Any], controllers: Sequence[str], phases: Sequence[str], first: int
) -> pd.DataFrame:
    """The engine's arrays -> the tidy table (finished realisations only)."""
    metrics = raw["metrics"]  # (count, n_ctrl, n_phase, n_metric)
    done = np.asarray(raw["done"], dtype=bool)
    count, n_ctrl, n_phase, _ = metrics.shape
    real = first + np.arange(count)
    shape = (count, n_ctrl, n_phase)
    diverged_at = np.broadcast_to(raw["diverged_at"][:, :, None], shape)
    keep = np.broadcast_to(done[:, None, None], shape).reshape(-1)
    frame = pd.DataFrame(
        {
            "realisation": np.broadcast_to(real[:, None, None], shape).reshape(-1),
            "controller": np.broadcast_to(np.asarray(controllers)[None, :, None], shape).reshape(
                -1
            ),
            "phase": np.broadcast_to(np.asarray(phases)[None, None, :], shape).reshape(-1),
        }
    )
    for k, name in enumerate(METRIC_COLUMNS):
        frame[name] = metrics[..., k].reshape(-1)
    frame["diverged"] = ~np.isnan(diverged_at.reshape(-1))
    frame["diverged_at"] = diverged_at.reshape(-1)
    frame["realisation"] = frame["realisation"].astype(np.int64)
    return frame[keep].reset_index(drop=True)


def spectrum_sums(raw: dict[str, Any], scenario: Scenario) -> SpectrumSums | None:
    if "spectrum_sum" not in raw:
        return None
    freqs = _core.describe(scenario.to_json())["spectrum_frequencies"]
    return SpectrumSums(
        list(freqs),
        list(raw["spectrum_sum"]),
        list(raw["spectrum_sum_sq"]),
        np.asarray(raw["spectrum_count"], dtype=np.int64),
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
) -> tuple[dict[str, Any], bool]:
    """Run realisations first..first+count in the engine (GIL released, on a worker thread)
    while this thread polls progress and turns Ctrl-C into a cancel. Returns the engine's
    arrays and whether it was interrupted."""
    progress = _core.Progress()
    box: dict[str, Any] = {}
    finished = threading.Event()

    def work() -> None:
        try:
            box["out"] = _core.run_batch(
                scenario.to_json(), list(controllers), seed, first, count, workers, spectra, progress
            )
        except BaseException as e:  # re-raised on the calling thread
            box["error"] = e
        finally:
            finished.set()

    # Poll an Event, not Thread.join: an interrupted join can mark a live thread as finished.
    threading.Thread(target=work, name="quadrs-batch", daemon=True).start()
    interrupted = False
    try:
        while not finished.wait(POLL_SECONDS):
            if on_progress is not None:
                on_progress(progress.done())
    except KeyboardInterrupt:
        progress.cancel()
        interrupted = True
        while not finished.wait(POLL_SECONDS):
            pass
    if "error" in box:
        raise box["error"]
    if on_progress is not None:
        on_progress(progress.done())
    return box["out"], interrupted


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
) -> MonteCarloResult:
    """Fly realisations ``first .. first + runs`` of the gust under every controller.

    Each realisation flies all controllers through the very same gust (a paired comparison).
    A realisation's numbers depend only on (scenario, seed, realisation index): not on
    ``workers`` or on how the range is split. A diverged realisation is flagged in
    ``runs.diverged`` and the batch goes on. Ctrl-C stops promptly and returns what finished
    (``result.interrupted`` is then True).
    """
    from tqdm.auto import tqdm

    controllers = tuple(check_controller(c) for c in controllers)
    if len(set(controllers)) != len(controllers) or not controllers:
        raise ValueError(f"controllers must be distinct and non-empty, got {controllers}")
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    if seed < 0 or first < 0:
        raise ValueError(f"seed and first must be >= 0, got {seed}, {first}")
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")
    from quadrs.stability import StabilityWarning, stability

    # Say so before a long batch starts on gains that cannot hold hover (MODEL.md section 6).
    for name in controllers:
        report = stability(scenario, name)
        if not report.stable:
            warnings.warn(report.warning(), StabilityWarning, stacklevel=2)

    bar = tqdm(total=runs, unit="run", desc="quadrs mc", delay=1.0, disable=not progress)
    try:
        raw, interrupted = run_range(
            scenario,
            controllers,
            seed,
            first,
            runs,
            workers,
            spectra,
            on_progress=lambda done: bar.update(done - bar.n),
        )
    finally:
        bar.close()
    if interrupted:
        warnings.warn(
            "Monte Carlo interrupted: the result holds only the realisations that finished",
            RuntimeWarning,
            stacklevel=2,
        )
    return MonteCarloResult(
        scenario=scenario,
        seed=seed,
        controllers=controllers,
        runs=runs_frame(raw, controllers, scenario.phase_names, first),
        spectrum_sums=spectrum_sums(raw, scenario),
        interrupted=interrupted,
    )
