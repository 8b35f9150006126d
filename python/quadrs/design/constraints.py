"""Constraints of the design loop: a statistic of a metric over a candidate's Monte Carlo runs,
bounded above or below (:func:`quadrs.optimize`, ``quadrs tune --constraint``).

Three statistics, each per phase over the realisations of the tuning seed (common random
numbers: every candidate flies the same gusts, so a constraint's value is a deterministic
function of the parameters):

- ``mean``: the mean of the metric, ``tracking_rms <= 0.5``;
- ``exceedance``: the fraction of realisations whose metric exceeds a threshold, the chance
  constraint ``P(max_accel > 8) <= 0.01``; a realisation that diverged in or before the phase
  exceeds every threshold (as in :mod:`quadrs.stats.risk`);
- ``quantile``: the ``q``-quantile (``np.quantile(method="inverted_cdf")``, diverged
  realisations as +inf), ``quantile(max_accel, 0.99) <= 8``.

Text form (the command line's, also accepted by :func:`quadrs.optimize`)::

    tracking_rms<=0.5              mean(tracking_rms)<=0.5 is the same
    tracking_rms@P2<=0.5           in phase P2 only
    P(max_accel>8)<=0.01           chance constraint
    P(max_accel@leg2>8)<=0.01
    quantile(max_accel,0.99)<=8

The text form's values of a metric (X and T) are in the unit the tables show, as ``--limit``
reads them (:data:`quadrs.present.labels.INPUT_UNITS`: degrees for swing, ``max_swing@transit
<=30`` is 30 degrees; an acceleration may be given in g, ``P(max_specific_force>1.5g)<=0.01``);
a :class:`Constraint` holds them in the results' unit (SI, radians), and so does the mapping
form. The text form is printed back in the shown unit.

Python mapping form: ``{"tracking_rms": ("<=", 0.5), ("max_accel", "exceedance", 8.0): ("<=",
0.01), ("max_accel", "quantile", 0.99): ("<=", 8.0)}``; a metric written ``metric@phase``
restricts the constraint to that phase. Without a phase a constraint holds in every phase of
the objective (its value is the worst of them), and, with several controllers, for each.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from quadrs import _core

__all__ = ["Constraint", "constraints_from", "parse_constraint"]

STATISTICS = ("mean", "exceedance", "quantile")
OPERATORS = ("<=", ">=", "<", ">")

_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
_METRIC = r"([A-Za-z_][A-Za-z0-9_]*)(?:@([^()<>=,\s]+))?"
_OP = r"(<=|>=|<|>)"
#: A metric's value as typed: a number, and optionally its unit (30deg, 0.5rad, 1.5g).
_VALUE = rf"({_NUMBER}\s*(?:deg|rad|g|G)?)"
_FORMS = (
    ("exceedance", re.compile(rf"^P\(\s*{_METRIC}\s*>\s*{_VALUE}\s*\)\s*{_OP}\s*({_NUMBER})$")),
    (
        "quantile",
        re.compile(rf"^quantile\(\s*{_METRIC}\s*,\s*({_NUMBER})\s*\)\s*{_OP}\s*{_VALUE}$"),
    ),
    ("mean", re.compile(rf"^mean\(\s*{_METRIC}\s*\)\s*{_OP}\s*{_VALUE}$")),
    ("mean", re.compile(rf"^{_METRIC}\s*{_OP}\s*{_VALUE}$")),
)


def _fmt(x: float) -> str:
    return f"{x:g}"


@dataclass(frozen=True)
class Constraint:
    """``statistic(metric) op bound``: see the module's docstring.

    ``level``: the threshold of an exceedance, the ``q`` of a quantile, None for a mean;
    ``phase``: the one phase it applies to, or None for every phase of the objective.
    """

    metric: str
    op: str
    bound: float
    statistic: str = "mean"
    level: float | None = None
    phase: str | None = None

    def __post_init__(self) -> None:
        what = f"constraint on {self.metric}"
        names = tuple(_core.METRIC_NAMES)
        if self.metric not in names:
            raise ValueError(
                f"constraint: metric must be one of {', '.join(names)}; got {self.metric!r}"
            )
        if self.statistic not in STATISTICS:
            raise ValueError(
                f"constraint on {self.metric}: statistic must be one of {STATISTICS}, "
                f"got {self.statistic!r}"
            )
        if self.op not in OPERATORS:
            raise ValueError(f"{what}: operator must be one of {OPERATORS}, got {self.op!r}")
        if not (isinstance(self.bound, int | float) and math.isfinite(self.bound)):
            raise ValueError(f"{what}: bound must be a finite number, got {self.bound!r}")
        if self.statistic == "mean" and self.level is not None:
            raise ValueError(f"{what}: a mean takes no level, got {self.level!r}")
        if self.statistic != "mean" and (self.level is None or not math.isfinite(self.level)):
            raise ValueError(f"{what}: {self.statistic} needs a finite level, got {self.level!r}")
        if self.statistic == "quantile" and not 0 < float(self.level or 0) < 1:
            raise ValueError(f"{what}: the quantile's q must be in (0, 1), got {self.level!r}")

    @property
    def label(self) -> str:
        """The statistic as text, e.g. ``P(max_accel@P2>8)``: the history's value column."""
        target = self.metric if self.phase is None else f"{self.metric}@{self.phase}"
        if self.statistic == "exceedance":
            return f"P({target}>{self._shown(float(self.level))})"  # type: ignore[arg-type]
        if self.statistic == "quantile":
            return f"quantile({target},{_fmt(float(self.level))})"  # type: ignore[arg-type]
        return target

    def __str__(self) -> str:
        """The text form, e.g. ``P(max_accel>8)<=0.01``: the history's satisfied column; a
        metric's values in the unit the tables show (``max_swing<=30deg``)."""
        bound = _fmt(self.bound) if self.statistic == "exceedance" else self._shown(self.bound)
        return f"{self.label}{self.op}{bound}"

    def _shown(self, value: float) -> str:
        """A value of the metric as the text form gives it, with its unit if it is an angle."""
        from quadrs.present.labels import is_angle, shown_value

        text = _fmt(shown_value(self.metric, value))
        return f"{text}deg" if is_angle(self.metric) else text

    def satisfied(self, value: float) -> bool:
        """Does ``value`` meet the bound? NaN never does."""
        if math.isnan(value):
            return False
        return {
            "<=": value <= self.bound,
            ">=": value >= self.bound,
            "<": value < self.bound,
            ">": value > self.bound,
        }[self.op]

    def violation(self, value: float) -> float:
        """How far ``value`` is past the bound, relative to the bound's size (1 if it is 0);
        0 when satisfied, +inf for NaN. Orders the infeasible candidates."""
        if math.isnan(value):
            return math.inf
        if self.satisfied(value):
            return 0.0
        scale = abs(self.bound) if self.bound != 0 else 1.0
        return max(abs(value - self.bound) / scale, 1e-12)

    def value(self, runs: pd.DataFrame, phases: Sequence[str]) -> float:
        """The statistic on a runs table: per controller and phase (this constraint's phase,
        else each of ``phases``), the worst one for the bound (the largest for ``<``/``<=``,
        the smallest for ``>``/``>=``); NaN if any is undefined."""
        from quadrs.stats.summary import phase_diverged

        chosen = [self.phase] if self.phase is not None else list(phases)
        values = []
        rows = runs[runs["phase"].isin(chosen)]
        for _, sel in rows.groupby(["controller", "phase"], sort=True):
            x = sel[self.metric].to_numpy(float)
            gone = phase_diverged(sel)
            values.append(self._statistic(x, gone))
        if not values or any(math.isnan(v) for v in values):
            return math.nan
        return max(values) if self.op in ("<", "<=") else min(values)

    def check(self, runs: pd.DataFrame, phases: Sequence[str], confidence: float = 0.95
              ) -> pd.DataFrame:  # fmt: skip
        """Per controller and phase (as :meth:`value`), the statistic with its interval:
        exact (Clopper-Pearson) for an exceedance, order-statistic for a quantile, Student t
        for a mean; ``met`` (the estimate meets the bound) and ``certain`` (the whole interval
        does). For re-checking a design on seeds it was not tuned on."""
        from quadrs.stats.risk import exceedance_stats, quantile_interval
        from quadrs.stats.summary import mean_ci, phase_diverged

        chosen = [self.phase] if self.phase is not None else list(phases)
        rows = []
        for (ctrl, phase), sel in runs[runs["phase"].isin(chosen)].groupby(
            ["controller", "phase"], sort=True
        ):
            x = sel[self.metric].to_numpy(float)
            gone = phase_diverged(sel)
            if self.statistic == "exceedance":
                e = exceedance_stats(x, float(self.level), gone, confidence)  # type: ignore[arg-type]
                n, value, lo, hi = e.n, e.probability, e.ci_low, e.ci_high
            elif self.statistic == "quantile":
                x = np.where(gone, np.inf, x)
                n, value, lo, hi = quantile_interval(x, float(self.level), confidence)  # type: ignore[arg-type]
            else:
                n, value, lo, hi = mean_ci(np.where(gone, np.nan, x), confidence)
                if gone.any():
                    value = lo = hi = math.nan
            rows.append({"constraint": str(self), "controller": ctrl, "phase": phase, "n": n,
                         "value": value, "ci_low": lo, "ci_high": hi,
                         "met": self.satisfied(value),
                         "certain": self.satisfied(lo) and self.satisfied(hi)})  # fmt: skip
        return pd.DataFrame(rows)

    def _statistic(self, x: np.ndarray, gone: np.ndarray) -> float:
        from quadrs.stats.risk import exceeds

        if self.statistic == "mean":
            return float(np.mean(x)) if x.size and not gone.any() else math.nan
        if self.statistic == "exceedance":
            hit, defined = exceeds(x, float(self.level), gone)  # type: ignore[arg-type]
            n = int(defined.sum())
            return float(hit.sum() / n) if n else math.nan
        x = x.copy()
        x[gone] = np.inf
        x = x[~np.isnan(x)]
        if not x.size:
            return math.nan
        q = float(self.level)  # type: ignore[arg-type]
        return float(np.quantile(x, q, method="inverted_cdf"))


