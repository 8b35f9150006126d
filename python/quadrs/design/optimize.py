"""Tune gains or calibrate unknown parameters with Monte Carlo: :func:`optimize`.

The objective of a candidate is a Monte Carlo statistic over ``runs`` realisations flown on
common random numbers: every evaluation uses the same ``seed``, hence the same gusts, so the
objective is a deterministic, smooth function of the parameters and two candidates are
compared on identical gusts. The optimiser is scipy.optimize's ``differential_evolution``
(global, bounded, derivative-free, deterministic for a given seed) or bounded Nelder-Mead
(local, cheaper): see docs/design-loop.md for why.

Candidates unstable at hover (:func:`quadrs.stability`) in a mode the scenario excites are
rejected before flying when ``require_stable`` (a mode the flight never excites cannot show in
it, as the paper SMC's lateral modes in vertical flight); candidates whose flights diverge are
penalised. Both are recorded in ``history``. The best candidate is re-evaluated on fresh
seeds (``holdout``), the check against having tuned to the particular gusts of ``seed``.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from quadrs import _core
from quadrs.design.constraints import Constraint, check_phases, constraints_from
from quadrs.engine.calls import CONTROLLERS, U64_MAX, check_controller, check_int
from quadrs.runs.montecarlo import monte_carlo
from quadrs.runs.montecarlo_result import MonteCarloResult
from quadrs.scenario.scenario import Scenario, design_keys, key_value, scenario_error

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

METHODS = ("differential_evolution", "nelder-mead")
#: Offset of the held-out seed from the tuning seed.
HOLDOUT_SEED_OFFSET = 1_000_003
#: Groups the held-out realisations are split into for a callable objective's interval.
HOLDOUT_BATCHES = 8

Objective = str | Callable[[MonteCarloResult], float]


def holdout_seed(seed: int) -> int:
    """The seed the best candidate is re-evaluated on: ``seed + HOLDOUT_SEED_OFFSET``,
    wrapping within the 64-bit seeds (a seed near 2**64 still has one)."""
    return (seed + HOLDOUT_SEED_OFFSET) % (U64_MAX + 1)


class InfeasibleWarning(UserWarning):
    """No candidate met every constraint: the result holds the least-violating one."""


class _Stop(Exception):
    """Ctrl-C inside an evaluation: unwinds scipy's loop to the caller."""


@dataclass(frozen=True)
class Holdout:
    """The best candidate re-evaluated on fresh seeds: ``objective`` with a 95 % interval.

    For a metric objective the interval is Student's t over the per-realisation values; for a
    callable one, over the callable's values on ``HOLDOUT_BATCHES`` disjoint groups of
    realisations (batch means). ``diverged``: realisations that diverged.
    """

    seed: int
    runs: int
    objective: float
    low: float
    high: float
    diverged: int


