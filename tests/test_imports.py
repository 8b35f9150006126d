"""The package's import graph has no cycles, lazy (in-function) imports included.

Every module under python/quadrs is parsed with ``ast``; each ``import quadrs...`` and
``from quadrs... import ...`` anywhere in it (module level, in functions, in try/except)
becomes an edge, except those under ``if TYPE_CHECKING:``, which never run. A cycle is
reported as the chain of modules that closes it.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = "quadrs"
ROOT = Path(__file__).resolve().parent.parent / "python" / PACKAGE


def module_names() -> dict[str, Path]:
    """Module name -> source; a compiled module (the engine) by its stub, a leaf."""
    names = {}
    for path in sorted([*ROOT.rglob("*.py"), *ROOT.rglob("*.pyi")]):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names.setdefault(".".join(parts), path)
    return names


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def _runtime_nodes(tree: ast.AST):
    """Every node except the bodies of ``if TYPE_CHECKING:`` blocks."""
    stack = [tree]
    while stack:
        node = stack.pop()
        yield node
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            stack.extend(node.orelse)
            continue
        stack.extend(ast.iter_child_nodes(node))


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package modules `name` imports when it runs (any depth, any function)."""
    if path.suffix == ".pyi":
        return set()
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    for node in _runtime_nodes(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = name.split(".")
                anchor = anchor if is_package else anchor[:-1]
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            # `from quadrs import plots` imports the submodule; `from quadrs import Flight`
            # imports the package itself
            targets = [
                f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                for alias in node.names
            ]
        else:
            continue
        for target in targets:
            # `import quadrs.results.x` means the longest known module on that path
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = module_names()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle as [a, b, ..., a], or None when the graph is acyclic (iterative DFS)."""
    state: dict[str, int] = {}  # 1 on the current path, 2 finished
    for start in sorted(graph):
        if start in state:
            continue
        path = [start]
        iters = [iter(sorted(graph[start]))]
        state[start] = 1
        while path:
            nxt = next(iters[-1], None)
            if nxt is None:
                state[path.pop()] = 2
                iters.pop()
            elif state.get(nxt) == 1:
                return [*path[path.index(nxt) :], nxt]
            elif nxt not in state:
                state[nxt] = 1
                path.append(nxt)
                iters.append(iter(sorted(graph.get(nxt, ()))))
    return None


def test_the_walker_sees_lazy_imports_and_finds_cycles():
    graph = import_graph()
    assert "quadrs.flight" in graph and "quadrs.scenario" in graph["quadrs.flight"]
    # cli imports its commands' modules inside functions only
    assert "quadrs.sweep" in graph["quadrs.cli"]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_cycles():
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


RUST = Path(__file__).resolve().parent.parent / "rust" / "src"


def rust_module_graph() -> dict[str, set[str]]:
    """Top-level engine module -> the top-level modules its code names (`crate::x`), from
    the sources without comments and unit tests (a test may reach for anything). lib.rs,
    the bindings, is the root and left out."""
    import re

    graph: dict[str, set[str]] = {}
    for path in RUST.rglob("*.rs"):
        rel = path.relative_to(RUST).with_suffix("").parts
        if rel == ("lib",) or rel[-1] == "tests" or rel[-1].endswith("_tests"):
            continue
        module = rel[0]
        code = path.read_text().split("#[cfg(test)]\nmod tests")[0]
        code = re.sub(r"//.*", "", code)
        uses = set(re.findall(r"\bcrate::(\w+)", code))
        graph.setdefault(module, set()).update(uses - {module})
    return graph


def test_the_engine_has_no_module_cycle():
    graph = rust_module_graph()
    assert {"config", "model", "integrate", "montecarlo"} <= set(graph)
    assert "config" in graph["integrate"]  # the walker sees `crate::` paths
    cycle = find_cycle(graph)
    assert cycle is None, "engine module cycle: " + " -> ".join(cycle or [])


#: Modules that only present results (tables, figures, notebook display, the command line).
PRESENTATION = {
    "quadrs.report",
    "quadrs.plots",
    "quadrs.paper",
    "quadrs._paper_grid",
    "quadrs.display",
    "quadrs.cli",
    "quadrs.cli_design",
}
#: The core: scenarios, engine calls, results, storage and integrity.
CORE = {
    "quadrs.scenario",
    "quadrs.flight",
    "quadrs.montecarlo",
    "quadrs.chunk",
    "quadrs.results",
    "quadrs.compiled",
    "quadrs.tables",
    "quadrs.summary",
    "quadrs.store",
    "quadrs.integrity",
    "quadrs.parquet",
    "quadrs.dispersion",
    "quadrs.guard",
    "quadrs.gust",
    "quadrs.linear",
    "quadrs.stability",
}


def reachable(graph: dict[str, set[str]], start: str) -> set[str]:
    seen: set[str] = set()
    stack = [start]
    while stack:
        for nxt in graph.get(stack.pop(), ()):
            if nxt not in seen:
                seen.add(nxt)
                stack.append(nxt)
    return seen


def display_imports_outside_repr_html(path: Path) -> list[int]:
    """Lines where ``path`` imports quadrs.display other than inside a ``_repr_html_``."""
    tree = ast.parse(path.read_text())
    allowed: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef) and node.name == "_repr_html_":
            allowed.update(id(n) for n in ast.walk(node))
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").endswith("display"):
            if id(node) not in allowed:
                bad.append(node.lineno)
    return bad


def test_the_core_imports_no_presentation_module():
    """The core never imports tables, figures or the command line, lazily or not. The one hook
    is the notebook display: Jupyter looks for ``_repr_html_`` on the result's class, so a
    result type may import ``quadrs.display`` inside that method, and nowhere else."""
    graph = import_graph()
    assert CORE <= set(graph) and PRESENTATION <= set(graph)
    modules = module_names()
    core_graph = {m: deps - {"quadrs.display"} for m, deps in graph.items()}
    for module in sorted(CORE):
        bad = reachable(core_graph, module) & PRESENTATION
        assert not bad, f"{module} imports presentation modules {sorted(bad)}"
        lines = display_imports_outside_repr_html(modules[module])
        assert not lines, f"{module} imports quadrs.display outside _repr_html_ (lines {lines})"
    assert reachable({"a": {"b"}, "b": {"c"}}, "a") == {"b", "c"}
