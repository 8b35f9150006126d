"""The package's layers, checked from its source: every module belongs to one layer by its
package prefix, no module imports a higher layer, and no import closes a cycle.

Every ``.py`` under python/quadrs is parsed with ``ast`` (nothing is imported, so no module
can be missed by an import that happens not to run); each ``import quadrs...`` and
``from quadrs... import ...`` anywhere in it becomes an edge: at module level, inside
functions, in try/except and under ``if TYPE_CHECKING:`` (a type-only import is still a
dependency: of the reader, of mypy, and of whoever moves the module). The layers, lowest
first, are :data:`LAYERS`; docs/architecture.md draws them.
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = "quadrs"
ROOT = Path(__file__).resolve().parent.parent / "python" / PACKAGE

#: The layers, lowest first: a module may import its own layer and those below it, never one
#: above. A module's layer is the longest prefix here that names it (``quadrs.runs.flight`` is
#: in ``quadrs.runs``); ``quadrs`` itself, the public face, is the top and nothing imports it.
LAYERS = (
    "quadrs._core",  # the compiled engine (Rust), seen through its stub
    "quadrs.engine",  # the compiled handle and the guarded calls into it
    "quadrs.scenario",  # what to fly: the validated scenario, dispersions, routes, units
    "quadrs.io",  # files: atomic writes, Parquet with metadata, run identity
    "quadrs.stats",  # statistics of runs tables: intervals, risk, tables per group
    "quadrs.present",  # text and HTML for people, from frames: Table 3, notebook display
    "quadrs.hover",  # the closed loop at hover: poles and the linear model
    "quadrs.runs",  # flights and batches: one flight, Monte Carlo, chunks, stores, sweeps
    "quadrs.design",  # the design loop: optimize, constraints, sensitivity, missions
    "quadrs.rare",  # rare events by subset simulation
    "quadrs.plots",  # figures
    "quadrs.paper",  # the paper's tables and figures in one call
    "quadrs.cli",  # the command line
    "quadrs",  # the public face (quadrs/__init__.py)
)


def module_names() -> dict[str, Path]:
    """Module name -> source; a compiled module (the engine) by its stub, a leaf."""
    names = {}
    for path in sorted([*ROOT.rglob("*.py"), *ROOT.rglob("*.pyi")]):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        names.setdefault(".".join(parts), path)
    return names


def imports_of(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package modules `name` imports (any depth, any function, type-only included)."""
    if path.suffix == ".pyi":
        return set()
    is_package = path.name == "__init__.py"
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
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
            if target != PACKAGE and not target.startswith(PACKAGE + "."):
                continue
            # `import quadrs.results.x` means the longest known module on that path
            while target and target not in modules:
                target = target.rpartition(".")[0]
            if target and target != name:
                found.add(target)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = module_names()
    return {name: imports_of(name, path, modules) for name, path in modules.items()}


def layer_of(module: str) -> int | None:
    """The index in LAYERS of the longest prefix naming ``module``; None if no layer does
    (only the face is ``quadrs`` alone: a module directly under it belongs to none)."""
    for index in sorted(range(len(LAYERS)), key=lambda i: -len(LAYERS[i])):
        layer = LAYERS[index]
        if module == layer or (layer != PACKAGE and module.startswith(layer + ".")):
            return index
    return None


def layer_violations(graph: dict[str, set[str]]) -> list[str]:
    """One line per module in no layer and per import of a higher layer."""
    bad = [f"{m} is in no layer of LAYERS" for m in sorted(graph) if layer_of(m) is None]
    for module in sorted(graph):
        own = layer_of(module)
        for target in sorted(graph[module]):
            theirs = layer_of(target)
            if own is not None and theirs is not None and theirs > own:
                bad.append(f"{module} ({LAYERS[own]}) imports {target} ({LAYERS[theirs]})")
    return bad


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


def test_the_walker_sees_every_kind_of_import(tmp_path):
    """Lazy, type-only, relative and ``from package import module`` imports are all edges."""
    pkg = tmp_path / PACKAGE
    (pkg / "low").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "low" / "__init__.py").write_text("")
    (pkg / "low" / "a.py").write_text(
        "from typing import TYPE_CHECKING\n"
        "if TYPE_CHECKING:\n    from quadrs.low.b import B\n"
        "def f():\n    from . import c\n    import quadrs.low.d.x\n"
    )
    for leaf in "bcd":
        (pkg / "low" / f"{leaf}.py").write_text("import os\n")
    modules = {
        ".".join(p.relative_to(tmp_path).with_suffix("").parts).removesuffix(".__init__"): p
        for p in pkg.rglob("*.py")
    }
    found = imports_of("quadrs.low.a", pkg / "low" / "a.py", modules)
    assert found == {"quadrs.low.b", "quadrs.low.c", "quadrs.low.d"}


