"""Nothing lies, aborts or is lost, fourth round (issue 40): the delivery vehicle's tables,
rotors and wind, routes, ``mission``, ``rare`` and the compiled engine.

One test (or a few) per item; each failed before the fix it proves (docs/guarantees.md lists
them beside their promise)."""

from __future__ import annotations

import re
import tracemalloc
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import quadrs
import quadrs.runs.montecarlo
from quadrs import Scenario, ScenarioError
from quadrs.io.integrity import run_identity
from tests.guarantees.test_design_loop_and_files import TINY_CLI
from tests.guarantees.test_guarantees import TINY, run_cli

pytestmark = pytest.mark.filterwarnings(
    "ignore::quadrs.StabilityWarning", "ignore::quadrs.StepSizeWarning"
)


@pytest.fixture(scope="module")
def tiny(paper: Scenario) -> Scenario:
    return paper.override(TINY)


@pytest.fixture(scope="module")
def delivery() -> Scenario:
    return Scenario.preset("delivery")


def one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# -- silent wrong -----------------------------------------------------------------------------
@pytest.mark.parametrize(
    "line, key",
    [
        ("wind = [5.0, 2.0]", "wind"),
        ("wind = []", "wind"),
        ("actuator = []", "actuator"),
        ("ground = []", "ground"),
        ("environment = [3.71]", "environment"),
        ("vehicle = [2.2]", "vehicle"),
    ],
)
def test_a_table_given_as_an_array_is_refused(line: str, key: str) -> None:
    """Read by position before: 5 m/s toward 2 degrees, ideal rotors, no ground, g = 3.71."""
    with pytest.raises(ScenarioError, match=rf"^{key} must be a table, got an array") as e:
        Scenario.from_toml_string(f'base = "delivery"\n{line}\n')
    assert e.value.key == key
    with pytest.raises(ScenarioError, match=rf"^{key} must be a table"):
        Scenario.preset("delivery").override({key: []})


def test_a_phase_or_gust_given_as_an_array_is_refused(delivery: Scenario) -> None:
    with pytest.raises(ScenarioError, match=r"^wind\.gusts\[0\] must be a table"):
        delivery.override({"wind.gusts": [[1.0, 2.0, [0.0, 0.0, 1.0]]]})
    with pytest.raises(ScenarioError, match=r"^phases\[0\] must be a table"):
        Scenario.paper().override({"phases": [["P1", 0.0, 10.0]]})


@pytest.mark.parametrize(
    "key, value", [("vehicle.arm_length", 1e155), ("actuator.torque_ratio", 5e-324)]
)
def test_rotors_whose_allocation_cannot_be_inverted_are_refused(
    delivery: Scenario, key: str, value: float
) -> None:
    """Passed before: NaN rotor thrusts, a calm hover ending `ground` at 0.66 s."""
    pattern = re.escape(key) + r" makes the rotors' allocation .* impossible to invert"
    with pytest.raises(ScenarioError, match="^" + pattern) as e:
        delivery.override({key: value})
    assert e.value.key == key


def test_stability_never_prints_an_unstable_verdict_without_a_mode() -> None:
    from quadrs.hover.stability import StabilityReport

    poles = pd.DataFrame({"real": [np.nan] * 2, "imag": [np.nan] * 2, "frequency_hz": np.nan,
                          "damping": np.nan, "mode": ["vertical", "yaw"], "dominant": "z",
                          "status": "unstable", "excited": True})  # fmt: skip
    report = StabilityReport("pd", False, "unstable", poles, (), 1e-6, np.full((2, 2), np.nan))
    text = str(report)
    assert text.startswith("PD: UNSTABLE: ") and not text.endswith(": "), text
    assert "no finite poles" in text


def test_a_roughness_without_a_finite_shear_factor_is_refused(delivery: Scenario) -> None:
    """Passed before (0 < z0 < 6.096): every flight ended non_finite at its first step."""
    for z0 in (5e-324, 1e-310):
        with pytest.raises(ScenarioError, match=r"^wind\.roughness .*got") as e:
            delivery.override({"wind.roughness": z0})
        assert e.value.key == "wind.roughness"
    delivery.override({"wind.roughness": 1e-6})  # smooth, and finite everywhere


def test_spectrum_frequencies_cannot_be_changed_in_place(tiny: Scenario) -> None:
    """Before: the cached arrays were handed out writeable; an edit corrupted every later
    flight's spectra and made a saved batch unreadable."""
    before = [f.copy() for f in tiny.spectrum_frequencies]
    f = tiny.spectrum_frequencies[0]
    with pytest.raises(ValueError, match="read-only"):
        f[:] = 0.0
    with pytest.raises(ValueError, match="read-only"):
        f *= 2.0
    for a, b in zip(before, tiny.spectrum_frequencies, strict=True):
        np.testing.assert_array_equal(a, b)
    flight = quadrs.simulate(tiny, "pd")
    np.testing.assert_array_equal(flight.spectra["P1"]["frequency"].to_numpy(), before[0])


