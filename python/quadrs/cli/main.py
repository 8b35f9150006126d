"""``quadrs``: the command line.

Exit status: 0 on success; 1 if an output could not be written (the results are then saved
to a recovery file whose path is printed), if ``stability`` found the closed loop unstable, or
if ``tune`` found no admissible or feasible candidate; 2 on bad input, with one line on
stderr naming the key or file; 130 on Ctrl-C and 143 on SIGTERM, after saving what had finished. Set
``QUADRS_TRACEBACK=1`` to see the full traceback of an error instead of its one-line reason.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import warnings
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

from quadrs.cli.common import (
    EXIT_FAIL,
    EXIT_INTERRUPT,
    EXIT_OK,
    EXIT_TERMINATED,
    EXIT_USAGE,
    BadInput,
    dask_client,
    scheduler_option,
    seed_and_workers,
)
from quadrs.present.terminal import terminal_text
from quadrs.scenario.dispersion import DISTRIBUTIONS, SAMPLINGS

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd


class Parser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line on stderr (then exit 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


# -- options ----------------------------------------------------------------------------------
def _scenario_options(default_preset: str = "paper") -> argparse.ArgumentParser:
    """The scenario's options, their help naming the command's own default preset (mission:
    delivery, every other command: paper)."""
    from quadrs.scenario.scenario import presets

    common = argparse.ArgumentParser(add_help=False)
    g = common.add_argument_group("scenario")
    g.add_argument(
        "--preset",
        default=None,
        choices=presets(),
        help=f"start from a shipped preset (default: {default_preset})",
    )
    g.add_argument(
        "--scenario",
        metavar="FILE.toml",
        type=Path,
        help='start from a scenario file instead (it may begin with base = "paper" and give '
        "only what differs)",
    )
    g.add_argument(
        "--set",
        metavar="KEY=VALUE",
        action="append",
        default=[],
        dest="overrides",
        help="override one dotted key, repeatable; VALUE in TOML syntax and SI units, e.g. "
        "payload.mass=0.44 (kg), gust.w20=15 (m/s), payload.natural_frequency=4 (Hz), "
        "integrator.duration=10 (s), 'trajectory.interpolation=\"min_jerk\"'; "
        "`quadrs scenario keys` lists every key with its value and unit",
    )
    g.add_argument(
        "--disperse",
        metavar="KEY=DIST(ARGS)",
        action="append",
        default=[],
        dest="dispersions",
        help="give a numeric key a distribution, repeatable: "
        + ", ".join(f"{d}({','.join(p)})" for d, p in DISTRIBUTIONS.items())
        + " (lognormal's of the logarithm); e.g. payload.mass=uniform(0.1,0.4); "
        "see docs/dispersions.md",
    )
    return common


def _batch_options(p: argparse.ArgumentParser, runs: int, out_help: str) -> None:
    p.add_argument(
        "--runs",
        type=int,
        default=runs,
        metavar="N",
        help="gust realisations (each flown by every controller) (default: %(default)s)",
    )
    seed_and_workers(p)
    p.add_argument(
        "--controllers",
        type=_controllers,
        default=_paper_controllers(),
        metavar="LIST",
        help=f"comma-separated controllers to fly, of {','.join(_controller_names())} "
        f"(default: the paper's {','.join(_paper_controllers())})",
    )
    p.add_argument("--out", type=Path, metavar="FILE.parquet", help=out_help)
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (there is none anyway unless stderr is a terminal)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run the chunks on a Dask cluster, e.g. tcp://10.0.0.5:8786 "
        "(needs pip install quadrs[dask])",
    )
    p.add_argument(
        "--sampling",
        choices=SAMPLINGS,
        default="random",
        help="how the values of dispersed keys are drawn: independent per realisation "
        "(random), or a stratified design over the batch (lhs, sobol) (default: random)",
    )


def _table_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--wide",
        action="store_true",
        help="print Table 3 in one wide row per phase with full intervals (about 190 columns)",
    )
    p.add_argument(
        "--no-paper",
        action="store_true",
        help="leave the paper's own P values out of Table 3 (they are shown for the paper "
        "preset only)",
    )


def _print_table3(mc: Any, args: argparse.Namespace) -> None:
    from quadrs.present.table3 import format_table3, shows_paper

    paper = not args.no_paper and shows_paper(mc.scenario)  # the paper's P: its own problem only
    print(terminal_text(format_table3(mc.summary(), wide=args.wide, paper=paper)))


def _controller_names() -> tuple[str, ...]:
    """The engine's controllers (the package's one list, quadrs.engine.calls.CONTROLLERS)."""
    from quadrs.engine.calls import CONTROLLERS

    return CONTROLLERS


def _paper_controllers() -> tuple[str, ...]:
    """The paper's pair, the default of the batch commands (quadrs.engine.calls)."""
    from quadrs.engine.calls import PAPER_CONTROLLERS

    return PAPER_CONTROLLERS


def _controllers(text: str) -> tuple[str, ...]:
    names = tuple(c.strip() for c in text.split(",") if c.strip())
    known = _controller_names()
    bad = [c for c in names if c not in known]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"controllers are {' and/or '.join(known)}, got {text!r}")
    return names