def parse_constraint(text: str) -> Constraint:
    """The text form (module docstring) -> a Constraint; ValueError quoting the text."""
    flat = text.strip()
    for statistic, pattern in _FORMS:
        m = pattern.match(flat)
        if m is None:
            continue
        from quadrs.present.labels import metric_value

        groups = m.groups()
        metric, phase = groups[0], groups[1]
        try:
            if metric not in _core.METRIC_NAMES:
                Constraint(metric, "<=", 0.0)  # the message naming the metrics
            if statistic == "mean":
                level, op, bound = None, groups[2], metric_value(metric, groups[3])
            elif statistic == "exceedance":
                level, op, bound = metric_value(metric, groups[2]), groups[3], float(groups[4])
            else:
                level, op, bound = float(groups[2]), groups[3], metric_value(metric, groups[4])
            return Constraint(metric, op, bound, statistic, level, phase)
        except ValueError as e:
            raise ValueError(f"{text!r}: {str(e).split(': ', 1)[-1]}") from None
    raise ValueError(
        f"{text!r}: expected METRIC<=X, P(METRIC>T)<=P or quantile(METRIC,Q)<=X (also >=; "
        "METRIC@PHASE for one phase)"
    )


def _from_item(key: Any, spec: Any) -> Constraint:
    try:
        op, bound = spec
    except (TypeError, ValueError):
        raise ValueError(f"constraint {key!r}: expected (operator, bound), got {spec!r}") from None
    if isinstance(key, str):
        key = (key,)
    if not isinstance(key, tuple) or not 1 <= len(key) <= 3 or not isinstance(key[0], str):
        raise ValueError(
            f"constraint {key!r}: expected METRIC, (METRIC, 'mean'), (METRIC, 'exceedance', "
            "THRESHOLD) or (METRIC, 'quantile', Q)"
        )
    metric, _, phase = key[0].partition("@")
    statistic = key[1] if len(key) > 1 else "mean"
    level = key[2] if len(key) > 2 else None
    if statistic != "mean" and level is None:
        raise ValueError(f"constraint {key!r}: {statistic} needs a level")
    try:
        bound_f = float(bound)
        level_f = None if level is None else float(level)
    except (TypeError, ValueError):
        raise ValueError(f"constraint {key!r}: bound and level must be numbers") from None
    return Constraint(metric.strip(), str(op), bound_f, str(statistic), level_f, phase or None)


def constraints_from(
    spec: Mapping[Any, Any] | Sequence[Constraint | str] | None,
) -> tuple[Constraint, ...]:
    """Constraints from a mapping ``{key: (op, bound)}`` or a sequence of Constraint objects
    and text forms (module docstring)."""
    if spec is None:
        return ()
    if isinstance(spec, Mapping):
        return tuple(_from_item(k, v) for k, v in spec.items())
    if isinstance(spec, str | Constraint):
        spec = [spec]
    out = []
    for item in spec:
        if isinstance(item, Constraint):
            out.append(item)
        elif isinstance(item, str):
            out.append(parse_constraint(item))
        else:
            raise TypeError(f"constraints: expected a Constraint or its text, got {item!r}")
    return tuple(out)


def check_phases(constraints: Sequence[Constraint], phase_names: Sequence[str]) -> None:
    """A constraint naming a phase the scenario lacks is refused by name."""
    for c in constraints:
        if c.phase is not None and c.phase not in phase_names:
            raise ValueError(f"constraint {c}: phase {c.phase!r} is not one of {list(phase_names)}")
