"""Scenario: presets, TOML round trip, overrides, and errors that name the key and value."""

import math

import pytest

import quadrs
from quadrs import Scenario, ScenarioError
from quadrs.scenario.scenario import parse_value, presets


def test_paper_preset_is_model_md(paper: Scenario) -> None:
    assert paper["vehicle.mass"] == 2.2
    assert paper["vehicle.inertia"] == [0.0167, 0.0167, 0.0231]
    assert paper["payload.mass"] == 0.22
    assert paper["controller.pd.kp"] == [1.5, 1.6, 1.5]
    assert paper["controller.smc.gamma"] == 0.2
    assert paper["gust.components"] == ["vertical"]
    assert paper.phase_names == ["P1", "P2", "P3", "flight"]  # the whole flight last
    assert paper.scenario_phases == ["P1", "P2", "P3"]
    assert paper.steps == 350_000
    # kc = mc (2 pi fn)^2 and d0 = mc g / kc
    assert paper.stiffness == pytest.approx(0.22 * (2 * math.pi * 2.0) ** 2, rel=1e-14)
    assert paper.hover_offset == pytest.approx(0.22 * 9.81 / paper.stiffness, rel=1e-14)
    assert "paper" in presets()


def test_toml_round_trips_exactly(paper: Scenario, tmp_path) -> None:
    text = paper.to_toml()
    again = Scenario.from_toml_string(text)
    assert again == paper
    assert again.to_toml() == text
    f = tmp_path / "s.toml"
    f.write_text(paper.override({"payload.stiffness": 40.0, "gust.w20": 7.5}).to_toml())
    back = Scenario.from_toml(f)
    assert back["payload.stiffness"] == 40.0
    assert back.get("payload.natural_frequency") is None


def test_override_is_a_new_scenario(paper: Scenario) -> None:
    s2 = paper.override({"gust.w20": 15.0, "payload.mass": 0.44, "phases[2].end": 65.0})
    assert s2["gust.w20"] == 15.0 and paper["gust.w20"] == 10.0
    assert s2["payload.mass"] == 0.44
    assert s2["phases[2].end"] == 65.0
    # kc follows the natural frequency: doubling mc doubles kc
    assert s2.stiffness == pytest.approx(2 * paper.stiffness)


def test_stiffness_replaces_natural_frequency(paper: Scenario) -> None:
    s = paper.override({"payload.stiffness": 50.0})
    assert s.stiffness == 50.0
    assert "natural_frequency" not in s.to_dict()["payload"]
    with pytest.raises(ScenarioError, match="exactly one"):
        paper.override({"payload.stiffness": 50.0, "payload.natural_frequency": 2.0})


def test_partial_file_from_a_base_preset(tmp_path) -> None:
    f = tmp_path / "mine.toml"
    f.write_text('base = "paper"\n[payload]\nmass = 0.5\n[gust]\nw20 = 12.0\n')
    s = Scenario.from_toml(f)
    assert s["payload.mass"] == 0.5 and s["gust.w20"] == 12.0
    assert s["vehicle.mass"] == 2.2


@pytest.mark.parametrize(
    ("changes", "key", "value"),
    [
        ({"payload.mass": -1.0}, "payload.mass", "-1.0"),
        ({"vehicle.mass": 0.0}, "vehicle.mass", "0.0"),
        ({"integrator.dt": 0.0}, "integrator.dt", "0.0"),
        ({"integrator.dt": -1e-3}, "integrator.dt", "-0.001"),
        ({"integrator.dt": 100.0}, "integrator.dt", "100.0"),
        ({"phases[2].end": 80.0}, "phases[2].end", "80.0"),
        ({"phases[0].start": -1.0}, "phases[0].start", "-1.0"),
        ({"trajectory.waypoints": [[0, 0, 0, 2, 0]]}, "trajectory.waypoints", "1"),
        ({"gust.airspeed": 0.0}, "gust.airspeed", "0.0"),
        ({"controller.smc.gamma": 0.0}, "controller.smc.gamma", "0.0"),
        ({"trajectory.interpolation": "cubic"}, "trajectory.interpolation", "cubic"),
    ],
)
def test_bad_values_name_key_and_value(paper: Scenario, changes, key: str, value: str) -> None:
    with pytest.raises(ScenarioError) as err:
        paper.override(changes)
    assert key in str(err.value)
    assert value in str(err.value)
    assert isinstance(err.value, ValueError)


