"""Closed-loop poles at hover: verdicts, hand-derived loops, excitation, the retuned preset and the
Monte Carlo warning."""

import warnings

import numpy as np
import pytest

import quadrs
from quadrs import Scenario, StabilityWarning

STATES = list(quadrs._core.STATE_NAMES)
MOVE_X = {
    "trajectory.waypoints": [[0, 0, 0, 2, 0], [5, 1, 0, 2, 0]],
    "integrator.duration": 25.0,
    "phases": [{"name": "all", "start": 0, "end": 25}],
}


def poles(report: quadrs.StabilityReport, *modes: str) -> np.ndarray:
    rows = report.poles[report.poles["mode"].isin(modes)]
    return np.sort_complex((rows["real"] + 1j * rows["imag"]).to_numpy())


def assert_same_roots(got: np.ndarray, coeffs: list[float]) -> None:
    want = np.sort_complex(np.roots(coeffs))
    assert len(got) == len(want)
    np.testing.assert_allclose(got, want, rtol=1e-7, atol=1e-9)


def smc_k(eta: float, eps: float, gamma: float) -> float:
    """Linear reaching rate of an SMC channel: eta + eps sat'(0) with sat'(0) = 1 / gamma."""
    return eta + eps / gamma


def test_paper_pd_is_stable(paper: Scenario) -> None:
    r = quadrs.stability(paper, "pd")
    assert r.stable and r.verdict == "stable"
    assert len(r.poles) == 14 and r.unstable.empty
    assert (r.poles["real"] < 0).all()
    assert str(r).startswith("PD: stable")
    assert r.warning() == ""


def test_paper_smc_is_laterally_unstable(paper: Scenario) -> None:
    r = quadrs.stability(paper, "smc")
    assert not r.stable and r.verdict == "unstable"
    top = r.poles.iloc[0]
    # MODEL.md section 2: a complex pair near +1.3 +/- 3.9j.
    assert top["real"] == pytest.approx(1.3, abs=0.2)
    assert abs(top["imag"]) == pytest.approx(3.9, abs=0.2)
    assert set(r.unstable["mode"]) == {"lateral x/pitch", "lateral y/roll"}
    assert not r.unstable["excited"].any()  # the paper flies vertically
    assert r.lateral_sources == ()
    text = str(r)
    assert text.startswith("SMC: UNSTABLE: lateral x/pitch mode +1.31 ± 3.90j")
    assert "(excited by this scenario: no)" in text


def test_report_table(paper: Scenario) -> None:
    r = quadrs.stability(paper, "smc")
    assert list(r.poles.columns) == [
        "real", "imag", "frequency_hz", "damping", "mode", "dominant", "status", "excited",
    ]  # fmt: skip
    s = r.poles["real"] + 1j * r.poles["imag"]
    np.testing.assert_allclose(r.poles["frequency_hz"], np.abs(s) / (2 * np.pi))
    np.testing.assert_allclose(r.poles["damping"], -s.to_numpy().real / np.abs(s))
    assert r.poles["real"].is_monotonic_decreasing
    assert set(r.poles["dominant"]) <= set(STATES)
    with pytest.raises(ValueError, match="controller"):
        quadrs.stability(paper, "lqr")


def test_yaw_loops_match_hand_derivation(paper: Scenario) -> None:
    # PD: Izz psi'' + kd psi' + kp psi = 0.
    pd = paper["controller.pd"]
    izz = paper["vehicle.inertia"][2]
    got = poles(quadrs.stability(paper, "pd"), "yaw")
    assert_same_roots(got, [izz, pd["kd_attitude"][2], pd["kp_attitude"][2]])
    # SMC (feedback-linearised): s^2 + (lambda + K) s + lambda K, K = eta + eps / gamma.
    g = paper["controller.smc"]
    lam = g["lambda_attitude"][2]
    k = smc_k(g["eta_attitude"][2], g["epsilon_attitude"][2], g["gamma"])
    got = poles(quadrs.stability(paper, "smc"), "yaw")
    assert_same_roots(got, [1.0, lam + k, lam * k])
    np.testing.assert_allclose(got.real, [-5.54, -1.5])


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_vertical_loop_matches_fourth_order_polynomial(paper: Scenario, controller: str) -> None:
    s = paper.override({"payload.damping": 0.2})
    m, mc, kc, cc = s["vehicle.mass"], s["payload.mass"], s.stiffness, 0.2
    if controller == "pd":
        a, b = s["controller.pd.kp"][2], s["controller.pd.kd"][2]
    else:
        g = s["controller.smc"]
        k = smc_k(g["eta"][2], g["epsilon"][2], g["gamma"])
        a, b = g["lambda"][2] * k, g["lambda"][2] + k
    # (m s^2 + mt (b s + a) + k(s)) (mc s^2 + k(s)) - k(s)^2, k(s) = kc + cc s, mt = m + mc.
    quad = np.poly1d([m, (m + mc) * b + cc, (m + mc) * a + kc])
    spring = np.poly1d([cc, kc])
    char = quad * np.poly1d([mc, cc, kc]) - spring * spring
    got = poles(quadrs.stability(s, controller), "vertical", "payload")
    assert_same_roots(got, list(char.coeffs))


