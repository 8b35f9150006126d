"""The order a ``.plan``'s mission items are flown in (quadrs.scenario.route_files): each item's
command checked, and ``DO_JUMP`` (177) followed as the autopilot flies it: back (or on) to the
item whose sequence number is ``param1`` (its ``doJumpId``, else its index + 1; home is 0),
``param2`` times, each jump counted over the whole mission as PX4 counts it."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from quadrs.scenario.plan_payload import RouteFileError, _number

#: MAV_CMD_DO_JUMP.
JUMP = 177
#: Most mission items flown once DO_JUMPs are expanded (a jump inside a jump multiplies).
MAX_FLOWN_ITEMS = 100_000


def item_command(item: Any, where: str) -> int:
    """An item's MAV_CMD, after checking the item's shape."""
    if not isinstance(item, dict):
        raise RouteFileError(f"{where}: not a mission item (a JSON object)")
    if item.get("type") != "SimpleItem":
        kind = item.get("complexItemType", item.get("type"))
        raise RouteFileError(
            f"{where}: a {kind!r} item is not supported: export the pattern as waypoints"
        )
    command = item.get("command")
    params = item.get("params")
    if (not isinstance(command, int) or isinstance(command, bool) or not isinstance(params, list)
            or len(params) != 7):  # fmt: skip
        raise RouteFileError(f"{where}: a mission item needs a command and 7 params")
    return command


def whole_number(value: Any, where: str, minimum: int) -> int:
    v = _number(value, where, float(minimum), 2.0**31)
    if v != int(v):
        raise RouteFileError(f"{where}: must be a whole number, got {value!r}")
    return int(v)


def flown_order(items: list[Any], commands: list[int], where: str) -> Iterator[int]:
    """The indices of ``items`` in the order the vehicle flies them, ``DO_JUMP``s followed
    (module docstring); the jumps themselves are not yielded."""
    seq: dict[int, int] = {}
    for i, item in enumerate(items):
        jump_id = item.get("doJumpId", i + 1)
        if isinstance(jump_id, int) and not isinstance(jump_id, bool):
            seq.setdefault(jump_id, i)
    targets: dict[int, tuple[int, int]] = {}
    for i, command in enumerate(commands):
        if command != JUMP:
            continue
        params, here = items[i]["params"], f"{where}[{i}]: DO_JUMP"
        if params[1] is not None and _number(params[1], f"{here} params[1] (repeat)") == -1:
            raise RouteFileError(f"{here} repeats forever (params[1] = -1): the flight would "
                                 "never end")  # fmt: skip
        number = whole_number(params[0], f"{here} params[0] (sequence number)", 0)
        if number not in seq:
            raise RouteFileError(f"{here} params[0]: no mission item has sequence number "
                                 f"{number} (home is 0, the first item 1)")  # fmt: skip
        targets[i] = (seq[number], whole_number(params[1], f"{here} params[1] (repeat)", 0))
    jumped = [0] * len(items)
    i = flown = 0
    while i < len(items):
        if i in targets:
            target, repeat = targets[i]
            if jumped[i] < repeat:
                jumped[i] += 1
                i = target
            else:
                i += 1
            continue
        flown += 1
        if flown > MAX_FLOWN_ITEMS:
            raise RouteFileError(f"{where}: its DO_JUMPs fly more than {MAX_FLOWN_ITEMS} items")
        yield i
        i += 1