def test_non_finite_values_are_rejected(paper: Scenario) -> None:
    for bad in (math.nan, math.inf):
        with pytest.raises(ScenarioError, match=r"payload\.mass must be a finite number"):
            paper.override({"payload.mass": bad})


def test_unknown_keys_are_rejected(paper: Scenario, tmp_path) -> None:
    with pytest.raises(ScenarioError, match=r"payload.*colour"):
        paper.override({"payload.colour": "red"})
    with pytest.raises(ScenarioError, match="unknown scenario key"):
        paper.override({"nothing.here": 1})
    f = tmp_path / "bad.toml"
    f.write_text(paper.to_toml() + "\n[extra]\nkey = 1\n")
    with pytest.raises(ScenarioError, match="extra"):
        Scenario.from_toml(f)


def test_wrong_types_and_missing_files(paper: Scenario, tmp_path) -> None:
    with pytest.raises(ScenarioError, match=r"vehicle\.mass"):
        paper.override({"vehicle.mass": "heavy"})
    with pytest.raises(ScenarioError, match="cannot be read"):
        Scenario.from_toml(tmp_path / "missing.toml")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        Scenario.from_toml_string("this is = = not toml")
    incomplete = tmp_path / "incomplete.toml"
    incomplete.write_text("[vehicle]\nmass = 2.0\n")
    with pytest.raises(ScenarioError, match="missing field"):
        Scenario.from_toml(incomplete)


def test_parse_value_reads_toml_literals() -> None:
    assert parse_value("2") == 2
    assert parse_value("2.5e-3") == 0.0025
    assert parse_value("true") is True
    assert parse_value("[1, 2]") == [1, 2]
    assert parse_value("min_jerk") == "min_jerk"
    assert parse_value('"quoted"') == "quoted"


def test_exported_names() -> None:
    for name in ("Scenario", "ScenarioError", "simulate", "monte_carlo", "MonteCarloResult"):
        assert hasattr(quadrs, name)


def test_show_keeps_the_presets_layout_and_parses_back(paper: quadrs.Scenario) -> None:
    """Unchanged: exactly the preset file. Changed: still that layout, the new values with the
    preset's value in their comment, and it parses back to the same scenario."""
    from importlib import resources

    text = resources.files("quadrs").joinpath("presets", "paper.toml").read_text()
    assert paper.to_toml(like="paper") == text
    changed = paper.override(
        {
            "payload.mass": 0.3,
            "payload.stiffness": 40.0,
            "vehicle.inertia": [0.02, 0.0167, 0.0231],
            "controller.thrust_max": 60.0,
            "phases": [{"name": "all", "start": 0.0, "end": 70.0}],
            "dispersions": {"gust.w20": {"dist": "uniform", "low": 5.0, "high": 15.0}},
        }
    )
    out = changed.to_toml(like="paper")
    assert quadrs.Scenario.from_toml_string(out) == changed
    lines = out.splitlines()
    assert "mass = 0.3                            # kg (10 % of the vehicle); paper: 0.22" in lines
    assert (
        "inertia = [0.02, 0.0167, 0.0231]      # kg m^2, nominal Ixx, Iyy, Izz (Table 1); "
        "paper: [0.0167, 0.0167, 0.0231]"
    ) in lines
    assert not any(line.startswith("natural_frequency") for line in lines)
    assert "thrust_max = 60.0                     # paper: not set" in lines
    # Compact arrays, as in the preset: no array spread one number per line.
    assert not any(line.strip() in ("0.0,", "0.0167,") for line in lines)


def test_differences_name_every_changed_key(paper: quadrs.Scenario) -> None:
    changed = paper.override({"payload.mass": 0.3, "payload.stiffness": 40.0, "gust.w20": 10.0})
    diff = changed.differences(paper)
    assert diff == {
        "payload.mass": (0.22, 0.3),
        "payload.natural_frequency": (2.0, None),
        "payload.stiffness": (None, 40.0),
    }
    assert paper.differences(paper) == {}
    dispersed = paper.override({"dispersions": {"payload.mass": {"dist": "normal", "mean": 0.2,
                                                                  "std": 0.01}}})  # fmt: skip
    assert set(dispersed.differences(paper)) == {
        'dispersions."payload.mass".dist',
        'dispersions."payload.mass".mean',
        'dispersions."payload.mass".std',
    }
