"""A measured wind from a CSV file (or a PX4 ``.ulg`` log's wind estimate,
:func:`quadrs.scenario.px4_files.read_ulog_wind`): the ``[wind.table]`` of a scenario
(docs/model.md, "A measured wind").

The file has a header row and one row per sample: ``t`` (s, by time) or ``z`` (m, by altitude),
then ``wind_x, wind_y, wind_z`` (m/s, inertial: x, y, z as the route's, z up), the first column
strictly increasing::

    t,wind_x,wind_y,wind_z
    0,2.0,0.5,0
    60,3.5,1.0,-0.2

The scenario names the file (``file``, relative to the scenario file, or to the working
directory for a scenario built in Python) and ``by`` (``"time"`` or ``"altitude"``); reading it
replaces ``file`` with the rows read (``points``), so the engine receives the numbers (it
interpolates them, linearly, holding the end rows' values outside them) and a saved scenario
carries the wind it flew.
"""

from __future__ import annotations

import csv
import io
import math
from pathlib import Path

__all__ = ["COLUMNS", "WindTableError", "read_wind_table"]

#: The first column for each ``by``, and the wind's columns after it.
FIRST = {"time": "t", "altitude": "z"}
COLUMNS = ("wind_x", "wind_y", "wind_z")
#: Largest table read (bytes): a wind table, not a flight log.
MAX_BYTES = 16 << 20


class WindTableError(ValueError):
    """A wind table the engine cannot fly, in one line naming the file and the column."""


def read_wind_table(path: str | Path, by: str) -> list[list[float]]:
    """The rows ``[t or z, wind_x, wind_y, wind_z]`` of the CSV file ``path`` for ``by``
    (``"time"`` or ``"altitude"``). WindTableError naming the file, the line and the column
    for anything else: a missing or misnamed column, a value that is not a finite number, a
    first column that does not increase, no rows."""
    path = Path(path)
    name = str(path)
    if by not in FIRST:
        raise WindTableError(f'wind.table.by must be "time" or "altitude", got {by!r}')
    first = FIRST[by]
    if path.suffix.lower() == ".ulg":  # a PX4 log: its wind estimate, by time
        if by != "time":
            raise WindTableError(f'wind table {name!r} is a PX4 log: by = "time", got {by!r}')
        from quadrs.scenario.px4_files import read_ulog_wind

        return read_ulog_wind(path)
    from quadrs.scenario.input_files import InputFileError, read_input_text

    try:
        text = read_input_text(path, "wind table", MAX_BYTES)
    except InputFileError as e:
        raise WindTableError(str(e)) from None
    except OSError as e:
        raise WindTableError(f"wind table {name!r} cannot be read: {e.strerror or e}") from None
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        rows = [r for r in reader if any(cell.strip() for cell in r)]
    except csv.Error as e:  # a cell beyond csv's field limit (128 KiB), a NUL
        raise WindTableError(f"wind table {name!r} line {reader.line_num}: not CSV ({e})") \
            from None  # fmt: skip
    if not rows:
        raise WindTableError(f"wind table {name!r} is empty: a header {first},"
                             f"{','.join(COLUMNS)} and one row per sample")  # fmt: skip
    header = [cell.strip() for cell in rows[0]]
    want = [first, *COLUMNS]
    if header != want:
        for i, (got, expected) in enumerate(zip(header + [""] * 4, want, strict=False)):
            if got != expected:
                what = f"is {got!r}" if got else "is missing"
                hint = f' (by = "{by}")' if i == 0 else ""
                raise WindTableError(
                    f"wind table {name!r}: column {i + 1} {what}, expected {expected!r}{hint}: "
                    f"the header is {','.join(want)}"
                )
        raise WindTableError(
            f"wind table {name!r}: {len(header)} columns in the header, expected the "
            f"{len(want)} of {','.join(want)}"
        )
    points: list[list[float]] = []
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(want):
            raise WindTableError(
                f"wind table {name!r} line {line}: {len(row)} values, expected {len(want)} "
                f"({','.join(want)})"
            )
        values = []
        for column, cell in zip(want, row, strict=True):
            try:
                x = float(cell)
            except ValueError:
                x = math.nan
            if not math.isfinite(x):
                raise WindTableError(
                    f"wind table {name!r} line {line} column {column}: not a finite number, "
                    f"got {cell.strip()!r}"
                )
            values.append(x)
        if points and values[0] <= points[-1][0]:
            raise WindTableError(
                f"wind table {name!r} line {line} column {first}: must be greater than the "
                f"line before's ({points[-1][0]:g}), got {values[0]:g}"
            )
        points.append(values)
    if not points:
        raise WindTableError(f"wind table {name!r} has a header and no rows")
    return points
