"""Is this gain set stable? Closed-loop poles of the model linearised at hover (MODEL.md §6).

The engine linearises ds/dt = f(s, u(s, r)) at the hover equilibrium (reference at the first
waypoint, psi = 0, zero wind; continuous time) and finds its 14 poles; see docs/stability.md.
A pole is *excited* when the scenario drives its mode: vertical, payload and yaw modes always
are; lateral ones only if something moves the vehicle sideways (a lateral waypoint, a horizontal
gust component or mean wind, an initial tilt or offset). Otherwise x and y stay exactly zero and
an unstable lateral mode never shows, as in the paper's vertical flights.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from quadrs import _core
from quadrs.flight import check_controller
from quadrs.scenario import Scenario

POLE_COLUMNS = ("real", "imag", "frequency_hz", "damping", "mode", "dominant", "status", "excited")


class StabilityWarning(UserWarning):
    """A gain set is not asymptotically stable at hover (issued before a Monte Carlo run)."""


class StepSizeWarning(UserWarning):
    """``integrator.dt`` is too large for the fastest closed-loop mode (issued before running)."""


#: Largest |pole| * dt considered safe. RK4 alone is stable up to about 2.8 (2.83 on the
#: imaginary axis, 2.79 on the real one), but the controls are held over each step, which
#: narrows the margin, and accuracy is poor long before that: at 1 a mode's per-step phase
#: error is already ~0.5 %.
STEP_LIMIT = 1.0


def step_size_warning(scenario: Scenario, reports: list[StabilityReport]) -> str:
    """Why ``integrator.dt`` is too large for these controllers' fastest modes ("" if not)."""
    dt = float(scenario["integrator.dt"])
    worst = max(
        ((float(np.hypot(r.real, r.imag)), r.mode, rep.controller)
         for rep in reports for r in rep.poles.itertuples()),
        default=(0.0, "", ""),
    )  # fmt: skip
    speed, mode, controller = worst
    if speed * dt <= STEP_LIMIT:
        return ""
    return (
        f"integrator.dt = {dt:g} s is too large for the {controller.upper()} closed loop's "
        f"fastest mode ({mode}, |pole| = {speed:.4g} 1/s): |pole| dt = {speed * dt:.3g} > "
        f"{STEP_LIMIT:g}. RK4 with held controls may be inaccurate or go unstable (flagged as "
        f"diverged); use integrator.dt <= {STEP_LIMIT / speed:.3g} s."
    )


def warn_before_running(
    scenario: Scenario, controllers: tuple[str, ...], *, gains: bool, stacklevel: int
) -> None:
    """Warn about a step too large for the fastest mode and, with ``gains``, unstable gains."""
    reports = [stability(scenario, c) for c in controllers]
    if gains:
        for report in reports:
            if not report.stable:
                warnings.warn(report.warning(), StabilityWarning, stacklevel=stacklevel + 1)
    message = step_size_warning(scenario, reports)
    if message:
        warnings.warn(message, StepSizeWarning, stacklevel=stacklevel + 1)


def _pole(real: float, imag: float) -> str:
    if abs(imag) > 0.0:
        return f"{real:+.2f} ± {abs(imag):.2f}j"
    return f"{real:+.2f}"