def build_parser() -> argparse.ArgumentParser:
    """The ``quadrs`` argument parser with every subcommand."""
    common = _scenario_options()
    parser = Parser(
        prog="quadrs",
        description="A quadrotor with a spring-attached or cable-slung payload through "
        "turbulence, wind and gusts: single flights, paired Monte Carlo batches, sweeps, "
        "stability and tuning, mission risk along a route, rare events and the paper's "
        "figures. Units are SI (m, s, kg, N; angles in scenario keys in rad; frequencies in "
        "Hz), but degrees for headings (wind.heading), swing (every table and figure, --limit, "
        "tune --constraint, rare --threshold) and PX4's angles and rates "
        "([controller.px4], as PX4 states them). Default controller: run and tune fly smc "
        "(the paper's proposed law, the paper preset's subject), mission and rare pd (the law "
        "the delivery preset is tuned for and its documented answers use), mc, stability and "
        "linearize both (paired); --controller picks another.",
        epilog="Exit status: 0 success; 1 an output could not be written (the results go to a "
        "recovery file), stability found an unstable closed loop, or tune found no admissible "
        "or feasible candidate; 2 bad input (one line on stderr); 130 Ctrl-C, 143 SIGTERM "
        "(what finished is saved).",
    )
    from quadrs._core import __version__

    parser.add_argument("--version", action="version", version=f"quadrs {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_run(sub, common)
    _add_mc(sub, common)
    _add_sweep(sub, common)
    _add_report(sub)
    _add_paper(sub, common)
    _add_stability(sub, common)
    _add_sensitivity(sub, common)
    _add_scenario(sub, common)
    from quadrs.cli.design import add_linearize, add_tune

    add_tune(sub, common)
    add_linearize(sub, common)
    from quadrs.cli.rare import add_rare

    add_rare(sub, common)
    from quadrs.cli.mission import DEFAULT_PRESET, add_mission

    add_mission(sub, _scenario_options(DEFAULT_PRESET))
    return parser


def _add_run(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "run",
        parents=[common],
        help="fly once and print the per-phase metrics",
        description="Fly the scenario once and print the per-phase metrics of the relative "
        "oscillation e_o (IAE in m s, ITAE in m s^2, max_abs/rms in m, tracking_rms in m, "
        "peak_frequency in Hz, peak_amplitude in m) and of the payload's vertical "
        "acceleration (max_accel, rms_accel in m/s^2).",
    )
    p.add_argument(
        "--controller", choices=_controller_names(), default="smc", help="controller (default: smc)"
    )
    p.add_argument("--seed", type=int, default=0, metavar="S", help="master seed (default: 0)")
    p.add_argument(
        "--realisation",
        type=int,
        default=0,
        metavar="I",
        help="gust realisation of the seed, the same as realisation I of `quadrs mc` (default: 0)",
    )
    p.add_argument("--plot", type=Path, metavar="DIR", help="write the flight's figures here")
    p.add_argument(
        "--trace",
        type=Path,
        metavar="FILE",
        help="write the time trace (t in s; states, references, controls, wind in m/s, e_o "
        "in m) as .parquet (with the scenario, seed, controller, realisation and version; "
        "read it with quadrs.Flight.read_parquet) or plain .csv",
    )


def _add_mc(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "mc",
        parents=[common],
        help="Monte Carlo batch; prints the Table-3 summary",
        description="Fly many gust realisations with every controller (paired: the same gust "
        "for each) and print the paper's Table 3 with 95% confidence intervals (IAE in m s, "
        "ITAE in m s^2; P = 100 SMC/PD in percent).",
    )
    _batch_options(p, 1000, "write the runs (one row per realisation, controller, phase)")
    _table_options(p)
    p.add_argument("--plots", type=Path, metavar="DIR", help="write the batch's figures here")
    p.add_argument(
        "--checkpoint",
        type=Path,
        metavar="DIR",
        help="append each finished chunk of realisations to this Parquet dataset directory "
        "as it completes, so a killed run loses at most the chunks in flight",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="continue the run in --checkpoint DIR: fly only the realisations it lacks "
        "(same scenario, seed and controllers required)",
    )
    p.add_argument(
        "--chunk",
        type=int,
        metavar="N",
        help="realisations per chunk (default: about 1/20 of the runs when checkpointing, "
        "4 tasks per thread on Dask, else all at once)",
    )
    p.add_argument(
        "--fused",
        action="store_true",
        help="fused multiply-adds: faster, equal to the default to about 1e-12 but not bit for "
        "bit, and not across instruction sets (docs/performance.md); recorded in --out and "
        "--checkpoint",
    )
    _limit_options(p)


def _add_sweep(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "sweep",
        parents=[common],
        help="Monte Carlo at every point of a one- or two-key grid",
        description="Run a Monte Carlo batch at every grid point of one or two scenario keys, "
        "with the same seed at every point (common random numbers: differences between "
        "points are not gust noise). Prints mean IAE (m s) and ITAE (m s^2) per controller "
        "and P = 100 SMC/PD (%) per point and phase.",
    )
    p.add_argument(
        "--param",
        required=True,
        metavar="KEY",
        help="dotted scenario key to sweep, e.g. payload.natural_frequency (Hz)",
    )
    p.add_argument(
        "--values",
        required=True,
        type=_values,
        metavar="V1,V2,...",
        help="its values in the key's unit, comma-separated (or a TOML array)",
    )
    p.add_argument("--param2", metavar="KEY", help="optional second key (full grid)")
    p.add_argument("--values2", type=_values, metavar="V1,V2,...", help="values of --param2")
    _batch_options(p, 100, "write the tidy runs table of every point (swept keys as columns)")
    p.add_argument("--plots", type=Path, metavar="DIR", help="write the sweep's figures here")
    _limit_options(p)


def _values(text: str) -> list[Any]:
    from quadrs.scenario.scenario import parse_value

    text = text.strip()
    if text.startswith("["):
        value = parse_value(text)
        if not isinstance(value, list):
            raise argparse.ArgumentTypeError(f"not a TOML array: {text!r}")
        return value
    values = [parse_value(v.strip()) for v in text.split(",") if v.strip()]
    if not values:
        raise argparse.ArgumentTypeError("no values given")
    return values


def _add_report(sub: Any) -> None:
    p = sub.add_parser(
        "report",
        help="reprint the summary of a saved Monte Carlo, mission or sweep file",
        description="Reprint the Table-3 summary (or a sweep's summary) from a Parquet file "
        "written by `quadrs mc --out` or `quadrs sweep --out`; for the flights of a route "
        "(`quadrs mission --out`), the mission's tables at the first --limit (default "
        "max_accel=9.81).",
    )
    p.add_argument(
        "file",
        type=Path,
        metavar="RUNS",
        help="the saved runs: a .parquet file (mc --out, sweep --out) or a --checkpoint directory",
    )
    p.add_argument("--plots", type=Path, metavar="DIR", help="write figures from the file here")
    _limit_options(p)
    _table_options(p)


def _limit_options(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--limit",
        metavar="METRIC=THRESHOLD",
        action="append",
        type=_limit,
        default=[],
        help="print P(METRIC > THRESHOLD) per controller and phase with its exact 95%% "
        "interval and the runs needed for a chosen width, e.g. max_accel=2.0 (m/s^2; a bare "
        "2.0 means max_accel), max_swing=30 (degrees); "
        "repeatable; a run counts as exceeding in the phase it diverged in and later ones",
    )
    p.add_argument(
        "--half-width",
        type=_half_width,
        default=1.0,
        metavar="PP",
        help="interval half-width, in percentage points, for the runs-needed column of "
        "--limit (default: %(default)s)",
    )


def _limit(text: str) -> tuple[str, float]:
    """``--limit`` (quadrs.cli.common.limit_option)."""
    from quadrs.cli.common import limit_option

    return limit_option(text)


def _half_width(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not 0 < value < 50:
        raise argparse.ArgumentTypeError(f"must be in (0, 50) percentage points, got {text!r}")
    return value


def _print_limits(result: Any, args: argparse.Namespace) -> None:
    """The exceedance tables of ``--limit`` (and the paired PD/SMC difference)."""
    from quadrs.stats.risk import limits_difference_table, limits_table

    if not args.limit:
        return
    print(
        "\nP(metric > threshold), exact 95% Clopper-Pearson intervals; a diverged run counts as "
        "exceeding from the phase it diverged in:"
    )
    _print_frame(_thresholds_shown(limits_table(result, args.limit, args.half_width / 100)))
    if {"pd", "smc"} <= set(result.controllers):
        print("\nSMC - PD, paired on the same gusts (Newcombe interval, exact McNemar p):")
        _print_frame(_thresholds_shown(limits_difference_table(result, args.limit)))


def _thresholds_shown(table: Any) -> Any:
    """A limits table's ``threshold`` column in the unit the tables show (degrees for swing),
    with that unit beside it: every table of limits the same way."""
    from quadrs.present.labels import shown_unit, shown_value

    if "threshold" in table:
        metrics = [str(m) for m in table.index]
        table["threshold"] = [shown_value(m, float(v)) for m, v in zip(metrics, table["threshold"],
                                                                         strict=True)]  # fmt: skip
        table.insert(list(table.columns).index("threshold") + 1, "unit",
                     [shown_unit(m) for m in metrics])  # fmt: skip
    return table


def _add_paper(sub: Any, common: argparse.ArgumentParser) -> None:
    from quadrs.paper.grid import FREQUENCIES, MASSES

    p = sub.add_parser(
        "paper",
        parents=[common],
        help="every table and figure of the paper, and report.md",
        description="Remake the paper's Figs. 4-16 and Table 3 with quadrs (with Monte Carlo "
        "versions) into DIR, with report.md setting our Table 3 beside the paper's. The numbers "
        "are not the paper's (see docs/paper-calibration.md).",
    )
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory")
    p.add_argument(
        "--runs",
        type=int,
        default=200,
        metavar="N",
        help="Monte Carlo realisations for Table 3 (default: %(default)s; raise for tighter "
        "intervals)",
    )
    p.add_argument(
        "--sweep-runs",
        type=int,
        default=None,
        metavar="N",
        help="realisations per natural frequency for Figs. 13/14 (default: runs/10, >= 2)",
    )
    p.add_argument(
        "--frequencies",
        type=_values,
        default=list(FREQUENCIES),
        metavar="F1,F2,...",
        help=f"payload natural frequencies in Hz for Figs. 13/14 (default: "
        f"{','.join(map(str, FREQUENCIES))})",
    )
    p.add_argument(
        "--masses",
        type=_values,
        default=list(MASSES),
        metavar="M1,M2,...",
        help=f"payload masses in kg for Fig. 16 (default: {','.join(map(str, MASSES))})",
    )
    p.add_argument("--seed", type=int, default=0, metavar="S", help="master seed (default: 0)")
    p.add_argument(
        "--workers", type=int, default=None, metavar="W", help="worker threads (default: all)"
    )
    _table_options(p)
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (there is none anyway unless stderr is a terminal)",
    )


def _add_stability(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "stability",
        parents=[common],
        help="closed-loop poles at hover and a verdict",
        description="Linearise the closed loop at hover and print its poles (1/s) and a "
        "stability verdict for each controller.",
    )
    p.add_argument(
        "--controller",
        choices=(*_controller_names(), "both"),
        default="both",
        help="a law, or both of the paper's (pd and smc; the default)",
    )
    p.add_argument(
        "--poles",
        action="store_true",
        help="also print every pole (real and imaginary part in 1/s, frequency in Hz)",
    )


def _add_sensitivity(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "sensitivity",
        parents=[common],
        help="which uncertain parameter matters most: Sobol' indices",
        description="Fly a Saltelli design over the scenario's dispersed keys (--disperse or "
        "a [dispersions] table) and the gust realisation, and print each key's first-order "
        "(S1) and total (ST) Sobol' index of one metric with 95% intervals, largest first.",
    )
    p.add_argument(
        "--runs",
        type=int,
        default=256,
        metavar="N",
        help="base sample size, a power of two; flies N (k + 2) realisations per controller "
        "for k factors (default: %(default)s)",
    )
    p.add_argument("--seed", type=int, default=0, metavar="S", help="master seed (default: 0)")
    p.add_argument(
        "--workers", type=int, default=None, metavar="W", help="worker threads (default: all)"
    )
    p.add_argument(
        "--controllers",
        type=_controllers,
        default=_paper_controllers(),
        metavar="LIST",
        help=f"comma-separated controllers, of {','.join(_controller_names())} "
        f"(default: the paper's {','.join(_paper_controllers())})",
    )
    p.add_argument(
        "--metric", default="iae", metavar="NAME", help="metric to rank by (default: iae)"
    )
    p.add_argument("--phase", metavar="NAME", help="only this phase (default: every phase)")
    p.add_argument(
        "--no-gust-factor",
        action="store_true",
        help="fly one gust for every row instead of treating the realisation as a factor",
    )
    scheduler_option(p)
    p.add_argument("--out", type=Path, metavar="FILE.parquet", help="write every index here")
    p.add_argument("--plots", type=Path, metavar="DIR", help="write index bar charts here")
    p.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (there is none anyway unless stderr is a terminal)",
    )


