"""How a :class:`quadrs.design.safety.SafetyCase` reads: the per-flight-hour block of
``quadrs mission`` and the one-page markdown of ``--safety-case FILE``. Both print the same
numbers, formatted by the same functions (a test reads both)."""

from __future__ import annotations

from typing import Any

#: A :class:`quadrs.design.safety.SafetyCase` and one of its failure modes (that module imports
#: this one to format itself: typed here by their role, not imported back).
SafetyCase = Any
FailureMode = Any

__all__ = ["bands_lines", "header", "rates_text", "safety_markdown", "shown"]


def shown(x: float) -> str:
    """A rate or probability as every table here prints it (3 significant digits; "-" for
    none, a band without flights)."""
    return "-" if x != x else f"{x:.3g}"


def _cells(m: FailureMode) -> list[str]:
    """A mode's row: events of flights, per flight [interval], per flight hour [interval],
    its one-sided upper bound, per 10,000 deliveries and its one-sided bound."""
    if m.rate is None:
        return [m.label, "not judged", m.why, "", "", ""]
    r = m.rate
    return [m.label, m.tally,
            f"{shown(m.probability)} [{shown(m.ci_low)}, {shown(m.ci_high)}]",
            f"{shown(r.rate)} [{shown(r.ci_low)}, {shown(r.ci_high)}]", shown(r.upper),
            f"{shown(r.per_10k)} (<= {shown(r.per_10k_upper)})"]  # fmt: skip


def header(confidence: float) -> list[str]:
    """The failure modes table's columns, the intervals' and bounds' level said."""
    c = f"{100 * confidence:.3g} %"
    return ["failure mode", "events", f"per flight [{c} CI]", f"per flight hour [{c} CI]",
            f"upper bound per flight hour (one-sided {c})",
            f"per 10,000 deliveries (<= one-sided {c})"]  # fmt: skip


def rates_text(case: SafetyCase, width: int = 100) -> str:
    """The failure modes per flight hour (and the targets' verdicts) for a terminal, at most
    ``width`` columns: per mode, one ``label: value`` line per number of the page's row."""
    import textwrap

    head = (
        f"Per flight hour ({case.controller.upper()}, {case.method}; "
        f"{100 * case.confidence:.3g} % intervals: {case.intervals}):"
    )
    lines = textwrap.wrap(head, width)
    names = header(case.confidence)[2:]
    for mode, m in case.modes.items():
        cells = _cells(m)
        said = f"{mode}: {cells[1]}" + (f" ({cells[2]})" if m.rate is None else "")
        lines += textwrap.wrap(said, width, subsequent_indent="    ")
        if m.rate is not None:
            lines += [f"  {name}: {value}" for name, value in zip(names, cells[2:], strict=True)]
    for v in case.verdicts:
        lines += textwrap.wrap(v.text(case.modes[v.mode].rate), width)
    if case.bands is not None:
        lines += bands_lines(case, width)
    return "\n".join(lines)


def _band_modes(bands: Any) -> list[str]:
    """The judged modes the bands table counts, in its order."""
    return [c.removesuffix("_events") for c in bands.columns if c.endswith("_events")]


def bands_lines(case: SafetyCase, width: int = 100) -> list[str]:
    """Which winds make the risk, short: a line per band of the drawn mean wind with its
    flights and their share, and per mode that has events the band's events and their share
    of the mode's (the page's table, the same numbers)."""
    import textwrap

    bands = case.bands
    modes = [m for m in _band_modes(bands) if bands[f"{m}_events"].sum() > 0]
    lines = textwrap.wrap("Which winds make the risk, per band of the drawn mean wind (W20, m/s): "
                          "its flights (share), each mode's events there (share of the mode's):",
                          width)  # fmt: skip
    for band, r in bands.iterrows():
        said = [f"{m} {int(r[f'{m}_events'])} ({shown(r[f'{m}_share'])})" for m in modes]
        flights = int(r["flights"])
        text = f"  {band}: {flights} flight{'s' * (flights != 1)} ({shown(r['share'])})"
        lines += textwrap.wrap("; ".join([text, *said]), width, subsequent_indent="    ")
    return lines


def _table(header: list[str], rows: list[list[str]]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    out += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(out)


def safety_markdown(case: SafetyCase) -> str:
    """The one-page summary: failure modes, method, targets, winds, assumptions."""
    parts = [
        f"# Safety case summary: {case.controller.upper()}",
        "",
        f"Method: {case.method}. Each flight is one delivery; {case.hours_said}. Intervals are "
        f"{100 * case.confidence:.3g} % ({case.intervals}); a target is judged against the "
        f"one-sided {100 * case.confidence:.3g} % upper bound.",
        "",
        "## Failure modes",
        "",
        _table(header(case.confidence), [_cells(m) for m in case.modes.values()]),
        "",
        "## Targets",
        "",
    ]
    if case.verdicts:
        rows = [[v.mode, shown(v.target), v.status, shown(case.modes[v.mode].rate.upper),
                 v.more_text()] for v in case.verdicts]  # fmt: skip
        columns = ["mode", "target per flight hour", "verdict",
                   f"upper bound per flight hour (one-sided {100 * case.confidence:.3g} %)",
                   "more flights to show it"]  # fmt: skip
        parts.append(_table(columns, rows))
    else:
        parts.append("No target given (`--target MODE=RATE`).")
    if case.bands is not None:
        parts += ["", "## Which winds make the risk", "",
                  "Per band of the drawn mean wind (W20, m/s): the flights in it, and per "
                  "failure mode its events there, the probability per flight in the band and "
                  "the band's share of the mode's events.", "",
                  _bands_table(case)]  # fmt: skip
    parts += ["", "## Assumptions", "",
              _table(["what", "value"], [[a, b] for a, b in case.assumptions])]  # fmt: skip
    return "\n".join(parts) + "\n"


def _bands_table(case: SafetyCase) -> str:
    bands = case.bands
    assert bands is not None
    modes = _band_modes(bands)
    header = ["wind (m/s)", "flights", "share"]
    for m in modes:
        header += [f"{m} events", f"{m} per flight", f"{m} share"]
    rows = []
    for band, r in bands.iterrows():
        row = [str(band), str(int(r["flights"])), shown(r["share"])]
        for m in modes:
            row += [str(int(r[f"{m}_events"])), shown(r[f"{m}_p"]), shown(r[f"{m}_share"])]
        rows.append(row)
    return _table(header, rows)
