"""A user's first hour: summaries that fit, warnings where they matter, honest partial results."""

import subprocess
import sys
import warnings

import numpy as np
import pytest

import quadrs
from quadrs import Scenario, ScenarioError, StepSizeWarning
from quadrs.hover.stability import STEP_ACCURACY, step_error, warn_before_running


def test_reprs_summarise(short: Scenario) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", quadrs.StabilityWarning)
        mc = quadrs.monte_carlo(short, runs=2, progress=False)
    flight = quadrs.simulate(short, "pd")
    for text in (repr(flight), repr(mc)):
        assert "\n" not in text and len(text) < 250, text
    assert "2 realisations x pd/smc" in repr(mc) and "did not diverge" in repr(flight)
    assert flight.metrics["phase"].tolist() == ["P1", "P2", "P3", "flight"]
    assert flight.metrics["phase"].dtype == mc.runs["phase"].dtype  # strings in both


def test_every_result_repr_is_one_short_line(short: Scenario, tmp_path) -> None:
    """Results summarise themselves instead of dumping their frames or matrices."""
    import pandas as pd

    from quadrs.design.optimize import OptimizeResult
    from quadrs.design.sensitivity import SensitivityResult
    from quadrs.paper.pipeline import PaperOutput

    sweep = quadrs.sweep(short, {"payload.mass": [0.1, 0.2]}, runs=2, controllers=("pd",),
                         progress=False)  # fmt: skip
    indices = pd.DataFrame({"controller": ["pd"], "phase": ["P2"], "metric": ["iae"],
                            "parameter": ["payload.mass"], "S1": [0.4], "S1_conf": [0.1],
                            "ST": [0.5], "ST_conf": [0.1]})  # fmt: skip
    results = {
        "SweepResult payload.mass x2 points": sweep,
        "StabilityReport PD stable": quadrs.stability(short, "pd"),
        "StabilityReport SMC unstable": quadrs.stability(short, "smc"),
        "LinearModel PD at hover": quadrs.linearize(short, controller="pd"),
        "SensitivityResult 1 parameters": SensitivityResult(
            short, 0, 8, ("payload.mass",), indices, pd.DataFrame()
        ),
        "OptimizeResult controller.pd.kp[2]=1.5": OptimizeResult(
            {"controller.pd.kp[2]": 1.5},
            0.1,
            short,
            pd.DataFrame({"x": range(40)}),
            None,
            False,
            "nelder-mead",
            0,
            8,
        ),
        "PaperOutput 0 files": PaperOutput(tmp_path),
    }
    for start, result in results.items():
        text = repr(result)
        assert text.startswith(f"<{start}"), text
        assert "\n" not in text and len(text) < 250, text


def test_step_warning_follows_accuracy_at_the_fastest_excited_mode(paper: Scenario) -> None:
    # the indicator: half-step lag of the held controls, or RK4's own error if larger
    assert step_error(-13j, 0.01) == pytest.approx(0.065)
    z = -2.5 + 0j  # near RK4's stability bound its own error dominates
    assert step_error(z, 1.0) > abs(z) / 2
    with pytest.warns(StepSizeWarning, match=r"integrator\.dt = 0\.05 s is coarse.*payload"):
        warn_before_running(
            paper.override({"integrator.dt": 0.05}), ("pd",), gains=False, stacklevel=1
        )
    for dt in (2e-4, 2e-3):  # the paper's step and the tests' coarse one
        with warnings.catch_warnings():
            warnings.simplefilter("error", StepSizeWarning)
            warn_before_running(
                paper.override({"integrator.dt": dt}), ("pd", "smc"), gains=False, stacklevel=1
            )
    assert 13.2 * 0.0076 / 2 == pytest.approx(STEP_ACCURACY, rel=0.01)


def test_a_law_at_its_own_rates_is_not_lagged_by_the_step() -> None:
    """Before: the half-step lag of controls held over a step was charged to every law, so the
    delivery preset, whose loops all run at their own rates (their holds the model's, the same
    at any step that divides them), warned at 2 ms that its metrics depend on dt by more than
    1 %; they move by less (the convergence test of the touchdown, the rates' table in
    docs/model.md)."""
    pole = -10 + 68j
    assert step_error(pole, 0.002, held=False) < 1e-5
    assert step_error(pole, 0.002) == pytest.approx(abs(pole) * 0.001)
    delivery = Scenario.preset("delivery")
    assert not any(delivery.engine.every_step("pd"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", StepSizeWarning)
        warn_before_running(delivery, ("pd", "smc"), gains=False, stacklevel=1)
    # Its inner loop every step: the 2 ms step holds the mixer, and the lag is the step's.
    tied = delivery.override({"controller.inner_rate": 0.0})
    assert tied.engine.every_step("pd") == [False, False, True]
    with pytest.warns(StepSizeWarning, match=r"integrator\.dt = 0\.002 s is coarse.*held"):
        warn_before_running(tied, ("pd",), gains=False, stacklevel=1)


def test_diverging_in_p2_keeps_p1(short: Scenario) -> None:
    s = short.override(
        {"gust.components": ["vertical", "lateral"], "integrator.duration": 30.0,
         "phases": [{"name": "P1", "start": 0, "end": 2}, {"name": "P2", "start": 2,
                     "end": 30}]}
    )  # fmt: skip
    with pytest.warns(quadrs.StabilityWarning, match="EXCITES"):
        bad = quadrs.simulate(s, "smc", record_every=50)
    assert bad.diverged and bad.diverged_at > 2.5
    calm = quadrs.simulate(
        s.override({"gust.components": ["vertical"]}), "smc", record_every=50
    )  # the same flight until the gust: P1 is identical, P2 is NaN
    m, c = bad.metrics.set_index("phase"), calm.metrics.set_index("phase")
    np.testing.assert_array_equal(m.loc["P1"].to_numpy(), c.loc["P1"].to_numpy())
    assert m.loc["P2"].isna().all()


def test_min_jerk_paper_flight_takes_off_holds_and_lands(paper: Scenario) -> None:
    s = paper.override({"trajectory.interpolation": "min_jerk", "integrator.dt": 0.002})
    tr = quadrs.simulate(s, "pd", record_every=50).trace
    z_ref = tr["z_ref"]
    assert z_ref.loc[0.0] == 0.0 and z_ref.loc[2.5] == pytest.approx(1.0)  # 5 s climb
    assert (z_ref.loc[5.0:60.0] == 2.0).all()  # holds the cruise altitude
    assert z_ref.loc[62.5] == pytest.approx(1.0) and (z_ref.loc[65.0:] == 0.0).all()
    assert (tr["z"] - z_ref).abs().max() < 0.3  # follows it (a step starts 2 m off)
    with pytest.raises(ScenarioError, match=r"trajectory\.transition"):
        paper.override({"trajectory.transition": -1.0})


def test_version_is_fast_and_imports_nothing_heavy() -> None:
    code = (
        "import sys; from quadrs.cli.main import main; "
        "assert main(['--version']) == 0; "
        "heavy = [m for m in ('scipy.stats', 'matplotlib', 'quadrs.paper.pipeline')"
        " if m in sys.modules]; "
        "assert not heavy, heavy"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("quadrs ")
