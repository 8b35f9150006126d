"""The command line end to end: `quadrs.cli.main.main([...])` in process, and `python -m quadrs.cli`
in a subprocess for what only a real process shows (exit status, stderr, Ctrl-C)."""

import argparse
import os
import re
import select
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib.image
import pandas as pd
import pytest

import quadrs
from quadrs import MonteCarloResult, Scenario
from quadrs.cli.main import build_parser, main
from quadrs.engine.calls import PAPER_CONTROLLERS
from quadrs.runs.sweep import SweepResult
from quadrs.scenario.scenario import parse_value

#: The metric columns, as the engine defines them (rust/src/metrics.rs).
METRICS = list(quadrs._core.METRIC_NAMES)
RUN_COLUMNS = ["realisation", "controller", "phase", *METRICS, "diverged", "diverged_at", "status"]
TABLE3_COLUMNS = [
    "phase", "IAE PD", "IAE SMC", "P_IAE %", "paper P_IAE %",
    "ITAE PD", "ITAE SMC", "P_ITAE %", "paper P_ITAE %", "n", "diverged",
]  # fmt: skip
# A 6 s take-off / gust / landing at dt = 2 ms, as command-line overrides.
SHORT = [
    "--set", "integrator.duration=6.0",
    "--set", "integrator.dt=0.002",
    "--set", "trajectory.waypoints=[[0, 0, 0, 2, 0], [4, 0, 0, 0, 0]]",
    "--set", 'phases=[{name = "P1", start = 0, end = 2}, {name = "P2", start = 2, end = 4}, '
             '{name = "P3", start = 4, end = 6}]',
    "--set", "gust.start=2.5",
    "--set", "gust.end=3.5",
]  # fmt: skip


def assert_png(path: Path) -> None:
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = matplotlib.image.imread(path)
    assert img.shape[0] > 100 and img.shape[1] > 100 and img.std() > 0


def assert_svg(path: Path) -> None:
    assert ET.parse(path).getroot().tag.endswith("svg")


def assert_figures(directory: Path, stems: list[str]) -> None:
    for stem in stems:
        assert_png(directory / f"{stem}.png")
        assert_svg(directory / f"{stem}.svg")