@dataclass(frozen=True)
class OptimizeResult:
    """What :func:`optimize` found.

    ``best``: {key: value} of the best candidate; ``objective``: its value on the tuning seed;
    ``scenario``: the input scenario with ``best`` applied; ``history``: one row per evaluation
    (``evaluation``, every parameter key, ``objective``, ``stable`` (in every mode),
    ``max_real`` (largest pole real part among the modes the scenario excites, 1/s), ``flown``,
    ``diverged`` (realisations), ``penalised``, ``unstable_modes`` (the excited modes that are
    not stable, e.g. "SMC lateral x/pitch +1.31 ± 3.90j"; "" if none)); ``holdout``: see
    :class:`Holdout` (None if interrupted); ``interrupted``: stopped by Ctrl-C, the best so
    far is kept. ``baseline``: the objective of the untuned input scenario on the tuning seed
    (NaN if its flights diverged or the run was interrupted); ``phase_effects`` (metric
    objectives): per phase, the metric's mean untuned and tuned on the tuning seed, the paired
    change with its 95 % interval and ``worse`` (the interval lies above 0), so a phase
    outside the objective that the tuning made worse shows.

    With ``constraints``: ``history`` has, per constraint, a column named by its statistic
    (e.g. ``P(max_accel>8)``: the value on the tuning seed) and one named by the constraint
    (e.g. ``P(max_accel>8)<=0.01``: met or not), and ``feasible`` (every one met; False for a
    candidate not flown); ``score`` is what the optimiser minimised (the objective, or a
    penalty); ``role`` is "best" on the chosen row, "baseline" on the last row (the untuned
    scenario on the same seed, flown whatever its stability, never a candidate), else "".
    ``feasible`` (the result's): the best met every constraint; when no candidate did, it is
    the least violating one, ``feasible`` is False and an :class:`InfeasibleWarning` is given.
    ``holdout_constraints``: every constraint re-checked on the held-out flights, per
    controller and phase, with its 95 % interval (:meth:`Constraint.check`).
    """

    best: dict[str, float]
    objective: float
    scenario: Scenario
    history: pd.DataFrame = field(repr=False)
    holdout: Holdout | None
    interrupted: bool
    method: str
    seed: int
    runs: int
    baseline: float = math.nan
    phase_effects: pd.DataFrame | None = field(default=None, repr=False)
    constraints: tuple[Constraint, ...] = ()
    feasible: bool = True
    holdout_constraints: pd.DataFrame | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        """The best values and objective, not the history."""
        best = ", ".join(f"{k}={v:.4g}" for k, v in self.best.items())
        note = ", interrupted" if self.interrupted else ""
        if not self.feasible:
            note += ", NO FEASIBLE CANDIDATE (this is the least violating)"
        searched = len(self.evaluations)
        return (
            f"<OptimizeResult {best}: objective {self.objective:.4g} after "
            f"{searched} evaluations{note}>"
        )

    @property
    def evaluations(self) -> pd.DataFrame:
        """The search's own rows of ``history`` (the baseline row left out)."""
        h = self.history
        return h[h["role"] != "baseline"] if "role" in h else h

    @property
    def comparison(self) -> pd.DataFrame:
        """The untuned baseline (the scenario's own values) beside the best candidate: their
        rows of ``history`` indexed by ``role`` (parameters, objective, every constraint's
        value and whether it is met, ``feasible``). No baseline row if interrupted."""
        h = self.history
        if "role" not in h:  # a history written before the baseline row existed
            return h.iloc[:0]
        return h[h["role"].isin(["baseline", "best"])].set_index("role").sort_index()

    def _repr_html_(self) -> str:
        """In a notebook: best values, objective beside the untuned one and the holdout, and
        the per-phase effects, as HTML."""
        from quadrs.present.html import render

        values = pd.DataFrame({"value": self.best}).rename_axis("key")
        ho = self.holdout
        scores = pd.DataFrame(
            {
                "objective": [self.objective, self.baseline, ho.objective if ho else math.nan],
                "ci_low": [math.nan, math.nan, ho.low if ho else math.nan],
                "ci_high": [math.nan, math.nan, ho.high if ho else math.nan],
            },
            index=["best (tuning seed)", "untuned (tuning seed)", "best (held-out seed)"],
        )
        tables = [("best values", values), ("objective", scores)]
        if self.phase_effects is not None:
            tables.append(("per phase, untuned -> tuned (same gusts)", self.phase_effects))
        if self.constraints and not self.comparison.empty:
            tables.append(("untuned and best on the tuning seed", self.comparison.T))
        if self.holdout_constraints is not None:
            tables.append(("constraints on the held-out seed", self.holdout_constraints))
        return render(repr(self), tables)


def expand(values: Mapping[str, float]) -> dict[str, float]:
    """{key: value} with tied keys ("a,b": one value for both) split into one entry each."""
    return {k.strip(): v for key, v in values.items() for k in key.split(",")}


def _canonical_params(
    scenario: Scenario, params: Mapping[str, Sequence[float]]
) -> dict[str, Sequence[float]]:
    """``params`` with every key (also each of a tied group) in its canonical spelling; a key
    given twice (in two groups, or two spellings) or also dispersed is refused by name."""
    groups = [[k.strip() for k in key.split(",")] for key in params]
    canon = iter(design_keys(scenario, [k for g in groups for k in g], "params"))
    names = [",".join(next(canon) for _ in g) for g in groups]
    return dict(zip(names, params.values(), strict=True))


