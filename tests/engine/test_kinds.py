"""Every kind, key and metric the engine defines reaches Python with a unit and a label, from
the engine's own definitions (a kind's file, metrics.rs), so a template cannot drift."""

from __future__ import annotations

import itertools

import pytest

from quadrs import ScenarioError, _core
from quadrs.scenario import units
from quadrs.scenario.scenario import Scenario, presets


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


def test_every_payload_and_actuator_model_is_registered_once_and_reads() -> None:
    """The models come from the one registration (`model::kinds!`): the paper's first, each a
    name a scenario may give, its state layout described by the engine."""
    assert _core.PAYLOAD_MODELS[0] == "spring" and "cable" in _core.PAYLOAD_MODELS
    assert _core.ACTUATOR_MODELS[0] == "ideal" and "rotors" in _core.ACTUATOR_MODELS
    assert _core.BODY_MODELS == ["paper", "rigid"]
    for body, payload, actuator in itertools.product(
        _core.BODY_MODELS, _core.PAYLOAD_MODELS, _core.ACTUATOR_MODELS
    ):
        data = Scenario.preset("delivery").to_dict()
        data["payload"]["model"], data["actuator"]["model"] = payload, actuator
        data["vehicle"]["body"] = body
        if body == "paper":  # the body-axis drag and the rotor aerodynamics are the rigid body's
            data["vehicle"].pop("drag_coefficients", None)
            for key in ("rotor_drag", "flapping", "translational_lift"):
                data["actuator"].pop(key, None)
        if payload != "cable":  # the cable's keys are refused with another payload
            for key in (
                "cable_length",
                "attachment_offset",
                "winch_speed",
                "winch_acceleration",
                "length_min",
                "release",
                "release_delay",
                "approach_height",
                "approach_speed",
            ):
                data["payload"].pop(key, None)
            for key in ("stiffness", "dissipation", "friction"):  # the contact: the cable's
                data["ground"].pop(key, None)
            data["trajectory"].pop("lower", None)
            data["trajectory"].pop("names", None)  # the lowering named one of them
        if body == "rigid" and payload == "spring":  # the rigid body flies the cable only
            with pytest.raises(ScenarioError, match=r"vehicle\.body"):
                _ = Scenario.from_dict(data).state_names
            continue
        names = Scenario.from_dict(data).state_names
        assert len(names) == len(set(names)), (payload, actuator, names)
        assert ("omega_1" in names) == (actuator == "rotors"), (payload, actuator)
        assert ("xc" in names) == (payload == "cable"), (payload, actuator)
        rigid = ["qw", "qx", "qy", "qz", "wx", "wy", "wz"]
        assert all((n in names) == (body == "rigid") for n in rigid), (body, names)
        assert ("phi" in names) == (body == "paper"), (body, names)


def test_every_key_of_every_preset_has_a_unit_and_a_label() -> None:
    """Every key a preset sets, and those of the optional tables (rotor faults, discrete gusts,
    a dispersion), has a unit and a label: a section or kind that adds a key without declaring
    it fails here."""
    scenarios = [Scenario.preset(name) for name in presets()]
    scenarios.append(
        Scenario.preset("delivery").override(
            {
                "actuator.faults": [{"rotor": 2, "start": 5.0, "thrust_fraction": 0.9}],
                "actuator.battery_sag": 0.05,
                "wind.gusts": [
                    {"start": 3.0, "duration": 1.0, "amplitude": [1.0, 0.0, 0.0], "shape": "pulse"}
                ],
                "dispersions": {"payload.mass": {"dist": "uniform", "low": 0.4, "high": 0.6}},
            }
        )
    )
    seen = set()
    for scenario in scenarios:
        for key in scenario.keys():
            assert units.unit(key).strip() and units.label(key).strip(), key
            seen.add(key)
    assert "actuator.faults[0].thrust_fraction" in seen and "wind.gusts[0].shape" in seen
    assert "dispersions.payload.mass.low" in seen
    assert units.label("dispersions.payload.mass.low") == "Payload mass: dispersion low"


def test_python_holds_no_second_table_of_units() -> None:
    """The engine declares every key but those Python alone reads (`wind.table.file`, the
    wind climate's sectors, drawn into wind.heading and wind.speed); Python's few never
    shadow the engine's."""
    python_only = set(units.UNITS) - set(_core.KEY_UNITS)
    climate = {f"wind.climate.sectors.{k}" for k in ("heading", "frequency", "shape", "scale")}
    assert python_only == {"wind.table.file", *climate}, python_only
    assert "wind.table.points" in _core.KEY_UNITS and "wind.table.file" in python_only
    for key, unit in _core.KEY_UNITS.items():
        assert units.UNITS[key] == unit and units.LABELS[key] == _core.KEY_LABELS[key], key
    assert set(units.UNITS) == set(units.LABELS)


def test_every_section_key_has_a_unit_and_a_label() -> None:
    """Each section of the scenario declares its keys beside its struct: a sample per section."""
    for key, unit in [
        ("vehicle.inertia", "kg m^2"),
        ("payload.natural_frequency", "Hz"),
        ("environment.gravity", "m/s^2"),
        ("initial.attitude", "rad"),
        ("actuator.thrust_coefficient", "N s^2/rad^2"),
        ("trajectory.waypoints", "[s, m, m, m, rad]"),
        ("phases.end", "s"),
        ("gust.air_density", "kg/m^3"),
        ("integrator.dt", "s"),
        ("metrics.spectrum_rate", "Hz"),
        ("divergence.max_rate", "rad/s"),
        ("ground.altitude", "m"),
    ]:
        assert _core.KEY_UNITS[key] == unit and _core.KEY_LABELS[key].strip(), key


def test_figures_label_keys_from_their_declaration() -> None:
    """The figures' labels of scenario keys come from the keys' declarations, with the unit as
    shown; the labels the figures had before the keys were declared are unchanged."""
    from quadrs.present.labels import PLAIN_LABELS

    for key, shown in [
        ("payload.natural_frequency", "Attachment natural frequency (Hz)"),
        ("payload.stiffness", "Attachment stiffness (N/m)"),
        ("payload.mass", "Payload mass (kg)"),
        ("payload.damping", "Attachment damping (N s/m)"),
        ("payload.drag_area", "Payload drag area (m²)"),
        ("gust.w20", "Wind at 20 ft (m/s)"),
        ("gust.airspeed", "Airspeed (m/s)"),
        ("gust.altitude", "Altitude of the gust model (m)"),
        ("gust.air_density", "Air density (kg/m³)"),
        ("vehicle.mass", "Quadrotor mass (kg)"),
        ("vehicle.drag_area", "Quadrotor drag area (m²)"),
        ("integrator.dt", "Integration step (s)"),
        ("payload.model", "Payload model"),
    ]:
        assert PLAIN_LABELS[key] == shown
    assert set(units.LABELS) <= set(PLAIN_LABELS)


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
