"""The paper's Table 3 for people: a summary's means with confidence intervals and P = 100
SMC/PD as text and Markdown, beside the paper's own values. The statistics are
:mod:`quadrs.stats.summary`'s."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd

from quadrs import _core

#: The paper's Table 3 (one gust realisation, MATLAB): P = 100 * SMC / PD, per phase.
PAPER_TABLE3 = pd.DataFrame(
    {"P_iae": [35.40, 11.38, 48.25], "P_itae": [26.73, 13.76, 49.51]},
    index=pd.Index(["P1", "P2", "P3"], name="phase"),
)

#: Metric names, from the engine (one list for the whole package).
_METRICS = tuple(_core.METRIC_NAMES)

# The statistics live in the core (`quadrs.stats.summary`); the TOML spelling with the scenario.
# Re-exported: tables and CLI read them from here.
from quadrs.scenario.scenario import toml_value  # noqa: E402
from quadrs.stats.summary import mean_ci, phase_diverged, ratio_ci, summarise  # noqa: E402

__all__ = ["mean_ci", "phase_diverged", "ratio_ci", "summarise", "toml_value"]


def shows_paper(scenario: Any) -> bool:
    """Whether the paper's own Table 3 applies to runs of ``scenario``: the paper preset,
    flown at any integrator step (any other change, even one that keeps the phase names
    P1-P3, makes the paper's numbers a different problem's)."""
    return set(scenario.differences(type(scenario).paper())) <= {"integrator.dt"}


#: Under the Table-3 heading when the paper's P is shown: why ours differs, and where it says
#: so at length.
PAPER_NOTE = (
    "Our P is not the paper's: the paper flew one gust with unstated payload, spring, drag and\n"
    "gust values, and no setting of them reproduces its P2 (see docs/paper-calibration.md)."
)


def table3(summary: pd.DataFrame, paper: bool = True) -> pd.DataFrame:
    """The paper's Table 3 layout: per phase, IAE and ITAE of PD and SMC and P, as text
    ``mean [low, high]``, beside the paper's own P (``paper``); ``n``: the fewest realisations
    in a mean of the phase; ``diverged``: realisations in which any controller diverged by the
    phase's end."""

    def fmt(mean: float, lo: float, hi: float, digits: int) -> str:
        if np.isnan(lo):
            return f"{mean:.{digits}f}"
        return f"{mean:.{digits}f} [{lo:.{digits}f}, {hi:.{digits}f}]"

    out = {}
    for metric in ("iae", "itae"):
        part = summary.xs(metric, level="metric")
        for c in ("pd", "smc"):
            if f"{c}_mean" in part:
                out[f"{metric.upper()} {c.upper()}"] = [
                    fmt(r[f"{c}_mean"], r[f"{c}_ci_low"], r[f"{c}_ci_high"], 4)
                    for _, r in part.iterrows()
                ]
        if "P" in part:
            out[f"P_{metric.upper()} %"] = [
                fmt(r["P"], r["P_ci_low"], r["P_ci_high"], 1) for _, r in part.iterrows()
            ]
            if paper:
                ref = PAPER_TABLE3[f"P_{metric}"].reindex(part.index)
                out[f"paper P_{metric.upper()} %"] = [
                    "" if np.isnan(v) else f"{v:.2f}" for v in ref.to_numpy(float)
                ]
    any_part = summary.xs("iae", level="metric")
    frame = pd.DataFrame(out, index=any_part.index)
    frame["n"] = [
        int(r[[c for c in r.index if c.endswith("_n")]].min()) for _, r in any_part.iterrows()
    ]
    frame["diverged"] = any_part["diverged"].to_numpy()
    return frame


def plus_minus(mean: float, lo: float, hi: float, sig: int = 2) -> str:
    """``mean ± half-width`` of an interval, the half-width to ``sig`` significant figures and
    the mean to the same decimal place (``0.0678 ± 0.0011``); the mean alone when the interval
    is unknown. An asymmetric interval shows its larger half."""
    if not np.isfinite(mean):
        return "nan"
    if not (np.isfinite(lo) and np.isfinite(hi)):
        return f"{mean:.4g}"
    half = max(hi - mean, mean - lo, 0.0)
    if half == 0.0 or half < 1e-12 * max(abs(mean), 1e-300):
        return f"{mean:.4g} ± 0"
    decimals = max(0, sig - 1 - int(np.floor(np.log10(half))))
    return f"{mean:.{decimals}f} ± {half:.{decimals}f}"


