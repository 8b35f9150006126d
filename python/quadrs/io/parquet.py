"""Parquet files with JSON metadata, sealed to their rows.

A frame is written with its metadata under a key of the file's schema and a digest of its rows
(:func:`write_frame`); reading it back (:func:`read_file`) checks that digest, so a file edited
or truncated after it was written is refused, not read. The bytes reach the disk through
:func:`quadrs.io.files.atomic_write`.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from quadrs.io.files import atomic_write, check_regular, loads_json, read_regular

__all__ = ["frame_bytes", "read_file", "read_frame", "read_meta", "write_frame"]


#: The metadata field that binds a saved file to its contents (see :func:`write_frame`).
CONTENTS = "contents"


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
        table = pq.ParquetFile(pa.BufferReader(_arrow_owned(data))).read(use_threads=False)
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
        frame = table.to_pandas(use_threads=False)
    except (pa.ArrowException, ValueError, TypeError) as e:
        raise CorruptRunError(f"{where!r}: its rows cannot be read ({_first_line(e)})") from None
    return SavedFile(frame, meta, attachments)


def _arrow_owned(data: bytes) -> pa.Buffer:
    """A copy of ``data`` in Arrow's own memory. Handed the Python bytes themselves, Arrow
    holds the Python object, and whichever of its threads drops the last reference must take
    the GIL to release it: one that does so while the interpreter finalises (a refusal just
    before exit leaves a reader's thread behind) is ended by Python inside Arrow's C++ and
    aborts the process ("terminate called without an active exception"). Read from Arrow's
    memory, on this thread alone (ParquetFile, not the dataset scanner, and no column
    threads), no Arrow thread ever needs the GIL."""
    sink = pa.BufferOutputStream()
    sink.write(data)
    return sink.getvalue()


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
