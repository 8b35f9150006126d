"""The one reader of every file a user gives quadrs to read (a scenario, a route, a wind
table): one size and file-type policy (docs/guarantees.md). In the scenario layer, beside
what reads those files; ``quadrs.io.files`` names it too."""

from __future__ import annotations

import os
import stat
from pathlib import Path

__all__ = ["InputFileError", "read_input_text"]


class InputFileError(ValueError):
    """A file given to quadrs as input that it will not read, in one line naming the file."""


def read_input_text(path: str | Path, what: str, limit: int, streams: bool = False) -> str:
    """The UTF-8 text (a byte-order mark dropped) of a file a user gives quadrs to read: a
    scenario, a route (``.plan``, ``.csv``), a wind table. The one policy for all of them:
    at most ``limit`` bytes, checked on the file's size before a byte is read; a regular
    file only (a device would be read forever, a FIFO would block), opened without blocking,
    so a FIFO swapped in after the check cannot hang us. ``streams``: a pipe or device is
    read too, at most ``limit`` bytes of it (``--scenario <(...)``; a FIFO without a writer
    then blocks). InputFileError naming ``what`` and the file for what the policy refuses;
    OSError (for the caller to word) if the system cannot open or read it."""
    name = f"{what} {str(path)!r}"
    fd = os.open(path, os.O_RDONLY | (0 if streams else getattr(os, "O_NONBLOCK", 0)))
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        regular = stat.S_ISREG(st.st_mode)
        if not regular and not streams:
            raise InputFileError(f"{name} is not a regular file (a directory, device, FIFO "
                                 "or socket?): refusing to read it")  # fmt: skip
        if regular and st.st_size > limit:
            raise InputFileError(f"{name} is larger than {limit} bytes ({st.st_size} bytes): "
                                 "refusing to read it")  # fmt: skip
        raw = f.read(limit + 1)
    if len(raw) > limit:  # a stream, or a file that grew while we read it
        raise InputFileError(f"{name} is larger than {limit} bytes: refusing to read it")
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise InputFileError(f"{name} is not UTF-8 text (byte {e.start})") from None