def table3_blocks(
    summary: pd.DataFrame, metrics: Sequence[str] = ("iae", "itae"), paper: bool = True
) -> dict[str, pd.DataFrame]:
    """The compact Table 3: one block per metric, rows per phase, cells ``mean ± 95 % CI
    half-width`` for each controller and for P = 100 SMC/PD (%), and (``paper``) the paper's
    P beside it. Fits 80 columns; :func:`table3` is the wide form."""
    blocks = {}
    for metric in metrics:
        part = summary.xs(metric, level="metric")
        cols: dict[str, list[str]] = {}
        for c in ("pd", "smc"):
            if f"{c}_mean" in part:
                cols[c.upper()] = [
                    plus_minus(r[f"{c}_mean"], r[f"{c}_ci_low"], r[f"{c}_ci_high"])
                    for _, r in part.iterrows()
                ]
        if "P" in part:
            cols["P = SMC/PD %"] = [
                plus_minus(r["P"], r["P_ci_low"], r["P_ci_high"]) for _, r in part.iterrows()
            ]
            ref = PAPER_TABLE3.get(f"P_{metric}")
            if paper and ref is not None:
                cols["paper P %"] = [
                    "" if np.isnan(v) else f"{v:.2f}"
                    for v in ref.reindex(part.index).to_numpy(float)
                ]
        blocks[metric] = pd.DataFrame(cols, index=part.index)
    return blocks


#: Units and names of the metrics, for tables and figures.
METRIC_LABELS = {
    "iae": ("IAE", "m s"),
    "itae": ("ITAE", "m s²"),
    "max_abs": ("peak |e_o|", "m"),
    "rms": ("RMS e_o", "m"),
    "tracking_rms": ("RMS altitude tracking error", "m"),
    "peak_frequency": ("spectral peak frequency", "Hz"),
    "peak_amplitude": ("spectral peak amplitude", "m"),
    "max_accel": ("peak payload acceleration", "m/s²"),
    "rms_accel": ("RMS payload acceleration", "m/s²"),
    "max_specific_force": ("peak payload specific force |a - g|", "m/s²"),
}


def format_table3(summary: pd.DataFrame, wide: bool = False, paper: bool = True) -> str:
    """Table 3 as text for a terminal: by default IAE and ITAE as separate blocks that fit
    100 columns (``mean ± 95 % CI half-width``); ``wide`` gives :func:`table3`'s one-row-per-
    phase form with full intervals. ``paper``: show the paper's P (%) beside ours."""
    paper = paper and "P" in summary
    lines = ["Table 3 (Geronel et al. 2023) with the paper's P beside ours", PAPER_NOTE, ""]
    lines = lines if paper else []
    if wide:
        with pd.option_context("display.width", 250, "display.max_columns", None):
            return "\n".join([*lines, table3(summary, paper).to_string(), *counts(summary)])
    for metric, block in table3_blocks(summary, paper=paper).items():
        name, unit = METRIC_LABELS[metric]
        lines += [f"{name} ({unit}): mean ± 95% CI half-width", block.to_string(), ""]
    return "\n".join([*lines, *counts(summary)])