# -- aborts -----------------------------------------------------------------------------------
@pytest.mark.parametrize("preset", ["slung", "paper_stable_lateral"])
def test_scenario_show_over_an_inherited_key(preset: str, capsys) -> None:
    """`--set gust.intensity=...` removes gust.w20, which these presets only inherit through
    `base`: a traceback before; now the file shown reads back as the scenario."""
    code, out, err = run_cli("scenario", "show", "--preset", preset, "--set",
                             'gust.intensity="light"', capsys=capsys)  # fmt: skip
    assert code == 0 and "Traceback" not in err, err
    want = Scenario.preset(preset).override({"gust.intensity": "light"})
    assert Scenario.from_toml_string(out) == want


@pytest.mark.parametrize("like", ["delivery", "slung", "paper", "paper_stable_lateral"])
@pytest.mark.parametrize("name", ["paper", "delivery", "slung"])
def test_to_toml_like_any_preset_reads_back_identical(name: str, like: str) -> None:
    """Before: a paper scenario written like="delivery" read back with empty [ground] and
    [wind] tables and another run identity; keys inherited through `base` were deleted."""
    for s in (Scenario.preset(name), Scenario.preset(name).override({"gust.intensity": "light"})):
        back = Scenario.from_toml_string(s.to_toml(like=like))
        assert back == s and back.to_dict() == s.to_dict()
        assert run_identity(back, 0, ["pd"], True) == run_identity(s, 0, ["pd"], True)


@pytest.mark.parametrize("address", ["tls://127.0.0.1:1", "127.0.0.1:abc", "inproc://x"])
def test_bad_scheduler_addresses_are_one_line(tiny: Scenario, address: str, capsys) -> None:
    pytest.importorskip("dask.distributed")
    code, _, err = run_cli("mc", *TINY_CLI, "--runs", "1", "--no-progress", "--scheduler",
                           address, capsys=capsys)  # fmt: skip
    assert code == 2, err
    assert one_line(err).startswith(f"quadrs mc: error: --scheduler {address}: cannot connect")


def test_run_innovations_caps_its_workers(tiny: Scenario) -> None:
    """Before: workers=10**6 started a million-thread pool."""
    from quadrs.rare.scenario_model import ScenarioModel

    engine = tiny.engine
    xi = np.zeros((1, ScenarioModel(tiny, "pd", "iae", "P1").dimension))
    for workers in (0, 4097, 10**6):  # 0 first: main refused it, and only it
        with pytest.raises(ValueError, match=rf"workers must be between 1 and 4096, got {workers}"):
            engine.run_innovations("pd", xi, None, workers, [], None)
    assert engine.run_innovations("pd", xi, None, 1, [], None).shape[0] == 1


@pytest.mark.slow
def test_run_innovations_runs_at_its_most_workers(tiny: Scenario) -> None:
    """The bound itself is accepted (a pool of 4096 threads: half a minute to start)."""
    from quadrs.rare.scenario_model import ScenarioModel

    xi = np.zeros((1, ScenarioModel(tiny, "pd", "iae", "P1").dimension))
    assert tiny.engine.run_innovations("pd", xi, None, 4096, [], None).shape[0] == 1


@pytest.mark.parametrize("per_level, dimension", [(100_000, 1), (100_000, 4), (20_000, 200)])
def test_rare_event_memory_check_covers_what_a_run_allocates(
    monkeypatch: pytest.MonkeyPatch, per_level: int, dimension: int
) -> None:
    """The estimate checked before a run is at least the peak a run allocates (tracemalloc),
    at large per_level and low dimension, where it was about 1/15 of it. Threshold 0: half
    the first level fails, the most failure samples a run holds."""
    import scipy.stats  # noqa: F401  (imported before measuring: a module is not the run's)

    from quadrs.rare import subset

    asked: list[int] = []
    monkeypatch.setattr(subset, "check_memory", lambda what, n: asked.append(n))
    tracemalloc.start()
    try:
        subset.subset_simulation(lambda x: x[:, 0] + 0.0 * x[:, -1], dimension, 0.0,
                                 per_level=per_level, p0=0.1, max_levels=4)  # fmt: skip
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(asked) == 1 and asked[0] >= peak, (asked, peak)


