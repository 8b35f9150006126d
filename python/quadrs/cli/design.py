"""``quadrs tune`` and ``quadrs linearize``: the design loop on the command line.

Kept apart from :mod:`quadrs.cli.main`, which registers these subcommands.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

from quadrs.cli.common import (
    EXIT_FAIL,
    EXIT_INTERRUPT,
    EXIT_OK,
    batch_scope,
    command_parser,
    controller_option,
    passed,
    scheduler_option,
    seed_option,
    workers_option,
)
from quadrs.design.optimize import METHODS
from quadrs.engine.calls import PAPER_CONTROLLERS
from quadrs.present.terminal import terminal_text


class BadParam(ValueError):
    """A malformed ``--param``."""


def _param(text: str) -> tuple[str, tuple[float, float]]:
    key, sep, rng = text.partition("=")
    low, sep2, high = rng.partition(":")
    try:
        lo, hi = float(low), float(high)
    except ValueError:
        lo = hi = math.nan
    if not (sep and sep2 and key.strip()) or not (math.isfinite(lo) and math.isfinite(hi)):
        raise argparse.ArgumentTypeError(f"--param {text!r}: expected KEY=LOW:HIGH")
    if not lo < hi:
        raise argparse.ArgumentTypeError(f"--param {text!r}: LOW must be < HIGH")
    return key.strip(), (lo, hi)


def _constraint(text: str) -> Any:
    from quadrs.design.constraints import parse_constraint

    try:
        return parse_constraint(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_tune(sub: Any, common: argparse.ArgumentParser) -> None:
    """tune gains or calibrate parameters against a Monte Carlo objective

    Minimise the mean over --runs gust realisations (the same ones for every candidate) of
    --objective summed over --phase, over the --param keys within their bounds. Candidates unstable
    at hover in a mode the flight excites are rejected before flying (the mode is named). Writes a
    scenario file that bases on the input and holds the tuned values (see docs/design-loop.md)."""
    from quadrs import _core
    from quadrs.present.labels import INPUT_UNITS

    p = command_parser(sub, add_tune, common)
    controller_option(p)
    p.add_argument(
        "--param",
        type=_param,
        action="append",
        required=True,
        metavar="KEY=LO:HI",
        help="a numeric scenario key and its bounds, repeatable, e.g. "
        "controller.smc.lambda[0]=0.5:8; KEY1,KEY2=LO:HI tunes several keys as one value",
    )
    p.add_argument(
        "--objective",
        choices=list(_core.METRIC_NAMES),
        default="iae",
        metavar="METRIC",
        help=f"metric to minimise, one of {', '.join(_core.METRIC_NAMES)} (default: iae)",
    )
    p.add_argument(
        "--phase",
        action="append",
        default=None,
        metavar="P",
        help="phase the metric is summed over, repeatable (default: every phase)",
    )
    p.add_argument(
        "--constraint",
        type=_constraint,
        action="append",
        default=[],
        metavar="C",
        help="a constraint every chosen candidate must meet, repeatable: METRIC<=X (the mean "
        "over the runs), P(METRIC>T)<=P (the fraction of runs above T), "
        "quantile(METRIC,Q)<=X; >= too; METRIC@PHASE for one phase, else each --phase; "
        "e.g. 'tracking_rms<=0.5' 'P(max_accel>8)<=0.01' 'max_swing@transit<=30'; X and T "
        f"{INPUT_UNITS} (see docs/design-loop.md)",
    )
    p.add_argument("--runs", type=int, default=64, metavar="N", help="realisations (default: 64)")
    seed_option(p)
    p.add_argument(
        "--method",
        choices=METHODS,
        default="differential_evolution",
        help="optimiser (default: differential_evolution)",
    )
    p.add_argument(
        "--maxiter",
        type=int,
        default=None,
        metavar="K",
        help="generations (differential_evolution, default 20) or evaluations (nelder-mead, "
        "default 100)",
    )
    p.add_argument(
        "--popsize",
        type=int,
        default=8,
        metavar="P",
        help="differential_evolution: candidates per generation per parameter (default: 8)",
    )
    p.add_argument(
        "--allow-unstable",
        action="store_true",
        help="fly candidates that are unstable at hover instead of rejecting them",
    )
    workers_option(p, help="threads (default: all)")
    scheduler_option(p)
    p.add_argument(
        "--out", type=Path, required=True, metavar="FILE.toml", help="tuned scenario file"
    )
    p.add_argument("--history", type=Path, metavar="FILE.csv", help="also save every evaluation")


def add_linearize(sub: Any, common: argparse.ArgumentParser) -> None:
    """the closed loop at hover as A, B, C, D and the gust-to-e_o frequency response

    Linearise the closed loop at hover about a steady vertical wind (default: the gust's
    statistically equivalent wind sigma_z sqrt(2/pi)), print its poles and the gust-to-e_o
    transmissibility of each controller, optionally plot it."""
    p = command_parser(sub, add_linearize, common)
    controller_option(p, both=True)
    p.add_argument(
        "--wind",
        type=float,
        default=None,
        metavar="W",
        help="steady vertical wind linearised about, m/s (default: sigma_z sqrt(2/pi))",
    )
    p.add_argument("--plot", type=Path, metavar="DIR", help="write the figure here")
    p.add_argument("--out", type=Path, metavar="FILE.npz", help="save A, B, C, D (numpy .npz)")


def _tuned_toml(args: argparse.Namespace, out: Path, keys: list[str], tuned: Any) -> str:
    """The tuned scenario as a file: ``base`` = the input (preset name or the file's path
    relative to ``out``), then every --set and tuned key (a key inside an array writes the
    whole array, phases included). If that text would not read back as exactly ``tuned``
    (a base that gives ``natural_frequency`` where ``stiffness`` is tuned, a scenario file
    that cannot be a ``base``), the complete scenario is written instead."""
    import tomli_w

    from quadrs.scenario.scenario import Scenario, _split_key

    if args.scenario is not None:
        src = Path(os.path.realpath(args.scenario))
        try:
            base = os.path.relpath(src, Path(os.path.realpath(out)).parent)
        except ValueError:  # another drive
            base = str(src)
    else:
        base = args.preset or "paper"
    keys = [item.partition("=")[0].strip() for item in args.overrides] + keys
    if getattr(args, "dispersions", None):
        keys.append("dispersions")
    data = tuned.to_dict()
    nested: dict[str, Any] = {}
    for key in keys:
        parts = _split_key(key)
        cut = next((i for i, p in enumerate(parts) if isinstance(p, int)), len(parts))
        path = [str(p) for p in parts[: max(cut, 1)]]  # up to the first array
        value: Any = data
        try:
            for part in path:
                value = value[part]
        except (KeyError, TypeError):  # set, then replaced (stiffness by natural_frequency)
            continue
        node = nested
        for part in path[:-1]:
            node = node.setdefault(part, {})
        node[path[-1]] = value
    head = "# Written by quadrs tune: the input, its --set values and the tuned values.\n"
    text = head + tomli_w.dumps({"base": base, **nested})
    try:
        if Scenario.from_toml_string(text, source=str(out)) == tuned:
            return text
    except ValueError:
        pass
    return ("# Written by quadrs tune: the complete tuned scenario (its input could not be "
            "its base).\n" + tuned.to_toml())  # fmt: skip


def _save_tuning(args: argparse.Namespace, result: Any, flown: int, history: Path) -> int:
    """The search's history (at ``history`` when interrupted without ``--history``) and, for
    an admissible and feasible best, the tuned scenario at ``--out``; EXIT_FAIL if a file the
    command was asked for could not be written, else EXIT_OK."""
    from quadrs.design.optimize import expand
    from quadrs.io.files import atomic_write_bytes, atomic_write_frame
    from quadrs.scenario.scenario import Scenario

    h = result.history
    status = EXIT_OK
    if result.interrupted and args.history is None:
        # Ctrl-C keeps the candidates flown: beside --out when --history was not given.
        if _save_text(lambda p: atomic_write_frame(h, p, index=False), history):
            print(f"quadrs tune: the {flown} candidates evaluated are in {history}",
                  file=sys.stderr)  # fmt: skip
    if args.history is not None and not _save_text(
        lambda p: atomic_write_frame(h, p, index=False), args.history
    ):
        status = EXIT_FAIL
    admissible = not bool(h[h["role"] == "best"].iloc[0]["penalised"])
    if admissible and (not result.constraints or result.feasible):
        text = _tuned_toml(args, args.out, list(expand(result.best)), result.scenario)
        # The file must give back exactly the tuned scenario.
        if Scenario.from_toml_string(text, source=str(args.out)) != result.scenario:
            raise RuntimeError(f"{args.out} would not reproduce the tuned scenario")  # a bug
        if not _save_text(lambda p: atomic_write_bytes(p, text.encode()), args.out):
            status = EXIT_FAIL
    return status


def cmd_tune(args: argparse.Namespace) -> int:
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.design.optimize import (
        InfeasibleWarning,
        OptimizeOptions,
        check_tuning,
        expand,
        optimize,
    )
    from quadrs.engine.calls import check_int
    from quadrs.io.files import check_writable

    if args.out.suffix != ".toml":
        raise ValueError(f"--out {str(args.out)!r}: expected a .toml file")
    for name in ("runs", "popsize", "maxiter", "workers"):
        value = getattr(args, name)
        if value is not None and value < 1:
            raise ValueError(f"--{name} must be >= 1, got {value}")
    check_int("--seed", args.seed)
    scenario = load_scenario(args)
    if len(dict(args.param)) != len(args.param):
        raise ValueError("--param: each key at most once")
    phases = tuple(args.phase) if args.phase else tuple(scenario.scenario_phases)
    # The whole problem is checked before the calibration flights and the announcement.
    _, params, phases, _ = check_tuning(scenario, args.controller, dict(args.param),
                                        args.objective, phases, args.constraint)  # fmt: skip
    # Before any flight: the outputs can be written, and the tuned file can be made from a
    # candidate (the midpoint of the bounds), so the work is not lost to a bad --out.
    for path in (args.out, args.history):
        if path is not None:
            check_writable(path)
    middle = {k: (lo + hi) / 2 for k, (lo, hi) in params.items()}
    _tuned_toml(args, args.out, list(expand(middle)), scenario.override(expand(middle)))
    progress = sys.stderr.isatty()
    if args.scheduler is None:  # a cluster's speed is not this machine's
        _announce_tune(args, scenario, len(params))
    history = args.history if args.history is not None else _default_history(args.out)
    flown: list[dict[str, Any]] = []
    with warnings.catch_warnings(), batch_scope(args.scheduler) as batch:
        warnings.simplefilter("ignore", InfeasibleWarning)  # said below, as the outcome
        try:
            options = OptimizeOptions(
                args.controller,
                params,
                args.objective,
                phases,
                require_stable=not args.allow_unstable,
                progress=progress,
                constraints=args.constraint,
                callback=flown.append,
                client=batch.client,
                **passed(args, "runs", "seed", "method", "maxiter", "workers", "popsize"),
            )
            result = optimize(scenario, options)
        except KeyboardInterrupt:
            print("quadrs tune: interrupted during the first candidate: no candidate finished, "
                  "nothing to keep", file=sys.stderr)  # fmt: skip
            return EXIT_INTERRUPT
        batch.flown()
        # Everything is saved before anything is printed: a Ctrl-C while the tables print (or
        # a closed pipe) loses nothing.
        status = _save_tuning(args, result, len(flown), history)
    best_row = result.history[result.history["role"] == "best"].iloc[0]
    admissible = not bool(best_row["penalised"])
    searched = result.evaluations
    rejected = searched["unstable_modes"].astype(bool) & ~searched["flown"]
    modes = ", ".join(
        dict.fromkeys("; ".join(searched.loc[rejected, "unstable_modes"]).split("; "))
    )
    why = f": {modes}" if rejected.any() else ""
    print(
        f"{len(searched)} evaluations ({int(rejected.sum())} rejected as unstable at hover in a "
        f"mode the flight excites{why}; {int(searched['penalised'].sum())} penalised"
        f"{_infeasible_count(searched, result)})"
        f"{' - interrupted' if result.interrupted else ''}"
    )
    for key, value in result.best.items():
        print(f"{key} = {value:.6g}")
    print(terminal_text(f"objective ({args.objective} over {', '.join(phases)}, seed "
                        f"{args.seed}): {result.objective:.6g} "
                        f"(untuned: {result.baseline:.6g})"))  # fmt: skip
    if result.holdout is not None:
        ho = result.holdout
        print(f"held out (seed {ho.seed}, {ho.runs} runs): {ho.objective:.6g} "
              f"[95% CI {ho.low:.6g}, {ho.high:.6g}]")  # fmt: skip
    _print_phase_effects(result.phase_effects, args.objective, phases)
    _print_comparison(result)
    if result.holdout_constraints is not None:
        print("\nconstraints on the held-out seed (95% intervals; certain: the whole interval "
              "meets the bound):")  # fmt: skip
        table = result.holdout_constraints.set_index(["constraint", "phase"])
        table = table.drop(columns=["controller"])
        print(terminal_text(table.to_string(float_format=lambda v: f"{v:.4g}")))
    if result.constraints and not result.feasible and admissible:
        broken = "; ".join(str(c) for c in result.constraints)
        print(terminal_text(f"quadrs tune: no candidate met every constraint ({broken}): "
                            "nothing written (the least violating is shown above)"),
              file=sys.stderr)  # fmt: skip
        return EXIT_INTERRUPT if result.interrupted else EXIT_FAIL
    if not admissible:
        print("quadrs tune: no admissible candidate (every one was unstable at hover in a mode "
              f"the flight excites{why}, diverged or gave a non-finite objective): nothing "
              "written", file=sys.stderr)  # fmt: skip
        return EXIT_INTERRUPT if result.interrupted else EXIT_FAIL
    if result.interrupted:
        print("quadrs tune: interrupted: the best so far is saved", file=sys.stderr)
        return EXIT_INTERRUPT
    return status


def _default_history(out: Path) -> Path:
    """Where an interrupted tune without --history keeps its candidates: FILE-history.csv."""
    return out.with_name(f"{out.stem}-history.csv")


def tune_budget(args: argparse.Namespace, n_params: int) -> tuple[int, int]:
    """(candidates, flights) a tune will fly at most: the search's candidates, then the
    untuned scenario, the best on the held-out seed and the best again for the per-phase
    effects (three more batches of --runs)."""
    if args.method == "differential_evolution":
        generations = 20 if args.maxiter is None else args.maxiter
        candidates = args.popsize * n_params * (generations + 1)
    else:
        candidates = 100 if args.maxiter is None else args.maxiter
    return candidates, (candidates + 3) * args.runs


def _announce_tune(args: argparse.Namespace, scenario: Any, n_params: int) -> None:
    """Say before the search what it flies and roughly how long, from a short calibration."""
    from quadrs.cli.cost import announce, calibrate, precheck, say

    precheck(scenario, (args.controller,), args.runs, args.workers, args.seed)
    candidates, flights = tune_budget(args, n_params)
    cal = calibrate(scenario, (args.controller,), args.workers, args.seed, at_most=args.runs)
    what = f"up to {candidates} candidates of {args.runs} flights, then 3 checks"
    say(announce("tune", what, flights, cal), cal.estimate(flights))


def _infeasible_count(searched: Any, result: Any) -> str:
    """The "; K broke a constraint" note of a constrained run (flown candidates only)."""
    if not result.constraints:
        return ""
    broke = searched["flown"].astype(bool) & ~searched["penalised"].astype(bool)
    broke &= ~searched["feasible"].astype(bool)
    return f"; {int(broke.sum())} broke a constraint"


def _print_comparison(result: Any) -> None:
    """The untuned scenario beside the best candidate (same gusts): parameters, objective and
    each constraint's value and verdict."""
    table = result.comparison
    if table.empty:
        return
    keys = list(result.best)
    columns = [*keys, "objective"]
    for c in result.constraints:
        columns += [col for col in (c.label, str(c)) if col not in columns]
    columns += ["feasible"] if result.constraints else []
    print("\nuntuned (the scenario's own values) and best, on the same gusts:")
    shown = table[columns].T
    print(terminal_text(shown.to_string(float_format=lambda v: f"{v:.6g}")))


