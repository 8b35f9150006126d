"""Variance-based (Sobol') sensitivity of the metrics to the dispersed keys.

Which uncertainty matters most? :func:`sensitivity` flies a Saltelli design over the
scenario's dispersed keys (SALib draws it and estimates the indices; nothing is hand-written)
and returns, per controller, phase and metric, each key's first-order index S1 (the share of
the metric's variance it explains alone) and total index ST (alone and through interactions),
with bootstrap confidence intervals.

The gust is random too. When the scenario has a gust, its realisation is one more factor of
the design, ``"gust"``: a uniform mapped to a gust stream, so the rows that differ only in a
key fly the same gust (the estimators need a deterministic model of the factors) and the
gust's own share of the variance is reported beside the keys'.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from quadrs.io.integrity import RunRecord
from quadrs.io.parquet import read_frame, write_frame
from quadrs.scenario.scenario import Scenario, scenario_error

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

__all__ = ["GUST_FACTOR", "SensitivityResult", "sensitivity", "sobol_design", "sobol_indices"]

#: The name of the gust-realisation factor in the design and the results.
GUST_FACTOR = "gust"
INDEX_COLUMNS = ["controller", "phase", "metric", "parameter", "S1", "S1_conf", "ST", "ST_conf"]
_META_KEY = b"quadrs_sensitivity"
_EDGE = 1e-16


def _problem(names: Sequence[str]) -> dict[str, Any]:
    return {"num_vars": len(names), "names": list(names), "bounds": [[0.0, 1.0]] * len(names)}


def sobol_design(names: Sequence[str], runs: int, seed: int) -> np.ndarray:
    """Saltelli's design (SALib, first and total order): ``runs * (len(names) + 2)`` rows of
    uniforms in (0, 1), one column per factor. ``runs`` should be a power of two."""
    from SALib.sample import sobol as saltelli

    with warnings.catch_warnings():
        # SALib warns on a runs that is not a power of two: sensitivity() checks it itself.
        warnings.simplefilter("ignore", UserWarning)
        u = saltelli.sample(_problem(names), runs, calc_second_order=False, seed=seed)
    return np.clip(u, _EDGE, 1.0 - _EDGE)


def sobol_indices(
    names: Sequence[str], outputs: np.ndarray, seed: int, confidence: float = 0.95
) -> pd.DataFrame:
    """S1, ST and their bootstrap half-widths (SALib) of one output vector over the rows of
    :func:`sobol_design`; NaN where the output is non-finite, or does not vary over the
    design's A and B rows (the estimators' variance: SALib would give 0 and a warning)."""
    from SALib.analyze import sobol

    y = np.asarray(outputs, dtype=np.float64)
    out = pd.DataFrame({"parameter": list(names)})
    step = len(names) + 2  # each row of A, then A with column j from B (j = 1..k), then B
    a_and_b = np.r_[y[0::step], y[step - 1 :: step]]
    if not np.all(np.isfinite(y)) or np.ptp(a_and_b) <= np.finfo(np.float64).eps:
        for col in ("S1", "S1_conf", "ST", "ST_conf"):
            out[col] = np.nan
        return out
    with warnings.catch_warnings():
        # A bootstrap resample whose A and B rows happen to be equal (a metric that is mostly
        # one value, at small N): SALib counts that resample's index as 0 and warns for each.
        warnings.filterwarnings("ignore", message="Constant values encountered")
        si = sobol.analyze(
            _problem(names), y, calc_second_order=False, conf_level=confidence, seed=seed
        )
    for col in ("S1", "S1_conf", "ST", "ST_conf"):
        out[col] = np.asarray(si[col], dtype=np.float64)
    return out


@dataclass(frozen=True)
class SensitivityResult:
    """Sobol' indices of a dispersed scenario.

    ``indices``: tidy, one row per (controller, phase, metric, parameter) with S1, S1_conf,
    ST, ST_conf (``_conf``: half-width of the 95 % bootstrap interval). ``samples``: every
    flight of the design (its factors and metrics).
    """

    scenario: Scenario
    seed: int
    runs: int
    parameters: tuple[str, ...]
    indices: pd.DataFrame
    samples: pd.DataFrame = field(repr=False)

    def __repr__(self) -> str:
        """A summary, not the tables: the design and the most influential parameter."""
        top = ""
        st = self.indices["ST"].dropna()
        if len(st):
            row = self.indices.loc[st.idxmax()]
            top = f"; largest ST {row['ST']:.2f}: {row['parameter']} ({row['controller']} " \
                f"{row['phase']} {row['metric']})"  # fmt: skip
        return (
            f"<SensitivityResult {len(self.parameters)} parameters, {self.runs} runs, seed "
            f"{self.seed}{top}>"
        )

    def _repr_html_(self) -> str:
        """In a notebook: the IAE ranking (largest total index first), as HTML."""
        from quadrs.present.html import render

        table = self.ranking("iae").set_index(["phase", "controller", "parameter"])
        return render(repr(self), [("Sobol' indices of iae (± : 95% half-width)", table)])

    def ranking(self, metric: str = "iae", phase: str | None = None) -> pd.DataFrame:
        """Parameters by total index (largest first) for one metric, per controller and phase."""
        t = self.indices[self.indices["metric"] == metric]
        if phase is not None:
            t = t[t["phase"] == phase]
        return t.sort_values(["phase", "controller", "ST"], ascending=[True, True, False])

    def metadata(self) -> dict[str, Any]:
        """What produced the indices, with a run identity checked when read back."""
        controllers = tuple(str(c) for c in pd.unique(self.indices["controller"]))
        design = {"runs": self.runs, "parameters": list(self.parameters)}
        return RunRecord(self.scenario, self.seed, controllers, False, "design", design).metadata()

    def to_parquet(self, path: str | Path) -> None:
        """Write ``indices`` with what produced them in the file's metadata (atomically)."""
        write_frame(self.indices, path, _META_KEY, self.metadata())

    @classmethod
    def read_parquet(cls, path: str | Path) -> SensitivityResult:
        """Read a file written by :meth:`to_parquet` (its ``samples`` are not stored)."""

        def validate(meta: Any) -> None:
            if meta is None:
                raise ValueError(f"{path} holds no quadrs sensitivity indices")
            # Types, version and the run identity: a foreign or edited file is refused.
            RunRecord.read(meta, path, "design", {"design": dict})

        indices, meta = read_frame(path, _META_KEY, validate=validate)
        scenario = RunRecord.read(meta, path, "design", {"design": dict}).scenario
        missing = set(INDEX_COLUMNS) - set(indices.columns)
        if missing:
            raise ValueError(f"{path} lacks the columns {sorted(missing)}")
        design = meta["design"]
        parameters = tuple(design.get("parameters", ()))
        if not set(indices["parameter"]) <= set(parameters):
            raise ValueError(f"{path}: its indices name parameters its metadata does not")
        return cls(
            scenario=scenario,
            seed=int(meta["seed"]),
            runs=int(design.get("runs", 0)),
            parameters=parameters,
            indices=indices,
            samples=pd.DataFrame(),
        )


