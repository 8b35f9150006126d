"""Saving the command line's outputs so that finished work is never lost: outputs checked
before any work, and a recovery copy (whose path is printed) when the target cannot be
written after it. Shared by the command modules beside it."""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from quadrs.cli.common import BadInput
from quadrs.io.files import check_writable


def check_suffix(path: Path | None, allowed: Sequence[str], option: str) -> None:
    """BadInput unless an output's name ends in one of ``allowed`` (None: not given)."""
    if path is not None and path.suffix.lower() not in allowed:
        raise BadInput(f"{option} {str(path)!r}: expected a file ending in {' or '.join(allowed)}")


def check_outputs(*paths: Path | None) -> None:
    """Before any work: each output file must be writable (not a directory, its directory
    creatable and accepting a new file), so a long batch is never lost to a bad --out."""
    for path in paths:
        if path is not None:
            check_writable(path)


def check_directories(*paths: Path | None, option: str = "--plots") -> None:
    """Before any work: each figure directory must be a directory or creatable, and accept a
    new file (an existing file there is refused now, not after the whole batch flew)."""
    for path in paths:
        if path is None:
            continue
        if path.exists() and not path.is_dir():
            raise NotADirectoryError(20, f"{option}: exists and is not a directory", str(path))
        path.mkdir(parents=True, exist_ok=True)
        check_writable(path / "figure")


def save_runs(result: Any, out: Path | None) -> bool:
    """A batch's runs written to ``out`` (``--out``; nothing without it or without a finished
    flight), before anything is printed so that a Ctrl-C keeps them; whether all that was
    asked is saved (else the runs went to a recovery file, :func:`save`)."""
    if out is None or result.runs.empty:
        return True
    return save(result.to_parquet, out)


def save(write: Callable[[Path], object], path: Path) -> bool:
    """``write(path)``; if that fails (full disk, permissions), save to a fresh recovery
    directory instead and say where. Returns True if ``path`` was written."""
    try:
        write(path)
    except OSError as e:
        reason = e.strerror or str(e)
        try:
            spare = Path(tempfile.mkdtemp(prefix="quadrs-recovered-")) / path.name
            write(spare)
        except OSError as e2:
            print(f"quadrs: error: could not write {path} ({reason}) nor a recovery copy "
                  f"({e2.strerror or e2})", file=sys.stderr)  # fmt: skip
        else:
            print(f"quadrs: error: could not write {path} ({reason}); the results were "
                  f"saved to {spare} instead", file=sys.stderr)  # fmt: skip
        return False
    print(f"wrote {path}", file=sys.stderr)
    return True
