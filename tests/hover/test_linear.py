"""quadrs.linearize: the closed loop at hover as A, B, C, D, checked against the stability
analysis (same Jacobian) and against flights with a prescribed sinusoidal wind."""

from __future__ import annotations

import math

import numpy as np
import pytest

import quadrs
from quadrs.hover.linear import OUTPUT_NAMES, LinearModel, equivalent_wind, linearize

T = 24.0
DT = 1e-3


def hover(duration: float = T) -> quadrs.Scenario:
    """Hover at 2 m from t = 0 (no take-off), no gust, a lightly damped payload."""
    return quadrs.Scenario.paper().override(
        {
            "initial.position": [0.0, 0.0, 2.0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.waypoints": [[0.0, 0.0, 0.0, 2.0, 0.0], [duration, 0.0, 0.0, 2.0, 0.0]],
            "phases": [{"name": "all", "start": 0.0, "end": duration}],
            "gust.enabled": False,
            "integrator.dt": DT,
            "integrator.duration": duration,
            "payload.damping": 0.5,
        }
    )


def match_poles(a: np.ndarray, b: np.ndarray) -> float:
    """Largest relative distance between the multisets a and b (greedy nearest matching)."""
    rest = list(b)
    worst = 0.0
    for x in a:
        k = int(np.argmin([abs(x - y) for y in rest]))
        worst = max(worst, abs(x - rest[k]) / max(abs(x), 1e-300))
        rest.pop(k)
    return worst


@pytest.mark.parametrize("preset", ["paper", "paper_stable_lateral"])
@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_eigenvalues_of_a_are_the_stability_poles(preset: str, controller: str) -> None:
    s = quadrs.Scenario.preset(preset)
    lin = linearize(s, controller)
    rep = quadrs.stability(s, controller)
    poles = rep.poles["real"].to_numpy() + 1j * rep.poles["imag"].to_numpy()
    assert lin.A.shape == (14, 14)
    assert match_poles(lin.poles(), poles) < 1e-9
    assert match_poles(poles, lin.poles()) < 1e-9


@pytest.mark.parametrize("controller", ["pd", "smc", "px4", "se3"])
def test_the_rigid_body_linearises_without_its_dependent_quaternion_part(controller: str) -> None:
    """The delivery preset (rigid body, rotors, cable with winch): `linearize` raised a bare
    AssertionError on it (it expected every state of `scenario.state_names` among the
    outputs; the linearisation has no `qw`, which the unit quaternion fixes). Its A's poles
    are the stability analysis's, and every output can be asked for by name or as "all"."""
    s = quadrs.Scenario.preset("delivery")
    # The continuous law's model against the continuous law's poles: PX4's own loop rates
    # (its default) make the stability analysis the sampled law's (tests/engine/test_rates.py).
    s = s.override({"controller.position_rate": 0.0, "controller.attitude_rate": 0.0,
                    "controller.inner_rate": 0.0})  # fmt: skip
    lin = linearize(s, controller, inputs=("wind_x", "wind_y", "wind_z"), outputs="all")
    states = tuple(n for n in s.state_names if n != "qw")
    assert lin.state_names == states and lin.A.shape == (len(states), len(states))
    assert lin.output_names == (*states, *OUTPUT_NAMES[14:])
    rep = quadrs.stability(s, controller)
    poles = rep.poles["real"].to_numpy() + 1j * rep.poles["imag"].to_numpy()
    # The x and y modes are equal pairs (a double root moves by ~sqrt(eps) of A's scale
    # between two eigen-solvers: the stability analysis solves block by block).
    assert match_poles(lin.poles(), poles) < 1e-5 and match_poles(poles, lin.poles()) < 1e-5
    swing = linearize(s, controller, outputs=("e_o", "xc", "omega_1"))
    assert swing.output_names == ("e_o", "xc", "omega_1")
    np.testing.assert_array_equal(swing.C, lin.C[[lin.output_names.index(n) for n in
                                                  ("e_o", "xc", "omega_1")]])  # fmt: skip
    with pytest.raises(ValueError, match="outputs must be among"):
        linearize(s, controller, outputs=("qw",))


def test_still_air_has_no_first_order_wind_input_and_outputs_are_named() -> None:
    lin = linearize(
        quadrs.Scenario.paper(), "pd", inputs=("wind_x", "wind_y", "wind_z"), outputs=OUTPUT_NAMES
    )
    assert isinstance(lin, LinearModel)
    assert lin.B.shape == (14, 3) and lin.C.shape == (20, 14) and lin.D.shape == (20, 3)
    assert not lin.B.any() and not lin.D.any()
    np.testing.assert_array_equal(lin.C[:14], np.eye(14))
    eo = lin.C[lin.output_names.index("e_o")]
    assert eo[lin.state_names.index("zc")] == 1.0 and eo[lin.state_names.index("z")] == -1.0


def test_bad_signal_names_are_rejected() -> None:
    s = quadrs.Scenario.paper()
    with pytest.raises(ValueError, match="inputs"):
        linearize(s, "pd", inputs=("gust",))
    with pytest.raises(ValueError, match="outputs"):
        linearize(s, "pd", outputs=("e_x",))
    with pytest.raises(ValueError, match="controller"):
        linearize(s, "lqr")
    with pytest.raises(ValueError, match="wind"):
        linearize(s, "pd", wind=(0.0, math.nan, 1.0))


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_frequency_response_matches_flights_with_a_sinusoidal_wind(controller: str) -> None:
    """A small sine on a steady updraft: the e_o amplitude and phase measured from the
    nonlinear flight (least-squares fit over the last 8 s, transients gone) match G(j w)."""
    s = hover()
    w0, amp = 2.0, 0.05
    lin = linearize(s, controller, inputs="wind_z", outputs="e_o", wind=(0.0, 0.0, w0))
    t = np.arange(s.steps + 1) * DT
    for f in (0.5, 2.0, 5.0):
        wind = np.zeros((t.size, 3))
        wind[:, 2] = w0 + amp * np.sin(2 * np.pi * f * t)
        trace = quadrs.simulate(s, controller, wind=wind, record_every=1).trace
        # Row k holds step k's wind; the closing row, which no step follows, the last step's.
        held = np.r_[wind[:-1, 2], wind[-2, 2]]
        np.testing.assert_allclose(trace["wind_z"].to_numpy(), held)
        tt = trace.index.to_numpy()
        m = tt >= T - 8.0
        x = np.column_stack(
            [np.sin(2 * np.pi * f * tt[m]), np.cos(2 * np.pi * f * tt[m]), np.ones(m.sum())]
        )
        c, *_ = np.linalg.lstsq(x, trace["e_o"].to_numpy()[m], rcond=None)
        measured = (c[0] + 1j * c[1]) / amp
        g = lin.frequency_response([f])[0, 0, 0]
        assert abs(g) > 1e-4  # a real response, not 0 = 0
        assert abs(abs(measured) / abs(g) - 1.0) < 0.02, (f, measured, g)
        # The held controls and wind lag by dt/2: the only phase difference expected.
        delay = 2 * np.pi * f * DT / 2
        assert abs(np.angle(measured / g) + delay) < 0.01, (f, np.angle(measured / g), delay)


def test_prescribed_wind_equals_the_same_steady_wind_from_the_gust_block() -> None:
    """Two independent paths to a steady wind inside a window: the gust block's mean wind
    with zero turbulence, and the prescribed wind array. Same flight, bit for bit."""
    s = hover(4.0).override(
        {
            "gust.enabled": True,
            "gust.w20": 0.0,
            "gust.start": 1.0,
            "gust.end": 3.0,
            "gust.mean_wind": [0.5, -0.2, 1.5],
        }
    )
    t = np.arange(s.steps + 1) * DT
    wind = np.zeros((t.size, 3))
    inside = (np.arange(t.size) >= 1000) & (np.arange(t.size) < 3000)
    wind[inside] = [0.5, -0.2, 1.5]
    a = quadrs.simulate(s, "pd", record_every=1).trace
    b = quadrs.simulate(s, "pd", record_every=1, wind=wind).trace
    np.testing.assert_array_equal(a["wind_z"].to_numpy(), b["wind_z"].to_numpy())
    np.testing.assert_array_equal(a.to_numpy(), b.to_numpy())


def test_prescribed_wind_of_the_wrong_shape_is_refused() -> None:
    s = hover(1.0)
    with pytest.raises(ValueError, match="rows"):
        quadrs.simulate(s, "pd", wind=np.zeros((10, 3)))
    with pytest.raises(ValueError, match="shape"):
        quadrs.simulate(s, "pd", wind=np.zeros((s.steps + 1, 2)))
    bad = np.zeros((s.steps + 1, 3))
    bad[5, 1] = np.inf
    with pytest.raises(ValueError, match="finite"):
        quadrs.simulate(s, "pd", wind=bad)


def test_equivalent_wind_is_the_booton_gain_of_the_vertical_gust() -> None:
    s = quadrs.Scenario.paper()  # sigma_z = 0.1 w20 = 1 m/s
    assert equivalent_wind(s) == pytest.approx(math.sqrt(2 / math.pi), rel=1e-12)
    assert equivalent_wind(s.override({"gust.enabled": False})) == 0.0


def test_to_control_is_the_same_system() -> None:
    control = pytest.importorskip("control")
    lin = linearize(quadrs.Scenario.paper(), "pd", wind=(0.0, 0.0, 1.0))
    sys = lin.to_control()
    assert isinstance(sys, control.StateSpace)
    g = control.frequency_response(sys, [2 * np.pi * 2.0])
    np.testing.assert_allclose(
        complex(g.complex.ravel()[0]), lin.frequency_response([2.0])[0, 0, 0], rtol=1e-9
    )