def _check_laws_read(params: Mapping[str, Sequence[float]], controllers: Sequence[str]) -> None:
    """A key of one law's gains (``controller.<law>.*``) tuned while only other laws fly
    changes nothing the objective sees: refused by name rather than searched in vain."""
    for key in params:
        for one in key.split(","):
            parts = one.strip().split(".")
            law = parts[1] if len(parts) > 2 and parts[0] == "controller" else None
            if law in CONTROLLERS and law not in controllers:
                flown = ", ".join(controllers)
                raise ValueError(
                    f"params: {one.strip()} is a gain of the {law} law, which this tuning does "
                    f"not fly (controller: {flown}), so it would change nothing; tune "
                    f"controller.{controllers[0]}.* keys, or fly {law}"
                )


def _check_params(scenario: Scenario, params: Mapping[str, Sequence[float]]) -> None:
    if not params:
        raise ValueError("params must name at least one scenario key with (low, high) bounds")
    for key, bounds in params.items():
        for one in key.split(","):
            try:
                value = key_value(scenario, one.strip())
            except KeyError:
                raise scenario_error(f"{one.strip()}: unknown scenario key", one.strip()) from None
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise scenario_error(
                    f"{one} must be a numeric scenario key to tune, got {value!r}", one.strip()
                )
        try:
            low, high = (float(b) for b in bounds)
        except (TypeError, ValueError):
            raise scenario_error(
                f"{key}: bounds must be (low, high), got {bounds!r}", key
            ) from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise scenario_error(
                f"{key}: bounds must be finite with low < high, got {bounds!r}", key
            )
        for b in (low, high):
            scenario.override(expand({key: b}))  # ScenarioError naming the key if out of its domain


def check_tuning(
    scenario: Scenario,
    controller: str | Sequence[str],
    params: Mapping[str, Sequence[float]] | None,
    objective: str | Callable[[MonteCarloResult], float],
    phases: str | Sequence[str],
    constraints: Mapping[Any, Any] | Sequence[Constraint | str] | None = None,
) -> tuple[tuple[str, ...], dict[str, Sequence[float]], tuple[str, ...], tuple[Constraint, ...]]:
    """What :func:`optimize` checks of its problem before flying (ValueError naming what is
    wrong): the controllers, the keys and their bounds, the objective, the phases and the
    constraints. Returns the controllers, the canonical params, the phases and the parsed
    constraints. The command line calls it before its calibration flights."""
    controllers = (controller,) if isinstance(controller, str) else tuple(controller)
    if not controllers:
        raise ValueError("controller must name at least one of 'pd', 'smc'")
    for c in controllers:
        check_controller(c)
    params = _canonical_params(scenario, dict(params or {}))
    _check_params(scenario, params)
    _check_laws_read(params, controllers)
    phases = (phases,) if isinstance(phases, str) else tuple(phases)
    if isinstance(objective, str):
        if objective not in _core.METRIC_NAMES:
            raise ValueError(f"objective must be one of {_core.METRIC_NAMES}, got {objective!r}")
        if len(controllers) != 1:
            raise ValueError(
                f"a metric objective needs one controller, got {controllers}: "
                "pass a callable objective to combine several"
            )
        unknown = [p for p in phases if p not in scenario.phase_names]
        if not phases or unknown:
            raise ValueError(f"phases must be among {scenario.phase_names}, got {list(phases)}")
        if objective in _core.EVENT_METRICS and len(phases) > 1:
            # An event's value is in the one phase the event falls in, NaN in the others: a
            # sum over several has no value, and every candidate would be rejected.
            raise ValueError(
                f"objective {objective} is an event's metric (a value only in the phase the "
                f"event falls in): summed over {len(phases)} phases ({', '.join(phases)}) it "
                "has none; give the one phase of the event (--phase, e.g. the lowering's)"
            )
    elif not callable(objective):
        raise TypeError(f"objective must be a metric name or a callable, got {objective!r}")
    cons = constraints_from(constraints)
    check_phases(cons, scenario.phase_names)
    if cons and not all(c.phase is not None for c in cons):
        unknown = [p for p in phases if p not in scenario.phase_names]
        if not phases or unknown:
            raise ValueError(
                f"phases (those of the constraints without their own) must be among "
                f"{scenario.phase_names}, got {list(phases)}"
            )
    return controllers, params, phases, cons