def test_layers_are_read_by_prefix():
    assert layer_of("quadrs") == len(LAYERS) - 1
    assert layer_of("quadrs.runs.flight") == LAYERS.index("quadrs.runs")
    assert layer_of("quadrs.rare") == LAYERS.index("quadrs.rare")
    assert layer_of("quadrs.flight") is None  # a flat module belongs to no layer
    assert layer_of("quadrs.runsx") is None
    graph = {"quadrs.runs.a": {"quadrs.plots.b"}, "quadrs.plots.b": {"quadrs.runs.a"}}
    assert layer_violations(graph) == [
        "quadrs.runs.a (quadrs.runs) imports quadrs.plots.b (quadrs.plots)"
    ]
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_every_module_sits_in_a_layer_and_imports_none_above_it():
    graph = import_graph()
    assert len(graph) > 40 and "quadrs._core" in graph  # the walker found the package
    bad = layer_violations(graph)
    assert not bad, "layer rule broken:\n" + "\n".join(bad)


def test_no_import_cycles():
    """No cycle between modules, type-only imports included."""
    cycle = find_cycle(import_graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def test_the_package_init_files_below_the_face_stay_light():
    """A subpackage's ``__init__`` imports nothing heavy on its own, so that importing one
    module of a layer does not load the layer: it holds a docstring (and, for the packages
    whose face it is, ``rare`` and ``plots``, their code)."""
    for path in sorted(ROOT.rglob("__init__.py")):
        package = ".".join(path.relative_to(ROOT.parent).parent.parts)
        if package in (PACKAGE, "quadrs.rare", "quadrs.plots"):
            continue
        tree = ast.parse(path.read_text())
        code = [
            n for n in tree.body
            if not (isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))
        ]  # fmt: skip
        assert not code, f"{package}/__init__.py holds code; keep it a docstring"
        assert ast.get_docstring(tree), f"{package}/__init__.py has no docstring"


RUST = Path(__file__).resolve().parent.parent / "rust" / "src"


def rust_module_graph() -> dict[str, set[str]]:
    """Top-level engine module -> the top-level modules its code names (`crate::x`), from
    the sources without comments and unit tests (a test may reach for anything). lib.rs,
    the crate root, is left out."""
    import re

    graph: dict[str, set[str]] = {}
    for path in RUST.rglob("*.rs"):
        rel = path.relative_to(RUST).with_suffix("").parts
        if rel == ("lib",) or rel[-1] == "tests" or rel[-1].endswith("_tests"):
            continue
        module = rel[0]
        code = re.split(r"#\[cfg\((?:all\()?test\b[^\]]*\]\s*mod tests", path.read_text())[0]
        code = re.sub(r"//.*", "", code)
        uses = set(re.findall(r"\bcrate::(\w+)", code))
        graph.setdefault(module, set()).update(uses - {module})
    return graph


def test_the_engine_has_no_module_cycle():
    graph = rust_module_graph()
    assert {"config", "model", "scenario", "integrate", "montecarlo"} <= set(graph)
    assert "scenario" in graph["integrate"]  # the walker sees `crate::` paths
    assert "gust" not in graph["lane"]  # unit tests (also `cfg(all(test, ...))`) are left out
    cycle = find_cycle(graph)
    assert cycle is None, "engine module cycle: " + " -> ".join(cycle or [])


#: Test folders that are not a layer: the suites that cut across the package, by topic, and
#: the data the tests read.
CROSS_CUTTING = {"guarantees", "first_hour", "data"}


def test_the_tests_mirror_the_package():
    """Each folder under tests/ is a layer of the package (tests/runs for quadrs.runs, ...) or a
    cross-cutting suite named by its topic; a test file sits in one of them or, for the
    package as a whole (its face, its layers, its modules' and engine files' sizes, its
    examples), at the top."""
    tests = Path(__file__).resolve().parent
    layers = {layer.removeprefix(PACKAGE + ".") for layer in LAYERS[1:-1]}
    folders = {p.name for p in tests.iterdir() if p.is_dir() and not p.name.startswith((".", "_"))}
    assert folders - layers - CROSS_CUTTING == set()
    top = {p.name for p in tests.glob("test_*.py")}
    assert top <= {
        "test_imports.py",
        "test_public_api.py",
        "test_module_sizes.py",
        "test_engine_file_sizes.py",
        "test_flight_loops.py",
        "test_examples.py",
        "test_docs_commands.py",
    }, top
