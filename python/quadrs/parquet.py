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
    previous: dict[int, Any] = {}
    for sig in _DEFERRED:
        try:
            previous[sig] = signal.signal(sig, lambda s, f: caught.append((s, f)))
        except (ValueError, OSError):  # not installable here
            pass
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for signum, frame in caught[:1]:
            handler = previous.get(signum)
            if callable(handler):
                handler(signum, frame)
            elif handler == signal.SIG_DFL:
                signal.raise_signal(signum)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def _staged(path: Path) -> Iterator[tuple[IO[bytes], str]]:
    """A new temporary file beside ``path`` (created exclusively, unpredictable name) for the
    block to fill; then flushed to disk with the permissions a new file gets. Removed if the
    block fails; the block's caller moves it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".partial", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            yield f, tmp
            f.flush()
            os.fsync(f.fileno())
            os.fchmod(f.fileno(), 0o666 & ~_umask())
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def atomic_write(path: str | Path, write: Callable[[IO[bytes]], object]) -> Path:
    """Write ``path`` atomically: ``write`` fills a binary file object that becomes ``path``
    only once complete (see the module docstring). The parent directory is created if needed.
    Returns the path."""
    path = Path(path)
    with deferred_signals():
        with _staged(path) as (f, tmp):
            write(f)
        try:
            os.replace(tmp, path)
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
            raise
    return path


def atomic_write_bytes(path: str | Path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_write`)."""
    return atomic_write(path, lambda f: f.write(data))


#: Floats in CSV files: 12 significant digits, so 0.1 + 0.05 prints 0.15, not
#: 0.15000000000000002 (far below any quantity's accuracy; Parquet keeps every bit).
CSV_FLOAT = "%.12g"


def atomic_write_frame(frame: pd.DataFrame, path: str | Path, index: bool | None = None) -> Path:
    """``frame`` as CSV (a ``.csv`` path; floats at :data:`CSV_FLOAT`) or Parquet (any other),
    written atomically. ``index`` as pandas takes it (None: CSV keeps the index, Parquet unless
    it is a plain range)."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        text = frame.to_csv(index=index is not False, float_format=CSV_FLOAT)
        return atomic_write_bytes(path, text.encode())
    return atomic_write(path, lambda f: frame.to_parquet(f, index=index))


def atomic_create(path: str | Path, data: bytes) -> Path:
    """Create ``path`` with ``data``, whole, only if it does not exist yet (FileExistsError
    otherwise): written to a temporary file, then hard-linked into place, which fails if the
    name is taken. Of several processes creating one file at once, exactly one succeeds."""
    path = Path(path)
    with deferred_signals():
        with _staged(path) as (f, tmp):
            f.write(data)
        try:
            try:
                os.link(tmp, path)
            except FileExistsError:
                raise
            except OSError:  # no hard links here: exclusive create, no symlink followed
                flags = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0)
                out = os.open(path, flags, 0o666)
                with os.fdopen(out, "wb") as g:
                    g.write(data)
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


def _table(frame: pd.DataFrame, key: bytes, meta: Any, index: bool = False) -> pa.Table:
    table = pa.Table.from_pandas(frame, preserve_index=index)
    schema_meta = dict(table.schema.metadata or {})
    schema_meta[key] = json.dumps(meta).encode()
    return table.replace_schema_metadata(schema_meta)


def write_frame(
    frame: pd.DataFrame, path: str | Path, key: bytes, meta: Any, index: bool = False
) -> None:
    """``frame`` (with its index if ``index``) to ``path`` with ``meta`` as JSON under ``key``."""
    table = _table(frame, key, meta, index)
    atomic_write(path, lambda f: pq.write_table(table, f))


def frame_bytes(frame: pd.DataFrame, key: bytes, meta: Any) -> bytes:
    """The Parquet file :func:`write_frame` would write, as bytes (to hash before saving)."""
    sink = pa.BufferOutputStream()
    pq.write_table(_table(frame, key, meta), sink)
    return bytes(sink.getvalue().to_pybytes())


def read_frame(path: str | Path | bytes, key: bytes) -> tuple[pd.DataFrame, Any | None]:
    """The frame and the JSON metadata under ``key`` (None if the file has none), from a file
    or from the bytes of one."""
    source = pa.BufferReader(path) if isinstance(path, bytes) else path
    table = pq.read_table(source)
    raw = (table.schema.metadata or {}).get(key)
    where = "<bytes>" if isinstance(path, bytes) else path
    return table.to_pandas(), (_loads(raw, where) if raw is not None else None)


def read_meta(path: str | Path, key: bytes) -> Any | None:
    """Only the JSON metadata under ``key``, without reading the data."""
    raw = (pq.read_schema(path).metadata or {}).get(key)
    return _loads(raw, path) if raw is not None else None


def _loads(raw: bytes, path: str | Path) -> Any:
    try:
        return json.loads(raw)
    except ValueError as e:
        raise ValueError(f"{str(path)!r}: its quadrs metadata is not valid JSON ({e})") from None
