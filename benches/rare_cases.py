"""The limit states the rare-event benches and tests hold subset simulation to against brute
force: a scenario, a metric and a phase, with the thresholds brute force counts."""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import quadrs

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from conftest import FOURTH_ROUND_DELIVERY_DROP, SHORT


@dataclass(frozen=True)
class Case:
    scenario: Callable[[], quadrs.Scenario]
    metric: str
    phase: str
    thresholds: tuple[float, ...]
    chunk: int


def _worked() -> quadrs.Scenario:
    return quadrs.Scenario.paper().override(SHORT)


def _delivery_drop() -> quadrs.Scenario:
    """The fourth round's delivery vehicle over its drop point, the one the reference in
    tests/data/rare_brute_force.json was flown on (the present preset's rigid body, rotor
    aerodynamics, winch and trimmed start swing its parcel further)."""
    return quadrs.Scenario.preset("delivery").override(FOURTH_ROUND_DELIVERY_DROP)


CASES = {
    "worked": Case(_worked, "max_accel", "P2", (4.9, 7.0, 7.5), 20_000),
    "delivery-drop": Case(
        _delivery_drop, "max_swing", "drop", (0.19, 0.20, 0.21, 0.22, 0.23, 0.24), 1_000
    ),
}
