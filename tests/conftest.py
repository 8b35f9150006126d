"""Shared fixtures: the paper preset and short, coarse variants of it that run in milliseconds;
the paper pipeline's output, made once per session (shared by the pytest workers:
scripts/test.sh runs one per core)."""

import fcntl
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

import quadrs

SHORT = {
    "integrator.duration": 6.0,
    "integrator.dt": 0.002,
    "trajectory.waypoints": [[0, 0, 0, 2, 0], [4, 0, 0, 0, 0]],
    "phases": [
        {"name": "P1", "start": 0, "end": 2},
        {"name": "P2", "start": 2, "end": 4},
        {"name": "P3", "start": 4, "end": 6},
    ],
    "gust.start": 2.5,
    "gust.end": 3.5,
}

# The delivery preset over its drop point: a 2 m descent to 5 m, then the preset's 15 s hover
# (vehicle, parcel on its line, rotors, sheared crosswind and turbulence at the vehicle's own
# altitude and airspeed as the preset flies them), 19 s a flight.
DELIVERY_DROP = {
    "trajectory.route": [[0.0, 0.0, 7.0], [0.0, 0.0, 5.0]],
    "trajectory.hold": [0.0, 15.0],
    "trajectory.names": ["descent", "drop"],
    "initial.position": [0.0, 0.0, 7.0],
    "integrator.duration": 19.0,
    "gust.end": 19.0,
}

# The fourth round's delivery vehicle (the preset as it was when tests/data/rare_brute_force.json's
# "delivery-drop" case was flown, 031ee14): the paper's body (Euler angles, drag per inertial
# axis), rotors without their aerodynamics, a fixed 1 m line (no winch, no hook that opens), the
# ground a plane the vehicle must not reach but the parcel never touches, the start at rest. Over
# the present preset these keys give that vehicle again; the route is DELIVERY_DROP's.
FOURTH_ROUND_DELIVERY_VEHICLE = {
    "vehicle.body": "paper",
    "vehicle.drag_coefficients": None,
    "actuator.rotor_drag": None,
    "actuator.translational_lift": None,
    "actuator.flapping": None,
    "payload.cable_length": 1.0,
    "payload.length_min": None,
    "payload.winch_speed": None,
    "payload.winch_acceleration": None,
    "payload.approach_height": None,
    "payload.approach_speed": None,
    "payload.release": None,
    "payload.release_delay": None,
    "ground.stiffness": None,
    "ground.dissipation": None,
    "ground.friction": None,
    "initial.trim": "rest",
    "trajectory.speed": 10.0,  # the fifth round slowed the cruise to 8 m/s (the descent's too)
    # The sixth round's: the laws on the state, every loop and the wind every 1 ms step.
    "navigation": None,
    "sensors": None,
    "controller.position_rate": None,
    "controller.attitude_rate": None,
    "controller.inner_rate": None,
    "gust.rate": None,
    "integrator.dt": 0.001,
}

# The fourth round's delivery vehicle over its drop point: the vehicle the brute-force reference
# of the "delivery-drop" case (tests/data/rare_brute_force.json) was computed for, which
# benches/rare_cases.py flies and tests/rare/test_against_brute_force.py checks against.
FOURTH_ROUND_DELIVERY_DROP = {**FOURTH_ROUND_DELIVERY_VEHICLE, **DELIVERY_DROP}


#: Where each test starts: Ctrl-C and SIGTERM as a terminal's process has them (a suite run
#: from a script's background job, or under nohup, starts with them ignored, and the tests of
#: a Ctrl-C would then test an ignored signal).
_SIGNALS_AT_START = {signal.SIGINT: signal.default_int_handler, signal.SIGTERM: signal.SIG_DFL}


@pytest.fixture(autouse=True)
def signals_as_from_a_terminal(request: pytest.FixtureRequest) -> Iterator[None]:
    """Each test starts with Ctrl-C and SIGTERM at their defaults and must leave them so: a
    handler left installed (a signal hold not undone) fails the test that left it, not a later
    test of Ctrl-C in the same worker."""
    before = {sig: signal.signal(sig, handler) for sig, handler in _SIGNALS_AT_START.items()}
    yield
    left = {sig: signal.getsignal(sig) for sig in _SIGNALS_AT_START}
    for sig, handler in before.items():
        signal.signal(sig, handler)
    changed = {
        signal.Signals(sig).name: h for sig, h in left.items() if h != _SIGNALS_AT_START[sig]
    }
    assert not changed, f"{request.node.nodeid} left signal handlers installed: {changed}"


@pytest.fixture(scope="session")
def paper() -> quadrs.Scenario:
    return quadrs.Scenario.paper()


@pytest.fixture(scope="session")
def short(paper: quadrs.Scenario) -> quadrs.Scenario:
    """Take-off, gust, landing in 6 s at dt = 2 ms."""
    return paper.override(SHORT)


@pytest.fixture(scope="session")
def still_hover(paper: quadrs.Scenario) -> quadrs.Scenario:
    """5 s of hover at 2 m in still air (no gust), dt = 1 ms: nothing should move."""
    return paper.override(
        {
            "gust.enabled": False,
            "initial.position": [0.0, 0.0, 2.0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.waypoints": [[0, 0, 0, 2.0, 0.0], [5, 0, 0, 2.0, 0.0]],
            "integrator.duration": 5.0,
            "integrator.dt": 0.001,
            "phases": [{"name": "all", "start": 0.0, "end": 5.0}],
        }
    )


@pytest.fixture(scope="session")
def paper_example(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """``examples/paper.py OUT 2`` run once per session, as a user runs it (the paper preset at
    dt = 2 ms, 2 realisations, the sweep at 1 and 4 Hz, the mass figure at 0.22 kg): its output
    directory and what it printed. The pipeline is the slowest thing the suite runs; the
    example's test and the check of every table and figure share this run, and so do the
    pytest workers (the first to ask runs it under a lock in the session's own directory, the
    others read its output: the tests only read it)."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent  # the session's directory, above each worker's own
    out = base / "paper-example"
    printed = base / "paper-example.stdout"
    with open(base / "paper-example.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not printed.exists():
            script = Path(__file__).resolve().parent.parent / "examples" / "paper.py"
            proc = subprocess.run([sys.executable, str(script), str(out), "2"],
                                  capture_output=True, text=True, timeout=900,
                                  check=False)  # fmt: skip
            assert proc.returncode == 0, proc.stderr
            printed.write_text(proc.stdout)  # last: a failed run leaves none
    return out, printed.read_text()


def pytest_report_header() -> list[str]:
    """Which engine path this machine runs (the cross-path tests skip what it cannot)."""
    import os

    flags = ""
    try:
        with open("/proc/cpuinfo") as f:
            words = next((line for line in f if line.startswith("flags")), "").split()
        flags = " ".join(w for w in ("avx2", "fma", "avx512f", "avx512dq") if w in words)
    except OSError:
        pass
    forced = os.environ.get("QUADRS_SIMD")
    note = f", QUADRS_SIMD={forced}" if forced else ""
    return [f"quadrs engine path: {quadrs._core.simd_path()}{note}; CPU flags: {flags or '?'}"]
