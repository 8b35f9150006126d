"""A new user's first hour (issue 27): honest first output, plausibility checks, divergence
accounting per controller and phase, figures that line up, tune's side effects, notebook
display and the documentation's claims. One test (or more) per item."""

from __future__ import annotations

import itertools
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

import quadrs
from quadrs import plots
from quadrs.cli.main import build_parser, main
from quadrs.scenario.scenario import Scenario, presets

ROOT = Path(__file__).resolve().parents[2]

#: A 1 m sideways step at t = 2.2 s sets off the SMC's unstable lateral modes: its tilt passes
#: 0.3 rad at about 4.6 s, in P3, after P1 and P2 ended; PD makes the step within 0.2 rad.
LATERAL_STEP = {
    "trajectory.waypoints": [[0, 0, 0, 2, 0], [2.2, 1.0, 0, 2, 0], [4, 1.0, 0, 0, 0]],
    "divergence.max_tilt": 0.3,
}


def cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def scenario_file(tmp_path: Path, scenario: Scenario) -> str:
    path = tmp_path / "scenario.toml"
    path.write_text(scenario.to_toml())
    return str(path)


@pytest.fixture(scope="module")
def diverging(short: Scenario) -> quadrs.MonteCarloResult:
    s = short.override(LATERAL_STEP)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loud warning for an excited unstable mode
        return quadrs.monte_carlo(s, runs=8, seed=0, progress=False)


# -- 1. the first command's output ------------------------------------------------------------
def test_table3_says_under_its_heading_why_p_differs_from_the_paper(short: Scenario) -> None:
    from quadrs.present.table3 import format_table3

    mc = quadrs.monte_carlo(short, runs=4, progress=False)
    text = format_table3(mc.summary(), paper=True)
    head = text.splitlines()[:3]
    assert head[0].startswith("Table 3")
    assert "not the paper's" in head[1] and "docs/paper-calibration.md" in head[2]
    assert all(len(line) <= 100 for line in head)
    assert "paper-calibration" not in format_table3(mc.summary(), paper=False)


def test_unexcited_unstable_modes_give_a_short_calm_note(short: Scenario) -> None:
    from quadrs.hover.stability import StabilityNote

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        quadrs.monte_carlo(short, runs=1, progress=False)
    notes = [w for w in caught if issubclass(w.category, quadrs.StabilityWarning)]
    assert [w.category for w in notes] == [StabilityNote]
    text = str(notes[0].message)
    assert len(text) < 125 and "UNSTABLE" not in text and "EXCITES" not in text
    assert "lateral x/pitch" in text and "does not excite" in text


@pytest.mark.filterwarnings("default::quadrs.StabilityWarning")  # shown, as a user sees it
def test_the_cli_prints_the_note_as_a_note_and_keeps_the_loud_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short: Scenario
) -> None:
    from quadrs.hover.stability import StabilityNote

    with warnings.catch_warnings():
        warnings.simplefilter("default", StabilityNote)  # the test suite ignores it
        _, _, err = cli(capsys, "mc", "--scenario", scenario_file(tmp_path, short), "--runs", "2")
    assert err.startswith("quadrs: note: SMC: unstable at hover only in modes")
    assert "warning" not in err
    loud = scenario_file(tmp_path, short.override(LATERAL_STEP))
    _, _, err = cli(capsys, "mc", "--scenario", loud, "--runs", "2")
    assert "quadrs: warning: SMC gains are UNSTABLE at hover and this scenario EXCITES" in err