def sensitivity(
    scenario: Scenario,
    runs: int = 256,
    seed: int = 0,
    controllers: Sequence[str] = ("pd", "smc"),
    *,
    workers: int | None = None,
    progress: bool = True,
    gust: bool = True,
    confidence: float = 0.95,
    on_progress: Callable[[int], None] | None = None,
    client: Client | None = None,
    chunk: int = 64,
) -> SensitivityResult:
    """Sobol' indices of every metric, per controller and phase, to the scenario's dispersed
    keys (and to the gust realisation, ``gust=True``, when the scenario has a gust).

    ``runs`` is the base sample size N of Saltelli's design (a power of two); it flies
    ``N * (k + 2)`` realisations per controller for k factors. The intervals shrink like
    1/sqrt(N): 256 gives about +/- 0.05 on a dominant key.

    ``client``: a ``dask.distributed.Client``; the design's rows then fly as tasks of ``chunk``
    rows on its workers (``workers`` ignored), with the same result as on this machine, bit
    for bit.
    """
    from quadrs.engine.calls import MAX_WORKERS, check_controller, check_int, default_workers
    from quadrs.runs.chunk import run_range, runs_frame
    from quadrs.runs.flight import METRIC_COLUMNS
    from quadrs.scenario.dispersion import dispersed_keys, values_of_uniforms

    seed = check_int("seed", seed)
    runs = check_int("runs", runs, 2, 2**40)
    if workers is not None:
        workers = check_int("workers", workers, 1, MAX_WORKERS)
    keys = dispersed_keys(scenario)
    if not keys:
        raise scenario_error(
            "sensitivity needs uncertain parameters: give the scenario a [dispersions] table",
            "dispersions",
        )
    if runs < 2 or runs & (runs - 1):
        raise ValueError(f"runs must be a power of two >= 2 (Saltelli's design), got {runs}")
    controllers = tuple(check_controller(c) for c in controllers)
    gusty = gust and bool(scenario["gust.enabled"])
    names = [*keys, GUST_FACTOR] if gusty else keys
    u = sobol_design(names, runs, seed)
    values = pd.DataFrame(values_of_uniforms(scenario, keys, u), columns=keys)
    # The gust factor picks one of 2**32 gust streams; without it every row flies stream 0.
    streams = (
        np.floor(u[:, -1] * 2.0**32).astype(np.uint64)
        if gusty
        else np.zeros(len(u), dtype=np.uint64)
    )
    workers = default_workers() if workers is None else int(workers)
    from quadrs.present.terminal import shows_progress, tqdm_class

    tqdm = tqdm_class()

    with tqdm(
        total=len(u), unit="run", desc="quadrs sensitivity", disable=not shows_progress(progress)
    ) as bar:

        def tick(done: int) -> None:
            bar.update(done - bar.n)
            if on_progress is not None:
                on_progress(done)

        if client is not None:
            from quadrs.runs.distributed import rows_on_dask

            samples = rows_on_dask(
                client, scenario, controllers, seed, values, streams, chunk, tick
            )
        else:
            raw, interrupted = run_range(
                scenario, controllers, seed, 0, len(u), workers, False, tick, values, streams
            )
            if interrupted:
                raise KeyboardInterrupt
            samples = runs_frame(raw, controllers, scenario.phase_names, 0, values)
    phases = scenario.phase_names
    samples = samples.rename(columns={"realisation": "row"})
    if gusty:
        samples[GUST_FACTOR] = np.repeat(streams, len(controllers) * len(phases))
    n_div = int(samples.loc[samples["diverged"], "row"].nunique())
    if n_div:
        warnings.warn(
            f"{n_div} of {len(u)} sensitivity flights diverged: the indices of the affected "
            "controllers are NaN (narrow the distributions, or see quadrs stability)",
            RuntimeWarning,
            stacklevel=2,
        )
    parts = []
    for (ctrl, phase), group in samples.groupby(["controller", "phase"], sort=False):
        group = group.sort_values("row")
        for metric in METRIC_COLUMNS:
            idx = sobol_indices(names, group[metric].to_numpy(), seed, confidence)
            idx.insert(0, "metric", metric)
            idx.insert(0, "phase", phase)
            idx.insert(0, "controller", ctrl)
            parts.append(idx)
    indices = pd.concat(parts, ignore_index=True)[INDEX_COLUMNS]
    return SensitivityResult(scenario, seed, runs, tuple(names), indices, samples)
