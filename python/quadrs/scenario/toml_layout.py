"""A scenario written as TOML laid out like a preset (``Scenario.to_toml(like=...)``): the
preset's own text, order, compact arrays, units and comments, with each value that differs
from it noting the preset's value in its comment."""

from __future__ import annotations

import re
from typing import Any

from quadrs.scenario.keys import toml_value
from quadrs.scenario.preset_files import _BASE_KEY, _preset_text
from quadrs.scenario.tables import _differences, _seeded

#: Column at which the presets start their end-of-line comments.
_COMMENT_COLUMN = 38


def _preset_document(preset: str, flat: bool) -> Any:
    """The preset's text as a tomlkit document; ``flat``: with its ``base`` chain merged in
    (tables key by key, the preset's own lines over its base's), so that it holds every key."""
    import tomlkit
    from tomlkit.items import Table

    doc = tomlkit.parse(_preset_text(preset))
    base = doc.get(_BASE_KEY)
    if not flat or base is None:
        return doc
    whole = _preset_document(str(base), flat=True)

    def merge(into: Any, extra: Any) -> None:
        for key, item in extra.items():
            if isinstance(item, Table) and isinstance(into.get(key), Table):
                merge(into[key], item)
            else:
                into[key] = item

    del doc[_BASE_KEY]
    merge(whole, doc)
    return whole


def _layout_like(data: dict[str, Any], base: dict[str, Any], preset: str) -> str:
    """A scenario's tables ``data`` written over the text of ``preset``, whose tables are
    ``base`` (see :meth:`quadrs.scenario.scenario.Scenario.to_toml`)."""
    import tomlkit
    from tomlkit.items import Item, Table

    differences = _differences(data, _seeded(base, data))
    doc = _preset_document(preset, flat=False)

    def held(parts: tuple[str, ...]) -> bool:
        node: Any = doc
        for part in parts:
            if not isinstance(node, dict) or part not in node:
                return False
            node = node[part]
        return True

    # A key the preset only inherits through `base` cannot be removed from a file that bases
    # on it: then write the whole scenario, laid out like the preset with its base merged in.
    if any(new is None and not held(p) for p, (_, new) in differences.items()):
        doc = _preset_document(preset, flat=True)
    added: set[int] = set()  # tables the preset lacks: their lines need no "preset: not set"
    for parts, (old, new) in differences.items():
        node: Any = doc
        for part in parts[:-1]:
            if part not in node:
                node[part] = tomlkit.table()
                added.add(id(node[part]))
            node = node[part]
        fresh = id(node) in added
        last = parts[-1]
        if new is None:
            del node[last]
        elif isinstance(new, list) and new and all(isinstance(v, dict) for v in new):
            tables = tomlkit.aot()
            for row in new:
                table = tomlkit.table()
                table.update(row)
                tables.append(table)
            node[last] = tables
        else:
            item = tomlkit.item(new)
            if not fresh:
                held_item = node.get(last)
                before = (
                    held_item.trivia.comment.lstrip("# ") if isinstance(held_item, Item) else ""
                )
                was = f"{preset}: {'not set' if old is None else toml_value(old)}"
                item.comment(f"{before}; {was}" if before else was)
                # The preset aligns its comments at one column: keep them aligned.
                width = len(f"{last} = {item.as_string()}")
                item.trivia.comment_ws = " " * max(1, _COMMENT_COLUMN - width)
            node[last] = item

    # Tables of the preset this scenario does not have (the delivery's [ground] under a paper
    # scenario) go whole, not as empty tables that would read back as a different scenario.
    def prune(node: Any, data: Any) -> None:
        for key in list(node.keys()):
            if isinstance(node[key], Table):
                if not isinstance(data, dict) or key not in data:
                    del node[key]
                else:
                    prune(node[key], data[key])

    prune(doc, data)
    # A blank line before every table header, as in the presets.
    return re.sub(r"(?<=[^\n])\n(?=\[)", "\n\n", tomlkit.dumps(doc))
