"""Rich display in notebooks: the HTML that Jupyter shows for a result (``_repr_html_``).

Each result type renders a heading (its ``repr``), optional short notes and its summary
tables, as pandas renders them; no figures, nothing recomputed beyond the summary.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from typing import Any

import pandas as pd


def render(
    title: str, tables: Sequence[tuple[str, pd.DataFrame]], notes: Sequence[str] = ()
) -> str:
    """``title`` as a heading, each note as a paragraph, then each (caption, frame) as an
    HTML table (all text escaped)."""
    parts = [f"<div class='quadrs'><strong>{html.escape(title)}</strong>"]
    parts += [f"<p>{html.escape(note)}</p>" for note in notes if note]
    for caption, frame in tables:
        parts.append(f"<p><em>{html.escape(caption)}</em></p>")
        parts.append(frame.to_html(float_format=lambda v: f"{v:.4g}", na_rep=""))
    parts.append("</div>")
    return "\n".join(parts)


def monte_carlo(mc: Any) -> str:
    """A Monte Carlo batch: Table 3 (IAE and ITAE, mean ± 95 % CI, P) and its counts."""
    from quadrs.present.table3 import METRIC_LABELS, counts, shows_paper, table3_blocks

    if mc.runs.empty:
        return render(repr(mc), [], ["no realisation finished"])
    summary = mc.summary()
    blocks = table3_blocks(summary, paper=shows_paper(mc.scenario))
    tables = [
        (f"{METRIC_LABELS[m][0]} ({METRIC_LABELS[m][1]}): mean ± 95% CI half-width", block)
        for m, block in blocks.items()
    ]
    return render(repr(mc), tables, counts(summary))


def stability(report: Any) -> str:
    """A stability report: its verdict and its poles."""
    return render(repr(report), [("poles at hover (1/s; frequency in Hz)", report.poles)],
                  [str(report)])  # fmt: skip
