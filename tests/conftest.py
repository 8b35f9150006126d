"""Shared fixtures: the paper preset and short, coarse variants of it that run in milliseconds."""

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
