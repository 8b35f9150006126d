"""Parquet files with JSON metadata, written atomically (a temporary file, then a rename), so
an interrupted or killed writer leaves the old file or the new one, never half of one."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq


def atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.partial")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def write_frame(frame: pd.DataFrame, path: str | Path, key: bytes, meta: Any) -> None:
    """``frame`` (without its index) to ``path`` with ``meta`` as JSON under ``key``."""
    path = Path(path)
    table = pa.Table.from_pandas(frame, preserve_index=False)
    schema_meta = dict(table.schema.metadata or {})
    schema_meta[key] = json.dumps(meta).encode()
    tmp = path.with_name(f".{path.name}.partial")
    pq.write_table(table.replace_schema_metadata(schema_meta), tmp)
    os.replace(tmp, path)


def read_frame(path: str | Path, key: bytes) -> tuple[pd.DataFrame, Any | None]:
    """The frame and the JSON metadata under ``key`` (None if the file has none)."""
    table = pq.read_table(path)
    raw = (table.schema.metadata or {}).get(key)
    return table.to_pandas(), (json.loads(raw) if raw is not None else None)


def read_meta(path: str | Path, key: bytes) -> Any | None:
    """Only the JSON metadata under ``key``, without reading the data."""
    raw = (pq.read_schema(path).metadata or {}).get(key)
    return json.loads(raw) if raw is not None else None
