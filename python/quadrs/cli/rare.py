"""``quadrs rare``: a rare-event probability by subset simulation on the command line.

Kept apart from :mod:`quadrs.cli.main`, which registers the subcommand (see docs/rare-events.md).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path
from typing import Any

from quadrs.cli.common import (
    EXIT_FAIL,
    EXIT_INTERRUPT,
    EXIT_OK,
    command_parser,
    no_progress_option,
    parquet_out_option,
    passed,
    scheduler_option,
    seed_option,
    workers_option,
)
from quadrs.cli.cost import Eta, duration, say
from quadrs.cli.safety_case import check_safety_case, safety_case_options, write_page
from quadrs.engine.calls import CONTROLLERS

#: The library's argument names -> the options that set them, in the sampler's messages.
OPTION_WORDS = (("per_level", "--per-level"), ("max_levels", "--max-levels"), ("p0", "--p0"))


def _threshold(text: str) -> str:
    """``--threshold X`` as typed: read in the metric's unit once ``--metric`` is known
    (``_threshold_value``)."""
    return text


def _threshold_value(metric: str, text: str) -> float:
    """``--threshold``'s text -> the results' unit (SI), read as ``--limit`` reads its value."""
    from quadrs.present.labels import metric_value

    try:
        return metric_value(metric, text)
    except ValueError as e:
        raise ValueError(f"--threshold {text!r}: {str(e).split(': ', 1)[-1]}") from None


def _controllers(text: str) -> tuple[str, ...]:
    """``pd`` or a comma-separated list of distinct controllers, ``pd,smc``."""
    names = tuple(n.strip() for n in text.split(","))
    bad = [n for n in names if n not in CONTROLLERS]
    if bad or len(set(names)) != len(names):
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected one of {', '.join(CONTROLLERS)} or a comma-separated list of "
            f"distinct ones (e.g. pd,smc)"
        )
    return names


def paired_paths(out: Path, controllers: tuple[str, ...]) -> dict[str, Path]:
    """Where ``--out FILE.parquet`` writes each controller's result: FILE itself for one
    controller, FILE-<controller>.parquet beside it for several."""
    if len(controllers) == 1:
        return {controllers[0]: out}
    return {c: out.with_name(f"{out.stem}-{c}{out.suffix}") for c in controllers}


def add_rare(sub: Any, common: argparse.ArgumentParser) -> None:
    """a small probability P(metric > threshold) by subset simulation

    Estimate P(METRIC in PHASE > THRESHOLD) over the gust's randomness by subset simulation: far
    fewer flights than plain Monte Carlo for small probabilities. Prints the estimate, its
    coefficient of variation and 95% interval, the levels and the flights, and the flights plain
    Monte Carlo would need for the same precision. A diverged flight counts as an exceedance (see
    docs/rare-events.md)."""
    from quadrs import _core
    from quadrs.present.labels import INPUT_UNITS

    p = command_parser(sub, add_rare, common)
    p.add_argument(
        "--metric",
        required=True,
        choices=list(_core.METRIC_NAMES),
        metavar="M",
        help=f"the metric, one of {', '.join(_core.METRIC_NAMES)}",
    )
    p.add_argument("--phase", required=True, metavar="P", help="the phase it is taken in")
    p.add_argument(
        "--threshold",
        required=True,
        type=_threshold,
        metavar="X",
        help=f"estimate P(metric > X), X {INPUT_UNITS}",
    )
    p.add_argument(
        "--controller",
        type=_controllers,
        default=("pd",),
        metavar="C",
        help="controller, or a comma-separated list flown on the same gusts (pd,smc: paired "
        "runs and the ratio of their probabilities) (default: pd)",
    )
    p.add_argument(
        "--per-level",
        type=int,
        default=1000,
        metavar="N",
        help="flights per level, a multiple of 1/p0 (default: 1000)",
    )
    p.add_argument(
        "--p0",
        type=float,
        default=0.1,
        metavar="P",
        help="conditional probability of a level, 1/L for a whole L (default: 0.1)",
    )
    p.add_argument(
        "--max-levels",
        type=int,
        default=None,
        metavar="K",
        help="deepest level tried (default: enough for about 1e-12)",
    )
    seed_option(p, help="seed (default: 0)")
    workers_option(p, help="threads (default: all)")
    parquet_out_option(
        p,
        "write the result here (the failure samples with their innovations, the levels "
        "and the run record; RareEventResult.read_parquet reads it); with several "
        "controllers, FILE-<controller>.parquet each",
    )
    scheduler_option(
        p,
        help="fly each level's flights on a Dask cluster, e.g. tcp://10.0.0.5:8786 (needs pip "
        "install quadrs[dask]); the result is the same as on one machine",
    )
    no_progress_option(p, help="no per-level progress lines")
    safety_case_options(p)


def _option_words(text: str) -> str:
    for name, option in OPTION_WORDS:
        # The name as the subject ("p0 must", "per_level = 105"), not inside "1/p0".
        text = re.sub(rf"(?<![/\w]){name}(?= must| =|,)", option, text)
    return text


def cmd_rare(args: argparse.Namespace) -> int:
    """Subset simulation of one controller, or of several paired on the same gusts (each
    one's table, then the ratios to the first): optional Parquet; 130 if interrupted (the
    finished levels are reported and saved)."""
    from quadrs.cli.common import batch_scope
    from quadrs.cli.outputs import check_outputs, save
    from quadrs.cli.scenario_args import load_scenario
    from quadrs.present.labels import shown_unit, shown_value
    from quadrs.rare import rare_event
    from quadrs.rare.result import RareEventComparison, RareEventResult
    from quadrs.rare.subset import Level, check_settings

    if args.out is not None and args.out.suffix.lower() != ".parquet":
        raise ValueError(f"--out {str(args.out)!r}: expected a file ending in .parquet")
    for option, value, low in (("--seed", args.seed, 0), ("--workers", args.workers, 1)):
        if value is not None and value < low:
            raise ValueError(f"{option} must be >= {low}, got {value}")
    if args.scheduler is not None and args.workers is not None:
        raise ValueError("--workers and --scheduler: give one (a cluster's workers set "
                         "their own threads)")  # fmt: skip
    try:
        check_settings(args.per_level, args.p0, args.max_levels)
    except ValueError as e:
        raise ValueError(_option_words(str(e))) from None
    args.threshold = _threshold_value(args.metric, args.threshold)
    shown = f"{shown_value(args.metric, args.threshold):g} {shown_unit(args.metric)}"
    shown_threshold = shown.rstrip()
    scenario = load_scenario(args)
    if args.phase not in scenario.phase_names:
        raise ValueError(_phase_error(args, scenario))
    controllers: tuple[str, ...] = args.controller
    paths = paired_paths(args.out, controllers) if args.out is not None else {}
    check_outputs(*paths.values())
    check_safety_case(args)
    if args.target or args.safety_case is not None:
        from quadrs.rare.safety import check_rare_targets

        check_rare_targets(args.metric, dict(args.target),
                           "--target" if args.target else "--safety-case")  # fmt: skip
    from quadrs.present.terminal import terminal_text

    value_name = terminal_text(f"{args.metric} in {args.phase}")
    show = not args.no_progress and sys.stderr.isatty()
    flying = [-1]  # which controller's levels are reported (level 0 starts the next one)
    _, p0, max_levels = check_settings(args.per_level, args.p0, args.max_levels)
    # A cluster's speed is not this machine's: no estimate there.
    per_level_seconds = (math.nan if args.scheduler is not None
                         else _announce(scenario, args, controllers, p0, max_levels))  # fmt: skip
    eta = Eta(None)
    per_level = (f", about {duration(per_level_seconds)} a level here"
                 if math.isfinite(per_level_seconds) else "")  # fmt: skip

    def on_level(level: Level) -> None:
        flying[0] += level.level == 0
        who = f" ({controllers[flying[0]]})" if len(controllers) > 1 else ""
        if show:
            print(f"quadrs rare{who}: level {level.level} done: cut "
                  f"{shown_value(args.metric, level.threshold):.4g} {shown_unit(args.metric)}, "
                  f"conditional p {level.conditional_p:.3g}, acceptance "
                  f"{level.acceptance_rate:.2f}, {level.flights} flights; levels {eta.step()}"
                  f"{per_level}",
                  file=sys.stderr, flush=True)  # fmt: skip

    with batch_scope(args.scheduler) as batch:
        out = rare_event(
            scenario,
            controller=controllers[0],
            on_level=on_level,
            controllers=controllers if len(controllers) > 1 else None,
            client=batch.client,
            **passed(args, "metric", "phase", "threshold", "per_level", "p0", "seed"),
            **passed(args, "max_levels", "workers"),
        )
        batch.flown()
        results: dict[str, RareEventResult]
        if isinstance(out, RareEventComparison):
            results = dict(out.results)
        else:
            assert isinstance(out, RareEventResult)
            results = {controllers[0]: out}
        saved = True
        for name, result in results.items():  # saved first: a second Ctrl-C keeps them
            if name in paths:
                saved = save(result.to_parquet, paths[name]) and saved
    interrupted = [name for name, r in results.items() if r.interrupted]
    # The controllers that finished before a Ctrl-C keep their estimates: printed first.
    for name, result in results.items():
        if result.interrupted:
            continue
        print(f"P({value_name} > {shown_threshold}), {name}, seed {args.seed}, "
              f"{_inputs(result)} a flight")  # fmt: skip
        for label, text in summary_rows(result):
            print(f"  {label:<34} {text}")
        for line in verdict_lines(result, dict(args.target)):
            print(line)
    if interrupted:
        result = results[interrupted[0]]
        done = len(result.levels)
        bound = result.upper_bound
        note = "" if bound is None else f"; P <= about {bound:.3g} (the last cut reached)"
        who = f" ({interrupted[0]})" if len(controllers) > 1 else ""
        print(f"quadrs rare{who}: interrupted after {done} finished "
              f"level{'s' * (done != 1)} ({result.flights} flights), no estimate{note}; "
              f"a level is {args.per_level} flights{per_level.removesuffix(' a level here')}"
              f"{' here' * bool(per_level)}",
              file=sys.stderr)  # fmt: skip
        return EXIT_INTERRUPT
    if isinstance(out, RareEventComparison):
        base = controllers[0]
        for name in controllers[1:]:
            print(ratio_line(out, name, base))
    if args.safety_case is not None:
        from quadrs.rare.safety import rare_safety_case

        cases = [rare_safety_case(r, dict(args.target), controllers) for r in results.values()]
        saved = write_page(cases, args.safety_case) and saved
    return EXIT_OK if saved else EXIT_FAIL


def _phase_error(args: argparse.Namespace, scenario: Any) -> str:
    """--phase names no phase of the scenario: which scenario that is (rare starts from the
    paper preset, where mission starts from delivery), its phases, and the presets that have
    the phase asked for."""
    from quadrs.cli.scenario_args import base_preset
    from quadrs.scenario.scenario import Scenario, presets

    base = base_preset(args)
    which = (f"the scenario file {str(args.scenario)!r}" if args.scenario is not None
             else f"the preset {base!r}" + ("" if args.preset else " (rare's default; "
                                             "quadrs mission's is 'delivery')"))  # fmt: skip
    text = f"--phase {args.phase!r}: {which} has the phases {', '.join(scenario.phase_names)}"
    having = [p for p in presets() if p != base and args.phase in Scenario.preset(p).phase_names]
    if having:
        text += f"; {' or '.join(f'--preset {p}' for p in having)} has {args.phase!r}"
    return text


def rare_budget(per_level: int, p0: float, max_levels: int, controllers: int = 1) -> int:
    """Flights of a run that goes to its deepest level: ``per_level`` for level 0, then
    ``per_level * (1 - p0)`` new flights per level (the seeds are kept), per controller."""
    return controllers * round(per_level * (1 + (max_levels - 1) * (1 - p0)))


def calibrate_rare(scenario: Any, args: argparse.Namespace, controller: str) -> Any:
    """Time one small level of the same sampler (20 flights; its flights cost more than a
    Monte Carlo batch's: each draws its own innovations)."""
    import time
    import warnings

    from quadrs.cli.cost import Calibration, _workers
    from quadrs.rare import rare_event

    flights = 20
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = rare_event(scenario, controller=controller, metric=args.metric, phase=args.phase,
                       threshold=args.threshold, per_level=flights, p0=0.5, seed=args.seed,
                       max_levels=1, workers=args.workers)  # fmt: skip
    if getattr(r, "interrupted", False):  # Ctrl-C in the calibration stops the command
        raise KeyboardInterrupt
    return Calibration(flights, time.perf_counter() - start, _workers(args.workers))


def _announce(
    scenario: Any,
    args: argparse.Namespace,
    controllers: tuple[str, ...],
    p0: float,
    max_levels: int,
) -> float:
    """Say what the run flies and roughly how long, from a short calibration (on stderr);
    the seconds of one level of every controller."""
    cal = calibrate_rare(scenario, args, controllers[0])
    level = cal.estimate(args.per_level * len(controllers))
    deepest = rare_budget(args.per_level, p0, max_levels, len(controllers))
    example = math.ceil(math.log(1e-4) / math.log(p0))
    say(
        f"quadrs rare: {args.per_level} flights a level{' per controller' * (len(controllers) > 1)}"
        f", about {duration(level)} a level here ({cal.per_flight:.2g} s a flight, from "
        f"{cal.flights} calibration flights) and {_memory(scenario, args, controllers[0], p0)}; a "
        f"probability p takes about log(p)/log({p0:g}) levels (1e-4: {example}), at most "
        f"{max_levels} ({deepest:,} flights, about {duration(cal.estimate(deepest))}); Ctrl-C "
        "keeps the finished levels",
        cal.estimate(deepest))  # fmt: skip
    return level


def _memory(scenario: Any, args: argparse.Namespace, controller: str, p0: float) -> str:
    """``about 1.2 GiB of memory``: what the levels' samples hold at once (each flight's
    innovations and dispersed keys' normals; :func:`quadrs.rare.subset.subset_memory`)."""
    from quadrs.rare.scenario_model import ScenarioModel
    from quadrs.rare.subset import subset_memory

    dimension = ScenarioModel(scenario, controller, args.metric, args.phase).dimension
    return f"about {subset_memory(dimension, args.per_level, p0) / 2**30:.2g} GiB of memory"


def _inputs(result: Any) -> str:
    """What a flight's standard normals drive: ``1000 innovations`` or ``1000 innovations
    and 1 parameter (payload.mass)``."""
    keys = getattr(result.model, "parameter_keys", ())
    gust = result.dimension - len(keys)
    if not keys:
        return f"{gust} innovations"
    plural = "s" * (len(keys) != 1)
    return f"{gust} innovations and {len(keys)} parameter{plural} ({', '.join(keys)})"


def ratio_line(comparison: Any, a: str, b: str) -> str:
    """``ratio smc / pd ...``: P_a / P_b with its 95 % interval, or why there is none."""
    r = comparison.ratio(a, b)
    if r["ratio"] is None:
        return f"ratio {a} / {b}: none (a run found no failure)"
    corr = r["first_level_correlation"]
    note = "" if corr is None else f"; first-level correlation {corr:.2f}"
    return (f"ratio {a} / {b}: {r['ratio']:.3g}, 95 % [{r['low']:.3g}, {r['high']:.3g}]"
            f"{note}")  # fmt: skip


def per_hour_rows(result: Any) -> list[tuple[str, str]]:
    """The estimate per flight hour (over the flight's scheduled duration: subset simulation
    gives a probability per flight, not a count of flights ended early), its one-sided 95 %
    upper bound (what a target is judged against, :func:`quadrs.rare.safety.rare_rate`) and
    per 10,000 deliveries; none for a limit-state function (no flight)."""
    from quadrs.rare.safety import rare_rate

    rate = rare_rate(result)
    if rate is None:
        return []
    seconds = 3600.0 * rate.hours / rate.flights
    level = f"one-sided {100 * rate.confidence:.3g} %"
    if rate.rate != rate.rate:  # no failure deeper than level 0: the bound alone
        said = f"no estimate ({seconds:g} s flights)"
    else:
        said = (f"{rate.rate:.3g} [{rate.ci_low:.3g}, {rate.ci_high:.3g}] ({seconds:g} s "
                "flights)")  # fmt: skip
    return [(f"per flight hour [{100 * rate.confidence:.3g} % interval]", said),
            ("upper bound per flight hour", f"{rate.upper:.3g} ({level}, {rate.method})"),
            ("per 10,000 deliveries", f"{rate.per_10k:.3g}, <= {rate.per_10k_upper:.3g} "
                                      f"({level})".removeprefix("nan, "))]  # fmt: skip


def verdict_lines(result: Any, targets: dict[str, float]) -> list[str]:
    """Each ``--target``'s verdict on the result's one-sided bound, wrapped to the report's
    width (the mode checked before flying)."""
    import textwrap

    from quadrs.cli.common import report_width
    from quadrs.rare.safety import rare_safety_case

    if not targets:
        return []
    case = rare_safety_case(result, targets)
    rate = next(iter(case.modes.values())).rate
    assert rate is not None  # the case is made of a finished result
    return [line for v in case.verdicts
            for line in textwrap.wrap(v.text(rate), report_width(), subsequent_indent="  ",
                                      break_on_hyphens=False)]  # fmt: skip


def summary_rows(result: Any) -> list[tuple[str, str]]:
    """(label, value) rows of the printed table of a :class:`RareEventResult`."""
    rows: list[tuple[str, str]] = []
    if result.probability is None:
        rows.append(("estimate", f"no failure in {result.flights} flights"))
        rows.append(("95 % upper confidence bound", f"P <= {result.upper_bound:.3g}"))
        rows.append(("largest value seen", f"{result.closest:.6g}"))
    else:
        lo, hi = result.interval
        rows.append(("estimate", f"{result.probability:.3g}"))
        rows.append(("coefficient of variation", f"{result.cov:.3f}"))
        rows.append(("95 % interval", f"[{lo:.3g}, {hi:.3g}]"))
    rows += per_hour_rows(result)
    rows.append(("levels", str(len(result.levels))))
    rows.append(("flights", str(result.flights)))
    if result.run.pilot_flights:
        rows.append(("  of which placing the levels", str(result.run.pilot_flights)))
    need = result.monte_carlo_flights
    if need is not None:
        rows.append(("Monte Carlo flights, same CoV", f"{need:.3g} ({need / result.flights:.1f}x)"))
    return rows
