"""Saving the command line's outputs so that finished work is never lost: outputs checked
before any work, and a recovery copy (whose path is printed) when the target cannot be
written after it. Shared by :mod:`quadrs.cli` and :mod:`quadrs.cli_design`."""

from __future__ import annotations

import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from quadrs.parquet import check_writable


def check_outputs(*paths: Path | None) -> None:
    """Before any work: each output file must be writable (not a directory, its directory
    creatable and accepting a new file), so a long batch is never lost to a bad --out."""
    for path in paths:
        if path is not None:
            check_writable(path)


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