def _add_scenario(sub: Any, common: argparse.ArgumentParser) -> None:
    p = sub.add_parser(
        "scenario",
        help="show a scenario, list its keys or the presets",
        description="Inspect scenarios: `show` prints the full TOML (SI units) laid out like "
        "its preset, with the preset's comments and units, `keys` every dotted key with its "
        "value and unit, `presets` the shipped presets.",
    )
    ssub = p.add_subparsers(dest="action", metavar="ACTION", required=True)
    show = ssub.add_parser("show", parents=[common], help="print the scenario as TOML")
    show.add_argument(
        "--diff",
        action="store_true",
        help="print only the keys that differ from the preset the scenario starts from "
        "(its `base`, else the --preset, else paper), as KEY = VALUE  # preset: OLD",
    )
    ssub.add_parser("keys", parents=[common], help="list every dotted key = current value  # unit")
    ssub.add_parser("presets", help="list the shipped presets")


# -- shared steps -----------------------------------------------------------------------------
def _base_preset(args: argparse.Namespace) -> str:
    """The preset the scenario starts from: its file's ``base``, else --preset, else paper."""
    from quadrs.scenario.scenario import base_preset

    found = base_preset(args.scenario) if args.scenario is not None else None
    return found or args.preset or "paper"


def load_scenario(args: argparse.Namespace) -> Any:
    """The scenario of ``--preset``/``--scenario`` with every ``--set`` applied at once, then
    flying the route of ``--plan`` if the command has it (quadrs.scenario.route_files)."""
    from quadrs.scenario.scenario import Scenario, canonical_key, parse_value

    if args.scenario is not None and args.preset is not None:
        raise BadInput("--preset and --scenario: give one or the other")
    if args.scenario is not None:
        base = Scenario.from_toml(args.scenario)
    else:
        base = Scenario.preset(args.preset or "paper")
    changes: dict[str, Any] = {}
    for item in args.overrides:
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise BadInput(f"--set {item!r}: expected KEY=VALUE")
        changes[key] = parse_value(value.strip())
    if args.dispersions:
        table = dict(base.dispersions)
        if isinstance(changes.get("dispersions"), dict):
            table.update(changes.pop("dispersions"))
        for item in args.dispersions:
            key, sep, spec = item.partition("=")
            if not sep or not key.strip():
                raise BadInput(f"--disperse {item!r}: expected KEY=DIST(ARGS)")
            table[canonical_key(key.strip())] = parse_distribution(spec)  # replaces the base's
        changes["dispersions"] = table
    plan = getattr(args, "plan", None)
    if plan is None:
        return base.override(changes) if changes else base
    if "trajectory.route_file" in changes:
        raise BadInput("--plan and --set trajectory.route_file: give one route file")
    return Scenario.from_plan(plan, base, changes)


