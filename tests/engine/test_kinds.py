"""Every kind, key and metric the engine defines reaches Python with a unit and a label, from
the engine's own definitions (a kind's file, metrics.rs), so a template cannot drift."""

from __future__ import annotations

from quadrs import _core
from quadrs.scenario import units


def test_every_metric_has_a_unit_and_a_label() -> None:
    names = list(_core.METRIC_NAMES)
    assert list(_core.METRIC_UNITS) == names == list(_core.METRIC_LABELS)
    for name in names:
        assert _core.METRIC_UNITS[name].strip(), name
        assert _core.METRIC_LABELS[name].strip(), name


def test_every_key_a_kind_owns_has_a_unit_and_a_label() -> None:
    assert set(_core.KEY_UNITS) == set(_core.KEY_LABELS)
    for key, unit in _core.KEY_UNITS.items():
        assert unit.strip() and _core.KEY_LABELS[key].strip(), key
        # quadrs.units reads the engine's, for indexed keys too
        assert units.unit(key) == unit
        assert units.unit(f"{key}[0]") == unit


def test_every_controller_kind_owns_its_table() -> None:
    for name in _core.CONTROLLER_NAMES:
        owned = [k for k in _core.KEY_UNITS if k.startswith(f"controller.{name}.")]
        assert owned, f"controller {name!r} declares no keys"


def test_the_wind_sources_declare_their_keys() -> None:
    """The `[wind]` keys come from the wind sources' own files (gust/steady.rs, gusts.rs,
    table.rs), not from a table in Python: each with its unit and label, indexed keys too."""
    wanted = {
        "wind.speed": "m/s",
        "wind.heading": "deg",
        "wind.shear": "-",
        "wind.roughness": "m",
        "wind.gusts.start": "s",
        "wind.gusts.duration": "s",
        "wind.gusts.amplitude": "m/s",
        "wind.gusts.shape": "-",
        "wind.table.by": "-",
    }
    for key, unit in wanted.items():
        assert _core.KEY_UNITS[key] == unit and _core.KEY_LABELS[key].strip(), key
    assert units.unit("wind.gusts[1].amplitude[2]") == "m/s"
    assert units.unit("wind.table.file") == "-"  # read in Python, never reaches the engine