def counts(summary: pd.DataFrame) -> list[str]:
    """The footer of a Table-3 summary: realisations in the means and diverged ones, per
    controller and phase (one line when every controller and phase has the same)."""
    part = summary.xs(summary.index.get_level_values("metric")[0], level="metric")
    ctrls = [str(c)[:-2] for c in part.columns if str(c).endswith("_n")]

    def per_phase(column: str) -> str:
        values = part[column].astype(int)
        if values.nunique() == 1:
            return f"{values.iloc[0]} in every phase"
        return ", ".join(f"{phase} {v}" for phase, v in values.items())

    n = {int(v) for c in ctrls for v in part[f"{c}_n"]}
    if len(n) == 1:
        lines = [f"n = {n.pop()} realisations per controller and phase"]
    else:
        ns = "; ".join(f"{c.upper()} {per_phase(f'{c}_n')}" for c in ctrls)
        lines = [f"n (realisations in the means): {ns}"]
    if not all(f"{c}_diverged" in part for c in ctrls):  # a summary from an older version
        lines[0] += f"; diverged: {int(part['diverged'].max())}"
    elif not any(part[f"{c}_diverged"].any() for c in ctrls):
        lines[0] += "; none diverged"
    else:
        div = "; ".join(f"{c.upper()} {per_phase(f'{c}_diverged')}" for c in ctrls)
        lines += [
            f"diverged by the phase's end (left out of its means and of P): {div}",
            "A phase that ended before its flight diverged keeps its metrics (docs/model.md §6).",
        ]
    return lines


#: The paper's spectral-peak ratio (percent, SMC/PD, read from its text: "about 35 %" in P1,
#: "around eight times smaller" in P2; not stated for P3).
PAPER_PEAK_RATIO = pd.Series({"P1": 35.0, "P2": 12.5}, name="P_peak", dtype=float)


def paper_comparison(summary: pd.DataFrame) -> pd.DataFrame:
    """Ours beside the paper's, per phase: P = 100 SMC/PD of IAE, ITAE and the spectral peak
    amplitude, each with its 95% CI (``lo``, ``hi``), the paper's value, and whether the
    paper's value lies inside our interval. Needs a summary with both PD and SMC."""
    if "P" not in summary:
        raise ValueError("the comparison needs runs of both controllers, pd and smc")
    paper = {"iae": PAPER_TABLE3["P_iae"], "itae": PAPER_TABLE3["P_itae"]}
    paper["peak_amplitude"] = PAPER_PEAK_RATIO
    rows = []
    for metric, ref in paper.items():
        part = summary.xs(metric, level="metric")
        for phase, r in part.iterrows():
            value = float(ref.get(phase, np.nan))
            inside = bool(r["P_ci_low"] <= value <= r["P_ci_high"]) if np.isfinite(value) else None
            rows.append(
                {
                    "metric": metric,
                    "phase": phase,
                    "P": r["P"],
                    "P_ci_low": r["P_ci_low"],
                    "P_ci_high": r["P_ci_high"],
                    "paper_P": value,
                    "paper_in_ci": inside,
                }
            )
    return pd.DataFrame(rows).set_index(["metric", "phase"])


def to_markdown(frame: pd.DataFrame, floatfmt: str = ".4g", index: bool = True) -> str:
    """A GitHub-flavoured Markdown table of ``frame`` (no extra dependency); NaN and None
    print as empty cells."""
    df = frame.reset_index() if index else frame

    def cell(v: object) -> str:
        if v is None or (isinstance(v, float) and np.isnan(v)):
            return ""
        if isinstance(v, float | np.floating):
            return format(float(v), floatfmt)
        return str(v).replace("|", "\\|")

    header = "| " + " | ".join(str(c) for c in df.columns) + " |"
    rule = "|" + "|".join("---" for _ in df.columns) + "|"
    body = ["| " + " | ".join(cell(v) for v in row) + " |" for row in df.itertuples(index=False)]
    return "\n".join([header, rule, *body])


def ordering(summary: pd.DataFrame, metric: str = "iae") -> pd.DataFrame:
    """Per phase, which controller has the smaller mean ``metric``: ``"SMC lower"`` when the
    CI of P = 100 SMC/PD lies below 100, ``"SMC higher"`` above, ``"no clear difference"``
    when it straddles 100; with P and the paper's P."""
    part = summary.xs(metric, level="metric")
    paper = PAPER_TABLE3.get(f"P_{metric}")

    def verdict(r: pd.Series) -> str:
        if r["P_ci_high"] < 100:
            return "SMC lower"
        if r["P_ci_low"] > 100:
            return "SMC higher"
        return "no clear difference"

    return pd.DataFrame(
        {
            "P": part["P"],
            "verdict": [verdict(r) for _, r in part.iterrows()],
            "paper_P": paper.reindex(part.index) if paper is not None else np.nan,
        }
    )
