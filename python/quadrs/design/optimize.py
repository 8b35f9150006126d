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

import dataclasses
import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from quadrs import _core
from quadrs.design.constraints import Constraint, check_phases, constraints_from
from quadrs.design.optimize_result import (
    HOLDOUT_BATCHES,
    HOLDOUT_SEED_OFFSET,
    Holdout,
    InfeasibleWarning,
    Objective,
    OptimizeResult,
    choose_best,
    holdout_of,
    holdout_seed,
    phase_effects,
)
from quadrs.engine.calls import CONTROLLERS, check_controller, check_int
from quadrs.runs.montecarlo import monte_carlo
from quadrs.runs.montecarlo_result import MonteCarloResult
from quadrs.scenario.scenario import Scenario, design_keys, key_value, scenario_error

if TYPE_CHECKING:  # pragma: no cover
    from dask.distributed import Client

__all__ = [
    "HOLDOUT_BATCHES",
    "HOLDOUT_SEED_OFFSET",
    "METHODS",
    "Holdout",
    "InfeasibleWarning",
    "Objective",
    "OptimizeOptions",
    "OptimizeResult",
    "check_tuning",
    "expand",
    "holdout_seed",
    "optimize",
    "phase_effects",
]

METHODS = ("differential_evolution", "nelder-mead")
#: Generations (differential evolution) or evaluations (Nelder-Mead) when ``maxiter`` is None.
DEFAULT_MAXITER = {"differential_evolution": 20, "nelder-mead": 100}


class _Stop(Exception):
    """Ctrl-C inside an evaluation: unwinds scipy's loop to the caller."""


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


@dataclass(frozen=True)
class OptimizeOptions:
    """What :func:`optimize` searches and how (docs/design-loop.md). Each value is checked
    when the options are made (ValueError naming the field); those that need the scenario
    (the keys, the objective's phases, the constraints) when the search starts."""

    controller: str | Sequence[str] = "smc"
    """The law flown, or several (a callable objective sees them all)."""
    params: Mapping[str, Sequence[float]] | None = None
    """{dotted key: (low, high)}: any numeric key, vector elements included
    (``"controller.smc.lambda[0]"``); keys joined by commas are tied to one value."""
    objective: Objective = "iae"
    """A metric name (``_core.METRIC_NAMES``; the mean over the realisations of that metric
    summed over ``phases``, for one controller) or a callable ``f(mc) -> float``."""
    phases: Sequence[str] = ("P2",)
    """The phases a metric objective sums, and the constraints read (unless their own)."""
    runs: int = 64
    """Realisations each candidate flies (``0..runs`` of ``seed``: common random numbers)."""
    seed: int = 0
    """The tuning's seed: the gusts every candidate flies, and the search's own draws."""
    require_stable: bool = True
    """Reject, without flying, a candidate unstable at hover in a mode the flight excites."""
    method: str = "differential_evolution"
    """``"differential_evolution"`` or ``"nelder-mead"`` (:data:`METHODS`)."""
    maxiter: int | None = None
    """Generations of differential evolution (default 20) or Nelder-Mead evaluations (100)."""
    workers: int | None = None
    """Threads each batch flies on (None: every core)."""
    progress: bool = False
    """Show a progress bar of the evaluations (on a terminal)."""
    popsize: int = 8
    """Differential evolution's candidates per generation, per parameter."""
    penalty: float = 1e6
    """The score of a candidate rejected (unstable, diverged); constraints score below it."""
    holdout_runs: int | None = None
    """Realisations the best flies on the held-out seed (default ``runs``)."""
    callback: Callable[[dict[str, Any]], None] | None = None
    """Receives each history row as it is recorded (e.g. for a progress display)."""
    constraints: Mapping[Any, Any] | Sequence[Constraint | str] | None = None
    """Bounds on Monte Carlo statistics (:mod:`quadrs.design.constraints`)."""
    client: Client | None = None
    """A ``dask.distributed.Client`` whose workers fly the batches (the same numbers)."""

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")
        for name in ("runs", "popsize", "maxiter", "holdout_runs"):
            value = getattr(self, name)
            if value is not None and not value >= 1:
                raise ValueError(f"{name} must be >= 1, got {value}")
        if not (math.isfinite(self.penalty) and self.penalty > 0):
            raise ValueError(f"penalty must be finite and > 0, got {self.penalty}")
        object.__setattr__(self, "seed", check_int("seed", self.seed))

    @classmethod
    def of_call(cls, args: Sequence[Any], keywords: Mapping[str, Any]) -> OptimizeOptions:
        """The options of a call in the keyword form (``optimize(s, runs=8)``), the positional
        one of the first release (``optimize(s, "smc", params, "iae", phases, runs, seed,
        require_stable, method, maxiter, workers, progress)``: the fields in their order), or
        an options object with fields replaced by keyword."""
        names = [f.name for f in fields(cls)]
        if args and isinstance(args[0], OptimizeOptions):
            if len(args) > 1:
                raise TypeError("optimize() takes the scenario and one options object")
            base: OptimizeOptions | None = args[0]
            args = ()
        else:
            base = None
        if len(args) > _POSITIONAL:
            raise TypeError(f"optimize() takes at most {_POSITIONAL} positional options "
                            f"({', '.join(names[:_POSITIONAL])}), got {len(args)}")  # fmt: skip
        given = dict(zip(names, args, strict=False))
        for name in keywords:
            if name not in names:
                raise TypeError(f"optimize() got an unexpected keyword argument {name!r}")
            if name in given:
                raise TypeError(f"optimize() got multiple values for argument {name!r}")
        given.update(keywords)
        return dataclasses.replace(base, **given) if base is not None else cls(**given)


