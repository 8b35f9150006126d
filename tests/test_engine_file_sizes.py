"""No engine source file is over LIMIT code lines: the engine is split by concern.

A code line is one that is neither blank nor only a `//` comment (doc comments included);
`#[cfg(test)]` modules written inline (`#[cfg(test)] mod tests { ... }`) and the files that
hold a module's tests (`tests.rs`, `*_tests.rs`) are not counted.
"""

import re
from pathlib import Path

LIMIT = 700
SOURCE = Path(__file__).resolve().parents[1] / "rust" / "src"

# `#[cfg(test)]`, then (after other attributes, comments or blank lines) `mod name {`.
_CFG_TEST = re.compile(r"#\[cfg\(test\)\]")
_MOD_OPEN = re.compile(r"(pub(\([^)]*\))?\s+)?mod\s+\w+\s*\{")


def _braces(line: str, in_block: bool) -> tuple[int, bool]:
    """The change in brace depth over `line`, outside strings, char literals and comments,
    and whether a `/* */` comment is still open at its end (`in_block`: open at its start)."""
    depth, i, n = 0, 0, len(line)
    while i < n:
        if in_block:
            end = line.find("*/", i)
            if end < 0:
                return depth, True
            in_block, i = False, end + 2
            continue
        c = line[i]
        if line.startswith("//", i):
            break
        if line.startswith("/*", i):
            in_block, i = True, i + 2
            continue
        raw = re.match(r'r(#*)"', line[i:])
        if raw:
            close = '"' + raw.group(1)
            end = line.find(close, i + len(raw.group(0)))
            i = n if end < 0 else end + len(close)
            continue
        if c == '"':
            i += 1
            while i < n and line[i] != '"':
                i += 2 if line[i] == "\\" else 1
            i += 1
            continue
        char = re.match(r"'(\\.[^']*|[^\\'])'", line[i:])
        if char:
            i += len(char.group(0))
            continue
        depth += (c == "{") - (c == "}")
        i += 1
    return depth, in_block


def code_lines(text: str) -> int:
    """`text`'s code lines: not blank, not only a `//` comment, not in a `#[cfg(test)]` module."""
    lines = text.splitlines()
    count, i = 0, 0
    while i < len(lines):
        stripped = lines[i].strip()
        if _CFG_TEST.fullmatch(stripped):
            j = i + 1
            while j < len(lines) and (
                not lines[j].strip() or lines[j].strip().startswith(("//", "#["))
            ):
                j += 1
            if j < len(lines) and _MOD_OPEN.match(lines[j].strip()):
                depth, in_block, k = 0, False, j
                while k < len(lines):
                    change, in_block = _braces(lines[k], in_block)
                    depth += change
                    if depth <= 0:
                        break
                    k += 1
                i = k + 1
                continue
        if stripped and not stripped.startswith("//"):
            count += 1
        i += 1
    return count


def is_tests_file(path: Path) -> bool:
    return path.name == "tests.rs" or path.name.endswith("_tests.rs")


def engine_files() -> list[Path]:
    return sorted(p for p in SOURCE.rglob("*.rs") if not is_tests_file(p))


def test_the_counting_rule():
    text = """//! A module.

/// A function.
fn f() {
    // a comment
    let s = "}"; // a brace in a string
    let c = '{';
}

#[cfg(test)]
#[allow(dead_code)]
mod tests {
    fn g() {
        let s = "{";
    }
}

fn h<'a>(x: &'a str) -> &'a str { x }
"""
    assert code_lines(text) == 5


def test_the_engine_has_source_files():
    files = engine_files()
    assert SOURCE / "lib.rs" in files
    assert len(files) > 50


def test_no_engine_file_is_over_the_limit():
    root = SOURCE.parents[1]
    sizes = {p.relative_to(root).as_posix(): code_lines(p.read_text()) for p in engine_files()}
    over = sorted(((n, path) for path, n in sizes.items() if n > LIMIT), reverse=True)
    assert not over, f"engine files over {LIMIT} code lines (split them by concern): " + ", ".join(
        f"{path} ({n})" for n, path in over
    )


#: Lines a Rust function may span, its signature to its closing brace (as Python's,
#: tests/test_module_sizes.py): a longer one is split into named pieces.
MAX_FUNCTION_LINES = 120
_FN = re.compile(r"\s*(pub(\([^)]*\))?\s+)?(const\s+)?(unsafe\s+)?fn\s+(\w+)")


def function_spans(text: str) -> list[tuple[str, int, int]]:
    """Each `fn` in `text` (outside `#[cfg(test)]` modules or not): its name, first line and
    the lines it spans, from its signature to its body's closing brace (a declaration without
    a body, `fn f();`, spans none)."""
    lines = text.splitlines()
    out = []
    for i, line in enumerate(lines):
        m = _FN.match(line)
        if not m:
            continue
        depth, in_block, opened = 0, False, False
        for j in range(i, len(lines)):
            change, in_block = _braces(lines[j], in_block)
            depth += change
            opened = opened or change > 0 or "{" in lines[j].split("//")[0]
            if not opened and lines[j].split("//")[0].rstrip().endswith(";"):
                break
            if opened and depth <= 0:
                out.append((m.group(5), i + 1, j - i + 1))
                break
    return out


def test_the_function_rule():
    text = (
        """fn short() {
    let s = "}";
}

fn declared();

pub(crate) fn long(x: u8) -> u8 {
"""
        + "    x;\n" * 200
        + "}\n"
    )
    spans = function_spans(text)
    assert spans == [("short", 1, 3), ("long", 7, 202)]


def test_no_engine_function_is_over_the_limit():
    root = SOURCE.parents[1]
    over = [
        f"{p.relative_to(root).as_posix()}:{line} {name} ({n} lines)"
        for p in engine_files()
        for name, line, n in function_spans(p.read_text())
        if n > MAX_FUNCTION_LINES
    ]
    assert not over, f"engine functions over {MAX_FUNCTION_LINES} lines: " + ", ".join(over)