def parse_distribution(text: str) -> dict[str, Any]:
    """``"uniform(0.1, 0.4)"`` or ``"normal(mean=2, std=0.2)"`` -> a dispersion entry."""
    from quadrs.scenario.scenario import parse_value

    name, sep, rest = text.strip().partition("(")
    name = name.strip()
    if not sep or not rest.endswith(")") or name not in DISTRIBUTIONS:
        raise BadInput(
            f"--disperse: {text!r} is not DIST(ARGS) with DIST one of {', '.join(DISTRIBUTIONS)}"
        )
    order = DISTRIBUTIONS[name]
    spec: dict[str, Any] = {"dist": name}
    args = [a.strip() for a in rest[:-1].split(",") if a.strip()]
    for i, arg in enumerate(args):
        pname, eq, value = arg.partition("=")
        if not eq:
            if i >= len(order):
                raise BadInput(f"--disperse: {name} takes {len(order)} values ({', '.join(order)})")
            pname, value = order[i], arg
        spec[pname.strip()] = parse_value(value.strip())
    return spec


def _print_frame(frame: pd.DataFrame, out: TextIO | None = None, digits: int = 4) -> None:
    import pandas as pd

    with pd.option_context(
        "display.width",
        250,
        "display.max_columns",
        None,
        "display.max_rows",
        500,
        "display.float_format",
        lambda v: f"{v:.{digits}g}",
    ):
        print(terminal_text(frame.to_string()), file=out or sys.stdout)


def _check_suffix(path: Path | None, allowed: Sequence[str], option: str) -> None:
    if path is not None and path.suffix.lower() not in allowed:
        raise BadInput(f"{option} {str(path)!r}: expected a file ending in {' or '.join(allowed)}")


def _check_positive(name: str, value: int | None, minimum: int = 1) -> None:
    if value is not None and value < minimum:
        raise BadInput(f"{name} must be >= {minimum}, got {value}")


def _progress(args: argparse.Namespace) -> bool:
    """Progress bars on a terminal only: none in logs, pipes or CI output."""
    return not args.no_progress and sys.stderr.isatty()


def _check_outputs(*paths: Path | None) -> None:
    """Before any work: the outputs can be written (:func:`quadrs.cli.outputs.check_outputs`)."""
    from quadrs.cli.outputs import check_outputs

    check_outputs(*paths)


def _check_directories(*paths: Path | None, option: str = "--plots") -> None:
    """Before any work: the figure directories can be written
    (:func:`quadrs.cli.outputs.check_directories`)."""
    from quadrs.cli.outputs import check_directories

    check_directories(*paths, option=option)