def _metric_values(
    mc: MonteCarloResult, metric: str, phases: Sequence[str]
) -> tuple[np.ndarray, int]:
    """Per-realisation metric summed over ``phases``; and the count of diverged realisations."""
    runs = mc.runs[mc.runs["phase"].isin(list(phases))]
    per = runs.groupby("realisation")[[metric]].sum(min_count=len(phases))[metric]
    diverged = int(runs.groupby("realisation")["diverged"].any().sum())
    return per.to_numpy(dtype=float), diverged


def optimize(
    scenario: Scenario,
    controller: str | Sequence[str] = "smc",
    params: Mapping[str, Sequence[float]] | None = None,
    objective: Objective = "iae",
    phases: Sequence[str] = ("P2",),
    runs: int = 64,
    seed: int = 0,
    require_stable: bool = True,
    method: str = "differential_evolution",
    maxiter: int | None = None,
    workers: int | None = None,
    progress: bool = False,
    *,
    popsize: int = 8,
    penalty: float = 1e6,
    holdout_runs: int | None = None,
    callback: Callable[[dict[str, Any]], None] | None = None,
    constraints: Mapping[Any, Any] | Sequence[Constraint | str] | None = None,
    client: Client | None = None,
) -> OptimizeResult:
    """Minimise a Monte Carlo objective over bounded scenario keys.

    ``params``: {dotted key: (low, high)}, any numeric key including vector elements
    (``"controller.smc.lambda[0]"``); a key naming several keys separated by commas ties them
    to one value (``"controller.smc.lambda[0],controller.smc.lambda[1]"``: x and y alike).
    ``objective``: a metric name (``_core.METRIC_NAMES``):
    the mean over the ``runs`` realisations of that metric summed over ``phases``, for one
    ``controller``; or a callable ``f(mc) -> float`` of the :class:`MonteCarloResult` of
    every ``controller`` given. Every evaluation flies realisations ``0..runs`` of ``seed``;
    with ``client`` (a ``dask.distributed.Client``) as tasks on its workers, with the same
    numbers, so the same search and result, as on this machine.

    Penalties (recorded, never NaN): a candidate not stable at hover under every controller
    scores ``penalty * (1 + max(0, largest real part))`` without flying when
    ``require_stable``; one with any diverged realisation, or a non-finite objective, scores
    ``penalty * (1 + diverged fraction)``.

    ``method``: "differential_evolution" (``maxiter`` generations of ``popsize`` x
    parameters candidates, default 20; ``polish=False``; seeded by ``seed``) or "nelder-mead"
    (from the scenario's values clipped to the bounds; ``maxiter`` evaluations, default 100).
    Same seed and budget give the same history. ``holdout_runs`` (default ``runs``):
    realisations flown at ``seed + HOLDOUT_SEED_OFFSET`` to re-evaluate the best. Ctrl-C
    stops and returns the best so far with ``interrupted=True``. ``callback`` receives each
    history row as it is recorded (e.g. for a progress display).

    ``constraints`` (see :mod:`quadrs.design.constraints` and docs/design-loop.md): e.g.
    ``{"tracking_rms": ("<=", 0.5), ("max_accel", "exceedance", 8.0): ("<=", 0.01)}`` or
    ``["tracking_rms<=0.5", "P(max_accel>8)<=0.01"]``: the mean, exceedance fraction or
    quantile of a metric over the ``runs`` realisations of ``seed`` (the same gusts for every
    candidate), in each of ``phases`` unless the constraint names its own
    (``"tracking_rms@P1"``), for every controller. A candidate that breaks one scores
    between ``penalty / 2`` and ``penalty`` (more for a larger relative violation), above
    every feasible one (objectives are assumed below ``penalty / 2``) and below every
    unstable or diverged one, and is never chosen as best. If none meets them all, the least
    violating flown candidate is returned with ``feasible=False`` and an
    :class:`InfeasibleWarning`.
    """
    from quadrs.present.terminal import shows_progress, tqdm_class

    tqdm = tqdm_class()

    from quadrs.hover.stability import stability

    controllers, params, phases, cons = check_tuning(
        scenario, controller, params, objective, phases, constraints
    )
    keys = list(params)
    bounds = [(float(params[k][0]), float(params[k][1])) for k in keys]
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if runs < 1:
        raise ValueError(f"runs must be >= 1, got {runs}")
    seed = check_int("seed", seed)
    if maxiter is not None and maxiter < 1:
        raise ValueError(f"maxiter must be >= 1, got {maxiter}")
    if popsize < 1:
        raise ValueError(f"popsize must be >= 1, got {popsize}")
    if not (math.isfinite(penalty) and penalty > 0):
        raise ValueError(f"penalty must be finite and > 0, got {penalty}")

    rows: list[dict[str, Any]] = []
    if method == "differential_evolution":
        generations = 20 if maxiter is None else maxiter
        total = popsize * len(keys) * (generations + 1)
    else:
        generations = 100 if maxiter is None else maxiter
        total = generations
    bar = tqdm(
        total=total, disable=not shows_progress(progress), unit="eval", desc="tune", leave=False
    )

    def fly(candidate: Scenario, seed_: int, count: int) -> MonteCarloResult:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # stability is judged here, not warned about
            mc = monte_carlo(
                candidate,
                runs=count,
                seed=seed_,
                controllers=controllers,
                workers=workers,
                progress=False,
                spectra=False,
                client=client,
            )
        if mc.interrupted:
            raise _Stop
        return mc

    def score(mc: MonteCarloResult) -> tuple[float, int, np.ndarray | None]:
        if isinstance(objective, str):
            values, diverged = _metric_values(mc, objective, phases)
            value = float(np.mean(values)) if diverged == 0 else math.nan
            return value, diverged, values
        diverged = int(mc.runs.groupby("realisation")["diverged"].any().sum())
        return float(objective(mc)), diverged, None

    def judge(row: dict[str, Any], mc: MonteCarloResult | None) -> float:
        """Each constraint's value and verdict into ``row``; the summed relative violation."""
        total = 0.0
        for c in cons:
            value = c.value(mc.runs, phases) if mc is not None else math.nan
            row[c.label] = value
            row[str(c)] = c.satisfied(value)
            total += c.violation(value)
        row["feasible"] = total == 0.0
        return total

    def measure(
        values: dict[str, float], candidate: Scenario, require: bool
    ) -> tuple[dict[str, Any], MonteCarloResult | None]:
        """One candidate's history row (before its score) and its flights (None if not
        flown)."""
        row: dict[str, Any] = {"evaluation": len(rows), **values}
        reports = [stability(candidate, c) for c in controllers]
        # Judged on the modes the scenario excites: the others stay exactly at rest in flight.
        max_real = max(float(r.excited_poles["real"].max()) for r in reports)
        stable = all(r.stable for r in reports)
        unstable = "; ".join(
            f"{r.controller.upper()} {mode}" for r in reports for mode in r.excited_unstable_modes()
        )
        row.update(stable=stable, max_real=max_real, flown=False, diverged=0, penalised=False,
                   unstable_modes=unstable)  # fmt: skip
        mc = None
        if require and unstable:
            value = penalty * (1.0 + max(0.0, max_real))
            row.update(penalised=True)
        else:
            try:
                mc = fly(candidate, seed, runs)
            except KeyboardInterrupt:
                raise _Stop from None
            value, diverged, _ = score(mc)
            row.update(flown=True, diverged=diverged)
            if diverged > 0 or not math.isfinite(value):
                value = penalty * (1.0 + diverged / runs)
                row.update(penalised=True)
        row["objective"] = value
        violation = judge(row, mc)
        row["score"] = value
        if violation > 0 and not row["penalised"]:
            # Feasible < infeasible (ordered by violation) < unstable or diverged.
            frac = 1.0 if math.isinf(violation) else violation / (1.0 + violation)
            row["score"] = penalty * (0.5 + 0.5 * frac)
        row["violation"] = violation
        row["role"] = ""
        return row, mc

    def evaluate(x: np.ndarray) -> float:
        values = {k: float(v) for k, v in zip(keys, x, strict=True)}
        candidate = scenario.override(expand(values))
        row, _ = measure(values, candidate, require_stable)
        value = float(row["score"])
        rows.append(row)
        bar.update(1)
        if callback is not None:
            callback(dict(row))
        return value

    from scipy import optimize as sopt  # lazily: `quadrs --version` stays fast

    interrupted = False
    try:
        if method == "differential_evolution":
            sopt.differential_evolution(
                evaluate,
                bounds,
                maxiter=generations,
                popsize=popsize,
                seed=seed,
                polish=False,
                tol=0.0,  # no early stop: the budget is maxiter generations
                updating="deferred",
                workers=1,
                init="latinhypercube",
            )
        else:
            x0 = [
                min(max(float(key_value(scenario, k.split(",")[0].strip())), lo), hi)
                for k, (lo, hi) in zip(keys, bounds, strict=True)
            ]
            sopt.minimize(
                evaluate,
                x0,
                method="Nelder-Mead",
                bounds=bounds,
                options={"maxfev": generations, "xatol": 1e-4, "fatol": 1e-9},
            )
    except (_Stop, KeyboardInterrupt):
        interrupted = True
    finally:
        bar.close()

    columns = [
        "evaluation",
        *keys,
        "objective",
        "stable",
        "max_real",
        "flown",
        "diverged",
        "penalised",
        "unstable_modes",
    ]
    for con in cons:
        columns += [col for col in (con.label, str(con)) if col not in columns]
    columns += ["feasible", "violation", "score", "role"]
    if not rows:
        raise KeyboardInterrupt("interrupted before the first evaluation finished")
    history = pd.DataFrame(rows, columns=columns)
    pick, feasible = _choose(history)
    if not feasible:
        warnings.warn(
            "no candidate met every constraint ("
            + "; ".join(str(c) for c in cons)
            + "): the result is the least violating one, not a feasible design",
            InfeasibleWarning,
            stacklevel=2,
        )
    history.loc[pick, "role"] = "best"
    best_row = history.loc[pick]
    best = {k: float(best_row[k]) for k in keys}
    tuned = scenario.override(expand(best))

    holdout, baseline, effects, held = None, math.nan, None, None
    if not interrupted:
        try:
            # The untuned scenario on the same gusts, beside the best in the history.
            own = {k: float(key_value(scenario, k.split(",")[0].strip())) for k in keys}
            row, before = measure(own, scenario, require=False)
            row["role"] = "baseline"
            history = pd.concat([history, pd.DataFrame([row], columns=columns)],
                                ignore_index=True)  # fmt: skip
            if before is not None:
                baseline = score(before)[0]
            if not bool(best_row["penalised"]):
                count = runs if holdout_runs is None else int(holdout_runs)
                hseed = holdout_seed(seed)
                mc = fly(tuned, hseed, count)
                holdout = _holdout(mc, objective, phases, hseed, count, score)
                if cons:
                    held = pd.concat([c.check(mc.runs, phases) for c in cons], ignore_index=True)
                if isinstance(objective, str) and before is not None:
                    effects = phase_effects(before, fly(tuned, seed, runs), objective)
        except (_Stop, KeyboardInterrupt):
            interrupted = True
    return OptimizeResult(
        best=best,
        objective=float(best_row["objective"]),
        scenario=tuned,
        history=history,
        holdout=holdout,
        interrupted=interrupted,
        method=method,
        seed=seed,
        runs=runs,
        baseline=baseline,
        phase_effects=effects,
        constraints=cons,
        feasible=feasible,
        holdout_constraints=held,
    )