def test_jacobian_entries(paper: Scenario) -> None:
    r = quadrs.stability(paper, "smc")
    jac = r.jacobian
    i = {name: k for k, name in enumerate(STATES)}
    g = paper["environment.gravity"]
    assert jac[i["vx"], i["theta"]] == pytest.approx(g, rel=1e-12)  # x'' = g theta at hover
    assert jac[i["vy"], i["phi"]] == pytest.approx(-g, rel=1e-12)
    assert jac[i["z"], i["vz"]] == 1.0
    assert jac[i["vzc"], i["z"]] == pytest.approx(paper.stiffness / paper["payload.mass"])


def test_marginal_when_a_position_has_no_feedback(paper: Scenario) -> None:
    r = quadrs.stability(paper.override({"controller.pd.kp": [0.0, 1.6, 1.5]}), "pd")
    assert not r.stable and r.verdict == "marginal"
    assert list(r.unstable["mode"]) == ["lateral x/pitch"]
    assert r.unstable["real"].iloc[0] == 0.0
    assert str(r).startswith("PD: MARGINAL: lateral x/pitch mode +0.00")


def test_no_mass_compensation_is_linearised_at_its_droop(paper: Scenario) -> None:
    r = quadrs.stability(paper.override({"controller.mass_compensation": False}), "pd")
    assert r.stable and r.residual < 1e-9


@pytest.mark.parametrize(
    ("changes", "source"),
    [
        ({"trajectory.waypoints": [[0, 0, 0, 2, 0], [30, 0, 1, 2, 0]]}, "waypoints move in x/y"),
        ({"initial.position": [0.5, 0.0, 0.0]}, "initial x/y off the first waypoint"),
        ({"initial.attitude": [0.0, 0.01, 0.5]}, "initial roll/pitch"),
        ({"gust.components": ["longitudinal"]}, "horizontal gust components"),
        ({"gust.mean_wind": [0.0, 2.0, 0.0]}, "horizontal mean wind"),
    ],
)
def test_lateral_sources_excite_lateral_modes(
    paper: Scenario, changes: dict[str, object], source: str
) -> None:
    r = quadrs.stability(paper.override(changes), "smc")
    assert r.lateral_sources == (source,)
    assert r.unstable["excited"].all()
    assert f"(excited by this scenario: yes: {source})" in str(r)


@pytest.mark.parametrize(
    "changes",
    [
        {"gust.enabled": False, "gust.components": ["lateral"]},
        {"gust.end": 25.0, "gust.mean_wind": [3.0, 0.0, 0.0]},  # empty window
        {"trajectory.waypoints": [[0, 0, 0, 2, 0], [30, 0, 0, 5, 1.0]]},  # climb and yaw only
    ],
)
def test_vertical_flight_does_not_excite_lateral_modes(
    paper: Scenario, changes: dict[str, object]
) -> None:
    r = quadrs.stability(paper.override(changes), "smc")
    assert r.lateral_sources == ()
    lateral = r.poles["mode"].str.startswith("lateral")
    assert not r.poles.loc[lateral, "excited"].any()
    assert r.poles.loc[~lateral, "excited"].all()  # vertical, payload, yaw: always


def test_retuned_preset_is_stable_and_keeps_the_paper_elsewhere(paper: Scenario) -> None:
    s = Scenario.preset("paper_stable_lateral")
    r = quadrs.stability(s, "smc")
    assert r.stable
    lateral = r.poles[r.poles["mode"].str.startswith("lateral")]
    assert len(lateral) == 8 and (lateral["damping"] >= 0.5).all()
    # The inner (attitude) loop is well separated from the outer (position) one: its fastest
    # pole is >= 5x the slowest lateral pole.
    speed = np.abs(lateral["real"])
    assert speed.max() >= 5 * speed.min()
    # Only the SMC's x, y, roll, pitch entries differ from the paper; z and yaw are the paper's.
    mine, theirs = s.to_dict(), paper.to_dict()
    smc, paper_smc = mine["controller"].pop("smc"), theirs["controller"].pop("smc")
    assert mine == theirs
    assert smc["gamma"] == paper_smc["gamma"]
    for key in ("epsilon", "lambda", "eta", "epsilon_attitude", "lambda_attitude", "eta_attitude"):
        assert smc[key][2] == paper_smc[key][2], key
    # Vertical and yaw poles are therefore the paper's exactly.
    old = quadrs.stability(paper, "smc")
    for mode in ("vertical", "payload", "yaw"):
        np.testing.assert_allclose(poles(r, mode), poles(old, mode), rtol=1e-12)


