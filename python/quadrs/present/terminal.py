"""Text for the terminal: what a scenario holds (phase names, keys) is shown, never obeyed; and
the progress bar every long call draws."""

from __future__ import annotations

import unicodedata
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["fit_columns", "shows_progress", "terminal_text", "tqdm_class"]


def terminal_text(text: str) -> str:
    """``text`` safe to show on a terminal: control characters (escape sequences, backspaces,
    carriage returns, bidirectional overrides; all but newline and tab) as ``\\xNN``/``\\uNNNN``
    escapes, so a scenario string (a phase name, a key) cannot drive the terminal."""

    def safe(c: str) -> str:
        if c in "\n\t" or unicodedata.category(c) not in ("Cc", "Cf"):
            return c
        return repr(c)[1:-1] if ord(c) < 0x10000 else f"\\U{ord(c):08x}"

    return "".join(safe(c) for c in text) if not text.isprintable() else text


def fit_columns(frame: pd.DataFrame, width: int) -> str:
    """``frame`` as terminal text in blocks of columns, each at most ``width`` wide, the index
    repeated in each (a single column wider than ``width`` gets a block of its own). Formats
    as ``frame.to_string()`` does under the caller's pandas options."""

    def render(columns: list[int]) -> str:
        return terminal_text(frame.iloc[:, columns].to_string())

    blocks: list[str] = []
    current: list[int] = []
    for column in range(frame.shape[1]):
        trial = [*current, column]
        if current and max(len(line) for line in render(trial).splitlines()) > width:
            blocks.append(render(current))
            current = [column]
        else:
            current = trial
    if current or not blocks:
        blocks.append(render(current) if current else terminal_text(frame.to_string()))
    return "\n\n".join(blocks)


def tqdm_class() -> type:
    """The progress bar class: the notebook widget (``tqdm.auto``) where ipywidgets is
    installed, else the text bar; never the "IProgress not found" warning box that
    ``tqdm.auto`` shows in a notebook without ipywidgets."""
    try:
        import ipywidgets  # type: ignore[import-not-found]  # noqa: F401
    except ImportError:
        from tqdm.std import tqdm
    else:
        from tqdm.auto import tqdm
    return tqdm


def shows_progress(progress: bool) -> bool:
    """Whether a progress bar asked for (``progress``) is drawn: only where someone watches it,
    stderr a terminal or a notebook's front end; never into a pipe, a file or a log."""
    import sys

    if not progress:
        return False
    isatty = getattr(sys.stderr, "isatty", None)
    if callable(isatty) and isatty():
        return True
    kernel = sys.modules.get("ipykernel")
    return kernel is not None and type(sys.stderr).__module__.startswith("ipykernel")
