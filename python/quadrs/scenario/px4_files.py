"""PX4's own files read into a scenario (docs/delivery.md, "PX4 files"): an airframe's
parameters from a QGroundControl ``.params`` file or a PX4 ``.ulg`` flight log into
``[controller.px4]`` (``quadrs mission --px4-params FILE``, :meth:`Scenario.with_px4_params`),
and a log's wind estimate as a ``[wind.table]`` by time.

Only the parameters ``[controller.px4]`` knows are read, in PX4's own units as the table takes
them (degrees, deg/s, normalised thrust); every other parameter of the file is listed and
ignored (an airframe has about a thousand). A ``.ulg`` is read with pyulog, the PX4 project's
own reader.
"""

from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

from quadrs import _core

__all__ = ["Px4Parameters", "read_px4_parameters", "read_ulog_wind"]

#: Largest PX4 file read (bytes): a parameter file is kilobytes, a long flight's log a few
#: hundred megabytes.
MAX_BYTES = 1 << 30
#: The log topics that carry PX4's wind estimate, newest name first (``wind_estimate`` before
#: PX4 1.13).
WIND_TOPICS = ("wind", "wind_estimate")


@dataclass(frozen=True)
class Px4Parameters:
    """What a PX4 file gave: ``known``, the parameters ``[controller.px4]`` takes (name ->
    value, PX4's units), and ``ignored``, the names of the file's other parameters."""

    path: str
    known: dict[str, float]
    ignored: tuple[str, ...]

    def note(self) -> str:
        """One line: what was read and what was not."""
        shown = ", ".join(self.ignored[:6]) + (", ..." if len(self.ignored) > 6 else "")
        rest = f"; {len(self.ignored)} others ignored ({shown})" if self.ignored else ""
        return (f"{self.path}: {len(self.known)} parameters read into [controller.px4]"
                f"{rest}")  # fmt: skip


def px4_keys() -> tuple[str, ...]:
    """The PX4 parameters ``[controller.px4]`` knows (its keys that are PX4's names)."""
    table = json.loads(_core.CONTROLLER_DEFAULTS["px4"])
    return tuple(k for k in table if k.isupper())


def _error(path: Path, what: str) -> _core.ScenarioError:
    error = _core.ScenarioError(f"PX4 file {str(path)!r}: {what}")
    error.key = None  # no scenario key is at fault: the file is
    return error


def _read(path: Path) -> bytes:
    """The file's bytes: a regular file (a device or FIFO would be read forever or block)
    of at most MAX_BYTES, opened without blocking."""
    import errno
    import os
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        with os.fdopen(fd, "rb") as f:
            st = os.fstat(f.fileno())
            if not stat.S_ISREG(st.st_mode):
                raise OSError(errno.EINVAL, "not a regular file (a device, FIFO or socket?)")
            if st.st_size > MAX_BYTES:
                raise OSError(errno.EFBIG, f"larger than {MAX_BYTES} bytes")
            return f.read(MAX_BYTES + 1)[:MAX_BYTES]
    except OSError as e:
        raise _error(path, f"cannot be read: {e.strerror or e}") from None


def read_px4_parameters(path: str | Path) -> Px4Parameters:
    """The parameters of a QGroundControl ``.params`` file (``Vehicle-Id Component-Id Name
    Value Type`` rows, ``#`` comments) or of a PX4 ``.ulg`` log (its initial parameters).
    ScenarioError naming the file and the line for a file that is neither, or a value that is
    not a finite number."""
    path = Path(path)
    raw = _read(path)
    values = _ulog_parameters(path, raw) if path.suffix.lower() == ".ulg" else _qgc(path, raw)
    keys = set(px4_keys())
    known = {k: _px4_float(v) for k, v in values.items() if k in keys}
    ignored = tuple(sorted(k for k in values if k not in keys))
    return Px4Parameters(str(path), known, ignored)


def _px4_float(x: float) -> float:
    """A PX4 parameter as PX4 holds it, a 32-bit float, read back as the shortest decimal
    that is that float: ``0.949999988...`` (a log's bits, a .params file's 18 digits) and
    ``0.95`` (typed) are the same parameter, 0.95."""
    import numpy as np

    return float(str(np.float32(x)))


def _qgc(path: Path, raw: bytes) -> dict[str, float]:
    """A QGroundControl parameter file: tab- (or space-) separated rows of five columns."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise _error(path, f"not UTF-8 text (byte {e.start})") from None
    out: dict[str, float] = {}
    for line, row in enumerate(text.splitlines(), start=1):
        cells = row.split()
        if not cells or cells[0].startswith("#"):
            continue
        if len(cells) != 5:
            raise _error(path, f"line {line}: {len(cells)} columns, expected the 5 of a "
                               "QGroundControl .params row (Vehicle-Id Component-Id Name Value "
                               "Type)")  # fmt: skip
        name, value = cells[2], cells[3]
        try:
            x = float(value)
        except ValueError:
            x = math.nan
        if not math.isfinite(x):
            raise _error(path, f"line {line}: {name} is not a finite number, got {value!r}")
        out[name] = x
    if not out:
        raise _error(path, "no parameters (a QGroundControl .params file or a PX4 .ulg log)")
    return out


def _ulog(path: Path, raw: bytes, topics: list[str]) -> object:
    from pyulog import ULog  # type: ignore[import-untyped]

    try:
        return ULog(io.BytesIO(raw), message_name_filter_list=topics)
    except Exception as e:  # pyulog raises several kinds for a file that is not a log
        raise _error(path, f"not a PX4 .ulg log ({type(e).__name__}: {e})") from None


def _ulog_parameters(path: Path, raw: bytes) -> dict[str, float]:
    log = _ulog(path, raw, [])
    params = dict(log.initial_parameters)  # type: ignore[attr-defined]
    if not params:
        raise _error(path, "the log holds no parameters")
    return {str(k): float(v) for k, v in params.items()}


def read_ulog_wind(path: str | Path) -> list[list[float]]:
    """A ``[wind.table]`` by time from a PX4 log's wind estimate (topic ``wind``, or
    ``wind_estimate`` in older logs): rows ``[t, wind_x, wind_y, wind_z]``, t in s from the
    topic's first sample, x east and y north (as a ``.plan`` route's axes) from PX4's
    ``windspeed_east`` and ``windspeed_north``, no vertical wind (PX4 estimates none).
    ScenarioError naming the file when it has no such topic."""
    path = Path(path)
    raw = _read(path)
    log = _ulog(path, raw, list(WIND_TOPICS))
    data = {d.name: d for d in log.data_list}  # type: ignore[attr-defined]
    topic = next((data[t] for t in WIND_TOPICS if t in data), None)
    if topic is None:
        raise _error(path, f"the log has no wind estimate (topic {' or '.join(WIND_TOPICS)})")
    fields = topic.data
    for f in ("timestamp", "windspeed_north", "windspeed_east"):
        if f not in fields:
            raise _error(path, f"topic {topic.name!r} has no field {f!r}")
    stamps = [int(t) for t in fields["timestamp"]]
    rows: list[list[float]] = []
    for t, north, east in zip(stamps, fields["windspeed_north"], fields["windspeed_east"],
                              strict=True):  # fmt: skip
        s = (t - stamps[0]) * 1e-6
        if rows and s <= rows[-1][0]:
            continue  # a repeated timestamp: the first sample kept
        if not (math.isfinite(float(north)) and math.isfinite(float(east))):
            continue  # the estimator not yet running
        rows.append([s, float(east), float(north), 0.0])
    if not rows:
        raise _error(path, f"topic {topic.name!r} has no finite samples")
    return rows