def _save(write: Any, path: Path) -> bool:
    """``write(path)``, or a recovery copy named on stderr (:func:`quadrs.cli.outputs.save`)."""
    from quadrs.cli.outputs import save

    return save(write, path)


# -- commands ---------------------------------------------------------------------------------
def cmd_run(args: argparse.Namespace) -> int:
    """One flight: metrics table, optional figures and trace."""
    from quadrs import plots
    from quadrs.runs.flight import simulate

    scenario = load_scenario(args)
    _check_suffix(args.trace, (".parquet", ".csv"), "--trace")
    _check_outputs(args.trace)
    _check_directories(args.plot, option="--plot")
    flight = simulate(scenario, args.controller, args.seed, realisation=args.realisation)
    print(f"{args.controller.upper()}, seed {args.seed}, realisation {args.realisation}")
    _print_frame(flight.metrics.set_index("phase"))
    if flight.diverged:
        print(f"warning: the flight diverged at t = {flight.diverged_at:g} s", file=sys.stderr)
    status = EXIT_OK

    def write_trace(path: Path) -> None:
        if path.suffix.lower() == ".csv":
            flight.to_csv(path)
        else:
            flight.to_parquet(path)

    if args.trace is not None and not _save(write_trace, args.trace):
        status = EXIT_FAIL
    if args.plot is not None:
        d = args.plot
        files = plots.save(plots.altitude(flight), d / "altitude")
        files += plots.save(plots.oscillation(flight), d / "oscillation")
        files += plots.save(plots.spectra(flight), d / "spectra")
        files += plots.save(plots.psd(flight), d / "psd")
        files += plots.save(plots.gust_force(flight), d / "gust_force")
        print(f"wrote {len(files)} figure files to {d}", file=sys.stderr)
    return status


def cmd_mc(args: argparse.Namespace) -> int:
    """A Monte Carlo batch: Table 3, optional Parquet and figures; 130 if interrupted."""
    from quadrs.runs.montecarlo import monte_carlo

    scenario = load_scenario(args)
    _check_suffix(args.out, (".parquet",), "--out")
    _check_positive("--runs", args.runs)
    _check_positive("--workers", args.workers)
    _check_positive("--chunk", args.chunk)
    if args.resume and args.checkpoint is None:
        raise BadInput("--resume needs --checkpoint DIR (the run to continue)")
    if args.checkpoint is not None and not args.resume and args.checkpoint.exists():
        if any(args.checkpoint.iterdir()):
            raise BadInput(f"--checkpoint {args.checkpoint} already holds a run: add --resume")
    _check_outputs(args.out)
    _check_directories(args.plots)
    if args.scheduler is None:  # a cluster's speed is not this machine's
        _announce_batch("mc", scenario, args.controllers, args.runs, args.workers, args.seed)
    from quadrs.engine.calls import deferred_signals

    with contextlib.ExitStack() as keeping:
        with dask_client(args.scheduler) as client:
            mc = monte_carlo(
                scenario,
                runs=args.runs,
                seed=args.seed,
                controllers=args.controllers,
                workers=args.workers,
                progress=_progress(args),
                out=args.checkpoint,
                resume=args.resume,
                chunk=args.chunk,
                client=client,
                sampling=args.sampling,
                fused=args.fused,
            )
            # The batch is over: a Ctrl-C from here (a second one after the one that stopped
            # it) waits until what finished is saved, then ends the command (status 130).
            keeping.enter_context(deferred_signals())
        saved = True
        if args.out is not None and not mc.runs.empty:  # saved first: Ctrl-C keeps it
            saved = _save(mc.to_parquet, args.out)
    if not mc.runs.empty:
        _print_dispersions(mc)
        if _is_mission(mc):
            _print_mission(mc, args)
        else:
            _print_table3(mc, args)
        _print_limits(mc, args)
    if args.plots is not None and not mc.runs.empty:
        _mc_plots(mc, args.plots, args.limit)
    return EXIT_INTERRUPT if mc.interrupted else EXIT_OK if saved else EXIT_FAIL


def _announce_batch(
    command: str,
    scenario: Any,
    controllers: Sequence[str],
    runs: int,
    workers: int | None,
    seed: int,
    extra: int = 0,
    what: str = "",
) -> None:
    """Say on stderr what a long batch flies and roughly how long (quadrs.cli.cost): ``runs``
    realisations of each controller, plus ``extra`` flights."""
    from quadrs.cli.cost import announce, calibrate, precheck, say

    precheck(scenario, controllers, runs, workers, seed)
    cal = calibrate(scenario, controllers, workers, seed, flights=min(runs, 8))
    flights = runs * len(controllers) + extra
    names = " and ".join(c.upper() for c in controllers)
    what = what or f"{runs} realisations x {names}"
    say(announce(command, what, flights, cal), cal.estimate(flights))


def _print_dispersions(mc: Any) -> None:
    """A dispersed batch says what varied before its table."""
    from quadrs.scenario.dispersion import describe

    lines = describe(mc.scenario)
    if lines:
        print(f"Dispersed ({mc.sampling} sampling, values per realisation in the runs table):")
        for line in lines:
            print(f"  {line}")


def _mc_plots(mc: Any, directory: Path, limits: Sequence[tuple[str, float]] = ()) -> None:
    from quadrs import plots

    figures: list[tuple[str, Any]] = [("distributions", lambda: plots.distributions(mc.runs))]
    if mc.spectra is not None:
        figures += [("spectra", lambda: plots.ensemble_spectra(mc.spectra)),
                    ("psd", lambda: plots.ensemble_psd(mc.spectra))]  # fmt: skip
    for metric in dict.fromkeys([m for m, _ in limits] or ["max_accel"]):
        marks = [t for m, t in limits if m == metric]
        curves = lambda m=metric, t=marks: plots.exceedance_curves(mc.runs, m, t)  # noqa: E731
        figures.append((f"exceedance_{metric}", curves))
    if mc.dispersed_keys:
        figures.append(("dispersion_iae", lambda: plots.dispersion_scatter(mc, "iae")))
    files: list[Path] = []
    for name, make in figures:
        # One figure without data to draw (every flight diverged: nothing on a log scale)
        # must not cost the others.
        try:
            files += plots.save(make(), directory / name)
        except ValueError as e:
            print(terminal_text(f"quadrs: warning: figure {name} not drawn ({_one_line(str(e))})"),
                  file=sys.stderr)  # fmt: skip
    print(f"wrote {len(files)} figure files to {directory}", file=sys.stderr)