def one_error_line(err: str, *needles: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for n in needles:
        assert n in lines[0], lines[0]
    return lines[0]


def run_cli(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "quadrs.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
    )


# -- single flights -------------------------------------------------------------------------
def test_run_prints_metrics_writes_trace_and_figures(tmp_path, capsys) -> None:
    trace = tmp_path / "trace.csv"
    figs = tmp_path / "figs"
    code = main(
        [
            "run",
            *SHORT,
            "--controller",
            "pd",
            "--seed",
            "2",
            "--trace",
            str(trace),
            "--plot",
            str(figs),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    for word in ["PD", "P1", "P2", "P3", *METRICS]:
        assert word in out
    frame = pd.read_csv(trace, index_col="t")
    assert {"z", "zc", "z_ref", "vz", "wind_z", "e_o"} <= set(frame.columns)
    assert frame.index[-1] == pytest.approx(6.0)
    # the printed IAE is the flight's
    short = Scenario.paper().override(_short_dict())
    flight = quadrs.simulate(short, "pd", seed=2)
    assert f"{flight.metrics['iae'].iloc[0]:.4g}" in out
    assert_figures(figs, ["altitude", "oscillation", "spectra", "gust_force"])


def test_run_trace_parquet(tmp_path) -> None:
    trace = tmp_path / "trace.parquet"
    assert main(["run", *SHORT, "--trace", str(trace)]) == 0
    frame = pd.read_parquet(trace)
    assert frame.index.name == "t" and "e_o" in frame.columns


def _short_dict() -> dict:
    pairs = [SHORT[i + 1].split("=", 1) for i in range(0, len(SHORT), 2)]
    return {k: parse_value(v) for k, v in pairs}


# -- Monte Carlo and report -----------------------------------------------------------------
def test_mc_writes_parquet_and_report_reprints_it(tmp_path, capsys) -> None:
    out = tmp_path / "runs.parquet"
    code = main(
        [
            "mc",
            *SHORT,
            "--runs",
            "4",
            "--seed",
            "1",
            "--workers",
            "2",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    printed = capsys.readouterr().out
    assert code == 0
    for col in ["IAE (m s)", "ITAE (m s²)", "PD", "SMC", "P = SMC/PD %", " ± "]:
        assert col in printed
    assert "paper P" not in printed  # phases named P1-P3, but not the paper's problem
    assert max(len(line) for line in printed.splitlines()) <= 100  # fits a terminal
    mc = MonteCarloResult.read_parquet(out)
    assert list(mc.runs.columns) == RUN_COLUMNS
    # the paper's two laws (the command's default), P1-P3 and the whole flight
    assert len(mc.runs) == 4 * len(PAPER_CONTROLLERS) * 4 and mc.seed == 1 and not mc.interrupted
    assert mc.scenario == Scenario.paper().override(_short_dict())

    figs = tmp_path / "figs"
    assert main(["report", str(out), "--plots", str(figs)]) == 0
    again = capsys.readouterr().out
    assert printed.strip() in again  # the very same table
    assert "4 realisations, seed 1" in again
    assert main(["report", str(out), "--wide", "--no-paper"]) == 0
    wide = capsys.readouterr().out
    for col in ["IAE PD", "IAE SMC", "P_IAE %", "P_ITAE %"]:  # the one-row-per-phase form
        assert col in wide
    assert "paper" not in wide
    assert_figures(figs, ["distributions", "spectra"])


def test_mc_ctrl_c_saves_what_finished_and_exits_130(tmp_path, monkeypatch, capsys) -> None:
    import quadrs.runs.montecarlo as montecarlo

    real = montecarlo.monte_carlo

    def interrupted(scenario, runs, *args, **kwargs):
        res = real(scenario, 3, *args, **kwargs)
        res.interrupted = True
        return res

    monkeypatch.setattr(montecarlo, "monte_carlo", interrupted)
    out = tmp_path / "runs.parquet"
    assert main(["mc", *SHORT, "--runs", "50", "--out", str(out), "--no-progress"]) == 130
    saved = MonteCarloResult.read_parquet(out)
    assert saved.interrupted and len(saved.realisations) == 3
    assert "P = SMC/PD %" in capsys.readouterr().out


def test_keyboard_interrupt_anywhere_exits_130(monkeypatch, capsys) -> None:
    import quadrs.runs.flight as flight

    def boom(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(flight, "simulate", boom)
    assert main(["run", *SHORT]) == 130
    assert "interrupted" in capsys.readouterr().err


def test_ctrl_c_while_the_parser_is_built_exits_130_in_one_line(monkeypatch, capsys) -> None:
    """Building the parser imports what its choices come from (a second or two on a cold
    start): a Ctrl-C then is one line and exit 130, not a traceback."""
    import quadrs.cli.main as cli_main

    def boom(only=None):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli_main, "build_parser", boom)
    assert main(["run", *SHORT]) == 130
    assert capsys.readouterr().err == "quadrs: interrupted\n"


def _declared(parser: argparse.ArgumentParser) -> dict[str, list[tuple]]:
    """Each subcommand's options as declared: strings, dest, default, choices, nargs, help."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))

    def options(p: argparse.ArgumentParser) -> list[tuple]:
        return [(tuple(a.option_strings), a.dest, repr(a.default), repr(a.choices), a.nargs,
                 a.help) for a in p._actions]  # fmt: skip

    return {name: options(p) for name, p in sub.choices.items()}


def test_a_command_parser_built_alone_is_the_whole_parsers() -> None:
    """``main`` builds only the named command's parser (the other commands' modules stay
    unimported): each, built alone, declares exactly what the whole parser declares for it,
    and parses a command line to the same namespace."""
    whole = _declared(build_parser())
    assert len(whole) == 12
    for name, options in whole.items():
        assert _declared(build_parser(name)) == {name: options}, name
    line = ["mission", "--runs", "7", "--limit", "max_swing=30", "--set", "gust.w20=4"]
    assert build_parser("mission").parse_args(line) == build_parser().parse_args(line)


def test_a_command_imports_only_its_own_module() -> None:
    """``quadrs run --help`` does not import the design loop nor the mission's tables (nor
    scipy.optimize with them); ``quadrs --help`` lists every command."""
    probe = (
        "import sys, contextlib, io\n"
        "from quadrs.cli.main import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    assert main(['run', '--help']) == 0\n"
        "print(sorted(m for m in sys.modules if m.startswith(('quadrs.cli', 'quadrs.design', "
        "'scipy.optimize'))))\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout  # fmt: skip
    assert "quadrs.cli.run" in out
    for other in ["quadrs.cli.design", "quadrs.cli.mission", "quadrs.cli.rare",
                  "quadrs.design.optimize", "scipy.optimize"]:  # fmt: skip
        assert f"'{other}'" not in out, (other, out)
    help_all = subprocess.run([sys.executable, "-m", "quadrs.cli", "--help"],
                              capture_output=True, text=True, check=True).stdout  # fmt: skip
    for command in ["run", "mc", "sweep", "tune", "linearize", "rare", "mission", "report"]:
        assert command in help_all


def test_a_background_import_is_the_module_imported_later() -> None:
    """``import_in_background`` (the mission's statistics load while the batch flies): the
    module is there once its thread ends, the same object a later import gives; a module that
    cannot be imported raises nothing on the thread, and its error where the command imports
    it. The batch imports no scipy at all (so the mission's two threads never wait on each
    other's imports)."""
    from quadrs.cli.common import import_in_background

    probe = (
        "import sys, importlib\n"
        "from quadrs.cli.common import import_in_background\n"
        "assert 'quadrs.design.mission' not in sys.modules\n"
        "import_in_background('quadrs.design.mission').join()\n"
        "m = sys.modules['quadrs.design.mission']\n"
        "assert importlib.import_module('quadrs.design.mission') is m\n"
        "assert 'scipy.stats' in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", probe], check=True)
    batch = (
        "import sys, warnings\n"
        "warnings.simplefilter('ignore')\n"
        "import quadrs\n"
        "quadrs.monte_carlo(quadrs.Scenario.preset('delivery'), runs=1, workers=1,"
        " progress=False, spectra=False)\n"
        "assert not [m for m in sys.modules if m.split('.')[0] == 'scipy']\n"
    )
    subprocess.run([sys.executable, "-c", batch], check=True)
    import_in_background("quadrs.no_such_module").join()
    with pytest.raises(ModuleNotFoundError, match="no_such_module"):
        __import__("quadrs.no_such_module")


def test_real_sigint_mid_batch_saves_and_exits_130(tmp_path) -> None:
    """A real Ctrl-C (SIGINT) while the batch runs: exit 130 and the finished runs saved.
    stderr is a pseudo-terminal, so the progress bar is drawn (it is not in a pipe)."""
    import fcntl
    import pty
    import struct
    import termios

    out = tmp_path / "runs.parquet"
    master, terminal = pty.openpty()
    fcntl.ioctl(terminal, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 100 columns
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "quadrs.cli",
            "mc",
            "--runs",
            "100000",
            "--workers",
            "1",
            "--out",
            str(out),
        ],
        stdout=subprocess.PIPE,
        stderr=terminal,
    )
    os.close(terminal)
    try:
        seen = b""
        # wait for the progress bar to count at least one finished realisation
        while re.search(rb"quadrs mc.*\| *[1-9][0-9]*/100000", seen) is None:
            ready, _, _ = select.select([master], [], [], 60)
            assert ready, "no progress bar within 60 s"
            chunk = os.read(master, 4096)
            assert chunk, seen
            seen += chunk
        proc.send_signal(signal.SIGINT)
        proc.communicate(timeout=60)
    finally:
        proc.kill()
        os.close(master)
    assert proc.returncode == 130, seen
    saved = MonteCarloResult.read_parquet(out)
    assert saved.interrupted and 0 < len(saved.realisations) < 100000


def test_no_progress_bar_unless_stderr_is_a_terminal(monkeypatch) -> None:
    import quadrs.runs.montecarlo as montecarlo

    asked = []
    real = montecarlo.monte_carlo

    def spy(*args, **kwargs):
        asked.append(kwargs["progress"])
        return real(*args, **kwargs)

    monkeypatch.setattr(montecarlo, "monte_carlo", spy)
    assert main(["mc", *SHORT, "--runs", "1"]) == 0  # pytest's stderr is no terminal
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["mc", *SHORT, "--runs", "1"]) == 0
    assert main(["mc", *SHORT, "--runs", "1", "--no-progress"]) == 0
    assert asked == [False, True, False]


# -- sweep ----------------------------------------------------------------------------------
def test_two_point_sweep(tmp_path, capsys) -> None:
    out = tmp_path / "sweep.parquet"
    code = main(
        [
            "sweep",
            *SHORT,
            "--param",
            "payload.natural_frequency",
            "--values",
            "1.5,3",
            "--runs",
            "3",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    printed = capsys.readouterr().out
    assert code == 0
    assert "payload.natural_frequency" in printed and "P_ITAE %" in printed
    res = SweepResult.read_parquet(out)
    assert list(res.runs.columns) == ["payload.natural_frequency", *RUN_COLUMNS]
    assert sorted(res.runs["payload.natural_frequency"].unique()) == [1.5, 3.0]
    assert len(res.runs) == 2 * 3 * len(PAPER_CONTROLLERS) * 4
    # same seed at every point: realisations 0..2 at both
    for _, g in res.runs.groupby("payload.natural_frequency"):
        assert sorted(g["realisation"].unique()) == [0, 1, 2]
    assert main(["report", str(out)]) == 0
    assert "payload.natural_frequency" in capsys.readouterr().out


def test_two_key_sweep_with_plots(tmp_path, capsys) -> None:
    figs = tmp_path / "figs"
    code = main(
        [
            "sweep",
            *SHORT,
            "--param",
            "payload.natural_frequency",
            "--values",
            "[1.5, 3]",
            "--param2",
            "controller.mass_compensation",
            "--values2",
            "true,false",
            "--runs",
            "2",
            "--plots",
            str(figs),
            "--no-progress",
        ]
    )
    assert code == 0
    assert "controller.mass_compensation" in capsys.readouterr().out
    assert_figures(figs, ["sweep_max_abs", "sweep_iae", "distributions"])


# -- paper ----------------------------------------------------------------------------------
PAPER_FIGURES = [
    "fig04_07_altitude", "fig05_oscillation_P1", "fig06_spectrum_P1",
    "fig08_spectrum_gust_vs_calm_P2", "fig09_oscillation_P2", "fig10_spectrum_P2",
    "fig11_oscillation_P3", "fig12_spectrum_P3", "fig13_14_max_amplitude", "fig15_gust_force",
    "fig16_mass_compensation", "mc_spectra", "mc_distributions",
]  # fmt: skip


def test_paper_writes_every_table_and_figure(paper_example) -> None:
    """The pipeline's output, made once per session by examples/paper.py (the ``paper_example``
    fixture: the paper preset at dt = 2 ms, 2 realisations, the sweep at 1 and 4 Hz); the
    command line's own path through it is test_paper_ctrl_c_keeps_the_batch's and the bad-input
    tests'."""
    out, _ = paper_example
    assert_figures(out, PAPER_FIGURES)
    assert list(pd.read_csv(out / "table3.csv").columns) == TABLE3_COLUMNS
    summary = pd.read_csv(out / "summary.csv")
    assert {"metric", "phase", "pd_mean", "smc_mean", "P", "P_ci_low", "P_ci_high"} <= set(
        summary.columns
    )
    comparison = pd.read_csv(out / "paper_comparison.csv")
    assert list(comparison.columns) == [
        "metric",
        "phase",
        "P",
        "P_ci_low",
        "P_ci_high",
        "paper_P",
        "paper_in_ci",
    ]
    assert comparison.set_index(["metric", "phase"]).loc[("iae", "P2"), "paper_P"] == 11.38
    runs = MonteCarloResult.read_parquet(out / "runs.parquet").runs
    assert list(runs.columns) == RUN_COLUMNS and len(runs) == 2 * 2 * 4
    sweep = SweepResult.read_parquet(out / "sweep_natural_frequency.parquet")
    assert sorted(sweep.runs["payload.natural_frequency"].unique()) == [1, 4]
    assert Scenario.from_toml(out / "scenario.toml") == Scenario.paper().override(
        {"integrator.dt": 0.002}
    )
    flight_metrics = pd.read_csv(out / "flight_metrics.csv")
    assert {"phase", "controller", *METRICS} <= set(flight_metrics.columns)

    report = (out / "report.md").read_text()
    for text in [
        "Table 3",
        "35.40",
        "11.38",
        "49.51",
        "payload.mass",
        "gust.w20",
        "trajectory.waypoints",
        "vehicle.drag_area",
        "stability",
    ]:
        assert text in report, text
    for stem in PAPER_FIGURES:
        assert f"]({stem}.png)" in report, stem


def test_paper_ctrl_c_keeps_the_batch(tmp_path, monkeypatch) -> None:
    import quadrs.paper.pipeline as paper

    real = paper.monte_carlo

    def interrupted(scenario, runs, *args, **kwargs):
        res = real(scenario, 2, *args, **kwargs)
        res.interrupted = True
        return res

    monkeypatch.setattr(paper, "monte_carlo", interrupted)
    out = tmp_path / "paper"
    code = main(
        [
            "paper",
            *SHORT,
            "--out",
            str(out),
            "--runs",
            "40",
            "--frequencies",
            "1",
            "--masses",
            "0.2",
            "--no-progress",
        ]
    )
    assert code == 130
    assert MonteCarloResult.read_parquet(out / "runs.parquet").interrupted
    assert (out / "fig04_07_altitude.png").exists()
    assert not (out / "report.md").exists()


# -- scenario, stability, help --------------------------------------------------------------
def test_scenario_show_round_trips(capsys) -> None:
    assert main(["scenario", "show", "--preset", "paper"]) == 0
    assert Scenario.from_toml_string(capsys.readouterr().out) == Scenario.paper()
    assert main(["scenario", "show", *SHORT, "--set", "gust.w20=15"]) == 0
    shown = Scenario.from_toml_string(capsys.readouterr().out)
    assert shown["gust.w20"] == 15 and shown["integrator.duration"] == 6.0


def test_scenario_from_file_with_base(tmp_path, capsys) -> None:
    f = tmp_path / "mine.toml"
    f.write_text('base = "paper"\n[payload]\nmass = 0.44\n')
    assert main(["scenario", "show", "--scenario", str(f)]) == 0
    assert Scenario.from_toml_string(capsys.readouterr().out)["payload.mass"] == 0.44


def test_scenario_show_diff_prints_only_what_differs_from_the_base(tmp_path, capsys) -> None:
    f = tmp_path / "mine.toml"
    f.write_text('base = "paper_stable_lateral"\n[payload]\nmass = 0.44\n')
    assert main(["scenario", "show", "--scenario", str(f), "--diff", "--set", "gust.w20=15"]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0] == "# 2 key(s) differ from the preset 'paper_stable_lateral'"
    assert [line.split(" = ")[0] for line in lines[1:]] == ["payload.mass", "gust.w20"]
    assert lines[1].endswith("# paper_stable_lateral: 0.22")
    # What --diff prints is what --set accepts back.
    sets = [x for line in lines[1:] for x in ("--set", line.split("#")[0].replace(" ", ""))]
    assert main(["scenario", "show", "--preset", "paper_stable_lateral", *sets]) == 0
    shown = Scenario.from_toml_string(capsys.readouterr().out)
    assert shown == Scenario.from_toml(f).override({"gust.w20": 15})
    assert main(["scenario", "show", "--diff"]) == 0
    assert capsys.readouterr().out.strip() == "# 0 key(s) differ from the preset 'paper'"


def test_scenario_keys_lists_every_key_with_a_value_set_accepts(capsys) -> None:
    assert main(["scenario", "keys"]) == 0
    out = capsys.readouterr().out
    lines = out.split("\n\n")[0].strip().splitlines()  # then the keys it does not set
    paper = Scenario.paper()
    assert [line.split(" = ", 1)[0] for line in lines] == list(paper.keys())
    assert "\n# Not set here" in out
    for line in lines:
        key, value = line.split(" = ", 1)
        assert parse_value(value) == paper[key], line
    assert main(["scenario", "presets"]) == 0
    assert "paper" in capsys.readouterr().out.split()


def test_stability_prints_a_verdict_per_controller(capsys) -> None:
    # exit 1 on an unstable verdict (the paper's SMC), 0 when every verdict is stable
    assert main(["stability"]) == 1
    out = capsys.readouterr().out
    assert "== PD ==" in out and "== SMC ==" in out
    for c in ("pd", "smc"):
        assert str(quadrs.stability(Scenario.paper(), controller=c)) in out
    assert main(["stability", "--controller", "smc", "--poles"]) == 1
    assert "real" in capsys.readouterr().out
    assert main(["stability", "--controller", "pd"]) == 0
    assert main(["stability", "--preset", "paper_stable_lateral"]) == 0


def test_every_option_is_explained() -> None:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert {
        "run",
        "mc",
        "sweep",
        "report",
        "paper",
        "stability",
        "sensitivity",
        "scenario",
        "tune",
    } <= set(sub.choices)
    for name, p in sub.choices.items():
        for action in p._actions:
            if not isinstance(action, argparse._SubParsersAction):
                assert action.help, f"{name} {action.option_strings or action.dest}"


def test_help_exits_0_and_names_units(capsys) -> None:
    assert main(["mc", "--help"]) == 0
    text = capsys.readouterr().out
    assert "--runs" in text and "m s" in text and "(kg)" in text


# -- bad input ------------------------------------------------------------------------------
BAD = [
    (["--set", "payload.mas=1"], "payload.mas"),
    (["--set", "payload.mass=abc"], "payload.mass"),
    (["--set", "payload.mass=-1"], "payload.mass"),
    (["--set", "gust.enabled=3"], "gust.enabled"),
    (["--set", "payload.mass"], "payload.mass"),
    (["--scenario", "MISSING/none.toml"], "none.toml"),
    (["--runs", "0"], "--runs"),
    (["--controllers", "pd,lqr"], "lqr"),
]


@pytest.mark.parametrize(("args", "needle"), BAD)
def test_bad_input_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, args, needle):
    out = tmp_path / "runs.parquet"
    args = [a.replace("MISSING", str(tmp_path)) for a in args]
    runs = [] if "--runs" in args else ["--runs", "2"]
    assert main(["mc", *SHORT, *args, *runs, "--out", str(out), "--no-progress"]) == 2
    one_error_line(capsys.readouterr().err, needle)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["run", "--trace", "OUT/trace.txt"], "--trace"),
        (["run", "--set", "phases[7].end=3"], "phases[7].end"),
        (
            ["sweep", "--param", "payload.mas", "--values", "1,2", "--out", "OUT/s.parquet"],
            "payload.mas",
        ),
        (
            ["sweep", "--param", "payload.mass", "--values", "0.1,-2", "--out", "OUT/s.parquet"],
            "payload.mass",
        ),
        (["paper", "--out", "OUT/paper", "--set", "payload.mass=-1"], "payload.mass"),
        (["paper", "--out", "OUT/paper", "--frequencies", "1,-2"], "natural_frequency"),
        (["report", "OUT/none.parquet"], "none.parquet"),
        (["scenario", "show", "--set", "vehicle.mass=0"], "vehicle.mass"),
    ],
)
def test_bad_input_in_every_command(tmp_path, capsys, args, needle) -> None:
    args = [a.replace("OUT", str(tmp_path)) for a in args]
    assert main(args) == 2
    one_error_line(capsys.readouterr().err, needle)
    assert list(tmp_path.iterdir()) == []


