"""Files written atomically, and Parquet files with JSON metadata.

Every file quadrs writes goes through :func:`atomic_write`: the bytes go to a temporary file
with an unpredictable name, created exclusively in the target's directory (``O_EXCL``: an
existing file or a planted symlink there is never opened, let alone followed), flushed to
disk, then renamed over the target. An interrupted or killed writer leaves the old file or the
new one, never half of one; Ctrl-C or SIGTERM arriving during the (short) write is held back
until the rename is done, then delivered.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import tempfile
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

#: Signals held back while a file is being written (delivered right after).
_DEFERRED = (signal.SIGINT, signal.SIGTERM)


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold Ctrl-C and SIGTERM back for the duration of the block, then deliver them (only on
    the main thread, where Python runs signal handlers; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[tuple[int, Any]] = []
    previous = {}
    for sig in _DEFERRED:
        try:
            previous[sig] = signal.signal(sig, lambda s, f: caught.append((s, f)))
        except (ValueError, OSError):  # not installable here
            pass
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for sig, frame in caught[:1]:
            handler = previous.get(sig)
            if callable(handler):
                handler(sig, frame)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(sig)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], None]) -> Path:
    """Write ``path`` atomically: ``write`` fills a binary file object that becomes ``path``
    only once complete (see the module docstring). The parent directory is created if needed.
    Returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with deferred_signals():
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                write(f)
                f.flush()
                os.fsync(f.fileno())
                os.fchmod(f.fileno(), 0o666 & ~_umask())
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
    return path


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    return atomic_write(path, lambda f: f.write(data))


def atomic_create(path: str | Path, data: bytes) -> Path:
    """Create ``path`` with ``data``, whole, only if it does not exist yet (FileExistsError
    otherwise): written to a temporary file, then hard-linked into place, which fails if the
    name is taken. Of several processes creating one file at once, exactly one succeeds."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with deferred_signals():
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
                os.fchmod(f.fileno(), 0o666 & ~_umask())
            try:
                os.link(tmp, path)
            except FileExistsError:
                raise
            except OSError:  # no hard links here: exclusive create, no symlink followed
                flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
                out = os.open(path, flags, 0o666)
                with os.fdopen(out, "wb") as f:
                    f.write(data)
        finally:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
    return path


def check_writable(path: str | Path) -> None:
    """Fail now (OSError naming the path) if ``path`` could not be written later: it must not
    be a directory, and its directory must accept a new file (created exclusively, removed)."""
    path = Path(path)
    if path.is_dir():
        raise IsADirectoryError(21, "is a directory, not a file", str(path))
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".probe", dir=path.parent)
    try:
        os.write(fd, b"quadrs")
    finally:
        os.close(fd)
        os.unlink(tmp)


def write_frame(
    frame: pd.DataFrame, path: str | Path, key: bytes, meta: Any, index: bool = False
) -> None:
    """``frame`` (with its index if ``index``) to ``path`` with ``meta`` as JSON under ``key``."""
    table = pa.Table.from_pandas(frame, preserve_index=index)
    schema_meta = dict(table.schema.metadata or {})
    schema_meta[key] = json.dumps(meta).encode()
    table = table.replace_schema_metadata(schema_meta)
    atomic_write(path, lambda f: pq.write_table(table, f))


def read_frame(path: str | Path, key: bytes) -> tuple[pd.DataFrame, Any | None]:
    """The frame and the JSON metadata under ``key`` (None if the file has none)."""
    table = pq.read_table(path)
    raw = (table.schema.metadata or {}).get(key)
    return table.to_pandas(), (_loads(raw, path) if raw is not None else None)


def read_meta(path: str | Path, key: bytes) -> Any | None:
    """Only the JSON metadata under ``key``, without reading the data."""
    raw = (pq.read_schema(path).metadata or {}).get(key)
    return _loads(raw, path) if raw is not None else None


def _loads(raw: bytes, path: str | Path) -> Any:
    try:
        return json.loads(raw)
    except ValueError as e:
        raise ValueError(f"{str(path)!r}: its quadrs metadata is not valid JSON ({e})") from None
