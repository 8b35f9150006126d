"""The safety-case options of ``quadrs mission``, ``quadrs report`` and ``quadrs rare``:
``--target MODE=RATE`` (per flight hour: met, not met or not yet shown against the one-sided
95 % upper bound) and ``--safety-case FILE`` (the one-page markdown summary,
:mod:`quadrs.design.safety_text`); the per-flight-hour block a mission prints, and the one
writer of the page."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from quadrs.cli.common import path_option
from quadrs.stats.rates import TARGET_MODES, parse_target

__all__ = ["check_safety_case", "safety_case_options", "safety_outputs", "target", "write_page"]


def target(text: str) -> tuple[str, float]:
    """``--target containment=1e-4``: a failure mode and a rate per flight hour."""
    try:
        return parse_target(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e).removeprefix(f"--target {text!r}: ")) from None


def safety_case_options(p: argparse.ArgumentParser) -> None:
    """``--target MODE=RATE`` (repeatable) and ``--safety-case FILE``."""
    p.add_argument(
        "--target",
        type=target,
        action="append",
        default=[],
        metavar="MODE=RATE",
        help=f"a target per flight hour for a failure mode ({', '.join(TARGET_MODES)}), e.g. "
        "containment=1e-4: says met (the one-sided 95%% upper bound at or below it), not met "
        "(the estimate at or above it) or not yet shown (how many more flights would show "
        "it); repeatable",
    )
    path_option(
        p,
        "--safety-case",
        "FILE",
        "write the safety-case summary here (markdown, one page): the failure modes per "
        "flight and per flight hour with their one-sided 95%% upper bounds, the method, the "
        "targets, the winds that make the risk, the assumptions (docs/risk.md)",
    )


def check_safety_case(args: argparse.Namespace) -> None:
    """Before any work: the summary's file is a writable .md."""
    from quadrs.cli.outputs import check_outputs, check_suffix

    check_suffix(args.safety_case, (".md",), "--safety-case")
    check_outputs(args.safety_case)


def write_page(cases: list[Any], path: Path | None) -> bool:
    """Write ``cases``' pages (every law's in turn) to ``path`` atomically (nothing if None);
    False if it could not be written."""
    from quadrs.cli.outputs import save
    from quadrs.io.files import atomic_write_bytes

    if path is None:
        return True
    page = "\n".join(case.to_markdown() for case in cases)
    return save(lambda to: atomic_write_bytes(to, page.encode()), path)


def safety_outputs(mc: Any, reports: list[Any], args: argparse.Namespace,
                   targets: dict[str, float] | None = None) -> bool:  # fmt: skip
    """A mission's: print each law's per-flight-hour block; write ``--safety-case``.
    ``targets``: those given, else the ones saved with the runs. False if the file could not
    be written."""
    from quadrs.cli.common import report_width
    from quadrs.design.safety import safety_case

    given = dict(args.target) if args.target else dict(targets or {})
    cases = [safety_case(mc, report, given) for report in reports]
    for case in cases:
        print()
        print(case.to_text(report_width()))
    return write_page(cases, args.safety_case)
