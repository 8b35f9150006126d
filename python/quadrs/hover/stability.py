"""Is this gain set stable? Closed-loop poles of the model linearised at hover (docs/model.md §8).

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

from quadrs.engine.calls import check_controller
from quadrs.scenario.scenario import Scenario

POLE_COLUMNS = ("real", "imag", "frequency_hz", "damping", "mode", "dominant", "status", "excited")


class StabilityWarning(UserWarning):
    """A gain set is not asymptotically stable at hover (issued before a Monte Carlo run)."""


class StabilityNote(StabilityWarning):
    """A gain set is unstable at hover only in modes the scenario does not excite: those
    states stay exactly zero, so the flight is unaffected (a note, not an alarm)."""


class StartWarning(UserWarning):
    """The flights cannot start trimmed in their wind: the vehicle cannot hover in the start's
    steady wind, so it starts level at rest and the wind carries it off (issued before
    running)."""


class StepSizeWarning(UserWarning):
    """``integrator.dt`` is too large for the fastest closed-loop mode (issued before running)."""


#: Largest |pole| * dt considered safe for stability. RK4 alone is stable up to about 2.8
#: (2.83 on the imaginary axis, 2.79 on the real one), but the controls are held over each step,
#: which narrows the margin.
STEP_LIMIT = 1.0
#: Largest accuracy indicator (see :func:`step_error`) accepted without a warning. Holding the
#: controls over a step delays them by dt/2 on average, a phase lag of |pole| dt / 2 at a mode;
#: 0.05 rad corresponds, for the paper preset's fastest excited mode (the payload pair,
#: |pole| ~ 13 1/s), to dt ~ 8 ms, where take-off (P1) IAE has moved by about 1 % from its
#: dt -> 0 value (6 % at dt = 0.05 s; docs/stability.md).
STEP_ACCURACY = 0.05


def step_error(pole: complex, dt: float, held: bool = True) -> float:
    """Accuracy indicator of one step ``dt`` at a closed-loop ``pole`` (1/s): the larger of the
    half-step lag of the controls held over the step, |pole| dt / 2 (rad; only where ``held``:
    a loop that runs every step, so the step sets its hold), and RK4's own relative error per
    step, |R(z) exp(-z) - 1| with z = pole dt and R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24 (about
    |z|^5 / 120; far smaller until |z| nears RK4's stability bound). A law whose every loop
    runs at its own rate holds its outputs for its own periods at any step that divides them:
    that lag is the model's (``stability`` of the sampled law), not the step's."""
    z = complex(pole) * dt
    rk4 = 1 + z + z * z / 2 + z**3 / 6 + z**4 / 24
    rk4_error = abs(rk4 * np.exp(-z) - 1) if abs(z) < 50 else math.inf
    return max(abs(z) / 2 if held else 0.0, rk4_error)


def step_size_warning(scenario: Scenario, reports: list[StabilityReport]) -> str:
    """Why ``integrator.dt`` is too large for these controllers' fastest excited modes ("" if
    it is fine): beyond RK4's stability margin (|pole| dt > :data:`STEP_LIMIT`), or accurate
    to less than :data:`STEP_ACCURACY` (see :func:`step_error`). Modes the scenario does not
    excite are ignored: their states stay exactly zero."""
    dt = float(scenario["integrator.dt"])
    worst = max(
        ((float(np.hypot(r.real, r.imag)), r.mode, rep.controller, complex(r.real, r.imag))
         for rep in reports for r in rep.poles.itertuples() if r.excited),
        default=(0.0, "", "", 0j),
        key=lambda row: row[0],
    )  # fmt: skip
    speed, mode, controller, pole = worst
    held = any(scenario.engine.every_step(controller)) if controller else True
    where = f"the {controller.upper()} closed loop's fastest excited mode ({mode}, |pole| = "
    where += f"{speed:.4g} 1/s)"
    if speed * dt > STEP_LIMIT:
        return (
            f"integrator.dt = {dt:g} s is too large for {where}: |pole| dt = {speed * dt:.3g} > "
            f"{STEP_LIMIT:g}. RK4 with held controls may be inaccurate or go unstable (flagged "
            f"as diverged); use integrator.dt <= {STEP_LIMIT / speed:.3g} s."
        )
    error = step_error(pole, dt, held)
    if error <= STEP_ACCURACY:
        return ""
    if not held:
        return (
            f"integrator.dt = {dt:g} s is coarse for {where}: RK4's error per step is "
            f"{error:.2g} (> {STEP_ACCURACY:g}), so the metrics depend on dt by more than about "
            "1 %; a smaller integrator.dt keeps them within it."
        )
    return (
        f"integrator.dt = {dt:g} s is coarse for {where}: the controls held over a step lag it "
        f"by {error:.2g} rad (> {STEP_ACCURACY:g}), so the metrics depend on dt by more than "
        f"about 1 %; integrator.dt <= {2 * STEP_ACCURACY / speed:.2g} s keeps them within it."
    )


def warn_before_running(
    scenario: Scenario, controllers: tuple[str, ...], *, gains: bool, stacklevel: int
) -> None:
    """Warn about a step too large for the fastest excited mode and about unstable gains:
    loudly whenever the scenario excites an unstable mode (the flight will diverge), and, with
    ``gains``, in one short line when it does not."""
    reports = [stability(scenario, c) for c in controllers]
    for report in reports:
        if not report.stable and (gains or report.excited_unstable):
            category = StabilityWarning if report.excited_unstable else StabilityNote
            warnings.warn(report.warning(), category, stacklevel=stacklevel + 1)
    for message in (step_size_warning(scenario, reports), contact_step_warning(scenario)):
        if message:
            warnings.warn(message, StepSizeWarning, stacklevel=stacklevel + 1)
    untrimmed = start_warning(scenario)
    if untrimmed:
        warnings.warn(untrimmed, StartWarning, stacklevel=stacklevel + 1)


def start_warning(scenario: Scenario) -> str:
    """Why the flights do not start trimmed in their wind ("" if they do): with
    ``initial.trim = "wind"``, a vehicle that cannot hover in the start's steady wind (no tilt
    within its thrust balances the drag) starts level at rest instead, and the wind carries
    it off (docs/model.md, "The start"): its flights measure that, not the route."""
    engine = scenario.engine
    if engine.start_balanced:
        return ""
    speed = math.hypot(*engine.start_wind)
    z = float(scenario["initial.position"][2])
    return (
        f"the vehicle cannot hover in the start's wind ({speed:.3g} m/s at {z:g} m): it starts "
        "level at rest and the wind carries it off; the flights measure that, not the route"
    )


#: m/s, the engine's friction regularisation speed (rust/src/model/payload/cable.rs
#: FRICTION_SPEED): below it the Coulomb force grows linearly with the sliding speed.
FRICTION_SPEED = 0.01


def contact_step_warning(scenario: Scenario) -> str:
    """Why ``integrator.dt`` is too large for the parcel's contact with the ground ("" if it
    is fine, or the parcel never meets one): the contact is a spring and damper on the
    parcel's mass, m s^2 + c s + k = 0 (``ground.stiffness``; Hunt and Crossley's damping
    at rest, c = alpha m g with alpha ``ground.dissipation``: k d alpha at the static depth
    d = m g / k), and the
    friction, regularised below FRICTION_SPEED, a pole at -mu g / FRICTION_SPEED. The hover's
    poles (:func:`step_size_warning`) do not hold them: the parcel hangs clear. Past RK4's
    margin (|pole| dt > STEP_LIMIT) a contact rings or blows up (a flight ends "tilt",
    blaming the vehicle; an undamped one doubles its peak force)."""
    data = scenario.to_dict()
    ground, payload = data.get("ground", {}), data.get("payload", {})
    k = ground.get("stiffness")
    if k is None or payload.get("model") != "cable" or not payload.get("mass"):
        return ""
    dt, m = float(scenario["integrator.dt"]), float(payload["mass"])
    c = float(ground.get("dissipation", 0.0)) * m * float(scenario["environment.gravity"])
    # |pole| of m s^2 + c s + k: sqrt(k / m) for a complex pair, the larger real root's size
    # otherwise (in closed form: a mass near zero overflows to inf, which np.roots refuses).
    disc = c * c - 4.0 * m * float(k)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        contact = float(np.sqrt(float(k) / m) if disc < 0 else (c + np.sqrt(disc)) / (2.0 * m))
    if not math.isfinite(contact):
        return ""  # an absurd parcel mass: the plausibility check names it
    sliding = float(ground.get("friction", 0.0)) * float(scenario["environment.gravity"])
    sliding /= FRICTION_SPEED
    speed, what = max((contact, f"ground.stiffness = {k:g} N/m with ground.dissipation = "
                                f"{ground.get('dissipation', 0.0):g} s/m on the parcel's {m:g} kg"),
                      (sliding, f"ground.friction = {ground.get('friction', 0.0):g} (its "
                                f"regularisation below {FRICTION_SPEED:g} m/s)"))  # fmt: skip
    if speed * dt <= STEP_LIMIT:
        return ""
    return (
        f"integrator.dt = {dt:g} s is too large for the parcel's contact with the ground "
        f"({what}: |pole| = {speed:.4g} 1/s, |pole| dt = {speed * dt:.3g} > {STEP_LIMIT:g}): "
        f'the touchdown rings or blows up (a flight may end "tilt" or overstate its peak '
        f"force); use integrator.dt <= {STEP_LIMIT / speed:.3g} s or a softer ground"
    )


def _pole(real: float, imag: float) -> str:
    """``+0.04 ± 2.98j``; a real part that two decimals would show as 0.00 keeps two
    significant digits (``+3.1e-04``), so a mode called unstable never reads "+0.00"."""
    re_text = f"{real:+.2f}" if real == 0.0 or abs(real) >= 0.005 else f"{real:+.1e}"
    if abs(imag) > 0.0:
        return f"{re_text} ± {abs(imag):.2f}j"
    return re_text


@dataclass(frozen=True)
class StabilityReport:
    """Closed-loop poles of one controller at hover.

    ``verdict``: "stable" (every real part < -tolerance), "marginal" (none > tolerance, some
    within it: e.g. a position without feedback) or "unstable". ``poles``: one row per pole,
    least stable first: ``real``, ``imag`` (1/s), ``frequency_hz`` (natural frequency |s|/2pi),
    ``damping`` (-real/|s|), ``mode`` ("lateral x/pitch", "lateral y/roll", "vertical",
    "payload", "swing x", "swing y", "yaw" or "actuator"), ``dominant`` (largest
    state in the eigenvector), ``status`` and ``excited`` (whether this scenario drives the
    mode). ``lateral_sources``: what moves this scenario sideways (empty: x and y stay exactly
    zero). ``jacobian``: the closed-loop matrix (one row and column per state of the
    scenario's layout), states in ``quadrs._core.STATE_NAMES`` order for the paper's 14.
    ``residual``: |ds/dt| at the linearisation point (0 unless the closed loop has no hover
    equilibrium). ``period`` (s): where the law's loops run at rates (``controller.*_rate``),
    the poles are the discrete-time model's over one period of its schedule (each multiplier
    z as s = ln(z) / period), the holds and the sampling in them; None: the continuous law's.
    ``unmodelled_period`` (s): the loops' common period where it is too long to fly for that
    model (past ``quadrs._core.MAX_PERIOD_STEPS`` steps: a loop at a fraction of a hertz, or
    rates whose steps share no factor); the poles are then the continuous law's, and say so.
    """

    controller: str
    stable: bool
    verdict: str
    poles: pd.DataFrame
    lateral_sources: tuple[str, ...]
    tolerance: float
    jacobian: np.ndarray = field(repr=False)
    residual: float = field(default=0.0, repr=False)
    period: float | None = field(default=None, repr=False)
    unmodelled_period: float | None = field(default=None, repr=False)

    def __repr__(self) -> str:
        """One line: the verdict and the least stable pole (``print`` gives the modes)."""
        worst = self.poles.iloc[0] if len(self.poles) else None
        pole = f", least stable {_pole(worst['real'], worst['imag'])}" if worst is not None else ""
        return f"<StabilityReport {self.controller.upper()} {self.verdict}{pole}>"

    def _repr_html_(self) -> str:
        """In a notebook: the verdict and the poles, as HTML."""
        from quadrs.present.html import stability

        return stability(self)

    @property
    def unstable(self) -> pd.DataFrame:
        """The poles that are not asymptotically stable (unstable and marginal ones)."""
        return self.poles[self.poles["status"] != "stable"]

    def _unstable_modes(self) -> list[tuple[str, str, bool]]:
        """(mode, pole, excited) per non-stable mode; a complex pair is shown once."""
        rows = self.unstable
        rows = rows[rows["imag"] >= 0]
        return [
            (r.mode, _pole(r.real, r.imag) + (" (marginal)" if r.status == "marginal" else ""),
             bool(r.excited))
            for r in rows.itertuples()
        ]  # fmt: skip

    def __str__(self) -> str:
        name = self.controller.upper()
        if self.residual > 1e-6:
            name += " (no hover equilibrium: linearised at the reference point)"
        if self.period is not None:
            name += f" (sampled: the discrete-time model over {self.period * 1e3:g} ms)"
        if self.unmodelled_period is not None:
            name += (f" (the continuous law's model: its loops' common period, "
                     f"{self.unmodelled_period:.4g} s, is too long to model sampled)")  # fmt: skip
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
        if not modes:  # never a bare "UNSTABLE: "; say what the poles lack
            finite = bool(np.isfinite(self.poles[["real", "imag"]].to_numpy(float)).all())
            why = ("no mode could be named (see the poles)" if finite and len(self.poles)
                   else "the linearisation at hover has no finite poles")  # fmt: skip
            modes.append(why)
        return f"{name}: {self.verdict.upper()}: " + "; ".join(modes)

    @property
    def excited_unstable(self) -> bool:
        """True if this scenario excites a mode that is not asymptotically stable."""
        return bool(self.unstable["excited"].any())

    @property
    def excited_poles(self) -> pd.DataFrame:
        """The poles of the modes this scenario excites (the ones its flights can show)."""
        return self.poles[self.poles["excited"]]

    def excited_unstable_modes(self) -> list[str]:
        """``"mode pole"`` for each mode that this scenario excites and that is not
        asymptotically stable, e.g. ``["lateral x/pitch +1.31 ± 3.90j"]`` (a pair once)."""
        return [f"{mode} {pole}" for mode, pole, excited in self._unstable_modes() if excited]

    def warning(self) -> str:
        """The message of the :class:`StabilityWarning` for this report ("" if stable): one
        short, calm line (a :class:`StabilityNote`) when the scenario excites none of the
        unstable modes, a loud one (naming what excites them and how fast they grow) when it
        does."""
        if self.stable:
            return ""
        modes = self._unstable_modes()
        name = f"{self.controller.upper()} gains are {self.verdict.upper()} at hover"
        if not any(excited for _, _, excited in modes):
            names = ", ".join(dict.fromkeys(mode for mode, _, _ in modes))
            return (
                f"{self.controller.upper()}: unstable at hover only in modes this flight does "
                f"not excite ({names}): no effect here."
            )
        poles = ", ".join(f"{mode} {pole}" for mode, pole, excited in modes if excited)
        growth = self.unstable[self.unstable["excited"]]["real"].max()
        sources = ", ".join(self.lateral_sources)
        by = f" ({sources})" if sources else ""
        fast = f", the fastest growing e-fold every {1 / growth:.2g} s" if growth > 0 else ""
        return (
            f"{name} and this scenario EXCITES them{by}: {poles}{fast}. Expect diverged "
            "flights (flagged in the runs' diverged column); the preset paper_stable_lateral is "
            "a stable retune; see the stability analysis (quadrs.stability, `quadrs stability`)."
        )


def stability(scenario: Scenario, controller: str = "smc") -> StabilityReport:
    """Closed-loop poles of ``controller`` ("pd" or "smc") linearised at hover, with a verdict.

    ``print(quadrs.stability(s, "smc"))`` gives a one-line summary; see
    :class:`StabilityReport` for the tables.
    """
    check_controller(controller)
    raw = scenario.engine.stability(controller)
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
        period=_seconds(raw["period"]),
        unmodelled_period=_seconds(raw["unmodelled_period"]),
    )


def _seconds(value: float | None) -> float | None:
    """A period the engine gives (s), or None where it gives none."""
    return None if value is None else float(value)
