"""What :func:`quadrs.rare_event` found: the estimate, its uncertainty, the levels, the failures."""

from __future__ import annotations

import dataclasses
import html
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from quadrs.rare.subset import Level, SubsetRun, lognormal_interval

if TYPE_CHECKING:  # pragma: no cover
    from quadrs.rare.scenario_model import RareEventModel
    from quadrs.runs.flight import Flight

__all__ = ["RareEventComparison", "RareEventResult"]

_META_KEY = b"quadrs"
#: What a saved result records (name -> type), checked on reading.
_FIELDS: dict[str, Any] = {
    "value_name": str,
    "method": str,
    "threshold": float,
    "per_level": int,
    "p0": float,
    "max_levels": int,
    "dimension": int,
    "flights": int,
    "closest": float,
    "levels": list,
}

#: Columns of ``RareEventResult.levels``.
LEVEL_COLUMNS = ("level", "threshold", "conditional_p", "acceptance_rate", "flights", "above",
                 "gamma", "cov", "sigma")  # fmt: skip


@dataclass
class RareEventResult:
    """P(value > threshold) estimated by subset simulation.

    ``probability``: the estimate (None if no sample crossed the threshold: then
    ``upper_bound`` holds the estimated probability of the highest level reached, which the
    failure probability does not exceed, and ``closest`` the largest value seen).
    ``cov``: its coefficient of variation (Au & Beck, with the chains' correlation).
    ``interval``: 95 % interval, lognormal with that coefficient of variation.
    ``levels``: one row per level (see :data:`LEVEL_COLUMNS`). ``flights``: model evaluations
    in all. ``failures``: the last level's failure samples (each chain state once; ``copies``:
    how many of the level's samples it stands for), their values; their standard normals are
    the rows of ``xi``. ``flight(k)`` re-flies failure sample ``k`` (scenario runs only).
    """

    run: SubsetRun = field(repr=False)
    #: What the value is: the metric and phase of a scenario run, or "limit_state".
    value_name: str = "value"
    #: "subset" (the only method so far).
    method: str = "subset"
    #: The model of flights that produced a scenario run (None for a limit-state function).
    model: RareEventModel | None = field(default=None, repr=False)
    confidence: float = 0.95

    # -- the estimate ---------------------------------------------------------------------
    @property
    def probability(self) -> float | None:
        """The estimate of P(value > threshold); None if no failure was found."""
        return self.run.probability

    @property
    def cov(self) -> float | None:
        """The estimate's coefficient of variation; None if no failure was found."""
        return self.run.cov

    @property
    def interval(self) -> tuple[float, float] | None:
        """The 95 % interval, inside [0, 1]: lognormal from :attr:`cov` with a t quantile on
        the failures' independent ancestries (Clopper-Pearson when plain Monte Carlo reached
        the threshold); (0, upper_bound) if no failure was found; None when interrupted."""
        if self.run.interval is not None:
            return self.run.interval
        if self.run.probability is None or self.run.cov is None:
            return None if self.run.upper_bound is None else (0.0, self.run.upper_bound)
        return lognormal_interval(self.run.probability, self.run.cov, self.confidence)

    @property
    def upper_bound(self) -> float | None:
        """Without a failure: a 95 % upper confidence bound on the probability (when
        interrupted: the estimated probability of the last cut reached, no bound)."""
        return self.run.upper_bound

    @property
    def interrupted(self) -> bool:
        """True if Ctrl-C stopped the run: :attr:`levels` are the levels done, no estimate."""
        return self.run.interrupted

    @property
    def reached(self) -> bool:
        """True if some sample crossed the threshold."""
        return self.run.reached

    @property
    def threshold(self) -> float:
        return self.run.threshold

    @property
    def closest(self) -> float:
        """The largest value any sample reached."""
        return self.run.closest

    @property
    def dimension(self) -> int:
        """Standard normals per sample."""
        return self.run.dimension

    @property
    def seed(self) -> int:
        return self.run.seed

    @property
    def flights(self) -> int:
        """Model evaluations (flights) in all."""
        return self.run.flights

    @property
    def monte_carlo_flights(self) -> float | None:
        """Flights plain Monte Carlo would need for the same coefficient of variation:
        (1 - p) / (p cov^2)."""
        p, c = self.run.probability, self.run.cov
        if p is None or c is None or c == 0:
            return None
        return (1.0 - p) / (p * c * c)

    # -- tables ---------------------------------------------------------------------------
    @property
    def levels(self) -> pd.DataFrame:
        """level, threshold (the cut the level set; the target on the last), conditional_p,
        acceptance_rate (NaN on level 0), flights, above (samples above the cut), gamma (the
        chains' correlation factor), cov (of conditional_p), sigma (the proposal's step)."""
        rows = [dataclasses.asdict(level) for level in self.run.levels]
        return pd.DataFrame(rows, columns=list(LEVEL_COLUMNS))

    @property
    def failures(self) -> pd.DataFrame:
        """One row per failure sample k: ``sample`` (k), the value (column named after it),
        ``copies``, ``chain`` and ``step`` (where the chain reached it; on level 0, ``chain``
        is the sample's index), then, for a dispersed scenario, each dispersed key's value
        (the parameters the flight flew). Their standard normals: ``xi[k]``."""
        run = self.run
        frame = pd.DataFrame(
            {
                "sample": np.arange(len(run.failure_values)),
                self.value_name: run.failure_values,
                "copies": run.failure_copies,
                "chain": run.failure_chain,
                "step": run.failure_step,
            }
        )
        keys = getattr(self.model, "parameter_keys", ())
        if keys:
            theta = self.model.parameters(run.failure_xi)  # type: ignore[union-attr]
            for j, key in enumerate(keys):
                frame[key] = theta[:, j]
        return frame

    @property
    def xi(self) -> np.ndarray:
        """The failure samples' standard normals, shape (failures, dimension)."""
        return self.run.failure_xi

    def flight(self, k: int) -> Flight:
        """Re-fly failure sample ``k`` with its trace (scenario runs only)."""
        n = len(self.run.failure_values)
        if isinstance(k, bool) or not isinstance(k, int | np.integer) or not 0 <= k < n:
            raise IndexError(f"k must be a failure sample index in 0 .. {n - 1}, got {k!r}")
        if self.model is None:
            raise ValueError(
                "flight(k) re-flies a failure of a scenario run; this result is of a "
                "limit_state function, which has no flight: its failure sample k is "
                "result.xi[k] and its value result.failures.loc[k]"
            )
        import dataclasses

        flight = self.model.fly(self.run.failure_xi[int(k)])
        # Not realisation 0 of a seed: the sampler's k-th failure, flown from its innovations.
        return dataclasses.replace(flight, label=f"failure sample {int(k)} of a rare-event run")

    # -- files ----------------------------------------------------------------------------
    def metadata(self) -> dict[str, Any]:
        """What produced this result and what it found, as its saved file records them. A
        scenario run carries the run record (scenario, seed, controller, and under
        ``rare_event`` the metric, phase and settings) and its run identity."""
        run = self.run
        fields: dict[str, Any] = {
            "kind": "rare_event",
            "value_name": self.value_name,
            "method": self.method,
            "threshold": run.threshold,
            "per_level": run.per_level,
            "p0": run.p0,
            "max_levels": run.max_levels,
            "dimension": run.dimension,
            "flights": run.flights,
            "closest": run.closest,
            "probability": run.probability,
            "cov": run.cov,
            "upper_bound": run.upper_bound,
            "interval": None if run.interval is None else list(run.interval),
            "pilot_flights": run.pilot_flights,
            "clusters": run.clusters,
            "interrupted": run.interrupted,
            "levels": [dataclasses.asdict(level) for level in run.levels],
        }
        record = self._record()
        if record is None:
            from quadrs import _core

            return {"version": _core.__version__, "seed": run.seed, **fields}
        return record.metadata(**fields)

    def _record(self) -> Any:
        from quadrs.rare.scenario_model import ScenarioModel

        model = self.model
        if not isinstance(model, ScenarioModel):
            return None
        from quadrs.io.integrity import RunRecord

        run = self.run
        extra = {"metric": model.metric, "phase": model.phase, "threshold": run.threshold,
                 "per_level": run.per_level, "p0": run.p0, "max_levels": run.max_levels,
                 "method": self.method}  # fmt: skip
        return RunRecord(model.scenario, run.seed, (model.controller,), False, "rare_event", extra)

    def to_parquet(self, path: str | Path) -> None:
        """Write :attr:`failures` with each sample's standard normals (column ``xi``) and
        :meth:`metadata` (the estimate, the levels, the settings); written to a temporary
        file, then renamed, so never half-written."""
        from quadrs.io.parquet import write_frame
        from quadrs.runs.flight import _json_safe

        frame = self.failures
        frame["xi"] = list(self.run.failure_xi)
        write_frame(frame, path, _META_KEY, _json_safe(self.metadata()))

    @classmethod
    def read_parquet(cls, path: str | Path) -> RareEventResult:
        """Read a file written by :meth:`to_parquet`. A scenario run's file must match its
        run identity (else :class:`quadrs.io.integrity.CorruptRunError`) and comes back with its
        model, so ``flight(k)`` re-flies its failures."""
        from quadrs.io.integrity import RunRecord, _fail
        from quadrs.io.parquet import read_frame

        frame, meta = read_frame(path, _META_KEY)
        if not isinstance(meta, dict) or meta.get("kind") != "rare_event":
            raise _fail(path, "it is not a quadrs rare-event result (no rare_event metadata)")
        for key, kind in {**_FIELDS, "seed": int, "version": str}.items():
            value = meta.get(key)
            ok = isinstance(value, kind) or (kind is float and isinstance(value, int))
            ok = ok or (key == "closest" and value is None)  # +inf (a diverged flight)
            if not ok or (kind is int and isinstance(value, bool)):
                raise _fail(path, f"metadata {key!r} must be {kind.__name__}, got {value!r}")
        model = None
        if "scenario" in meta:
            from quadrs.rare.scenario_model import ScenarioModel

            record = RunRecord.read(meta, path, "rare_event")
            extra = record.extra if isinstance(record.extra, dict) else {}
            if extra.get("threshold") != meta["threshold"] or len(record.controllers) != 1:
                raise _fail(path, "its settings disagree with its run identity (edited?)")
            try:
                model = ScenarioModel(record.scenario, record.controllers[0], extra["metric"],
                                      extra["phase"])  # fmt: skip
            except (KeyError, ValueError) as e:
                raise _fail(path, f"its scenario run is invalid ({e})") from None
        else:
            from quadrs import _core

            if meta["version"] != _core.__version__:
                raise _fail(path, f"written by quadrs {meta['version']}, this is "
                                  f"{_core.__version__}")  # fmt: skip
        try:
            levels = [Level(**{k: _nan(v) for k, v in row.items()}) for row in meta["levels"]]
            interrupted = meta.get("interrupted") is True
            n = len(frame)
            dimension = meta["dimension"]
            xi = np.stack(frame["xi"].to_numpy()) if n else np.empty((0, dimension))
            if xi.shape != (n, dimension):
                raise ValueError(f"xi has shape {xi.shape}, not ({n}, {dimension})")
            run = SubsetRun(
                probability=_number(meta.get("probability")),
                cov=_number(meta.get("cov")),
                upper_bound=_number(meta.get("upper_bound")),
                levels=levels,
                flights=meta["flights"],
                failure_xi=xi.astype(np.float64),
                failure_values=frame[meta["value_name"]].to_numpy(np.float64),
                failure_copies=frame["copies"].to_numpy(np.int64),
                failure_chain=frame["chain"].to_numpy(np.int64),
                failure_step=frame["step"].to_numpy(np.int64),
                closest=_closest(meta["closest"], interrupted and not levels),
                dimension=dimension,
                threshold=float(meta["threshold"]),
                per_level=meta["per_level"],
                p0=float(meta["p0"]),
                seed=meta["seed"],
                max_levels=meta["max_levels"],
                interrupted=interrupted,
                interval=_pair(meta.get("interval")),
                pilot_flights=int(meta.get("pilot_flights", 0)),
                clusters=int(meta.get("clusters", 0)),
            )
        except (KeyError, TypeError, ValueError) as e:
            raise _fail(path, f"its rare-event tables are malformed ({e})") from None
        return cls(run, value_name=meta["value_name"], method=meta["method"], model=model)

    # -- display --------------------------------------------------------------------------
    def _headline(self) -> str:
        run = self.run
        if run.interrupted:
            bound = "" if run.upper_bound is None else f" <= about {run.upper_bound:.3g}"
            return (
                f"interrupted after {len(run.levels)} levels ({run.flights} flights): "
                f"P({self.value_name} > {run.threshold:g}){bound}, no estimate"
            )
        if run.probability is None:
            return (
                f"no failure in {run.flights} flights: P({self.value_name} > "
                f"{run.threshold:g}) <= {run.upper_bound:.3g} (the upper end of the two-sided "
                "95 % interval; "
                f"largest value {run.closest:.4g})"
            )
        lo, hi = self.interval or (math.nan, math.nan)
        return (
            f"P({self.value_name} > {run.threshold:g}) = {run.probability:.3g} "
            f"(cov {run.cov:.2f}, 95 % [{lo:.3g}, {hi:.3g}])"
        )

    def __repr__(self) -> str:
        run = self.run
        return (
            f"<RareEventResult {self._headline()}; {len(run.levels)} levels, {run.flights} "
            f"flights, {len(run.failure_values)} failure samples, {run.dimension} dimensions, "
            f"p0 {run.p0:g}, {run.per_level} per level, seed {run.seed}>"
        )

    def _repr_html_(self) -> str:
        """The headline and the levels table, for notebooks."""
        head = html.escape(self._headline())
        meta = html.escape(
            f"{self.run.flights} flights, {self.run.dimension} dimensions, p0 {self.run.p0:g}, "
            f"{self.run.per_level} per level, seed {self.run.seed}"
        )
        return f"<p><b>{head}</b><br>{meta}</p>" + self.levels.to_html(index=False)


