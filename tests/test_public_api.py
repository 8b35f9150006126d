"""The public names of the contract (the project's API description) stay importable from
``quadrs``, whatever module holds them; the documented module paths keep working; the command
line keeps its documented subcommands. A rename or a move that drops one fails here."""

from __future__ import annotations

import importlib

import pytest

import quadrs

#: The names ``quadrs`` offers, with the members of each that the contract uses.
PUBLIC: dict[str, tuple[str, ...]] = {
    "Scenario": ("paper", "from_toml", "to_toml", "override", "from_plan"),
    "ScenarioError": (),
    "EngineError": (),
    "simulate": (),
    "Flight": ("metrics", "trace", "to_parquet", "read_parquet"),
    "monte_carlo": (),
    "MonteCarloResult": (
        "runs",
        "summary",
        "exceedance",
        "quantile",
        "to_parquet",
        "read_parquet",
    ),
    "sweep": (),
    "SweepResult": ("runs", "summary", "exceedance", "quantile", "to_parquet", "read_parquet"),
    "gust_series": (),
    "gust_scales": (),
    "stability": (),
    "StabilityReport": (),
    "StabilityNote": (),
    "StabilityWarning": (),
    "StepSizeWarning": (),
    "sensitivity": (),
    "SensitivityResult": ("indices", "read_parquet"),
    "optimize": (),
    "OptimizeResult": ("best", "scenario", "history"),
    "Constraint": (),
    "InfeasibleWarning": (),
    "linearize": (),
    "LinearModel": ("A", "B", "C", "D", "to_control"),
    "rare_event": (),
    "RareEventResult": (
        "probability",
        "cov",
        "interval",
        "levels",
        "flights",
        "failures",
        "flight",
        "read_parquet",
    ),
    "RareEventComparison": (),
    "PlausibilityWarning": (),
    "__version__": (),
}

#: Module paths the documentation names (the engine's vocabularies, the figures, the subset
#: simulation on any model) -> a name each must hold.
MODULES = {
    "quadrs._core": ("CONTROLLER_NAMES", "METRIC_NAMES", "TRACE_COLUMNS", "Engine"),
    "quadrs.plots": (
        "altitude",
        "distributions",
        "exceedance_curves",
        "gust_spectra",
        "psd",
        "wind_met",
        "gust_transmissibility",
    ),
    "quadrs.rare": ("rare_event",),
    "quadrs.rare.subset": ("subset_simulation",),
}


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_each_public_name_is_importable_from_quadrs(name):
    value = getattr(quadrs, name)
    for member in PUBLIC[name]:
        # a dataclass field may exist on instances only: look at the annotations too
        fields = getattr(value, "__dataclass_fields__", {})
        assert hasattr(value, member) or member in fields, f"quadrs.{name}.{member} is gone"
    namespace: dict[str, object] = {}
    exec(f"from quadrs import {name}", namespace)
    assert namespace[name] is value


def test_the_face_lists_what_it_offers():
    assert set(PUBLIC) <= set(quadrs.__all__)
    assert set(quadrs.__all__) <= set(dir(quadrs))
    for name in quadrs.__all__:
        assert getattr(quadrs, name) is not None
    with pytest.raises(AttributeError, match="no_such_name"):
        quadrs.no_such_name  # noqa: B018


@pytest.mark.parametrize("module", sorted(MODULES))
def test_documented_module_paths_hold_their_names(module):
    mod = importlib.import_module(module)
    for name in MODULES[module]:
        assert hasattr(mod, name), f"{module}.{name} is gone"


def test_a_function_and_its_module_are_told_apart():
    """``quadrs.sweep`` is the function; its module is ``quadrs.runs.sweep`` (no module of the
    same name shadows or is shadowed by it), and its result type is on the face too."""
    from quadrs.runs import sweep as sweep_module

    assert callable(quadrs.sweep) and quadrs.sweep is sweep_module.sweep
    assert quadrs.SweepResult is sweep_module.SweepResult
    for name, module in [("stability", "quadrs.hover.stability"),
                         ("sensitivity", "quadrs.design.sensitivity"),
                         ("optimize", "quadrs.design.optimize")]:  # fmt: skip
        assert getattr(quadrs, name) is getattr(importlib.import_module(module), name)
        with pytest.raises(ModuleNotFoundError):
            importlib.import_module(f"quadrs.{name}")


def test_the_documented_subcommands_exist():
    from quadrs.cli.main import build_parser

    parser = build_parser()
    choices = next(a.choices for a in parser._actions if getattr(a, "choices", None))
    documented = {"run", "mc", "sweep", "report", "paper", "stability", "scenario",
                  "sensitivity", "tune", "linearize", "rare", "mission"}  # fmt: skip
    assert documented <= set(choices)


def test_the_lazy_face_names_each_object_once():
    """Every name ``__getattr__`` serves is in ``__all__`` and in ``__dir__``, and comes from
    the module ``_WHERE`` names (the TYPE_CHECKING imports mypy reads are checked by mypy)."""
    where = quadrs._WHERE  # type: ignore[attr-defined]
    assert sorted(quadrs.__all__) == sorted({"EngineError", "ScenarioError", "__version__",
                                             *where})  # fmt: skip
    for name, module in where.items():
        assert getattr(importlib.import_module(module), name) is getattr(quadrs, name)
    assert set(quadrs.__all__) <= set(dir(quadrs))


def test_import_quadrs_loads_nothing_heavy():
    """``import quadrs`` loads the engine's bindings and nothing of pandas, scipy, matplotlib
    or pyarrow (their cost comes with the first flight, table or figure); ``quadrs --version``
    neither."""
    import subprocess
    import sys

    heavy = ("pandas", "scipy", "matplotlib", "pyarrow", "quadrs.runs.flight")
    for code in ("import quadrs",
                 "from quadrs.cli.main import main; assert main(['--version']) == 0"):  # fmt: skip
        check = f"import sys; {code}; print([m for m in {heavy!r} if m in sys.modules])"
        out = subprocess.run([sys.executable, "-c", check], capture_output=True, text=True,
                             check=True)  # fmt: skip
        assert out.stdout.strip().splitlines()[-1] == "[]", (code, out.stdout)


def test_every_layer_is_an_attribute_of_the_package_after_a_bare_import():
    """``import quadrs; quadrs.runs`` works in a fresh interpreter, as after ``import
    quadrs.runs`` (the layers load on first use), for every subpackage on disk."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(quadrs.__file__).parent
    layers = sorted(p.name for p in root.iterdir() if (p / "__init__.py").is_file())
    assert layers == sorted(quadrs._SUBPACKAGES)  # type: ignore[attr-defined]
    code = f"import quadrs; print([quadrs.__getattr__(n).__name__ for n in {layers!r}])"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == repr([f"quadrs.{n}" for n in layers])