def _choose(history: pd.DataFrame) -> tuple[Any, bool]:
    """The best row's label and whether it is feasible: the least objective among the feasible
    candidates flown without penalty; if there is none, the least violation (then objective)
    among those flown without penalty; if none was, the least score (as without
    constraints)."""
    admissible = history[~history["penalised"].astype(bool)]
    ok = admissible[admissible["feasible"].astype(bool)]
    if not ok.empty:
        return ok["objective"].idxmin(), True
    if admissible.empty:
        return history["score"].idxmin(), bool(history["feasible"].all())
    order = admissible.sort_values(["violation", "objective"], kind="stable")
    return order.index[0], False


def phase_effects(
    before: MonteCarloResult, after: MonteCarloResult, metric: str, confidence: float = 0.95
) -> pd.DataFrame:
    """Per phase (rows) of one controller's batches flown on the same gusts: the mean of
    ``metric`` ``untuned`` and ``tuned``, ``change`` (paired mean difference) with its
    Student-t interval ``ci_low``/``ci_high``, ``change_pct`` and ``worse`` (the interval
    lies above 0). Realisations that diverged in a phase in either batch are left out of it."""
    from scipy import stats

    def wide(mc: MonteCarloResult) -> pd.DataFrame:
        return mc.runs.pivot(index="realisation", columns="phase", values=metric)

    a, b = wide(before), wide(after)
    rows = []
    for phase in before.scenario.phase_names:
        x, y = a[phase].to_numpy(float), b[phase].to_numpy(float)
        ok = np.isfinite(x) & np.isfinite(y)
        d = y[ok] - x[ok]
        mean = float(d.mean()) if d.size else math.nan
        half = (
            float(stats.t.ppf(0.5 + confidence / 2, d.size - 1) * d.std(ddof=1) / np.sqrt(d.size))
            if d.size >= 2
            else math.nan
        )
        untuned = float(x[ok].mean()) if d.size else math.nan
        rows.append({
            "phase": phase,
            "untuned": untuned,
            "tuned": float(y[ok].mean()) if d.size else math.nan,
            "change": mean,
            "ci_low": mean - half,
            "ci_high": mean + half,
            "change_pct": 100 * mean / untuned if untuned else math.nan,
            "worse": bool(mean - half > 0),
        })  # fmt: skip
    return pd.DataFrame(rows).set_index("phase")