def test_lateral_move_diverges_with_paper_smc_and_not_with_the_retune(paper: Scenario) -> None:
    with pytest.warns(StabilityWarning, match="EXCITES them"):  # loud, even for one flight
        bad = quadrs.simulate(paper.override(MOVE_X), "smc", record_every=50)
    err = (bad.trace["x"] - bad.trace["x_ref"]).abs()
    assert bad.diverged or err.max() > 10.0
    good = quadrs.simulate(Scenario.preset("paper_stable_lateral").override(MOVE_X), "smc")
    assert not good.diverged
    tr = good.trace
    err = (tr["x"] - tr["x_ref"]).abs()
    assert tr["x"].max() < 1.0 + 1e-3  # no overshoot
    assert err.loc[20.0:].max() < 1e-3  # settled 15 s after the step
    assert tr[["phi", "theta"]].abs().max().max() < 0.2


def mc_warnings(scenario: Scenario, controllers: tuple[str, ...]) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        quadrs.monte_carlo(scenario, runs=1, controllers=controllers, workers=1, progress=False)
    return [str(w.message) for w in caught if issubclass(w.category, StabilityWarning)]


def test_monte_carlo_warns_on_excited_unstable_smc(short: Scenario) -> None:
    (msg,) = mc_warnings(short.override({"gust.components": ["vertical", "lateral"]}), ("smc",))
    assert msg.startswith("SMC gains are UNSTABLE at hover and this scenario EXCITES them")
    assert "(horizontal gust components): lateral x/pitch +1.31 ± 3.90j" in msg
    assert "e-fold every 0.76 s" in msg  # 1 / 1.31
    assert "does not excite" not in msg and "diverged" in msg


def test_monte_carlo_warns_on_unexcited_unstable_smc(short: Scenario) -> None:
    (msg,) = mc_warnings(short, ("pd", "smc"))
    assert msg.startswith("SMC: unstable at hover only in modes this flight does not excite")
    assert "\n" not in msg and len(msg) < 160  # one short line


def test_monte_carlo_stays_quiet_for_stable_gains(short: Scenario) -> None:
    assert mc_warnings(short, ("pd",)) == []
    keys = ("integrator.duration", "integrator.dt", "trajectory.waypoints", "phases")
    retuned = Scenario.preset("paper_stable_lateral").override(
        {k: short[k] for k in (*keys, "gust.start", "gust.end")}
    )
    assert mc_warnings(retuned, ("pd", "smc")) == []


@pytest.mark.parametrize(
    ("changes", "source"),
    [
        ({"gust.components": ["vertical", "longitudinal"]}, "horizontal gust components"),
        ({"trajectory.waypoints": [[0, 0, 0, 2, 0], [3, 0, 0.5, 2, 0]]}, "waypoints move"),
        ({"initial.position": [0.05, 0.0, 0.0]}, "initial x/y off the first waypoint"),
        ({"initial.attitude": [0.01, 0.0, 0.5]}, "initial roll/pitch"),
    ],
)
def test_a_single_flight_that_excites_unstable_modes_warns_loudly_and_diverges(
    short: Scenario, changes: dict, source: str
) -> None:
    s = short.override({**changes, "integrator.duration": 12.0})
    with pytest.warns(StabilityWarning, match=f"EXCITES them \\({source}"):
        flight = quadrs.simulate(s, "smc", record_every=100)

    def drift(f: quadrs.Flight) -> float:  # m, the largest lateral excursion
        return float(np.hypot(f.trace["x"], f.trace["y"]).max())

    assert flight.diverged or drift(flight) > 2.0  # the warning was right: a runaway
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # PD is stable: no warning at all
        steady = quadrs.simulate(s, "pd", record_every=100)
    assert not steady.diverged and drift(steady) < 0.6


def test_a_vertical_single_flight_does_not_warn_about_unexcited_modes(short: Scenario) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not quadrs.simulate(short, "smc", record_every=100).diverged


def axis_of(mode: str) -> str:
    return "x" if mode.startswith(("lateral x", "swing x")) else "y"


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_a_symmetric_vehicle_names_each_repeated_mode_once_per_axis(controller: str) -> None:
    """The delivery vehicle is symmetric in x and y (equal inertias and gains, a round sling):
    every lateral and swing pole comes twice, and the pair is one mode in x and one in y,
    whichever basis of the repeated eigenvalue's plane the eigensolver returns."""
    s = Scenario.preset("delivery")
    assert s["vehicle.inertia"][0] == s["vehicle.inertia"][1]
    poles = quadrs.stability(s, controller).poles
    sideways = poles[poles["mode"].str.startswith(("lateral", "swing"))]
    assert set(sideways["mode"].str.split().str[0]) == {"lateral", "swing"}
    z = sideways["real"].to_numpy() + 1j * sideways["imag"].to_numpy()
    modes = sideways["mode"].to_numpy()
    unpaired = list(range(len(z)))
    while unpaired:
        i = unpaired.pop(0)
        j = min(unpaired, key=lambda k: abs(z[k] - z[i]))
        assert abs(z[j] - z[i]) < 1e-6 * max(1.0, abs(z[i])), f"{z[i]} has no twin"
        unpaired.remove(j)
        assert modes[i].split()[0] == modes[j].split()[0], (modes[i], modes[j])
        assert {axis_of(modes[i]), axis_of(modes[j])} == {"x", "y"}, (z[i], modes[i], modes[j])