def test_report_of_a_file_that_is_not_parquet(tmp_path, capsys) -> None:
    f = tmp_path / "runs.parquet"
    f.write_text("not parquet")
    assert main(["report", str(f)]) == 2
    one_error_line(capsys.readouterr().err)


# -- a real process -------------------------------------------------------------------------
def test_subprocess_run_and_bad_input(tmp_path) -> None:
    good = run_cli("run", *SHORT, "--controller", "smc")
    assert good.returncode == 0, good.stderr
    assert "SMC" in good.stdout and "P3" in good.stdout
    out = tmp_path / "runs.parquet"
    bad = run_cli("mc", "--set", "payload.mass=-1", "--out", str(out))
    assert bad.returncode == 2
    line = one_error_line(bad.stderr, "payload.mass")
    assert line.startswith("quadrs mc: error:")
    assert not out.exists()
    usage = run_cli("run", "--controller", "lqr")
    assert usage.returncode == 2
    one_error_line(usage.stderr, "--controller")


# -- report helpers behind `paper` ----------------------------------------------------------
def _fake_summary() -> pd.DataFrame:
    idx = pd.MultiIndex.from_product(
        [["iae", "itae", "peak_amplitude"], ["P1", "P2", "P3"]], names=["metric", "phase"]
    )
    p = [30.0, 50.0, 101.0] * 3
    return pd.DataFrame(
        {
            "P": p,
            "P_ci_low": [x - 10 for x in p],
            "P_ci_high": [x + 10 for x in p],
        },
        index=idx,
    )


