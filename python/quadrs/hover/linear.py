"""The closed loop linearised at hover as a state-space model: :func:`linearize`.

The engine (rust/src/stability.rs) linearises ds/dt = f(s, u(s, r), w) at the hover
equilibrium in a steady wind ``wind`` with an exact (dual-number) Jacobian: the same
linearisation :func:`quadrs.stability` takes its poles from. A is the continuous-time closed
loop with the controls as static functions of the state (the controllers have no internal
states; the zero-order hold of the digital controller, a dt/2 delay, is neglected), so in
still air eig(A) are exactly the poles :func:`quadrs.stability` reports. See
docs/design-loop.md.

Drag is quadratic in the relative velocity, so in still air (the default) a small wind acts
only at second order and B = 0. To study gust transmission linearise about a steady wind: the
drag slope is then rho CdA |w0| per body. :func:`equivalent_wind` gives the steady vertical
wind whose slope equals the statistical-linearisation gain of a zero-mean Gaussian gust.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from quadrs import _core
from quadrs.engine.calls import check_controller, is_sampled, loop_rates
from quadrs.scenario.scenario import Scenario


class SampledLawNote(UserWarning):
    """The linear model of a law whose loops run at rates is the continuous law's."""


#: Every input :func:`linearize` accepts (m/s, inertial, z up).
INPUT_NAMES: tuple[str, ...] = ("wind_x", "wind_y", "wind_z")
#: Every output of the paper's vehicle: its 14 states, e_o (m), the controls U1 (N) and
#: tau_* (N m), and ``azc``, the payload's vertical inertial acceleration d(vzc)/dt (m/s^2).
#: Another payload or actuator model has its own states first (``scenario.state_names``).
OUTPUT_NAMES: tuple[str, ...] = (
    *_core.STATE_NAMES,
    "e_o",
    "U1",
    "tau_phi",
    "tau_theta",
    "tau_psi",
    "azc",
)


@dataclass(frozen=True)
class LinearModel:
    """ds/dt = A ds + B du, dy = C ds + D du: deviations from the hover equilibrium.

    ``state_names`` label A's rows and columns (the scenario's states; a rigid body's without
    its dependent ``qw``), ``input_names`` B's and D's
    columns, ``output_names`` C's and D's rows. ``equilibrium`` is the state linearised at and
    ``wind`` the steady wind (m/s) about which the inputs deviate. Time in seconds.
    """

    A: npt.NDArray[np.float64]
    B: npt.NDArray[np.float64]
    C: npt.NDArray[np.float64]
    D: npt.NDArray[np.float64]
    state_names: tuple[str, ...]
    input_names: tuple[str, ...]
    output_names: tuple[str, ...]
    controller: str
    wind: tuple[float, float, float]
    equilibrium: npt.NDArray[np.float64]

    def __repr__(self) -> str:
        """The sizes and names, not the matrices."""
        return (
            f"<LinearModel {self.controller.upper()} at hover: {len(self.state_names)} states, "
            f"inputs {', '.join(self.input_names)}; outputs {', '.join(self.output_names)}>"
        )

    def poles(self) -> npt.NDArray[np.inexact[Any]]:
        """Eigenvalues of A (1/s), sorted by real part, largest first."""
        ev = np.linalg.eigvals(self.A)
        return ev[np.lexsort((-ev.imag, -ev.real))]

    def frequency_response(self, freqs_hz: npt.ArrayLike) -> npt.NDArray[np.complex128]:
        """G(j 2 pi f) = C (j w I - A)^-1 B + D, shape (len(freqs), outputs, inputs).

        Units: output unit per input unit (e.g. m of e_o per m/s of wind).
        """
        f = np.atleast_1d(np.asarray(freqs_hz, dtype=float))
        n = self.A.shape[0]
        out = np.empty((f.size, self.C.shape[0], self.B.shape[1]), dtype=complex)
        for k, fk in enumerate(f):
            jw = 2j * math.pi * fk
            out[k] = self.C @ np.linalg.solve(jw * np.eye(n) - self.A, self.B) + self.D
        return out

    def to_control(self) -> Any:
        """The model as a python-control ``StateSpace`` (``pip install 'quadrs[control]'``)."""
        try:
            import control
        except ImportError as e:  # pragma: no cover - depends on the environment
            raise ImportError(
                "LinearModel.to_control needs python-control: pip install 'quadrs[control]'"
            ) from e
        return control.ss(
            self.A,
            self.B,
            self.C,
            self.D,
            states=list(self.state_names),
            inputs=list(self.input_names),
            outputs=list(self.output_names),
        )