#: The options the first release took by position (``controller`` to ``progress``).
_POSITIONAL = 11


def optimize(scenario: Scenario, *args: Any, **keywords: Any) -> OptimizeResult:
    """Minimise a Monte Carlo objective over bounded scenario keys:
    ``optimize(scenario, OptimizeOptions(...))``, or with the options as keywords
    (``optimize(scenario, controller="smc", params={...}, runs=64)``; see
    :class:`OptimizeOptions` for each, and :meth:`OptimizeOptions.of_call`).

    Every evaluation flies realisations ``0..runs`` of ``seed``; with ``client`` as tasks on
    its workers, with the same numbers, so the same search and result, as on this machine.

    Penalties (recorded, never NaN): a candidate not stable at hover under every controller
    scores ``penalty * (1 + max(0, largest real part))`` without flying when
    ``require_stable``; one with any diverged realisation, or a non-finite objective, scores
    ``penalty * (1 + diverged fraction)``.

    ``method``: "differential_evolution" (``maxiter`` generations of ``popsize`` x
    parameters candidates, default 20; ``polish=False``; seeded by ``seed``) or "nelder-mead"
    (from the scenario's values clipped to the bounds; ``maxiter`` evaluations, default 100).
    Same seed and budget give the same history. ``holdout_runs`` (default ``runs``):
    realisations flown at ``seed + HOLDOUT_SEED_OFFSET`` to re-evaluate the best. Ctrl-C
    stops and returns the best so far with ``interrupted=True``.

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
    options = OptimizeOptions.of_call(args, keywords)
    search = _Search(scenario, options)
    interrupted = search.run()
    history = search.history()
    pick, feasible = choose_best(history)
    if not feasible:
        warnings.warn(
            "no candidate met every constraint ("
            + "; ".join(str(c) for c in search.constraints)
            + "): the result is the least violating one, not a feasible design",
            InfeasibleWarning,
            stacklevel=2,
        )
    history.loc[pick, "role"] = "best"
    best_row = history.loc[pick]
    best = {k: float(best_row[k]) for k in search.keys}
    tuned = scenario.override(expand(best))
    after = _After(history)
    if not interrupted:
        try:
            after = search.after(history, tuned, penalised=bool(best_row["penalised"]))
        except (_Stop, KeyboardInterrupt):
            interrupted = True
    return OptimizeResult(
        best=best,
        objective=float(best_row["objective"]),
        scenario=tuned,
        history=after.history,
        holdout=after.holdout,
        interrupted=interrupted,
        method=options.method,
        seed=options.seed,
        runs=options.runs,
        baseline=after.baseline,
        phase_effects=after.effects,
        constraints=search.constraints,
        feasible=feasible,
        holdout_constraints=after.held,
    )


@dataclass(frozen=True)
class _After:
    """What is measured after the search: the history with the untuned baseline's row, its
    objective, the best's held-out interval and constraints, and the per-phase effects."""

    history: pd.DataFrame
    baseline: float = math.nan
    holdout: Holdout | None = None
    effects: pd.DataFrame | None = None
    held: pd.DataFrame | None = None