def _save_text(write: Callable[[Path], object], path: Path) -> bool:
    """The command line's saving with a recovery copy (quadrs.cli.outputs.save)."""
    from quadrs.cli.outputs import save

    return save(write, path)


def _print_phase_effects(effects: Any, metric: str, tuned: tuple[str, ...]) -> None:
    """Every phase's mean ``metric`` untuned and tuned (same gusts): a phase outside the
    objective that the tuning made worse shows, and is named on stderr."""
    if effects is None:
        return
    print(f"\n{metric} per phase, untuned -> tuned (same gusts; worse: the paired 95% interval "
          "of the change lies above 0):")  # fmt: skip
    table = effects[["untuned", "tuned", "change_pct", "worse"]].copy()
    table["in objective"] = [p in tuned for p in table.index]
    print(terminal_text(table.to_string(float_format=lambda v: f"{v:.4g}")))
    hurt = [p for p, r in effects.iterrows() if r["worse"] and p not in tuned]
    if hurt:
        note = f"the tuned values raise {metric} in {', '.join(hurt)}, outside the objective"
        print(terminal_text(f"quadrs tune: note: {note}"), file=sys.stderr)


def cmd_linearize(args: argparse.Namespace) -> int:
    import numpy as np

    from quadrs.cli.scenario_args import load_scenario
    from quadrs.hover.linear import INPUT_NAMES, equivalent_wind, linearize
    from quadrs.io.files import atomic_write, check_writable

    scenario = load_scenario(args)
    wind = equivalent_wind(scenario) if args.wind is None else args.wind
    if not math.isfinite(wind):
        raise ValueError(f"--wind must be finite, got {wind}")
    if args.out is not None:
        check_writable(args.out)
    controllers = PAPER_CONTROLLERS if args.controller == "both" else (args.controller,)
    models = {}
    for c in controllers:
        lin = linearize(scenario, c, inputs=("wind_z",), outputs=("e_o",), wind=(0.0, 0.0, wind))
        models[c] = lin
        freqs = np.array([0.1, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0])
        mag = np.abs(lin.frequency_response(freqs)[:, 0, 0])
        print(f"== {c.upper()} == (linearised about a steady vertical wind of {wind:.3g} m/s)")
        poles = lin.poles()
        print("poles (1/s): " + ", ".join(f"{p.real:+.3g}{p.imag:+.3g}j" for p in poles))
        print("|e_o / wind_z| (m per m/s): " + ", ".join(
            f"{f:g} Hz: {m:.3g}" for f, m in zip(freqs, mag, strict=True)))  # fmt: skip
    if args.out is not None:
        full = {c: linearize(scenario, c, inputs=INPUT_NAMES, outputs="all",
                             wind=(0.0, 0.0, wind)) for c in controllers}  # fmt: skip
        arrays = {f"{c}_{m}": getattr(lin, m) for c, lin in full.items() for m in "ABCD"}
        # np.savez appends .npz to a name without it: write the name it would load from.
        out = args.out if args.out.suffix == ".npz" else args.out.with_name(args.out.name + ".npz")
        if not _save_text(lambda p: atomic_write(p, lambda f: np.savez(f, **arrays)), out):
            return EXIT_FAIL
    if args.plot is not None:
        from quadrs.plots import gust_transmissibility

        args.plot.mkdir(parents=True, exist_ok=True)
        path = args.plot / "gust_transmissibility"
        gust_transmissibility(scenario, controllers, wind=wind, path=path)
        print(f"wrote {path}.png and .svg", file=sys.stderr)
    return EXIT_OK