# -- 2. require_stable judges the modes the scenario excites ----------------------------------
def tune_altitude_gain(scenario: Scenario) -> quadrs.OptimizeResult:
    """A few evaluations of the SMC's altitude gain lambda_z (a vertical, stable mode)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the loud warning where the lateral modes are excited
        return quadrs.optimize(scenario, "smc", {"controller.smc.lambda[2]": (2.5, 4.0)}, runs=2,
                               method="nelder-mead", maxiter=3)  # fmt: skip


def test_require_stable_ignores_modes_the_flight_does_not_excite(short: Scenario) -> None:
    """The paper's SMC is unstable laterally, which vertical flights never excite: tuning a
    vertical gain must fly candidates, not reject every one."""
    h = tune_altitude_gain(short).evaluations
    assert h["flown"].all() and not h["penalised"].any()
    assert not h["stable"].any()  # unstable in some mode, all the same
    assert (h["unstable_modes"] == "").all()


def test_a_rejection_names_the_excited_mode(short: Scenario) -> None:
    s = short.override({"gust.components": ["vertical", "lateral"]})
    h = tune_altitude_gain(s).evaluations
    assert not h["flown"].any() and h["penalised"].all()
    assert h["unstable_modes"].str.contains("SMC lateral x/pitch +1.31 ± 3.90j", regex=False).all()


def test_tune_names_the_mode_that_rejected_every_candidate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short: Scenario
) -> None:
    s = scenario_file(tmp_path, short.override({"gust.components": ["vertical", "lateral"]}))
    args = (
        f"tune --scenario {s} --param controller.smc.lambda[2]=2.5:4 --runs 2 --method"
        f" nelder-mead --maxiter 2 --out {tmp_path / 't.toml'}"
    )
    code, out, err = cli(capsys, *args.split())
    assert code == 1
    assert "lateral x/pitch" in out and "lateral x/pitch" in err


# -- 3. divergence accounting per controller and phase ----------------------------------------
@pytest.mark.filterwarnings("ignore::quadrs.StabilityWarning")  # it excites the SMC on purpose
def test_diverged_flights_keep_the_phases_that_ended_before(
    diverging: quadrs.MonteCarloResult,
) -> None:
    runs = diverging.runs
    smc = runs[runs["controller"] == "smc"]
    assert smc["diverged"].all() and (smc["diverged_at"] > 4.0).all()  # after P2 ended
    assert not runs.loc[runs["controller"] == "pd", "diverged"].any()
    summary = diverging.summary().xs("iae", level="metric")
    # P1, P2, P3, then the whole flight (open at the divergence, so diverged like P3).
    assert list(summary["smc_n"]) == [8, 8, 0, 0]
    assert list(summary["smc_diverged"]) == [0, 0, 8, 8]
    assert list(summary["pd_n"]) == [8, 8, 8, 8] and list(summary["pd_diverged"]) == [0] * 4
    assert list(summary["diverged"]) == [0, 0, 8, 8]
    # The phases that ended before are the flights' own: the same as without the divergence.
    calm = quadrs.monte_carlo(
        diverging.scenario.override({"divergence.max_tilt": 1.0}),
        runs=8,
        controllers=("smc",),
        progress=False,
    ).summary()
    assert calm.loc[("iae", "P2"), "smc_mean"] == summary.loc["P2", "smc_mean"]


def test_the_footer_counts_per_controller_and_phase(diverging: quadrs.MonteCarloResult) -> None:
    from quadrs.present.table3 import format_table3

    text = format_table3(diverging.summary(), paper=False)
    assert "n (realisations in the means): PD 8 in every phase; SMC P1 8, P2 8, P3 0" in text
    assert "SMC P1 0, P2 0, P3 8" in text and "PD 0 in every phase" in text
    assert "n = 0" not in text


def test_exceedance_counts_divergence_from_its_phase_on(
    diverging: quadrs.MonteCarloResult,
) -> None:
    table = diverging.exceedance("max_accel", threshold=1e6).set_index(["controller", "phase"])
    for phase in ("P1", "P2"):  # the climb and the cruise stayed under the limit
        assert (
            table.loc[("smc", phase), "exceedances"] == 0 == table.loc[("smc", phase), "diverged"]
        )
    assert table.loc[("smc", "P3"), "exceedances"] == 8 == table.loc[("smc", "P3"), "diverged"]
    assert table.loc[("pd", "P3"), "exceedances"] == 0


# -- 4. figures that line up --------------------------------------------------------------------
def test_boxes_sit_on_their_ticks(short: Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=6, progress=False)
    fig = plots.distributions(mc.runs)
    for ax in fig.axes:
        ticks = list(ax.get_xticks())
        labels = [t.get_text() for t in ax.get_xticklabels()]
        # Medians and caps are horizontal segments centred on their box.
        flat = [line.get_xdata() for line in ax.lines if len(line.get_xdata()) == 2]
        centres = {round(float(np.mean(x)), 9) for x in flat if x[0] != x[1]}
        assert labels == ["PD", "SMC"] and ticks == [1.0, 2.0]
        assert sorted(centres) == pytest.approx(ticks)


def test_sweep_figures_keep_their_y_labels_apart(short: Scenario) -> None:
    result = quadrs.sweep(short, {"payload.natural_frequency": [1.0, 3.0]}, runs=2, progress=False)
    for metric in ("max_abs", "iae"):
        fig = plots.sweep_metric(result.summary(), metric)
        renderer = FigureCanvasAgg(fig).get_renderer()
        fig.draw(renderer)
        boxes = [ax.yaxis.label.get_window_extent(renderer) for ax in fig.axes]
        panels = [ax.get_window_extent(renderer) for ax in fig.axes]
        for box, panel in zip(boxes, panels, strict=True):  # each label beside its own panel
            assert box.y0 >= panel.y0 - 1 and box.y1 <= panel.y1 + 1
        for a, b in itertools.pairwise(boxes):
            assert not a.overlaps(b)


# -- 5. plausibility --------------------------------------------------------------------------
def test_a_thrust_limit_below_the_weight_is_refused_with_the_numbers(paper: Scenario) -> None:
    with pytest.raises(
        quadrs.ScenarioError,
        match=r"controller\.thrust_max = 10 N is below the "
        r"weight .* = \(2\.2 \+ 0\.22\) kg \* 9\.81 m/s\^2 = 23\.74 N",
    ) as e:
        paper.override({"controller.thrust_max": 10.0})
    assert e.value.key == "controller.thrust_max"
    paper.override({"controller.thrust_max": 30.0})  # above the weight: fine


def test_the_cli_refuses_it_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, err = cli(capsys, "run", "--set", "controller.thrust_max=10")
    assert code == 2 and out == "" and err.count("\n") == 1 and "thrust_max = 10 N" in err


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"payload.mass": 220.0}, "payload.mass = 220 kg is over 10 times vehicle.mass"),
        ({"vehicle.mass": 2200.0}, "vehicle.mass = 2200 kg (> 100): typed in grams?"),
        ({"payload.natural_frequency": 62.8}, "payload.natural_frequency = 62.8 Hz (> 50): the"),
        ({"initial.attitude": [0.0, 0.0, 90.0]}, "initial.attitude[2] (yaw) = 90 rad (> 2 pi)"),
        ({"gust.w20": 45.0}, "gust.w20 = 45 m/s is beyond severe turbulence (45 kt = 23 m/s)"),
        ({"gust.altitude": 600.0}, "gust.altitude = 600 m is above the low-altitude Dryden"),
    ],
)
def test_implausible_values_warn_once_with_the_likely_slip(
    paper: Scenario, changes: dict, message: str
) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("default")  # Python's own: each distinct warning once
        paper.override(changes)
        paper.override(changes).override({"gust.w20": paper["gust.w20"]})
    got = [str(w.message) for w in caught if w.category is quadrs.PlausibilityWarning]
    assert len(got) == 1 and got[0].startswith(message), got
    assert got[0].endswith(("grams?", "wrong unit?", "degrees?", "ft/s?", "feet?"))


def test_plausible_scenarios_are_silent() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error", quadrs.PlausibilityWarning)
        for name in presets():
            Scenario.preset(name)


# -- 6. tune's side effects and sweep --limit ---------------------------------------------------
def test_tune_reports_the_untuned_objective_and_every_phase(short: Scenario) -> None:
    result = quadrs.optimize(
        short,
        "pd",
        {"controller.pd.kd[2]": (0.5, 4.0)},
        "max_accel",
        ("P2",),
        runs=3,
        method="nelder-mead",
        maxiter=4,
    )
    fx = result.phase_effects
    assert list(fx.index) == ["P1", "P2", "P3", "flight"]
    untuned = quadrs.monte_carlo(short, runs=3, controllers=("pd",), progress=False)
    direct = untuned.runs.groupby("phase")["max_accel"].mean()
    assert fx["untuned"].to_numpy() == pytest.approx(direct.to_numpy(), rel=1e-12)
    assert result.baseline == pytest.approx(direct["P2"], rel=1e-12)
    assert fx.loc["P2", "tuned"] == pytest.approx(result.objective, rel=1e-12)
    assert (fx["worse"] == (fx["ci_low"] > 0)).all()


def test_tune_prints_untuned_and_the_phases_table(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short: Scenario
) -> None:
    args = (
        f"tune --scenario {scenario_file(tmp_path, short)} --controller pd --param"
        f" controller.pd.kd[2]=0.5:4 --objective max_accel --phase P2 --runs 2 --method"
        f" nelder-mead --maxiter 3 --out {tmp_path / 't.toml'}"
    )
    code, out, _ = cli(capsys, *args.split())
    assert code == 0
    assert re.search(r"objective \(max_accel over P2, seed 0\): \S+ \(untuned: \S+\)", out)
    assert "max_accel per phase, untuned -> tuned" in out and "in objective" in out


def test_sweep_takes_limit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short: Scenario
) -> None:
    args = (
        f"sweep --scenario {scenario_file(tmp_path, short)} --param gust.w20 --values"
        f" 5,10 --runs 3 --limit max_accel=1.0"
    )
    code, out, _ = cli(capsys, *args.split())
    assert code == 0 and "P(metric > threshold)" in out and "gust.w20" in out


# -- 8. small things ------------------------------------------------------------------------
def test_the_paper_column_is_for_the_paper_preset_only(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], paper: Scenario, short: Scenario
) -> None:
    from quadrs.present.table3 import shows_paper

    assert shows_paper(paper) and shows_paper(paper.override({"integrator.dt": 0.001}))
    assert not shows_paper(short)  # phases named P1-P3, another problem
    assert not shows_paper(paper.override({"payload.mass": 0.3}))
    _, out, _ = cli(capsys, "mc", "--scenario", scenario_file(tmp_path, short), "--runs", "2")
    assert "paper P" not in out and "P = SMC/PD %" in out


def test_sensitivity_draws_no_progress_bar_into_a_log(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], short: Scenario
) -> None:
    args = (
        f"sensitivity --scenario {scenario_file(tmp_path, short)} --runs 4 --disperse"
        f" payload.mass=uniform(0.2,0.25) --controllers pd"
    )
    code, _, err = cli(capsys, *args.split())
    assert code == 0 and "quadrs sensitivity" not in err and "%|" not in err


def test_help_shows_no_doubled_percent(capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    texts = [parser.format_help()]
    texts += [p.format_help() for p in sub.choices.values()]  # type: ignore[union-attr]
    assert all("%%" not in t for t in texts)
    assert any("95%" in t for t in texts)


def test_docs_cite_docs_model_md_not_the_spec() -> None:
    files = [ROOT / "README.md", *(ROOT / "docs").glob("*.md"), *(ROOT / "python").rglob("*.py")]
    assert [f.name for f in files if "MODEL.md" in f.read_text()] == []


def test_scenario_keys_shows_every_unit(capsys: pytest.CaptureFixture[str]) -> None:
    _, out, _ = cli(capsys, "scenario", "keys", "--set", "controller.thrust_max=40")
    lines = out.split("\n\n")[0].splitlines()  # then the keys it does not set (issue 54)
    assert len(lines) == len(list(Scenario.paper().override({"controller.thrust_max": 40}).keys()))
    assert all("  # " in line for line in lines)
    assert re.search(r"^payload\.mass = 0\.22 +# kg$", out, re.M)
    assert re.search(r"^payload\.natural_frequency = 2\.0 +# Hz$", out, re.M)
    assert re.search(r"^controller\.thrust_max = 40 +# N$", out, re.M)


def test_every_key_of_every_preset_has_a_unit() -> None:
    from quadrs.scenario.units import unit

    for name in presets():
        s = Scenario.preset(name)
        extra = s.override({"controller.thrust_min": 1.0, "controller.thrust_max": 40.0})
        for key in extra.keys():
            assert unit(key), key
    dispersed = Scenario.paper().override(
        {"dispersions": {"payload.mass": {"dist": "lognormal", "mu": -1.5, "sigma": 0.1}}}
    )
    assert unit('dispersions."payload.mass".mu') == "ln(kg)"
    assert [unit(k) for k in dispersed.keys() if k.startswith("dispersions")] == [
        "-",
        "ln(kg)",
        "-",
    ]


# -- notebooks ------------------------------------------------------------------------------
def test_results_display_as_html_tables(short: Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=3, progress=False)
    flight = quadrs.simulate(short, "pd")
    sw = quadrs.sweep(short, {"gust.w20": [5.0, 10.0]}, runs=2, progress=False)
    report = quadrs.stability(short, "smc")
    tuned = quadrs.optimize(
        short, "pd", {"controller.pd.kd[2]": (1.0, 3.0)}, runs=2, method="nelder-mead", maxiter=2
    )
    sa = quadrs.sensitivity(
        short.override(
            {"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.2, "high": 0.25}}}
        ),
        runs=4,
        controllers=("pd",),
    )
    for obj in (mc, flight, sw, report, tuned, sa):
        html = obj._repr_html_()
        assert "<table" in html and "&lt;" in html  # the escaped repr heads it
    assert f"{flight.metrics['iae'].iloc[0]:.4g}" in flight._repr_html_()
    iae = mc.summary().loc[("iae", "P1"), "pd_mean"]
    assert f"{iae:.2g}"[:3] in mc._repr_html_()
    assert "lateral x/pitch" in report._repr_html_()
    assert "untuned (tuning seed)" in tuned._repr_html_() and "P3" in tuned._repr_html_()
    assert "payload.mass" in sa._repr_html_()