class _Search:
    """One tuning's evaluations: each candidate judged at hover, flown on the tuning seed,
    scored, checked against the constraints and recorded as a history row."""

    def __init__(self, scenario: Scenario, options: OptimizeOptions) -> None:
        controllers, params, phases, cons = check_tuning(
            scenario,
            options.controller,
            options.params,
            options.objective,
            options.phases,
            options.constraints,
        )
        self.scenario, self.options = scenario, options
        self.controllers, self.phases, self.constraints = controllers, phases, cons
        self.keys = list(params)
        self.bounds = [(float(params[k][0]), float(params[k][1])) for k in self.keys]
        self.rows: list[dict[str, Any]] = []
        self.bar: Any = None  # the progress bar, while the search runs

    @property
    def budget(self) -> tuple[int, int]:
        """The method's ``maxiter`` (generations or evaluations) and the evaluations it
        makes."""
        o = self.options
        steps = DEFAULT_MAXITER[o.method] if o.maxiter is None else o.maxiter
        if o.method == "differential_evolution":
            return steps, o.popsize * len(self.keys) * (steps + 1)
        return steps, steps

    def fly(self, candidate: Scenario, seed: int, count: int) -> MonteCarloResult:
        """``count`` realisations of ``seed`` under every controller; _Stop on Ctrl-C."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # stability is judged here, not warned about
            mc = monte_carlo(candidate, runs=count, seed=seed, controllers=self.controllers,
                             workers=self.options.workers, progress=False, spectra=False,
                             client=self.options.client)  # fmt: skip
        if mc.interrupted:
            raise _Stop
        return mc

    def score(self, mc: MonteCarloResult) -> tuple[float, int, np.ndarray | None]:
        """The objective of a batch, its diverged realisations, and (a metric objective) the
        per-realisation values."""
        objective = self.options.objective
        if isinstance(objective, str):
            values, diverged = _metric_values(mc, objective, self.phases)
            value = float(np.mean(values)) if diverged == 0 else math.nan
            return value, diverged, values
        diverged = int(mc.runs.groupby("realisation")["diverged"].any().sum())
        return float(objective(mc)), diverged, None

    def judge(self, row: dict[str, Any], mc: MonteCarloResult | None) -> float:
        """Each constraint's value and verdict into ``row``; the summed relative violation."""
        total = 0.0
        for c in self.constraints:
            value = c.value(mc.runs, self.phases) if mc is not None else math.nan
            row[c.label] = value
            row[str(c)] = c.satisfied(value)
            total += c.violation(value)
        row["feasible"] = total == 0.0
        return total

    def at_hover(self, candidate: Scenario) -> dict[str, Any]:
        """A candidate's stability columns: judged on the modes the scenario excites (the
        others stay exactly at rest in flight)."""
        from quadrs.hover.stability import stability

        reports = [stability(candidate, c) for c in self.controllers]
        unstable = "; ".join(
            f"{r.controller.upper()} {mode}" for r in reports for mode in r.excited_unstable_modes()
        )
        return {
            "stable": all(r.stable for r in reports),
            "max_real": max(float(r.excited_poles["real"].max()) for r in reports),
            "unstable_modes": unstable,
        }

    def measure(
        self, values: dict[str, float], candidate: Scenario, require: bool
    ) -> tuple[dict[str, Any], MonteCarloResult | None]:
        """One candidate's history row and its flights (None if not flown)."""
        penalty, runs = self.options.penalty, self.options.runs
        hover = self.at_hover(candidate)
        row: dict[str, Any] = {"evaluation": len(self.rows), **values, **hover, "flown": False,
                               "diverged": 0, "penalised": False}  # fmt: skip
        mc = None
        if require and hover["unstable_modes"]:
            value = penalty * (1.0 + max(0.0, hover["max_real"]))
            row.update(penalised=True)
        else:
            try:
                mc = self.fly(candidate, self.options.seed, runs)
            except KeyboardInterrupt:
                raise _Stop from None
            value, diverged, _ = self.score(mc)
            row.update(flown=True, diverged=diverged)
            if diverged > 0 or not math.isfinite(value):
                value = penalty * (1.0 + diverged / runs)
                row.update(penalised=True)
        row["objective"] = value
        violation = self.judge(row, mc)
        row["score"] = _constrained(value, violation, bool(row["penalised"]), penalty)
        row["violation"] = violation
        row["role"] = ""
        return row, mc

    def evaluate(self, x: np.ndarray) -> float:
        """The score the optimiser minimises, of the candidate ``x`` (one value per key)."""
        values = {k: float(v) for k, v in zip(self.keys, x, strict=True)}
        candidate = self.scenario.override(expand(values))
        row, _ = self.measure(values, candidate, self.options.require_stable)
        self.rows.append(row)
        self.bar.update(1)
        if self.options.callback is not None:
            self.options.callback(dict(row))
        return float(row["score"])

    def run(self) -> bool:
        """Search until the budget is spent; whether Ctrl-C stopped it first."""
        from quadrs.present.terminal import shows_progress, tqdm_class

        steps, total = self.budget
        self.bar = tqdm_class()(total=total, disable=not shows_progress(self.options.progress),
                                unit="eval", desc="tune", leave=False)  # fmt: skip
        try:
            self._minimise(steps)
        except (_Stop, KeyboardInterrupt):
            return True
        finally:
            self.bar.close()
        return False

    def _minimise(self, steps: int) -> None:
        from scipy import optimize as sopt  # lazily: `quadrs --version` stays fast

        if self.options.method == "differential_evolution":
            sopt.differential_evolution(
                self.evaluate,
                self.bounds,
                maxiter=steps,
                popsize=self.options.popsize,
                seed=self.options.seed,
                polish=False,
                tol=0.0,  # no early stop: the budget is maxiter generations
                updating="deferred",
                workers=1,
                init="latinhypercube",
            )
            return
        own = self.own_values().values()
        x0 = [min(max(v, lo), hi) for v, (lo, hi) in zip(own, self.bounds, strict=True)]
        sopt.minimize(
            self.evaluate,
            x0,
            method="Nelder-Mead",
            bounds=self.bounds,
            options={"maxfev": steps, "xatol": 1e-4, "fatol": 1e-9},
        )

    def own_values(self) -> dict[str, float]:
        """The scenario's own value of each key (a tied group's first)."""
        return {k: float(key_value(self.scenario, k.split(",")[0].strip())) for k in self.keys}

    @property
    def columns(self) -> list[str]:
        """The history's columns, in order."""
        columns = ["evaluation", *self.keys, "objective", "stable", "max_real", "flown",
                   "diverged", "penalised", "unstable_modes"]  # fmt: skip
        for con in self.constraints:
            columns += [col for col in (con.label, str(con)) if col not in columns]
        return [*columns, "feasible", "violation", "score", "role"]

    def history(self) -> pd.DataFrame:
        """The evaluations so far, one row each; KeyboardInterrupt if there is none."""
        if not self.rows:
            raise KeyboardInterrupt("interrupted before the first evaluation finished")
        return pd.DataFrame(self.rows, columns=self.columns)

    def after(self, history: pd.DataFrame, tuned: Scenario, penalised: bool) -> _After:
        """The untuned scenario on the same gusts (a row beside the best in the history);
        unless the best was penalised, the best on the held-out seed and, for a metric
        objective, the per-phase effects of the tuning."""
        o = self.options
        row, before = self.measure(self.own_values(), self.scenario, require=False)
        row["role"] = "baseline"
        history = pd.concat([history, pd.DataFrame([row], columns=self.columns)],
                            ignore_index=True)  # fmt: skip
        after = _After(history, self.score(before)[0] if before is not None else math.nan)
        if penalised:
            return after
        count = o.runs if o.holdout_runs is None else int(o.holdout_runs)
        hseed = holdout_seed(o.seed)
        mc = self.fly(tuned, hseed, count)
        holdout = holdout_of(mc, o.objective, self.phases, hseed, count, self.score)
        held = None
        if self.constraints:
            held = pd.concat([c.check(mc.runs, self.phases) for c in self.constraints],
                             ignore_index=True)  # fmt: skip
        effects = None
        if isinstance(o.objective, str) and before is not None:
            effects = phase_effects(before, self.fly(tuned, o.seed, o.runs), o.objective)
        return dataclasses.replace(after, holdout=holdout, effects=effects, held=held)


def _constrained(value: float, violation: float, penalised: bool, penalty: float) -> float:
    """The score of a candidate of objective ``value``: a constraint's violation puts it
    above every feasible one, ordered by the violation, and below every unstable or diverged
    one (already penalised)."""
    if violation > 0 and not penalised:
        frac = 1.0 if math.isinf(violation) else violation / (1.0 + violation)
        return penalty * (0.5 + 0.5 * frac)
    return value
