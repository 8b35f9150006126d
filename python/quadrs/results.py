"""What a Monte Carlo batch produced: the tidy runs table, ensemble spectra, persistence."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from quadrs import _core
from quadrs.flight import METRIC_COLUMNS
from quadrs.integrity import check_rows, check_run_metadata, check_spectra, run_identity
from quadrs.parquet import read_frame, write_frame
from quadrs.report import summarise
from quadrs.scenario import Scenario

_META_KEY = b"quadrs"


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
    #: How the dispersed values were drawn ("random", "lhs", "sobol").
    sampling: str = "random"
    #: The engine's arithmetic: "exact" (default; bit-identical on every machine) or "fused"
    #: (``monte_carlo(fused=True)``: fused multiply-adds, faster, not bit-identical).
    arithmetic: str = "exact"

    @property
    def dispersed_keys(self) -> list[str]:
        """The keys that carried a distribution (a column each in ``runs``)."""
        from quadrs.dispersion import dispersed_keys

        return dispersed_keys(self.scenario)

    def dispersions(self) -> pd.DataFrame:
        """Per dispersed key: its distribution, how it was sampled, and the range and mean of
        the values the realisations flew."""
        from quadrs.dispersion import describe

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
        its confidence interval, and P = 100 * mean(SMC) / mean(PD) with a paired CI. A
        dispersed batch lists its dispersions in ``.attrs["dispersions"]``."""
        table = summarise(self.runs, self.controllers, self.scenario.phase_names, confidence)
        if self.dispersed_keys:
            from quadrs.dispersion import describe

            table.attrs["dispersions"] = describe(self.scenario)
            table.attrs["sampling"] = self.sampling
        return table

    def exceedance(
        self,
        metric: str,
        threshold: float,
        confidence: float = 0.95,
        *,
        paired: bool = False,
        controllers: tuple[str, str] = ("smc", "pd"),
        half_width: float = 0.01,
        relative: bool = False,
    ) -> pd.DataFrame:
        """P(metric > threshold) per controller and phase with an exact (Clopper-Pearson)
        interval, the counts behind it and ``runs_needed`` for an interval half-width of
        ``half_width`` (default 0.01: +-1 percentage point; with ``relative``, a fraction of the
        probability). Diverged realisations count as exceedances (column ``diverged``).

        ``paired=True``: instead, per phase, P(a exceeds) - P(b exceeds) for ``controllers =
        (a, b)`` on the same gusts, with Newcombe's paired interval and McNemar's exact test.
        See :mod:`quadrs.risk` and docs/risk.md."""
        from quadrs import risk

        phases = self.scenario.phase_names
        if paired:
            pair = risk.check_pair(self.controllers, controllers)
            return risk.exceedance_difference_table(
                self.runs, metric, threshold, phases, pair, confidence
            )
        return risk.exceedance_table(
            self.runs, metric, threshold, self.controllers, phases, confidence, half_width, relative
        )

    def quantile(
        self,
        metric: str,
        q: float,
        confidence: float = 0.95,
        *,
        paired: bool = False,
        controllers: tuple[str, str] = ("smc", "pd"),
    ) -> pd.DataFrame:
        """The ``q``-quantile of ``metric`` per controller and phase with a distribution-free
        (order-statistic) interval; diverged realisations count as +inf. ``paired=True``: per
        phase, the ``q``-quantile of the per-realisation difference a - b instead."""
        from quadrs import risk

        phases = self.scenario.phase_names
        if paired:
            pair = risk.check_pair(self.controllers, controllers)
            return risk.quantile_difference_table(self.runs, metric, q, phases, pair, confidence)
        return risk.quantile_table(self.runs, metric, q, self.controllers, phases, confidence)

    # -- persistence ----------------------------------------------------------------------
    def metadata(self) -> dict[str, Any]:
        return {
            "version": _core.__version__,
            "seed": self.seed,
            "controllers": list(self.controllers),
            "scenario": self.scenario.to_toml(),
            "interrupted": self.interrupted,
            "sampling": self.sampling,
            "arithmetic": self.arithmetic,
            "spectra": self.spectrum_sums.to_json() if self.spectrum_sums else None,
            "run": run_identity(
                self.scenario,
                self.seed,
                self.controllers,
                self.spectrum_sums is not None,
                extra=self.sampling,
                arithmetic=self.arithmetic,
            ),
        }

    def to_parquet(self, path: str | Path) -> None:
        """Write ``runs`` with the scenario, seed, controllers, spectra and quadrs version in
        the file's metadata (written to a temporary file, then renamed: never half-written)."""
        write_frame(self.runs, path, _META_KEY, self.metadata())

    @classmethod
    def read_parquet(cls, path: str | Path) -> MonteCarloResult:
        """Read a file written by :meth:`to_parquet`, or a run directory written by
        ``monte_carlo(..., out=DIR)`` (complete or not)."""
        if Path(path).is_dir():
            from quadrs.store import RunStore  # the store builds on this module

            return RunStore(path).result()
        runs, meta = read_frame(path, _META_KEY)
        if meta is None:
            raise ValueError(f"{path} was not written by quadrs (no 'quadrs' metadata)")
        # Types, required keys and the run identity: a foreign or edited file is refused.
        scenario = check_run_metadata(
            meta, path, {"interrupted": bool, "sampling": str}, extra_key="sampling"
        )
        controllers = tuple(meta["controllers"])
        check_rows(runs, path, controllers, scenario.phase_names)
        spectra = meta.get("spectra")
        if spectra is not None:
            check_spectra(spectra, path, len(controllers), len(scenario.phase_names))
        return cls(
            scenario=scenario,
            seed=meta["seed"],
            controllers=controllers,
            runs=runs,
            spectrum_sums=SpectrumSums.from_json(spectra) if spectra else None,
            interrupted=meta["interrupted"],
            sampling=meta["sampling"],
            arithmetic=meta.get("arithmetic", "exact"),
        )


def runs_frame(
    raw: dict[str, Any],
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
    if values is not None:
        for key in values.columns:
            column = values[key].to_numpy(dtype=np.float64)
            frame[key] = np.broadcast_to(column[:, None, None], shape).reshape(-1)
    return frame[keep].reset_index(drop=True)


def sums_from_raw(raw: dict[str, Any], config_json: str) -> SpectrumSums | None:
    """The engine's spectrum arrays -> SpectrumSums (None when spectra were not asked for)."""
    if "spectrum_sum" not in raw:
        return None
    freqs = _core.describe(config_json)["spectrum_frequencies"]
    return SpectrumSums(
        list(freqs),
        list(raw["spectrum_sum"]),
        list(raw["spectrum_sum_sq"]),
        np.asarray(raw["spectrum_count"], dtype=np.int64),
    )