def _select(names: Sequence[str] | str, allowed: tuple[str, ...], what: str) -> list[int]:
    if isinstance(names, str):
        names = (names,)
    if len(names) == 0:
        raise ValueError(f"{what} must name at least one of {allowed}")
    out = []
    for name in names:
        if name not in allowed:
            raise ValueError(f"{what} must be among {allowed}, got {name!r}")
        out.append(allowed.index(name))
    return out


def linearize(
    scenario: Scenario,
    controller: str = "smc",
    inputs: Sequence[str] | str = ("wind_z",),
    outputs: Sequence[str] | str = ("e_o",),
    *,
    wind: Sequence[float] = (0.0, 0.0, 0.0),
) -> LinearModel:
    """The closed loop of ``controller`` linearised at hover: A, B, C, D.

    ``inputs`` from :data:`INPUT_NAMES`; ``outputs`` from the linearised states and
    :data:`OUTPUT_NAMES`' e_o, U1, tau_*, azc, or ``"all"`` for every one of them. The states
    are the scenario's (``scenario.state_names``) but for the rigid body's ``qw``, which its
    unit quaternion fixes (``LinearModel.state_names``); all of them are kept. ``wind`` (m/s,
    [x, y, z]) is the steady wind linearised about: in still air B = 0 (quadratic drag has no
    slope there), see :func:`equivalent_wind`.

    The model is the continuous law's: where the law's loops run at rates
    (``controller.*_rate``) it leaves their sampling and holds out (a
    :class:`~quadrs.SampledLawNote` says so); :func:`quadrs.stability` models them.
    """
    check_controller(controller)
    if is_sampled(scenario, controller):
        rates = ", ".join(f"{r:g}" for r in loop_rates(scenario, controller))
        warnings.warn(
            f"{controller}: the linear model is the continuous law's; its loops run at "
            f"{rates} Hz (position, attitude, inner), whose sampling and holds it leaves out "
            "(quadrs.stability models them)",
            SampledLawNote,
            stacklevel=2,
        )
    w = tuple(float(x) for x in wind)
    if len(w) != 3:
        raise ValueError(f"wind must have 3 components (x, y, z), got {wind!r}")
    cols = _select(inputs, INPUT_NAMES, "inputs")
    if not all(math.isfinite(x) for x in w):
        raise ValueError(f"wind must be finite, got {wind!r}")
    raw = scenario.engine.linearize(controller, list(w))
    # The engine's outputs: the linearised states (a rigid body's dependent qw left out),
    # then e_o, U1, tau_*, azc.
    names = tuple(raw["output_names"])
    assert names[len(raw["state_names"]) :] == OUTPUT_NAMES[len(_core.STATE_NAMES) :], names
    rows = list(range(len(names))) if outputs == "all" else _select(outputs, names, "outputs")
    bad = [m for m in ("A", "B", "C", "D") if not np.all(np.isfinite(raw[m]))]
    if bad or not np.all(np.isfinite(raw["equilibrium"])):
        # No trim exists (the thrust cannot balance such a wind) or its slopes overflow:
        # say so, naming the input, rather than hand back inf/NaN matrices.
        raise ValueError(
            f"wind = {list(w)} m/s: the closed loop of {controller} has no finite "
            f"linearisation about it ({', '.join(bad) or 'the equilibrium'} not finite); "
            "choose a smaller wind"
        )
    return LinearModel(
        A=raw["A"],
        B=raw["B"][:, cols],
        C=raw["C"][rows, :],
        D=raw["D"][np.ix_(rows, cols)],
        state_names=tuple(raw["state_names"]),
        input_names=tuple(INPUT_NAMES[c] for c in cols),
        output_names=tuple(names[r] for r in rows),
        controller=controller,
        wind=(w[0], w[1], w[2]),
        equilibrium=raw["equilibrium"],
    )


def equivalent_wind(scenario: Scenario) -> float:
    """The steady vertical wind (m/s) to linearise gust transmission about.

    For a zero-mean Gaussian gust of intensity sigma_z, the statistical-linearisation
    (Booton) gain of w|w| is E[2|w|] = 2 sigma_z sqrt(2/pi): the exact slope at a steady wind
    of sigma_z sqrt(2/pi). Returns that wind for the scenario's vertical gust (0 without one).
    """
    comps = scenario["gust.components"]
    if not scenario["gust.enabled"] or "vertical" not in comps:
        return 0.0
    # sigma_z = 0.1 W20 at every altitude: any altitude serves (gust.altitude may be "vehicle").
    sigma = _core.low_altitude_scales(10.0, scenario.turbulence_w20)
    return float(sigma[0][2]) * math.sqrt(2.0 / math.pi)
