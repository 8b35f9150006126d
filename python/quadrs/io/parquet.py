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
import errno
import hashlib
import json
import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from quadrs.engine.calls import deferred_signals

__all__ = ["atomic_write", "deferred_signals", "read_file", "write_frame"]


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


#: Largest JSON side file (a checkpoint's manifest) read, in bytes.
MAX_JSON_BYTES = 16 << 20
#: The metadata field that binds a saved file to its contents (see :func:`write_frame`).
CONTENTS = "contents"


def check_regular(path: str | Path) -> int:
    """The size of ``path`` if it is a regular file (symlinks followed); OSError naming it
    otherwise: a device (``/dev/zero``), a FIFO or a socket would be read forever or block, so
    nothing is ever read from one."""
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise OSError(errno.EINVAL, "not a regular file (a device, FIFO or socket?)", str(path))
    return st.st_size


def read_regular(path: str | Path, limit: int | None = None) -> bytes:
    """The bytes of the regular file ``path``, at most ``limit`` of them (default: what the
    memory available can hold): OSError naming the file if it is not a regular file or is
    larger. Opened without blocking, so a FIFO swapped in after the check cannot hang us."""
    from quadrs.engine.calls import check_memory

    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise OSError(errno.EINVAL, "not a regular file (a device, FIFO or socket?)",
                          str(path))  # fmt: skip
        if limit is not None and st.st_size > limit:
            raise OSError(errno.EFBIG, f"larger than {limit} bytes", str(path))
        if limit is None:
            check_memory(f"reading {str(path)!r}", 2 * st.st_size)
        cap = st.st_size if limit is None else limit
        data = f.read(cap + 1)
    if len(data) > cap:  # it grew while we read
        raise OSError(errno.EFBIG, "changed size while being read", str(path))
    return data


def _array_digest(h: Any, array: pa.Array) -> None:
    """Feed one column into ``h``: numbers by their bytes (every bit counts), lists by their
    offsets and their flattened values, anything else (controller and phase names) as the
    distinct values and, per row, which one it holds."""
    kind = array.type
    if pa.types.is_list(kind) or pa.types.is_large_list(kind):
        offsets = np.asarray(array.offsets.to_numpy(zero_copy_only=False), dtype=np.int64)
        valid = np.asarray(array.is_valid().to_numpy(zero_copy_only=False), dtype=np.bool_)
        h.update(b"list\0" + offsets.tobytes() + valid.tobytes())
        _array_digest(h, array.flatten())
        return
    values = None
    if pa.types.is_integer(kind) or pa.types.is_floating(kind) or pa.types.is_boolean(kind):
        values = np.asarray(array.to_numpy(zero_copy_only=False))
    if values is not None and values.dtype != object:
        h.update(values.dtype.str.encode() + b"\0" + np.ascontiguousarray(values).tobytes())
        return
    if pa.types.is_dictionary(kind):
        array = array.dictionary_decode()
    coded = array.dictionary_encode()
    index = np.asarray(coded.indices.fill_null(-1).to_numpy(), dtype=np.int64)
    distinct = [None if v is None else str(v) for v in coded.dictionary.to_pylist()]
    h.update(json.dumps(distinct).encode() + b"\0" + index.tobytes())


def _rows_digest(table: pa.Table) -> bytes:
    """SHA-256 of a table's column names and values (see :func:`_array_digest`)."""
    h = hashlib.sha256()
    for name, column in zip(table.column_names, table.columns, strict=True):
        h.update(json.dumps(name).encode() + b"\0")
        _array_digest(h, column.combine_chunks())
        h.update(b"\1")
    return h.digest()


def _seal(meta: dict[str, Any], table: pa.Table, others: dict[bytes, bytes]) -> str:
    """The content digest of a saved file: its metadata (but the digest), its rows, and every
    other entry of its schema metadata (the embedded spectrum table, pandas' index layout)."""
    h = hashlib.sha256()
    doc = {k: v for k, v in meta.items() if k != CONTENTS}
    h.update(json.dumps(doc, sort_keys=True).encode())
    h.update(_rows_digest(table))
    for k in sorted(others):
        h.update(hashlib.sha256(k).digest() + hashlib.sha256(others[k]).digest())
    return h.hexdigest()


def _table(
    frame: pd.DataFrame,
    key: bytes,
    meta: Any,
    index: bool = False,
    attachments: dict[bytes, bytes] | None = None,
) -> pa.Table:
    table = pa.Table.from_pandas(frame, preserve_index=index)
    schema_meta = dict(table.schema.metadata or {})
    schema_meta.update(attachments or {})
    if isinstance(meta, dict):
        meta = {**meta, CONTENTS: _seal(meta, table, schema_meta)}
    schema_meta[key] = json.dumps(meta).encode()
    return table.replace_schema_metadata(schema_meta)


def write_frame(
    frame: pd.DataFrame,
    path: str | Path,
    key: bytes,
    meta: Any,
    index: bool = False,
    attachments: dict[bytes, bytes] | None = None,
) -> None:
    """``frame`` (with its index if ``index``) to ``path`` with ``meta`` as JSON under ``key``
    and ``attachments`` (name -> bytes, e.g. an embedded table) beside it in the schema
    metadata: one file. A dict ``meta`` gets ``contents``, the SHA-256 of everything else in
    the file (metadata, rows, attachments), which :func:`read_frame` checks."""
    table = _table(frame, key, meta, index, attachments)
    atomic_write(path, lambda f: pq.write_table(table, f))


