"""Files written atomically, and files read without trusting them.

Every file quadrs writes goes through :func:`atomic_write`: the bytes go to a temporary file
with an unpredictable name, created exclusively in the target's directory (``O_EXCL``: an
existing file or a planted symlink there is never opened, let alone followed), flushed to
disk, then renamed over the target. An interrupted or killed writer leaves the old file or the
new one, never half of one; Ctrl-C or SIGTERM arriving during the (short) write is held back
until the rename is done, then delivered. What is read back is read only from a regular file,
within a size limit, and JSON only without repeated keys or unbounded nesting.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import stat
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from quadrs.engine.calls import deferred_signals

# The reader of user-given input files sits with what reads them (the scenario layer, below
# this one); named here too, as the one policy for every file quadrs reads.
from quadrs.scenario.input_files import InputFileError, read_input_text

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd

__all__ = ["InputFileError", "atomic_create", "atomic_write", "atomic_write_bytes",
           "atomic_write_frame", "check_writable", "loads_json", "read_input_text",
           "read_regular"]  # fmt: skip


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
