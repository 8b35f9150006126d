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

import dataclasses
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from quadrs import _core

__all__ = [
    "Px4FileWarning",
    "Px4Parameters",
    "px4_changes",
    "read_px4_parameters",
    "read_ulog_wind",
]

#: Largest PX4 files read (bytes): a parameter file is kilobytes (an airframe's thousand
#: parameters, 40 KiB), a long flight's log a few hundred megabytes; pyulog reads a log from
#: the file, keeping only the topic asked for.
MAX_PARAMS_BYTES = 1 << 20
MAX_LOG_BYTES = 512 << 20
#: The log topics that carry PX4's wind estimate, newest name first (``wind_estimate`` before
#: PX4 1.13).
WIND_TOPICS = ("wind", "wind_estimate")
#: A log's wind estimate is thinned to rows at least this far apart (s) and to at most
#: WIND_ROWS rows, evenly in time: the engine interpolates the table linearly, and PX4's
#: estimate (a slow filter's output) changes little between them.
WIND_SPACING = 0.1
WIND_ROWS = 20_000
#: Largest magnitude a PX4 parameter (a 32-bit float) holds.
FLOAT32_MAX = 3.4028234663852886e38
#: PX4's rate controller multiplies each axis's P, I and D by its K (the parallel form's
#: global gain, ``MC_ROLLRATE_K`` ...): read and folded into the gains the law flies.
RATE_K = {axis: (f"MC_{axis}RATE_K", tuple(f"MC_{axis}RATE_{g}" for g in "PID"))
          for axis in ("ROLL", "PITCH", "YAW")}  # fmt: skip


class Px4FileWarning(UserWarning):
    """What a PX4 file holds that is read in a way the user should know (a log with several
    instances of the wind topic)."""


@dataclass(frozen=True)
class Px4Parameters:
    """What a PX4 file gave: ``known``, the parameters ``[controller.px4]`` takes (name ->
    value, PX4's units), and ``ignored``, the names of the file's other parameters."""

    path: str
    known: dict[str, float]
    ignored: tuple[str, ...]
    #: The rate controller's K per axis the file gives (``MC_ROLLRATE_K`` -> value).
    rate_k: dict[str, float] = dataclasses.field(default_factory=dict)

    def note(self) -> str:
        """One line: what was read and what was not (a name holding control characters
        shown escaped, so that a file cannot drive the terminal)."""
        ignored = [_shown(n) for n in self.ignored]
        shown = ", ".join(ignored[:6]) + (", ..." if len(ignored) > 6 else "")
        rest = f"; {len(ignored)} others ignored ({shown})" if ignored else ""
        k = f", {', '.join(self.rate_k)} folded into the rate gains" if self.rate_k else ""
        return f"{self.path}: {len(self.known)} parameters read into [controller.px4]{k}{rest}"


def _shown(name: str) -> str:
    """A parameter's name as text to show: escaped (``\\x1b``) unless printable."""
    return name if name.isprintable() else repr(name)[1:-1]


def px4_changes(read: Px4Parameters, table: Mapping[str, Any]) -> dict[str, float]:
    """The ``controller.px4.*`` values a file gives: its parameters, with each axis's rate P,
    I and D (the file's, else the scenario's ``[controller.px4]`` ``table``, else the law's
    defaults) multiplied by the axis's K as PX4 does. ``MPC_THR_HOVER`` is the position loop's
    hover feed-forward, as in PX4 (the thrust's scale is the vehicle's full thrust)."""
    gains = {**json.loads(_core.CONTROLLER_DEFAULTS["px4"]), **table}
    values = dict(read.known)
    for k_name, gain_names in RATE_K.values():
        k = read.rate_k.get(k_name)
        if k is None:
            continue
        for g in gain_names:
            values[g] = float(values.get(g, gains[g])) * k
    return {f"controller.px4.{k}": v for k, v in values.items()}