def frame_bytes(frame: pd.DataFrame, key: bytes, meta: Any) -> bytes:
    """The Parquet file :func:`write_frame` would write, as bytes (to hash or embed)."""
    sink = pa.BufferOutputStream()
    pq.write_table(_table(frame, key, meta), sink)
    return bytes(sink.getvalue().to_pybytes())


@dataclass(frozen=True)
class SavedFile:
    """A Parquet file quadrs wrote: its rows, its metadata (JSON under its key, None if it has
    none) and the other entries of its schema metadata (embedded tables)."""

    frame: pd.DataFrame
    meta: Any
    attachments: dict[bytes, bytes]


def read_file(
    path: str | Path | bytes,
    key: bytes,
    sealed: bool = True,
    validate: Callable[[Any], object] | None = None,
) -> SavedFile:
    """A file (or its bytes) written by :func:`write_frame`. ``validate(meta)`` runs first
    (a reader's own checks of its metadata, whose errors say most precisely what is wrong).
    Then, with ``sealed`` (the default), a dict metadata must carry the ``contents`` digest of
    what the file holds: CorruptRunError naming the file if it lacks one (written before
    quadrs bound files to their contents) or if anything (rows, metadata, attachments) was
    changed since."""
    from quadrs.io.integrity import CorruptRunError

    where = "<bytes>" if isinstance(path, bytes) else str(path)
    data = path if isinstance(path, bytes) else read_regular(path)
    try:
        table = pq.read_table(pa.BufferReader(data))
    except (pa.ArrowException, OSError, ValueError) as e:
        raise CorruptRunError(f"{where!r}: not a readable Parquet file ({_first_line(e)})") \
            from None  # fmt: skip
    schema_meta = dict(table.schema.metadata or {})
    raw = schema_meta.pop(key, None)
    meta = loads_json(raw, where) if raw is not None else None
    if validate is not None:
        validate(meta)
    if sealed and isinstance(meta, dict):
        seal = meta.get(CONTENTS)
        if not isinstance(seal, str):
            raise CorruptRunError(
                f"{where!r}: it carries no content digest (written by an earlier quadrs, "
                "before saved files were bound to their contents): run it again; refusing "
                "to read it"
            )
        if seal != _seal(meta, table, schema_meta):
            raise CorruptRunError(
                f"{where!r}: its rows, metadata or spectra are not those it was written with "
                "(edited, or parts of two files combined); refusing to read it"
            )
    attachments = {k: v for k, v in schema_meta.items() if k != b"pandas"}
    try:
        frame = table.to_pandas()
    except (pa.ArrowException, ValueError, TypeError) as e:
        raise CorruptRunError(f"{where!r}: its rows cannot be read ({_first_line(e)})") from None
    return SavedFile(frame, meta, attachments)


def read_frame(
    path: str | Path | bytes,
    key: bytes,
    sealed: bool = True,
    validate: Callable[[Any], object] | None = None,
) -> tuple[pd.DataFrame, Any]:
    """The frame and the JSON metadata under ``key`` (None if the file has none), from a file
    or from the bytes of one; checked as :func:`read_file` checks it."""
    saved = read_file(path, key, sealed, validate)
    return saved.frame, saved.meta


def read_meta(path: str | Path, key: bytes) -> Any | None:
    """Only the JSON metadata under ``key``, without reading the data (nor checking it
    against the data: for telling kinds of file apart)."""
    check_regular(path)
    try:
        schema = pq.read_schema(path)
    except (pa.ArrowException, ValueError) as e:
        from quadrs.io.integrity import CorruptRunError

        raise CorruptRunError(f"{str(path)!r}: not a readable Parquet file ({_first_line(e)})") \
            from None  # fmt: skip
    raw = (schema.metadata or {}).get(key)
    return loads_json(raw, path) if raw is not None else None


def _first_line(e: BaseException) -> str:
    return (str(e).strip().splitlines() or [type(e).__name__])[0]


#: Deepest nesting of quadrs metadata (a scenario nests at most 32 deep in its own TOML).
MAX_META_DEPTH = 64


def loads_json(raw: bytes, path: str | Path) -> Any:
    """JSON metadata, refused (ValueError naming ``path``) if invalid, with a repeated key, or
    nested deeper than MAX_META_DEPTH (checked without recursion)."""
    try:
        value = json.loads(raw, object_pairs_hook=_unique_keys)
    except RecursionError:
        value = None
        too_deep = True
    except ValueError as e:
        raise ValueError(f"{str(path)!r}: its quadrs metadata is not valid JSON ({e})") from None
    else:
        too_deep = False
        stack = [(value, 0)]
        while stack and not too_deep:
            node, depth = stack.pop()
            too_deep = depth > MAX_META_DEPTH
            children = node.values() if isinstance(node, dict) else node if isinstance(
                node, list) else ()  # fmt: skip
            stack.extend((c, depth + 1) for c in children)
    if too_deep:
        raise ValueError(f"{str(path)!r}: its quadrs metadata is nested more than "
                         f"{MAX_META_DEPTH} levels deep")  # fmt: skip
    return value


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object whose keys are distinct (a repeated key would hide one value)."""
    out = dict(pairs)
    if len(out) != len(pairs):
        raise ValueError("a key is repeated")
    return out