def cmd_sweep(args: argparse.Namespace) -> int:
    """A one- or two-key sweep: compact summary, optional Parquet and figures."""
    from quadrs.runs.sweep import sweep

    scenario = load_scenario(args)
    grid = {args.param: args.values}
    if (args.param2 is None) != (args.values2 is None):
        raise BadInput("--param2 and --values2 go together")
    if args.param2 is not None:
        if args.param2 == args.param:
            raise BadInput(f"--param2 {args.param2}: the same key as --param")
        grid[args.param2] = args.values2
    _check_suffix(args.out, (".parquet",), "--out")
    _check_positive("--runs", args.runs)
    _check_positive("--workers", args.workers)
    _check_outputs(args.out)
    with dask_client(args.scheduler) as client:
        result = sweep(
            scenario,
            grid,
            runs=args.runs,
            seed=args.seed,
            controllers=args.controllers,
            workers=args.workers,
            progress=_progress(args),
            client=client,
        )
    saved = True
    if args.out is not None and not result.runs.empty:  # saved first: Ctrl-C keeps it
        saved = _save(result.to_parquet, args.out)
    if not result.runs.empty:
        _print_frame(result.compact())
        _print_limits(result, args)
    if args.plots is not None and not result.runs.empty:
        _sweep_plots(result, args.plots)
    return EXIT_INTERRUPT if result.interrupted else EXIT_OK if saved else EXIT_FAIL


def _sweep_plots(result: Any, directory: Path) -> None:
    from quadrs import plots

    summ = result.summary()
    files = plots.save(plots.sweep_metric(summ, "max_abs"), directory / "sweep_max_abs")
    files += plots.save(plots.sweep_metric(summ, "iae"), directory / "sweep_iae")
    fig = plots.distributions(result.runs, by=result.keys)  # one box per grid point
    files += plots.save(fig, directory / "distributions")
    print(f"wrote {len(files)} figure files to {directory}", file=sys.stderr)


#: Files quadrs writes that ``report`` does not read: their kind -> what to say instead.
_NOT_REPORTED = {
    "rare_event": "a rare-event result (quadrs rare --out): report reads Monte Carlo, mission "
    "and sweep files; read it with RareEventResult.read_parquet",
    "flight": "one flight's trace (quadrs run --trace): report reads Monte Carlo, mission and "
    "sweep files; read it with quadrs.Flight.read_parquet",
}


def _file_kind(path: Path) -> str | None:
    """The ``kind`` a quadrs Parquet file's metadata names (None if it names none)."""
    from quadrs.io.parquet import read_meta

    meta = read_meta(path, b"quadrs")
    kind = meta.get("kind") if isinstance(meta, dict) else None
    return kind if isinstance(kind, str) else None


def cmd_report(args: argparse.Namespace) -> int:
    """Reprint a saved batch's (or sweep's) summary; figures from it."""
    from quadrs.runs.montecarlo import MonteCarloResult
    from quadrs.runs.sweep import SweepResult, is_sweep_file

    if args.file.is_dir():
        from quadrs.runs.store import RunStore

        if not RunStore(args.file).exists():
            raise BadInput(f"{str(args.file)!r}: not a quadrs run directory")
    elif not args.file.exists():
        raise BadInput(f"{str(args.file)!r}: no such file")
    kind = None if args.file.is_dir() else _file_kind(args.file)
    if kind in _NOT_REPORTED:
        raise BadInput(f"{str(args.file)!r} is {_NOT_REPORTED[kind]}")
    if not args.file.is_dir() and is_sweep_file(args.file):
        result = SweepResult.read_parquet(args.file)
        _print_frame(result.compact())
        _print_limits(result, args)
        if args.plots is not None:
            _sweep_plots(result, args.plots)
    else:
        mc = MonteCarloResult.read_parquet(args.file)
        note = " (interrupted batch)" if mc.interrupted else ""
        print(f"{args.file}: {len(mc.realisations)} realisations, seed {mc.seed}{note}")
        if mc.runs.empty:  # a run stopped before its first realisation finished
            return EXIT_OK
        if _is_mission(mc):
            _print_mission(mc, args)
        else:
            _print_table3(mc, args)
        _print_limits(mc, args)
        if args.plots is not None:
            _mc_plots(mc, args.plots, args.limit)
    return EXIT_OK


def _is_mission(mc: Any) -> bool:
    """A batch of a route (``quadrs mission``, or ``mc`` of a routed scenario): its answer is
    the mission's tables, not the paper's Table 3 of the spring's displacement."""
    return str(mc.scenario["trajectory.interpolation"]) == "route"


def _print_mission(mc: Any, args: argparse.Namespace) -> None:
    """The mission's tables of each controller, at the first --limit; without one, the question
    the mission was asked when it was saved (``MonteCarloResult.question``), else the
    mission's default (max_specific_force at 2 g)."""
    from quadrs.cli.mission import DEFAULT_LIMIT, DEFAULT_METRIC
    from quadrs.design.mission import mission_report

    asked = dict(getattr(mc, "question", None) or {})
    if args.limit:
        asked["metric"], asked["limit"] = args.limit[0]
    metric = asked.get("metric", DEFAULT_METRIC)
    limit = asked.get("limit", DEFAULT_LIMIT)
    extra = {k: asked[k] for k in ("track_limit", "cross_track_limit", "quantile")
             if asked.get(k) is not None}  # fmt: skip
    if asked and not args.limit:
        print(f"(the question this mission was saved with: P({metric} > "
              f"{_shown_limit(metric, limit)}))")  # fmt: skip
    for ctrl in mc.controllers:
        print(mission_report(mc, limit, ctrl, metric=metric, **extra).to_text(width=100))