def px4_keys() -> tuple[str, ...]:
    """The PX4 parameters ``[controller.px4]`` knows (its keys that are PX4's names)."""
    table = json.loads(_core.CONTROLLER_DEFAULTS["px4"])
    return tuple(k for k in table if k.isupper())


def _error(path: Path, what: str) -> _core.ScenarioError:
    error = _core.ScenarioError(f"PX4 file {str(path)!r}: {what}")
    error.key = None  # no scenario key is at fault: the file is
    return error


def _open(path: Path, limit: int) -> BinaryIO:
    """The file opened for reading: a regular file (a device or FIFO would be read forever
    or block) of at most ``limit`` bytes, opened without blocking."""
    import errno
    import os
    import stat

    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
        f = os.fdopen(fd, "rb")
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            f.close()
            raise OSError(errno.EINVAL, "not a regular file (a device, FIFO or socket?)")
        if st.st_size > limit:
            f.close()
            raise OSError(errno.EFBIG, f"larger than {limit >> 20} MiB ({st.st_size} bytes)")
        return f
    except OSError as e:
        raise _error(path, f"cannot be read: {e.strerror or e}") from None


def _is_log(path: Path) -> bool:
    return path.suffix.lower() == ".ulg"


def read_px4_parameters(path: str | Path) -> Px4Parameters:
    """The parameters of a QGroundControl ``.params`` file (``Vehicle-Id Component-Id Name
    Value Type`` rows, ``#`` comments) or of a PX4 ``.ulg`` log (its initial parameters).
    ScenarioError naming the file and the line for a file that is neither, or a value that is
    not a finite number."""
    path = Path(path)
    with _open(path, MAX_LOG_BYTES if _is_log(path) else MAX_PARAMS_BYTES) as f:
        values = _ulog_parameters(path, f) if _is_log(path) else _qgc(path, f.read())
    keys = set(px4_keys())
    floats = {k: _px4_float(path, k, v) for k, v in values.items()}
    known = {k: v for k, v in floats.items() if k in keys}
    rate_k = {k: floats[k] for k, _ in RATE_K.values() if k in floats}
    ignored = tuple(sorted(k for k in values if k not in keys and k not in rate_k))
    return Px4Parameters(str(path), known, ignored, rate_k)


def _px4_float(path: Path, name: str, value: tuple[float, str]) -> float:
    """A PX4 parameter as PX4 holds it, a 32-bit float, read back as the shortest decimal
    that is that float: ``0.949999988...`` (a log's bits, a .params file's 18 digits) and
    ``0.95`` (typed) are the same parameter, 0.95. A value past the float's range is refused
    naming the parameter, where (a line) and the value the file holds."""
    import numpy as np

    x, where = value
    if abs(x) > FLOAT32_MAX:
        raise _error(path, f"{where}{name} = {x:g} is beyond a PX4 parameter's range (a 32-bit "
                           f"float, at most {FLOAT32_MAX:.8g} in magnitude)")  # fmt: skip
    return float(str(np.float32(x)))


