"""Monte Carlo throughput through the public API, in realisation-steps per second.

    python benches/throughput.py               # 1 worker, all workers, then 1,000 paired runs
    python benches/throughput.py --runs 100    # quicker: the long run with 100 realisations
    python benches/throughput.py --dispersions # dispersed against fixed parameters, paired
    python benches/throughput.py --paths       # every SIMD path and the fused mode, paired
    python benches/throughput.py --short       # per-flight tax: 0.2 s flights against 4 s ones,
                                               # and dispersed 0.2 s flights against fixed ones
    python benches/throughput.py --turbulence  # 4 s flights, gust on throughout: off, vertical,
                                               # three components, in turn, as ratios to off
    python benches/throughput.py --models      # 4 s flights of the vertical gust: spring/ideal,
                                               # cable, rotors, cable + rotors, as ratios to
                                               # the spring on ideal actuators (the paper's)
    python benches/throughput.py --mission     # the delivery preset case by case (as
                                               # shipped, at 1 ms, every loop each step, on
                                               # its state, mean wind only, no wind, a
                                               # dispersed mass) in simulated seconds per
                                               # second, as ratios to the paper preset with
                                               # the gust off (1 worker, PD)
    python benches/throughput.py --calls       # per-call cost of short engine calls: the
                                               # compiled engine (Scenario.engine) against a
                                               # call that compiles the scenario's JSON first

A realisation-step is one RK4 step of one realisation under one controller: a paired PD + SMC
realisation of the paper preset (70 s at dt = 2e-4 s) is 2 x 350,000 of them. Every timing is
``quadrs.monte_carlo(scenario, runs=..., workers=..., progress=False)`` end to end (stability
check, engine, results table), so it is what a user gets. Timings on a shared machine are
noisy: each is repeated (``--repeat``) and reported as median [min, max]; the load average is
printed before and after.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import subprocess
import sys
import time
import warnings

import quadrs
from quadrs import _core
from quadrs.runs.montecarlo import default_workers


def cpu_model() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def load() -> str:
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "n/a"


#: Four uncertain parameters of the paper preset: a different vehicle in every lane.
DISPERSIONS = {
    "payload.mass": {"dist": "uniform", "low": 0.18, "high": 0.26},
    "payload.natural_frequency": {"dist": "normal", "mean": 2.0, "std": 0.2},
    "vehicle.inertia[2]": {"dist": "triangular", "low": 0.04, "mode": 0.05, "high": 0.07},
    "gust.w20": {"dist": "lognormal", "mu": 2.3, "sigma": 0.3},
}


#: The paths ``--paths`` compares: (name, QUADRS_SIMD, fused). A path this CPU cannot run is
#: reported as skipped (the engine refuses it by name).
PATHS = [
    ("baseline", "baseline", False),
    ("avx2", "avx2", False),
    ("avx512", "avx512", False),
    ("fused", "auto", True),
]


def timed(
    scenario: quadrs.Scenario, runs: int, workers: int, seed: int, fused: bool = False
) -> float:
    t0 = time.perf_counter()
    res = quadrs.monte_carlo(
        scenario, runs=runs, workers=workers, progress=False, seed=seed, fused=fused
    )
    dt = time.perf_counter() - t0
    assert res.runs["realisation"].nunique() == runs
    return dt


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=1000, help="realisations of the long run")
    ap.add_argument(
        "--sample-runs", type=int, default=100, help="realisations per throughput timing"
    )
    ap.add_argument("--repeat", type=int, default=3, help="timings per configuration")
    ap.add_argument("--workers", type=int, default=default_workers(), help="all workers")
    ap.add_argument("--preset", default="paper", help="scenario preset")
    ap.add_argument("--dt", type=float, default=None, help="override integrator.dt (s)")
    ap.add_argument("--duration", type=float, default=None, help="override integrator.duration (s)")
    ap.add_argument(
        "--short",
        action="store_true",
        help="0.2 s flights against 4 s ones, fixed and dispersed, alternately (1 worker)",
    )
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--paths",
        action="store_true",
        help="time every SIMD path (QUADRS_SIMD) and the fused mode in turn, 1 worker",
    )
    ap.add_argument("--one-path", choices=[p[0] for p in PATHS], help=argparse.SUPPRESS)
    ap.add_argument(
        "--dispersions",
        action="store_true",
        help="time a batch with four dispersed keys against the fixed one, alternately",
    )
    ap.add_argument(
        "--turbulence",
        action="store_true",
        help="4 s flights with the gust off, vertical, three components, alternately (1 worker)",
    )
    ap.add_argument(
        "--models",
        action="store_true",
        help="4 s flights of each payload and actuator model, alternately (1 worker)",
    )
    ap.add_argument(
        "--mission",
        action="store_true",
        help="the delivery preset with its wind, parts of it and none, and the paper preset "
        "with the gust off, alternately (1 worker, PD)",
    )
    ap.add_argument(
        "--calls",
        action="store_true",
        help="per-call time of short flights and batches: compiled engine vs JSON, alternately",
    )
    args = ap.parse_args()

    scenario = quadrs.Scenario.preset(args.preset)
    if args.dt is not None:
        scenario = scenario.override({"integrator.dt": args.dt})
    if args.duration is not None:
        scenario = lasting(scenario, args.duration)
    # The paper's SMC gains are unstable laterally (docs/model.md section 8): the warning
    # is noise here.
    warnings.simplefilter("ignore")
    per_run = 2 * scenario.steps  # paired PD + SMC
    if args.one_path:
        fused = dict((p[0], p[2]) for p in PATHS)[args.one_path]
        timed(scenario, 4, 1, args.seed, fused)  # warm-up
        wall = timed(scenario, args.sample_runs, 1, args.seed, fused)
        print(f"{_core.simd_path()} {args.sample_runs * per_run / wall}")
        return

    print(f"machine: {cpu_model()}, {os.cpu_count()} CPUs, python {platform.python_version()}")
    print(f"quadrs {quadrs.__version__}, SIMD path: {_core.simd_path()}")
    print(
        f"scenario: {args.preset}, {scenario.steps} steps per flight (dt = "
        f"{scenario['integrator.dt']} s), {per_run:,} realisation-steps per paired run"
    )
    print(f"load average before: {load()}")

    if args.paths:
        compare_paths(args)
        return
    if args.mission:
        compare_mission(args)
        return
    timed(scenario, 4, 1, args.seed)  # warm-up: thread pool, page faults
    if args.dispersions:
        compare_dispersed(scenario, args)
        return
    if args.short:
        compare_short(scenario, args)
        return
    if args.turbulence:
        compare_turbulence(scenario, args)
        return
    if args.models:
        compare_models(scenario, args)
        return
    if args.calls:
        compare_calls(scenario, args)
        return
    rates = {}
    for workers in sorted({1, args.workers}):
        samples = [
            args.sample_runs * per_run / timed(scenario, args.sample_runs, workers, args.seed)
            for _ in range(args.repeat)
        ]
        rates[workers] = statistics.median(samples)
        print(
            f"{workers} worker(s), {args.sample_runs} paired runs: "
            f"{rates[workers] / 1e6:.2f} M realisation-steps/s "
            f"[{min(samples) / 1e6:.2f}, {max(samples) / 1e6:.2f}]"
            + (f" = {rates[workers] / workers / 1e6:.2f} M/s per worker" if workers > 1 else "")
        )
    if args.workers > 1:
        print(f"scaling {args.workers} workers / 1: {rates[args.workers] / rates[1]:.2f}x")

    wall = timed(scenario, args.runs, args.workers, args.seed)
    print(
        f"{args.runs} paired PD + SMC runs on {args.workers} worker(s): {wall:.1f} s wall "
        f"({args.runs * per_run / wall / 1e6:.2f} M realisation-steps/s)"
    )
    print(f"load average after: {load()}")


def compare_dispersed(scenario: quadrs.Scenario, args: argparse.Namespace) -> None:
    """Fixed and dispersed batches in turn (A B A B ...), the ratio pair by pair, so that the
    comparison holds on a noisy machine."""
    dispersed = scenario.override({"dispersions": DISPERSIONS})
    per_run = 2 * scenario.steps
    ratios, fixed_rates = [], []
    for _ in range(args.repeat):
        a = timed(scenario, args.sample_runs, args.workers, args.seed)
        b = timed(dispersed, args.sample_runs, args.workers, args.seed)
        ratios.append(a / b)
        fixed_rates.append(args.sample_runs * per_run / a)
    print(
        f"{args.workers} worker(s), {args.sample_runs} paired runs: fixed "
        f"{statistics.median(fixed_rates) / 1e6:.2f} M realisation-steps/s; dispersed/fixed "
        f"throughput {statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}]"
    )
    print(f"load average after: {load()}")


#: The payload and actuator models, as overrides of the preset (the cable as in "slung").
MODELS = {
    "spring, ideal": {},
    "cable, ideal": {
        "payload.model": "cable",
        "payload.cable_length": 1.0,
        "payload.attachment_offset": 0.05,
        "payload.natural_frequency": 10.0,
    },
    "spring, rotors": {"actuator.model": "rotors", "initial.attitude": [0.0, 0.0, 0.0]},
}
MODELS["cable, rotors"] = {**MODELS["cable, ideal"], **MODELS["spring, rotors"]}


def compare_models(scenario: quadrs.Scenario, args: argparse.Namespace) -> None:
    """The cost per step of each model against the paper's spring on ideal actuators: 4 s
    flights of the same gust, the models in turn (A B C D A B C D ...), one worker, each ratio
    taken round by round."""
    base = lasting(scenario, 4.0)
    cases = {name: base.override(change) for name, change in MODELS.items()}
    rates: dict[str, list[float]] = {name: [] for name in cases}
    ratios: dict[str, list[float]] = {name: [] for name in cases}
    for s in cases.values():  # warm-up
        timed(s, 4, 1, args.seed)
    for _ in range(args.repeat):
        rnd = {
            name: args.sample_runs * 2 * s.steps / timed(s, args.sample_runs, 1, args.seed)
            for name, s in cases.items()
        }
        for name, rate in rnd.items():
            rates[name].append(rate)
            ratios[name].append(rate / rnd["spring, ideal"])
    print(f"1 worker, {args.sample_runs} paired 4 s runs per model, path {_core.simd_path()}")
    for name in cases:
        r = ratios[name]
        print(
            f"  {name:15s} {statistics.median(rates[name]) / 1e6:6.2f} M realisation-steps/s, "
            f"throughput / spring on ideal {statistics.median(r):.3f} [{min(r):.3f}, {max(r):.3f}]"
        )
    print(f"load average after: {load()}")


def lasting(scenario: quadrs.Scenario, duration: float) -> quadrs.Scenario:
    """``scenario`` cut to ``duration`` s, one phase, the gust on throughout."""
    return scenario.override(
        {
            "integrator.duration": duration,
            "gust.start": 0.0,
            "gust.end": duration,
            "phases": [{"name": "all", "start": 0.0, "end": duration}],
        }
    )


def compare_short(scenario: quadrs.Scenario, args: argparse.Namespace) -> None:
    """The per-flight tax: short (0.2 s) flights against long (4 s) ones, and dispersed
    short flights against fixed short ones, in turn (A B C A B C ...), one worker, each ratio
    in steps per second taken round by round."""
    short, long = lasting(scenario, 0.2), lasting(scenario, 4.0)
    dispersed = short.override({"dispersions": DISPERSIONS})
    no_gust_keys = {k: v for k, v in DISPERSIONS.items() if not k.startswith("gust.")}
    dispersed_plain = short.override({"dispersions": no_gust_keys})
    runs_long = args.sample_runs
    runs_short = runs_long * 20  # the same number of steps
    cases = {"long": (long, runs_long), "short": (short, runs_short)}
    cases["dispersed"] = (dispersed, runs_short)
    cases["dispersed, no gust key"] = (dispersed_plain, runs_short)
    rates: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(args.repeat):
        for name, (s, runs) in cases.items():
            rates[name].append(runs * 2 * s.steps / timed(s, runs, 1, args.seed))
    print(f"1 worker, {args.repeat} rounds, {runs_long} x 4 s and {runs_short} x 0.2 s flights:")
    for name, samples in rates.items():
        ref = "long" if name == "short" else "short"
        ratios = [a / b for a, b in zip(samples, rates[ref], strict=True)]
        vs = "" if name == "long" else f"; / {ref}: {statistics.median(ratios):.3f}"
        vs += f" [{min(ratios):.3f}, {max(ratios):.3f}]" if name != "long" else ""
        print(f"  {name:24s}: {statistics.median(samples) / 1e6:.2f} M realisation-steps/s{vs}")
    print(f"load average after: {load()}")


def compare_turbulence(scenario: quadrs.Scenario, args: argparse.Namespace) -> None:
    """The turbulence's share of the loop: 4 s flights with the gust on throughout, off, the
    vertical component and all three, in turn (A B C A B C ...), one worker, each rate as a
    ratio to the same round's gust-off rate."""
    flight = lasting(scenario, 4.0)
    cases = {
        "off": flight.override({"gust.enabled": False}),
        "vertical": flight.override({"gust.components": ["vertical"]}),
        "three": flight.override({"gust.components": ["longitudinal", "lateral", "vertical"]}),
    }
    runs = args.sample_runs
    rates: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(args.repeat):
        for name, s in cases.items():
            rates[name].append(runs * 2 * s.steps / timed(s, runs, 1, args.seed))
    print(f"1 worker, {args.repeat} rounds, {runs} paired 4 s flights per timing:")
    for name, samples in rates.items():
        ratios = [a / b for a, b in zip(samples, rates["off"], strict=True)]
        vs = f"; / off: {statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}]"
        # The fastest timing of each case is the least disturbed one on a shared machine.
        best = f", best / best off: {max(samples) / max(rates['off']):.3f}"
        print(
            f"  {name:9s}: {statistics.median(samples) / 1e6:.2f} M realisation-steps/s{vs}{best}"
        )
    print(f"load average after: {load()}")