@dataclass
class RareEventComparison:
    """Paired runs: one subset simulation per controller (or model) on the same seed, so
    level 0 flies the very same samples and the chains draw the same proposal normals.
    ``results``: name -> :class:`RareEventResult`. :meth:`ratio` compares two of them."""

    results: Mapping[str, RareEventResult]

    def __getitem__(self, name: str) -> RareEventResult:
        return self.results[name]

    def ratio(self, a: str, b: str, confidence: float = 0.95) -> dict[str, Any]:
        """P_a / P_b with an interval on the log scale: ``ratio``, ``low``, ``high`` and
        ``first_level_correlation``. Var(log ratio) = s_a^2 + s_b^2 - 2 c_0 with s^2 =
        log(1 + cov^2) of each run and c_0 the covariance of the two runs' level-0 fractions
        (they fly the very same samples: estimated from which samples lie above each run's
        first cut). The conditional levels' correlation (through the shared proposal normals) is
        not estimated and taken as 0; it is positive if anything, so the interval errs wide.
        Without level 0's samples (a result read from a file), c_0 = 0. None values when
        either run found no failure."""
        for name in (a, b):
            if name not in self.results:
                raise KeyError(f"{name!r} is not one of {sorted(self.results)}")
        ra, rb = self.results[a].run, self.results[b].run
        if ra.probability is None or rb.probability is None or ra.cov is None or rb.cov is None:
            return {"ratio": None, "low": None, "high": None, "first_level_correlation": None}
        from scipy.stats import norm

        z = float(norm.ppf(0.5 + confidence / 2))
        var_a, var_b = math.log1p(ra.cov**2), math.log1p(rb.cov**2)
        c0, corr = _first_level_covariance(ra.first_above, rb.first_above)
        # Never below what the conditional levels alone contribute (c_0 cannot cancel them).
        shared = math.log1p(ra.levels[0].cov ** 2) + math.log1p(rb.levels[0].cov ** 2)
        s = math.sqrt(max(var_a + var_b - 2 * c0, var_a + var_b - shared))
        r = ra.probability / rb.probability
        return {"ratio": r, "low": r * math.exp(-z * s), "high": r * math.exp(z * s),
                "first_level_correlation": corr}  # fmt: skip

    def __repr__(self) -> str:
        parts = ", ".join(
            f"{k}: {'none found' if v.probability is None else f'{v.probability:.3g}'}"
            for k, v in self.results.items()
        )
        return f"<RareEventComparison {parts}>"


