"""No Python module of the package is too long to read: each holds at most
:data:`MAX_CODE_LINES` lines of code, counted from its source. A module past it is split by
concern into modules whose names say what they hold (the public names re-exported where they
were), not trimmed of its blank lines or comments, which are not counted."""

from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "python" / "quadrs"

#: The most lines of code a module may hold.
MAX_CODE_LINES = 600

#: The most lines a function (or method) may span, its docstring and comments included.
MAX_FUNCTION_LINES = 120

#: Tokens that are not code: comments and the layout around them.
NOT_CODE = {
    tokenize.COMMENT,
    tokenize.NL,
    tokenize.NEWLINE,
    tokenize.INDENT,
    tokenize.DEDENT,
    tokenize.ENCODING,
    tokenize.ENDMARKER,
}


def code_lines(source: str) -> int:
    """Lines that are neither blank nor only a comment; a docstring's or any string's lines
    count (its blank lines do not)."""
    lines = source.splitlines()
    code: set[int] = set()
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type not in NOT_CODE:
            code.update(range(token.start[0], token.end[0] + 1))
    return sum(1 for n in code if 0 < n <= len(lines) and lines[n - 1].strip())


def oversized(limit: int = MAX_CODE_LINES) -> dict[str, int]:
    """Each module over ``limit`` code lines, by its path in the repository, with its count."""
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        count = code_lines(path.read_text())
        if count > limit:
            found[str(path.relative_to(ROOT.parent.parent))] = count
    return found


def test_the_counter_counts_code_only():
    source = (
        '"""A docstring\n\nof three lines."""\n'
        "\n"
        "# a comment\n"
        "x = 1  # code with a comment\n"
        "    \n"
        "TEMPLATE = '''\n# a string's line, not a comment\n'''\n"
    )
    assert code_lines(source) == 2 + 1 + 3


def test_no_module_is_over_the_limit():
    modules = list(ROOT.rglob("*.py"))
    assert len(modules) > 40  # the package was found
    found = oversized()
    assert not found, f"modules over {MAX_CODE_LINES} code lines (split them by concern): " + (
        ", ".join(f"{path} ({count})" for path, count in found.items())
    )


def long_functions(limit: int = MAX_FUNCTION_LINES) -> dict[str, int]:
    """Each function or method of the package longer than ``limit`` lines (first to last
    line), by ``path:line name``, with its length."""
    found = {}
    for path in sorted(ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                span = (node.end_lineno or node.lineno) - node.lineno + 1
                if span > limit:
                    where = path.relative_to(ROOT.parent.parent)
                    found[f"{where}:{node.lineno} {node.name}"] = span
    return found


def test_no_function_is_over_the_limit():
    """A function past :data:`MAX_FUNCTION_LINES` is split into named pieces (issue 70)."""
    assert long_functions(limit=60), "the counter found no function longer than 60 lines"
    found = long_functions()
    assert not found, f"functions over {MAX_FUNCTION_LINES} lines (split them): " + ", ".join(
        f"{name} ({span})" for name, span in found.items()
    )
