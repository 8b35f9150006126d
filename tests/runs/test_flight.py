"""Single flights: equilibria, mass compensation, determinism, the trace and metric tables."""

import numpy as np
import pytest

import quadrs
from quadrs import Scenario

STATES = ["x", "y", "z", "phi", "theta", "psi", "zc", "vx", "vy", "vz", "p", "q", "r", "vzc"]
TRACE = [*STATES, "x_ref", "y_ref", "z_ref", "psi_ref", "U1", "tau_phi", "tau_theta",
         "tau_psi", "wind_x", "wind_y", "wind_z", "e_o", "accel_c", "drag_z", "swing",
         "tension"]  # fmt: skip
#: The metrics table: the phase, then the engine's metric columns (rust/src/metrics.rs).
METRICS = ["phase", *quadrs._core.METRIC_NAMES]


def hover(paper: Scenario) -> Scenario:
    return paper.override(
        {
            "gust.enabled": False,
            "initial.position": [0.5, -1.0, 2.0],
            "initial.attitude": [0.0, 0.0, 0.0],
            "trajectory.waypoints": [[0, 0.5, -1.0, 2.0, 0.0], [10, 0.5, -1.0, 2.0, 0.0]],
            "integrator.duration": 10.0,
            "phases": [{"name": "all", "start": 0.0, "end": 10.0}],
        }
    )


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_hover_equilibrium_stays_put(paper: Scenario, controller: str) -> None:
    s = hover(paper)
    f = quadrs.simulate(s, controller, record_every=500)
    start = f.trace.iloc[0][STATES].to_numpy()
    drift = np.abs(f.trace[STATES].to_numpy() - start).max()
    assert drift < 1e-9, drift
    assert start[6] == pytest.approx(2.0 - s.hover_offset, abs=1e-15)
    assert f.metrics["iae"].iloc[0] < 1e-9


@pytest.mark.parametrize(
    ("compensate", "offset"), [(False, 0.22 * 9.81 / (2.2 * 1.5)), (True, 0.0)]
)
def test_mass_compensation_offset(paper: Scenario, compensate: bool, offset: float) -> None:
    """The paper's Fig. 16: PD without compensation settles mc g / (m kpz) below the reference."""
    s = paper.override({"gust.enabled": False, "controller.mass_compensation": compensate})
    f = quadrs.simulate(s, "pd", record_every=50)
    z_settled = f.trace.loc[15.0:19.9, "z"]
    assert z_settled.mean() == pytest.approx(2.0 - offset, abs=1e-3)
    assert np.ptp(z_settled) < 1e-3
    if not compensate:
        assert offset == pytest.approx(0.654, abs=1e-3)


def test_paper_preset_without_gust(paper: Scenario) -> None:
    s = paper.override({"gust.enabled": False})
    pd_f = quadrs.simulate(s, "pd")
    smc_f = quadrs.simulate(s, "smc")
    for f in (pd_f, smc_f):
        assert list(f.metrics.columns) == METRICS
        assert list(f.metrics["phase"]) == ["P1", "P2", "P3", "flight"]
        events = list(quadrs._core.EVENT_METRICS)  # no touchdown or release in the paper
        assert f.metrics[events].isna().all().all()
        assert np.isfinite(f.metrics.drop(columns=["phase", *events]).to_numpy()).all()
        assert not f.diverged
    p1 = lambda f: f.metrics.set_index("phase").loc["P1", "iae"]  # noqa: E731
    assert p1(smc_f) < p1(pd_f)
    again = quadrs.simulate(s, "smc")
    assert again.metrics.equals(smc_f.metrics)
    assert again.trace.equals(smc_f.trace)