def test_paper_comparison_and_ordering() -> None:
    from quadrs.present.table3 import ordering, paper_comparison

    comp = paper_comparison(_fake_summary())
    assert comp.loc[("iae", "P1"), "paper_P"] == 35.40
    assert comp.loc[("iae", "P1"), "paper_in_ci"]  # 35.40 in [20, 40]
    assert not comp.loc[("iae", "P2"), "paper_in_ci"]  # 11.38 not in [40, 60]
    assert comp.loc[("peak_amplitude", "P2"), "paper_P"] == 12.5
    assert pd.isna(comp.loc[("peak_amplitude", "P3"), "paper_P"])
    order = ordering(_fake_summary(), "itae")
    assert list(order["verdict"]) == ["SMC lower", "SMC lower", "no clear difference"]
    with pytest.raises(ValueError, match="pd and smc"):
        paper_comparison(_fake_summary().drop(columns="P"))


def test_to_markdown_and_toml_value() -> None:
    from quadrs.present.table3 import to_markdown, toml_value

    text = to_markdown(pd.DataFrame({"a": [1.23456, float("nan")], "b": ["x|y", None]}))
    assert text.splitlines() == [
        "| index | a | b |",
        "|---|---|---|",
        "| 0 | 1.235 | x\\|y |",
        "| 1 |  |  |",
    ]
    for value in [True, 3, 0.1, "min_jerk", [[0.0, 1], [2, 3]], {"name": "P1", "end": 2.0}]:
        assert parse_value(toml_value(value)) == value


def test_mc_fused_is_recorded_and_kept_on_resume(tmp_path, capsys) -> None:
    out = tmp_path / "f.parquet"
    code = main(["mc", *SHORT, "--runs", "4", "--controllers", "pd", "--fused", "--out", str(out)])
    if quadrs._core.simd_path() == "baseline":  # no FMA: refused, in the CLI's words
        assert code == 2
        one_error_line(capsys.readouterr().err, "--fused needs")
        return
    assert code == 0
    assert quadrs.MonteCarloResult.read_parquet(out).arithmetic == "fused"
    ckpt = tmp_path / "c"
    assert main(["mc", *SHORT, "--runs", "4", "--fused", "--checkpoint", str(ckpt)]) == 0
    assert quadrs.MonteCarloResult.read_parquet(ckpt).arithmetic == "fused"
    capsys.readouterr()
    code = main(["mc", *SHORT, "--runs", "8", "--checkpoint", str(ckpt), "--resume"])
    assert code == 2  # the checkpoint is fused: resuming it exactly would mix the modes
    one_error_line(capsys.readouterr().err, "arithmetic")