def test_a_wrong_length_names_list_on_a_long_route_is_one_short_line(
    delivery: Scenario,
) -> None:
    """Before: a 26,000-character message. The 10,000-point route itself validates in one
    linear pass (unique names by hash, not pairwise)."""
    n = 10_000
    route = [[float(i), 0.0, 30.0] for i in range(n)]
    long = {"trajectory.route": route, "trajectory.hold": [], "integrator.duration": 2e4,
            "gust.end": 2e4, "trajectory.speed": 20.0,
            "trajectory.acceleration": 100.0}  # fmt: skip
    names = [f"n{i}" for i in range(n)]
    s = delivery.override({**long, "trajectory.names": names})
    assert s.scenario_phases == names
    with pytest.raises(ScenarioError, match=r"^trajectory\.names must name each") as e:
        delivery.override({**long, "trajectory.names": names[:-1]})
    assert len(str(e.value)) < 300, len(str(e.value))


# -- lost work --------------------------------------------------------------------------------
def test_rare_on_a_dispersed_scenario_is_checked_before_flying(
    tiny: Scenario, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A normal payload mass reaches negative values in its tail: refused before any flight
    (it died after 8 levels and 730 flights before, keeping nothing)."""
    from quadrs.rare import engine

    def no_flights(*args, **kwargs):
        raise AssertionError("flew before checking the dispersions")

    monkeypatch.setattr(engine, "run_rows", no_flights)
    monkeypatch.setattr("quadrs.rare.scenario_model.run_rows", no_flights)
    s = tiny.override({"dispersions": {"payload.mass": {"dist": "normal", "mean": 0.22,
                                                        "std": 0.05}}})  # fmt: skip
    with pytest.raises(ScenarioError, match=r"dispersions: payload\.mass ranges over") as e:
        quadrs.rare_event(s, metric="max_accel", phase="P2", threshold=3.5, per_level=100)
    assert e.value.key == "dispersions.payload.mass"
    assert "payload.mass must be > 0" in str(e.value)
    ok = tiny.override({"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.15,
                                                         "high": 0.3}}})  # fmt: skip
    from quadrs.rare.scenario_model import ScenarioModel

    ScenarioModel(ok, "pd", "max_accel", "P2")  # a bounded range the scenario accepts


def test_ctrl_c_during_the_second_controller_keeps_the_first_estimate(
    monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    from quadrs.rare.scenario_model import ScenarioModel

    flown = ScenarioModel.evaluate

    def evaluate(self, xi):
        if self.controller == "smc":
            raise KeyboardInterrupt
        return flown(self, xi)

    monkeypatch.setattr(ScenarioModel, "evaluate", evaluate)
    code, out, err = run_cli("rare", *TINY_CLI, "--metric", "max_accel", "--phase", "P2",
                             "--threshold", "0.5", "--per-level", "100", "--workers", "1",
                             "--controller", "pd,smc", capsys=capsys)  # fmt: skip
    assert code == 130, err
    assert out.startswith("P(max_accel in P2 > 0.5 m/s²), pd, seed 0"), out
    assert "estimate" in out and ", smc," not in out
    assert "quadrs rare (smc): interrupted after 0 finished levels" in err


@pytest.mark.parametrize("command", ["mc", "mission"])
def test_plots_into_an_existing_file_is_refused_before_flying(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    import quadrs.runs.montecarlo

    def no_flights(*args, **kwargs):
        raise AssertionError("flew before checking --plots")

    monkeypatch.setattr(quadrs.runs.montecarlo, "monte_carlo", no_flights)
    plots = tmp_path / "figures"
    plots.write_text("mine")
    # mission flies the delivery route unless told otherwise (issue 41): the paper's here
    extra = ["--controllers", "pd"] if command == "mc" else ["--preset", "paper", "--limit", "8"]
    code, _, err = run_cli(command, *TINY_CLI, "--runs", "2", "--no-progress", *extra,
                           "--plots", str(plots), capsys=capsys)  # fmt: skip
    assert code == 2, err
    assert "--plots" in one_line(err) and str(plots) in err
    assert plots.read_text() == "mine"


# -- security ---------------------------------------------------------------------------------
def test_rare_escapes_the_phase_name_in_its_summary(capsys) -> None:
    phase = "\x1b]0;pwned\x07P2"
    phases = (
        'phases=[{name="P1",start=0.0,end=1.0},{name="\\u001b]0;pwned\\u0007P2",start=1.0,end=2.0}]'
    )
    cli = [*TINY_CLI[:-6], "--set", phases, *TINY_CLI[-4:]]
    code, out, err = run_cli("rare", *cli, "--metric", "max_accel", "--phase", phase,
                             "--threshold", "0.5", "--per-level", "100", "--workers", "1",
                             capsys=capsys)  # fmt: skip
    assert code == 0, err
    assert "\x1b" not in out + err and "\x07" not in out + err
    assert out.startswith("P(max_accel in \\x1b]0;pwned\\x07P2 > 0.5 m/s²)"), out


# -- unclear ----------------------------------------------------------------------------------
def test_messages_say_what_is_wrong(delivery: Scenario, tiny: Scenario, tmp_path: Path,
                                    capsys) -> None:  # fmt: skip
    with pytest.raises(ScenarioError, match=r"^trajectory\.names\[1\] must not be blank"):
        # One name per segment of the preset's route (as many as it names), the second blank.
        names = list(delivery["trajectory.names"])
        names[1] = " "
        delivery.override({"trajectory.names": names})
    with pytest.raises(ScenarioError,
                       match=r"^trajectory\.route\[1\] must have 3 numbers, got 4$"):  # fmt: skip
        delivery.override({"trajectory.route[1]": [0.0, 0.0, 30.0, 1.0]})
    gust = {"start": 1.0, "duration": 2.0, "amplitude": [0.0, 1.0, 0.0, 1.0]}
    amplitude = r"^wind\.gusts\[0\]\.amplitude must have 3 numbers, got 4$"
    with pytest.raises(ScenarioError, match=amplitude):
        delivery.override({"wind.gusts": [gust]})
    with pytest.raises(ScenarioError, match=r"waypoints\[1\] must have 5 numbers, got 4$"):
        tiny.override({"trajectory.waypoints": [[0, 0, 0, 2, 0], [1, 0, 0, 1]]})
    # `report` on a rare-event file says what the file is.
    r = quadrs.rare_event(tiny, metric="max_accel", phase="P2", threshold=0.5, per_level=100,
                          workers=1)  # fmt: skip
    path = tmp_path / "rare.parquet"
    r.to_parquet(path)
    code, _, err = run_cli("report", str(path), capsys=capsys)
    assert code == 2
    assert "is a rare-event result" in one_line(err) and "lacks" not in err
    # and on a sensitivity file (its metadata under a key of its own): it said "not written
    # by quadrs".
    sa = quadrs.sensitivity(tiny.override({"dispersions": {"payload.mass": {
        "dist": "uniform", "low": 0.15, "high": 0.3}}}), runs=2, workers=1)  # fmt: skip
    path = tmp_path / "sens.parquet"
    sa.to_parquet(path)
    code, _, err = run_cli("report", str(path), capsys=capsys)
    assert code == 2
    assert "is a sensitivity result" in one_line(err) and "not written by" not in err, err


def test_a_figure_without_data_says_what_the_data_lacks(tmp_path: Path, capsys) -> None:
    """Every flight diverged: no matplotlib words ("Data cannot be log-scaled", "No artists
    with labels found") reach the user; the warning says what is missing."""
    code, _, err = run_cli("mc", *TINY_CLI, "--runs", "4", "--no-progress", "--controllers",
                           "pd", "--set", "divergence.max_speed=0.01", "--plots",
                           str(tmp_path), capsys=capsys)  # fmt: skip
    assert code == 0, err
    assert "log-scaled" not in err and "No artists" not in err, err
    assert "figure psd not drawn (nothing to draw on log axes" in err, err


def test_run_draws_a_released_parcels_flight(tmp_path: Path, capsys) -> None:
    """`run --plot` on the delivery preset (phases = "legs", the parcel released on the
    ground: its relative displacement is 0 from the drop on) crashed with a TypeError reading
    the phases. Now every figure is written, the released phases' spectral panels say there
    is nothing on log axes, and the others are drawn; exit 0, no warning."""
    from PIL import Image

    code, _, err = run_cli("run", "--preset", "delivery", "--plot", str(tmp_path),
                           capsys=capsys)  # fmt: skip
    assert code == 0 and "warning" not in err and "Traceback" not in err, err
    names = ["altitude", "oscillation", "spectra", "psd", "gust_force"]
    assert sorted(p.name for p in tmp_path.glob("*.png")) == sorted(f"{n}.png" for n in names)
    assert all(Image.open(tmp_path / f"{n}.png").size[1] > 100 for n in names)
    flight = quadrs.simulate(Scenario.preset("delivery"), "smc")
    fig = quadrs.plots.psd(flight)
    panels = {a.get_title().rsplit(", ", 1)[-1]: a for a in fig.axes}
    drawn = {phase: a.get_xscale() == "log" for phase, a in panels.items()}
    assert drawn["transit"] and drawn["lower"] and not drawn["away"], drawn
    assert any("nothing to draw on log axes" in t.get_text() for t in panels["away"].texts)
    # Only phases with nothing to draw: no figure, and a message saying why.
    with pytest.raises(ValueError, match=r"nothing to draw on log axes \(power spectral density"):
        quadrs.plots.psd(flight, ["drop", "away"])