def mission_cases() -> dict[str, quadrs.Scenario]:
    """The delivery preset taken apart: as shipped (2 ms step, each loop, the wind and the
    sensors at their own rates, flown on its estimate), the same at a 1 ms step, every loop at
    every 1 ms step (the fifth round's way), on its state (no estimator), a mean wind without
    turbulence, no wind; a dispersed parcel mass (each flight its own vehicle, so its own
    closed-loop start); and the paper preset with the gust off (the goal's reference)."""
    delivery = quadrs.Scenario.preset("delivery")
    every_step = {f"controller.{k}_rate": 0.0 for k in ("position", "attitude", "inner")}
    return {
        "delivery as shipped": delivery,
        "delivery at 1 ms": delivery.override({"integrator.dt": 0.001}),
        "every loop each 1 ms": delivery.override(
            {"integrator.dt": 0.001, "gust.rate": 0.0, **every_step}
        ),
        "delivery on its state": delivery.override({"navigation.mode": "truth"}),
        "mean wind only": delivery.override({"gust.enabled": False}),
        "no wind": delivery.override({"gust.enabled": False, "wind.speed": 0.0}),
        "dispersed parcel mass": delivery.override(
            {"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.4, "high": 0.6}}}
        ),
        "paper, gust off": quadrs.Scenario.preset("paper").override({"gust.enabled": False}),
    }


def compare_mission(args: argparse.Namespace) -> None:
    """Each case of ``mission_cases`` in turn (A B C ... A B C ...), one worker, PD only,
    ``--sample-runs`` whole flights per timing: realisation-steps per second, and simulated
    seconds per second (a coarser step counts) as a ratio to the same round's paper preset
    without gust (the sixth round's goal: the delivery as shipped at >= 0.45), median [min,
    max] over the rounds."""
    cases = mission_cases()
    runs = args.sample_runs
    for s in cases.values():  # warm-up: compile each scenario's engine, page faults
        quadrs.monte_carlo(s, runs=1, seed=args.seed, controllers=("pd",), workers=1,
                           progress=False)  # fmt: skip
    seconds: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(args.repeat):
        for name, s in cases.items():
            t0 = time.perf_counter()
            quadrs.monte_carlo(s, runs=runs, seed=args.seed, controllers=("pd",), workers=1,
                               progress=False)  # fmt: skip
            seconds[name].append(time.perf_counter() - t0)
    ref = "paper, gust off"
    print(f"1 worker, PD, {args.repeat} rounds, {runs} whole flights per timing:")
    head = f"{'case':24s} {'step ms':>7s} {'M steps/s':>9s} {'flight s/s':>10s}"
    print(f"  {head}   / paper, gust off")
    for name, took in seconds.items():
        s = cases[name]
        flown = [runs * float(s["integrator.duration"]) / t for t in took]
        paper = [runs * float(cases[ref]["integrator.duration"]) / t for t in seconds[ref]]
        ratios = [a / b for a, b in zip(flown, paper, strict=True)]
        print(
            f"  {name:24s} {1e3 * float(s['integrator.dt']):7.3g} "
            f"{runs * s.steps / statistics.median(took) / 1e6:9.2f} "
            f"{statistics.median(flown):10.0f}   "
            f"{statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}]"
        )
    print(f"load average after: {load()}")


def compare_paths(args: argparse.Namespace) -> None:
    """Every path in turn (one process each, as QUADRS_SIMD is read once per process), round
    after round, with each round's rates relative to that round's avx2 rate (or baseline's),
    so that the ratios hold on a noisy machine."""
    rates: dict[str, list[float]] = {}
    skipped: dict[str, str] = {}
    for _ in range(args.repeat):
        for name, simd, _fused in PATHS:
            if name in skipped:
                continue
            cmd = [sys.executable, __file__, "--one-path", name, "--preset", args.preset]
            cmd += ["--sample-runs", str(args.sample_runs), "--seed", str(args.seed)]
            if args.dt is not None:
                cmd += ["--dt", str(args.dt)]
            env = {**os.environ, "QUADRS_SIMD": simd}
            run = subprocess.run(cmd, env=env, capture_output=True, text=True)
            if run.returncode != 0:
                skipped[name] = (run.stderr.strip().splitlines() or ["failed"])[-1]
                continue
            path, rate = run.stdout.split()[-2:]
            rates.setdefault(name, []).append(float(rate))
            if name == "fused":
                skipped.setdefault("_fused_path", path)
    ref = "avx2" if "avx2" in rates else "baseline"
    print(f"1 worker, {args.sample_runs} paired runs per timing, {args.repeat} rounds:")
    for name, samples in rates.items():
        ratios = [r / b for r, b in zip(samples, rates[ref], strict=True)]
        on = f" (on {skipped['_fused_path']})" if name == "fused" else ""
        print(
            f"  {name:8s}{on}: {statistics.median(samples) / 1e6:.2f} M realisation-steps/s "
            f"[{min(samples) / 1e6:.2f}, {max(samples) / 1e6:.2f}], {ref} = 1: "
            f"{statistics.median(ratios):.3f} [{min(ratios):.3f}, {max(ratios):.3f}]"
        )
    for name, why in skipped.items():
        if not name.startswith("_"):
            print(f"  {name:8s}: skipped ({why})")
    print(f"load average after: {load()}")


def compare_calls(scenario: quadrs.Scenario, args: argparse.Namespace) -> None:
    """What a call costs besides its flights: 0.01 s single flights (``simulate``) and batches
    of 4 (``run_batch``, one lane-set, 1 worker), 200 calls each, through the compiled engine
    and through the module function that compiles the scenario's JSON at every call (what
    every call did before the engine handle), alternately; per call, median [min, max]."""
    short = lasting(scenario, 0.01)
    js, engine = short.to_json(), short.engine
    n = 200
    calls = {
        "simulate, compiled engine": lambda: engine.simulate("pd", 0, 0, 10),
        "simulate, JSON each call": lambda: _core.simulate(js, "pd", 0, 0, 10),
        "batch of 4, compiled engine": lambda: engine.run_batch(["pd"], 0, 0, 4, 1, False),
        "batch of 4, JSON each call": lambda: _core.run_batch(js, ["pd"], 0, 0, 4, 1, False),
    }
    samples: dict[str, list[float]] = {k: [] for k in calls}
    for _ in range(args.repeat):
        for name, call in calls.items():
            t0 = time.perf_counter()
            for _ in range(n):
                call()
            samples[name].append((time.perf_counter() - t0) / n * 1e6)
    for name, s in samples.items():
        print(f"{name:30s} {statistics.median(s):8.1f} us per call [{min(s):.1f}, {max(s):.1f}]")
    print(f"load average after: {load()}")


if __name__ == "__main__":
    main()