def _qgc(path: Path, raw: bytes) -> dict[str, tuple[float, str]]:
    """A QGroundControl parameter file: tab- (or space-) separated rows of five columns;
    name -> (value, "line N: "). A name given twice is refused, naming both lines."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise _error(path, f"not UTF-8 text (byte {e.start})") from None
    out: dict[str, tuple[float, str]] = {}
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
            raise _error(path, f"line {line}: {name!r} is not a finite number, got {value!r}")
        if name in out:
            first, at = out[name]
            raise _error(path, f"line {line}: {name!r} is given twice ({at}{first:g}; "
                               f"line {line}: {value}): keep one")  # fmt: skip
        out[name] = (x, f"line {line}: ")
    if not out:
        raise _error(path, "no parameters (a QGroundControl .params file or a PX4 .ulg log)")
    return out


def _ulog(path: Path, f: BinaryIO, topics: list[str]) -> object:
    from pyulog import ULog  # type: ignore[import-untyped]

    try:
        return ULog(f, message_name_filter_list=topics)
    except Exception as e:  # pyulog raises several kinds for a file that is not a log
        raise _error(path, f"not a PX4 .ulg log ({type(e).__name__}: {e})") from None


def _ulog_parameters(path: Path, f: BinaryIO) -> dict[str, tuple[float, str]]:
    log = _ulog(path, f, [])
    params = dict(log.initial_parameters)  # type: ignore[attr-defined]
    if not params:
        raise _error(path, "the log holds no parameters")
    return {str(k): (float(v), "") for k, v in params.items()}


def read_ulog_wind(path: str | Path) -> list[list[float]]:
    """A ``[wind.table]`` by time from a PX4 log's wind estimate (topic ``wind``, or
    ``wind_estimate`` in older logs): rows ``[t, wind_x, wind_y, wind_z]``, t in s from the
    topic's first sample, x east and y north (as a ``.plan`` route's axes) from PX4's
    ``windspeed_east`` and ``windspeed_north``, no vertical wind (PX4 estimates none),
    thinned (WIND_SPACING, WIND_ROWS). A log with several instances of the topic (several
    estimators) is read from its first, multi_id 0, with a Px4FileWarning saying so.
    ScenarioError naming the file when it has no such topic."""
    import warnings

    path = Path(path)
    with _open(path, MAX_LOG_BYTES) as f:
        log = _ulog(path, f, list(WIND_TOPICS))
    found = [d for d in log.data_list if d.name in WIND_TOPICS]  # type: ignore[attr-defined]
    if not found:
        raise _error(path, f"the log has no wind estimate (topic {' or '.join(WIND_TOPICS)})")
    name = min((d.name for d in found), key=WIND_TOPICS.index)
    instances = sorted((d for d in found if d.name == name), key=lambda d: d.multi_id)
    topic = instances[0]
    if len(instances) > 1:
        ids = ", ".join(str(d.multi_id) for d in instances)
        warnings.warn(f"{path}: the log has {len(instances)} instances of topic {name!r} "
                      f"(multi_id {ids}): the first, multi_id {topic.multi_id}, is read",
                      Px4FileWarning, stacklevel=2)  # fmt: skip
    fields = topic.data
    for field in ("timestamp", "windspeed_north", "windspeed_east"):
        if field not in fields:
            raise _error(path, f"topic {name!r} has no field {field!r}")
    rows = _thinned(fields["timestamp"], fields["windspeed_east"], fields["windspeed_north"])
    if not rows:
        raise _error(path, f"topic {name!r} has no finite samples")
    return rows


def _thinned(stamps: Any, east: Any, north: Any) -> list[list[float]]:
    """Rows ``[t, east, north, 0]`` from the log's samples (t from the first sample, in s):
    the finite ones (the estimator runs), each at least WIND_SPACING after the last kept and
    at most WIND_ROWS of them, spread evenly over the log."""
    import numpy as np

    t = (np.asarray(stamps, dtype=np.int64) - int(stamps[0])) * 1e-6
    e, n = np.asarray(east, dtype=float), np.asarray(north, dtype=float)
    ok = np.isfinite(e) & np.isfinite(n)
    t, e, n = t[ok], e[ok], n[ok]
    if t.size == 0:
        return []
    spacing = max(WIND_SPACING, float(t[-1] - t[0]) / WIND_ROWS)
    rows: list[list[float]] = []
    i = 0
    # The first sample, then each first one at least `spacing` after the last kept (a
    # repeated timestamp: the first); the log's samples are in time order.
    while i < t.size and len(rows) <= WIND_ROWS:
        rows.append([float(t[i]), float(e[i]), float(n[i]), 0.0])
        i = max(i + 1, int(np.searchsorted(t, t[i] + spacing * (1 - 1e-9), side="left")))
    return rows