def _holdout(
    mc: MonteCarloResult,
    objective: Objective,
    phases: Sequence[str],
    seed: int,
    count: int,
    score: Callable[[MonteCarloResult], tuple[float, int, np.ndarray | None]],
) -> Holdout:
    from scipy import stats

    value, diverged, values = score(mc)
    if values is not None:
        ok = values[np.isfinite(values)]
        value = float(np.mean(ok)) if ok.size else math.nan
        samples = ok
    else:
        real = mc.realisations
        groups = np.array_split(real, min(HOLDOUT_BATCHES, real.size))
        samples = np.array(
            [float(objective(_subset(mc, g))) for g in groups if g.size]  # type: ignore[operator]
        )
    if samples.size >= 2 and np.all(np.isfinite(samples)):
        sem = float(stats.sem(samples))
        low, high = (
            stats.t.interval(0.95, samples.size - 1, loc=float(np.mean(samples)), scale=sem)
            if sem > 0
            else (value, value)
        )
        if values is None:  # centre the batch-means interval on the full-sample value
            half = (high - low) / 2
            low, high = value - half, value + half
    else:
        low = high = math.nan
    return Holdout(
        seed=seed, runs=count, objective=value, low=float(low), high=float(high), diverged=diverged
    )


def _subset(mc: MonteCarloResult, realisations: np.ndarray) -> MonteCarloResult:
    runs = mc.runs[mc.runs["realisation"].isin(realisations)].reset_index(drop=True)
    return MonteCarloResult(
        scenario=mc.scenario, seed=mc.seed, controllers=mc.controllers, runs=runs
    )