def _shown_limit(metric: str, limit: float) -> str:
    from quadrs.present.labels import shown_unit, shown_value

    return f"{shown_value(metric, limit):g} {shown_unit(metric)}".rstrip()


def cmd_sensitivity(args: argparse.Namespace) -> int:
    """Sobol' indices of the dispersed keys: a compact ranking, optional Parquet and bars."""
    from quadrs.design.sensitivity import sensitivity
    from quadrs.engine.calls import MAX_WORKERS, check_int
    from quadrs.runs.flight import METRIC_COLUMNS

    scenario = load_scenario(args)
    _check_suffix(args.out, (".parquet",), "--out")
    _check_positive("--workers", args.workers)
    check_int("--seed", args.seed)
    if args.workers is not None:
        check_int("--workers", args.workers, 1, MAX_WORKERS)
    if args.metric not in METRIC_COLUMNS:
        raise BadInput(f"--metric {args.metric!r}: one of {', '.join(METRIC_COLUMNS)}")
    if args.phase is not None and args.phase not in scenario.phase_names:
        raise BadInput(f"--phase {args.phase!r}: one of {', '.join(scenario.phase_names)}")
    _check_outputs(args.out)
    with dask_client(args.scheduler) as client:
        sa = sensitivity(
            scenario,
            runs=args.runs,
            seed=args.seed,
            controllers=args.controllers,
            workers=args.workers,
            progress=_progress(args),
            gust=not args.no_gust_factor,
            client=client,
        )
    status = EXIT_OK
    if args.out is not None and not _save(sa.to_parquet, args.out):  # first: Ctrl-C keeps it
        status = EXIT_FAIL
    print(
        f"Sobol' indices of {args.metric} (N = {sa.runs}, {len(sa.samples['row'].unique())} "
        f"flights per controller; ± half-width of the 95% interval)"
    )
    _print_frame(sensitivity_table(sa, args.metric, args.phase), digits=2)
    if args.plots is not None:
        from quadrs import plots

        files = plots.save(plots.sobol_bars(sa, args.metric), args.plots / f"sobol_{args.metric}")
        print(f"wrote {len(files)} figure files to {args.plots}", file=sys.stderr)
    return status


def sensitivity_table(sa: Any, metric: str, phase: str | None) -> pd.DataFrame:
    """Phase, controller, parameter, S1 ± and ST ±: largest total index first, fits 100
    columns."""
    import pandas as pd

    t = sa.ranking(metric, phase)
    pm = lambda v, c: "" if pd.isna(v) else f"{v:5.2f} ± {c:4.2f}"  # noqa: E731
    out = pd.DataFrame(
        {
            "phase": t["phase"].to_numpy(),
            "controller": t["controller"].to_numpy(),
            "parameter": t["parameter"].to_numpy(),
            "S1": [pm(v, c) for v, c in zip(t["S1"], t["S1_conf"], strict=True)],
            "ST": [pm(v, c) for v, c in zip(t["ST"], t["ST_conf"], strict=True)],
        }
    )
    return out.set_index(["phase", "controller", "parameter"])