@dataclass(frozen=True)
class StabilityReport:
    """Closed-loop poles of one controller at hover.

    ``verdict``: "stable" (every real part < -tolerance), "marginal" (none > tolerance, some
    within it: e.g. a position without feedback) or "unstable". ``poles``: one row per pole,
    least stable first: ``real``, ``imag`` (1/s), ``frequency_hz`` (natural frequency |s|/2pi),
    ``damping`` (-real/|s|), ``mode`` ("lateral x/pitch", "lateral y/roll", "vertical",
    "payload" or "yaw"), ``dominant`` (largest state in the eigenvector), ``status`` and
    ``excited`` (whether this scenario drives the mode). ``lateral_sources``: what moves this
    scenario sideways (empty: x and y stay exactly zero). ``jacobian``: the 14x14 closed-loop
    matrix, states in ``quadrs._core.STATE_NAMES`` order. ``residual``: |ds/dt| at the
    linearisation point (0 unless the closed loop has no hover equilibrium).
    """

    controller: str
    stable: bool
    verdict: str
    poles: pd.DataFrame
    lateral_sources: tuple[str, ...]
    tolerance: float
    jacobian: np.ndarray = field(repr=False)
    residual: float = field(default=0.0, repr=False)

    @property
    def unstable(self) -> pd.DataFrame:
        """The poles that are not asymptotically stable (unstable and marginal ones)."""
        return self.poles[self.poles["status"] != "stable"]

    def _unstable_modes(self) -> list[tuple[str, str, bool]]:
        """(mode, pole, excited) per non-stable mode; a complex pair is shown once."""
        rows = self.unstable
        rows = rows[rows["imag"] >= 0]
        return [(r.mode, _pole(r.real, r.imag), bool(r.excited)) for r in rows.itertuples()]

    def __str__(self) -> str:
        name = self.controller.upper()
        if self.residual > 1e-6:
            name += " (no hover equilibrium: linearised at the reference point)"
        if self.stable:
            slow = self.poles.iloc[0]
            mode = f"{slow['mode']} {_pole(slow['real'], slow['imag'])}"
            return f"{name}: stable: slowest-decaying mode {mode}, damping {slow['damping']:.2f}"
        modes = []
        for mode, pole, excited in self._unstable_modes():
            said = "yes" if excited else "no"
            if excited and mode.startswith("lateral"):
                said += ": " + ", ".join(self.lateral_sources)
            modes.append(f"{mode} mode {pole} (excited by this scenario: {said})")
        return f"{name}: {self.verdict.upper()}: " + "; ".join(modes)

    def warning(self) -> str:
        """The message of the :class:`StabilityWarning` for this report ("" if stable)."""
        if self.stable:
            return ""
        modes = self._unstable_modes()
        parts = [
            f"{mode} mode {pole}, {'' if excited else 'not '}excited by this scenario"
            for mode, pole, excited in modes
        ]
        if any(excited for _, _, excited in modes):
            outlook = "Expect diverged realisations (flagged in runs.diverged)."
        else:
            outlook = (
                "Nothing in this scenario moves the vehicle sideways, so x and y stay exactly"
                " zero; any lateral disturbance would grow."
            )
        return (
            f"{self.controller.upper()} gains are {self.verdict.upper()} at hover: "
            f"{'; '.join(parts)}. {outlook} See quadrs.stability()."
        )


def stability(scenario: Scenario, controller: str = "smc") -> StabilityReport:
    """Closed-loop poles of ``controller`` ("pd" or "smc") linearised at hover, with a verdict.

    ``print(quadrs.stability(s, "smc"))`` gives a one-line summary; see
    :class:`StabilityReport` for the tables.
    """
    check_controller(controller)
    raw = _core.stability(scenario.to_json(), controller)
    real = np.asarray(raw["real"], dtype=float)
    imag = np.asarray(raw["imag"], dtype=float)
    magnitude = np.hypot(real, imag)
    with np.errstate(invalid="ignore", divide="ignore"):
        damping = np.where(magnitude > 0.0, -real / magnitude, np.nan)
    poles = pd.DataFrame(
        {
            "real": real,
            "imag": imag,
            "frequency_hz": magnitude / (2.0 * math.pi),
            "damping": damping,
            "mode": list(raw["mode"]),
            "dominant": list(raw["dominant"]),
            "status": list(raw["status"]),
            "excited": np.asarray(raw["excited"], dtype=bool),
        },
        columns=list(POLE_COLUMNS),
    )
    return StabilityReport(
        controller=controller,
        stable=bool(raw["stable"]),
        verdict=str(raw["verdict"]),
        poles=poles,
        lateral_sources=tuple(raw["lateral_sources"]),
        tolerance=float(raw["tolerance"]),
        jacobian=np.asarray(raw["jacobian"]),
        residual=float(raw["residual"]),
    )