def _first_level_covariance(
    above_a: np.ndarray | None, above_b: np.ndarray | None
) -> tuple[float, float | None]:
    """(c_0, correlation): the covariance of log p_a and log p_b of level 0, two fractions of
    the same samples, (P(both) - p_a p_b) / (N p_a p_b); (0, None) without the samples."""
    if above_a is None or above_b is None or len(above_a) != len(above_b) or not len(above_a):
        return 0.0, None
    pa, pb = float(above_a.mean()), float(above_b.mean())
    if not 0 < pa < 1 or not 0 < pb < 1:
        return 0.0, None
    joint = float((above_a & above_b).mean()) - pa * pb
    corr = joint / math.sqrt(pa * (1 - pa) * pb * (1 - pb))
    return joint / (len(above_a) * pa * pb), corr


def _nan(value: Any) -> Any:
    """JSON null back as NaN for level fields; other values as they are."""
    return math.nan if value is None else value


def _closest(value: Any, nothing_flown: bool) -> float:
    """The largest value seen, back from JSON: null is +inf (a diverged flight), or -inf
    when a run was interrupted before its first level (no value seen)."""
    if value is None:
        return -math.inf if nothing_flown else math.inf
    return float(value)


def _pair(value: Any) -> tuple[float, float] | None:
    """A saved interval: two numbers in [0, 1], low <= high; None if absent."""
    if value is None:
        return None
    if not isinstance(value, list) or len(value) != 2:
        raise ValueError(f"interval must be two numbers, got {value!r}")
    lo, hi = (float(v) for v in value)
    if not 0.0 <= lo <= hi <= 1.0:
        raise ValueError(f"interval must lie in [0, 1], got {value!r}")
    return lo, hi


def _number(value: Any) -> float | None:
    """An optional number of the metadata (None stays None: nothing was found)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"expected a number or null, got {value!r}")
    return float(value)