def test_trace_layout(short: Scenario) -> None:
    f = quadrs.simulate(short, "smc", record_every=1)
    assert list(f.trace.columns) == TRACE
    assert f.trace.index.name == "t"
    assert len(f.trace) == short.steps + 1
    assert f.trace.index[-1] == pytest.approx(short["integrator.duration"])
    # e_o is the payload's displacement from its hover equilibrium relative to the quadrotor
    e = f.trace["zc"] - f.trace["z"] + short.hover_offset
    np.testing.assert_allclose(f.trace["e_o"], e, atol=1e-15)
    assert f.trace["z_ref"].iloc[0] == 2.0 and f.trace["z_ref"].iloc[-1] == 0.0
    thinned = quadrs.simulate(short, "smc", record_every=10)
    assert len(thinned.trace) == short.steps // 10 + 1
    np.testing.assert_array_equal(thinned.trace.to_numpy(), f.trace.iloc[::10].to_numpy())


def test_metrics_match_the_trace(short: Scenario) -> None:
    """IAE/ITAE/max/RMS recomputed from the full-rate trace with numpy's trapezoid."""
    f = quadrs.simulate(short, "pd", record_every=1)
    m = f.metrics.set_index("phase")
    for name, (a, b) in {"P1": (0, 2), "P2": (2, 4), "P3": (4, 6)}.items():
        part = f.trace.loc[a - 1e-9 : b + 1e-9]
        t, e = part.index.to_numpy(), part["e_o"].to_numpy()
        assert m.loc[name, "iae"] == pytest.approx(np.trapezoid(np.abs(e), t), rel=1e-12)
        assert m.loc[name, "itae"] == pytest.approx(np.trapezoid(t * np.abs(e), t), rel=1e-12)
        assert m.loc[name, "max_abs"] == pytest.approx(np.abs(e).max(), rel=1e-15)
        rms = np.sqrt(np.trapezoid(e**2, t) / (b - a))
        assert m.loc[name, "rms"] == pytest.approx(rms, rel=1e-12)
        trk = np.sqrt(np.trapezoid((part["z_ref"] - part["z"]) ** 2, t) / (b - a))
        assert m.loc[name, "tracking_rms"] == pytest.approx(trk, rel=1e-12)


def test_spectral_peak_near_the_attachment_mode(paper: Scenario) -> None:
    """Take-off excites the payload: the P1 spectrum peaks near the two-body frequency
    fn sqrt((m + mc) / m) (closed-loop coupling shifts it a little)."""
    f = quadrs.simulate(paper.override({"gust.enabled": False}), "pd")
    peak = f.metrics.set_index("phase").loc["P1", "peak_frequency"]
    assert peak == pytest.approx(2.0 * np.sqrt(2.42 / 2.2), abs=0.15)
    spec = f.spectra["P1"]
    assert list(spec.columns) == ["frequency", "amplitude"]
    assert spec["amplitude"].idxmax() == spec.index[spec["frequency"] == peak][0]


def test_bad_call_arguments(short: Scenario) -> None:
    with pytest.raises(ValueError, match="controller"):
        quadrs.simulate(short, "lqr")
    with pytest.raises(ValueError, match="record_every"):
        quadrs.simulate(short, "pd", record_every=0)


def test_every_metric_has_a_unit_and_a_label_from_the_engine() -> None:
    """The engine defines each metric once (name, unit, label); figures read them from it."""
    from quadrs.present.labels import PLAIN_LABELS, UNITS

    names = list(quadrs._core.METRIC_NAMES)
    assert list(quadrs._core.METRIC_UNITS) == names
    assert list(quadrs._core.METRIC_LABELS) == names
    for m in names:
        assert quadrs._core.METRIC_UNITS[m].strip() and quadrs._core.METRIC_LABELS[m].strip(), m
        assert PLAIN_LABELS[m] == f"{quadrs._core.METRIC_LABELS[m]} ({UNITS[m]})"
    assert UNITS["max_swing"] == "deg" and quadrs._core.METRIC_UNITS["max_swing"] == "rad"
    assert PLAIN_LABELS["max_accel"] == "Payload acceleration peak (m/s²)"