def cmd_paper(args: argparse.Namespace) -> int:
    """Every table and figure of the paper, and report.md."""
    from quadrs.paper.pipeline import paper

    scenario = load_scenario(args)
    _check_positive("--runs", args.runs, 2)
    _check_positive("--sweep-runs", args.sweep_runs, 2)
    _check_positive("--workers", args.workers)
    sweep_runs = max(2, args.runs // 10) if args.sweep_runs is None else args.sweep_runs
    from quadrs.paper.pipeline import _check as check_paper

    check_paper(args.runs, sweep_runs, args.seed, args.frequencies, args.masses, scenario)
    _check_directories(args.out, option="--out")  # refused before the estimate, not after
    extra = 2 * sweep_runs * len(args.frequencies)
    what = (f"{args.runs} realisations x PD and SMC, a sweep of {len(args.frequencies)} "
            f"frequencies x {sweep_runs}")  # fmt: skip
    _announce_batch("paper", scenario, ("pd", "smc"), args.runs, args.workers, args.seed,
                    extra, what)  # fmt: skip
    result = paper(
        args.out,
        scenario,
        args.runs,
        args.seed,
        args.workers,
        _progress(args),
        sweep_runs=args.sweep_runs,
        frequencies=args.frequencies,
        masses=args.masses,
    )
    if result.mc is not None and not result.mc.runs.empty:
        _print_table3(result.mc, args)
    print(f"wrote {len(result.files)} files to {result.out}", file=sys.stderr)
    return EXIT_INTERRUPT if result.interrupted else EXIT_OK


def cmd_stability(args: argparse.Namespace) -> int:
    """Closed-loop poles at hover, per controller."""
    from quadrs.hover.stability import stability as check

    scenario = load_scenario(args)
    controllers = _paper_controllers() if args.controller == "both" else (args.controller,)
    unstable = False
    for controller in controllers:
        report = check(scenario, controller=controller)
        print(f"== {controller.upper()} ==")
        print(str(report))
        if args.poles:
            _print_frame(report.poles)
        unstable |= report.verdict == "unstable"
    return EXIT_FAIL if unstable else EXIT_OK


def cmd_scenario(args: argparse.Namespace) -> int:
    """Show a scenario as TOML, list its keys, or list the presets."""
    from quadrs.present.table3 import toml_value
    from quadrs.scenario.scenario import Scenario, presets

    if args.action == "presets":
        print("\n".join(presets()))
        return EXIT_OK
    scenario = load_scenario(args)
    if args.action == "show":
        base = _base_preset(args)
        if not args.diff:
            sys.stdout.write(scenario.to_toml(like=base))
            return EXIT_OK
        changes = scenario.differences(Scenario.preset(base))
        print(f"# {len(changes)} key(s) differ from the preset {base!r}")
        for key, (old, new) in changes.items():
            was = f"{base}: {'not set' if old is None else toml_value(old)}"
            line = f"# {key} not set" if new is None else f"{key} = {toml_value(new)}"
            print(f"{line:<37} # {was}")
    else:
        from quadrs.scenario.units import unit

        lines = [(f"{key} = {toml_value(scenario[key])}", key) for key in scenario.keys()]
        width = min(max(len(line) for line, _ in lines), 60)
        for line, key in lines:
            try:
                print(f"{line:<{width}}  # {unit(key)}")
            except KeyError:  # a key the units table does not know (the engine refuses those)
                print(line)
        _print_unset_keys(scenario)
    return EXIT_OK


def _print_unset_keys(scenario: Any) -> None:
    """The keys this scenario does not set (optional tables such as ``wind.table``,
    ``actuator.faults``, other kinds' parameters), with their units and labels: every key the
    scenario may take, from the one table of them (``quadrs.scenario.units``)."""
    import re

    from quadrs.scenario.units import LABELS, UNITS

    index = re.compile(r"\[\d+\]")
    present = {index.sub("", k) for k in scenario.keys()}
    unset = [k for k in sorted(UNITS) if k not in present
             and not any(k.startswith(f"{p}.") for p in present)]  # fmt: skip
    if not unset:
        return
    print("\n# Not set here (optional tables and other kinds' keys; --set or a file may give "
          "them):")  # fmt: skip
    width = min(max(len(k) for k in unset), 48)
    for key in unset:
        print(f"# {key:<{width}}  {UNITS[key]:<8} {LABELS.get(key, '')}".rstrip())


COMMANDS = {
    "run": cmd_run,
    "mc": cmd_mc,
    "sweep": cmd_sweep,
    "report": cmd_report,
    "paper": cmd_paper,
    "stability": cmd_stability,
    "sensitivity": cmd_sensitivity,
    "scenario": cmd_scenario,
    "tune": lambda args: _design("cmd_tune", args),
    "linearize": lambda args: _design("cmd_linearize", args),
    "rare": lambda args: _rare(args),
    "mission": lambda args: _mission(args),
}


def _mission(args: argparse.Namespace) -> int:
    """``mission`` lives in quadrs.cli.mission."""
    from quadrs.cli.mission import cmd_mission

    return cmd_mission(args, load_scenario)


def _rare(args: argparse.Namespace) -> int:
    """``rare`` lives in quadrs.cli.rare."""
    from quadrs.cli.rare import cmd_rare

    return cmd_rare(args, load_scenario)


def _design(name: str, args: argparse.Namespace) -> int:
    """``tune`` and ``linearize`` live in quadrs.cli.design."""
    from quadrs.cli import design as cli_design

    # It gets the scenario loader rather than importing this module (no import cycle).
    return int(getattr(cli_design, name)(args, load_scenario))


# -- entry point ------------------------------------------------------------------------------
@contextlib.contextmanager
def _terse_warnings() -> Iterator[None]:
    """Warnings as one ``quadrs: warning: ...`` line each, without source lines, each distinct
    message once (a sweep would otherwise repeat the same stability warning at every point)."""
    seen: set[str] = set()

    def show(message: Warning | str, category: type[Warning], *_: Any, **__: Any) -> None:
        text = _one_line(str(message))
        if text not in seen:
            seen.add(text)
            kind = "note" if category.__name__ == "StabilityNote" else "warning"  # calm: harmless
            print(terminal_text(f"quadrs: {kind}: {text}"), file=sys.stderr)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


def _one_line(text: str) -> str:
    return "; ".join(line.strip() for line in text.strip().splitlines() if line.strip())


def _bad_input_types() -> tuple[type[BaseException], ...]:
    """What counts as bad input: scenario errors (a ValueError), other ValueErrors from the
    API (which include pyarrow's ArrowInvalid) and files that cannot be read."""
    return (ValueError, OSError, MemoryError)


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``quadrs`` with ``argv`` (default: the process's arguments); returns the exit
    status (the console script exits with it)."""
    if list(sys.argv[1:] if argv is None else argv) == ["--version"]:
        # answered before the parser is built: its choices come from modules that load
        # pandas and the design loop (seconds on a cold start)
        from quadrs._core import __version__

        print(f"quadrs {__version__}")
        return EXIT_OK
    try:
        # building the parser imports the libraries its choices come from (a second or two
        # on a cold start): a Ctrl-C meanwhile is an interruption, not a traceback
        parser = build_parser()
        args = parser.parse_args(argv)
    except SystemExit as e:  # --help, --version or a usage error
        return int(e.code) if isinstance(e.code, int) else EXIT_USAGE
    except KeyboardInterrupt:
        print("quadrs: interrupted", file=sys.stderr)
        return EXIT_INTERRUPT
    prog = f"quadrs {args.command}"
    terminated: list[int] = []
    try:
        with _terse_warnings(), _sigterm_as_interrupt(terminated):
            status = COMMANDS[args.command](args)
        return EXIT_TERMINATED if terminated and status == EXIT_INTERRUPT else status
    except KeyboardInterrupt:
        print(f"{prog}: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return EXIT_TERMINATED if terminated else EXIT_INTERRUPT
    except _bad_input_types() as e:
        if os.environ.get("QUADRS_TRACEBACK"):
            raise
        print(terminal_text(f"{prog}: error: {_describe(e)}"), file=sys.stderr)
        return EXIT_USAGE


@contextlib.contextmanager
def _sigterm_as_interrupt(terminated: list[int]) -> Iterator[None]:
    """SIGTERM handled like Ctrl-C (cancel, save what finished), noted in ``terminated`` so
    that the exit status is 143. Only on the main thread; the old handler is restored."""
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        terminated.append(signum)
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _describe(e: BaseException) -> str:
    if isinstance(e, OSError) and e.filename is not None:
        return f"{e.filename!r}: {e.strerror or e}"
    return _one_line(str(e)) or type(e).__name__


if __name__ == "__main__":
    sys.exit(main())
