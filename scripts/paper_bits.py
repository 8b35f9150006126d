"""The paper model's numbers, bit for bit: a digest of every output the engine gives for it.

The third round changes the engine's structure, never the paper model's numbers (docs/model.md).
This script flies a fixed set of cases (traces, metrics, Monte Carlo rows fixed and dispersed,
ensemble spectra, gust series, linearisations, poles) and prints one SHA-256 per named output.
Each array is hashed by column name, so reordering columns changes nothing; any change of any
bit of any value does.

    python scripts/paper_bits.py                  # print the digests as JSON
    python scripts/paper_bits.py --check FILE     # compare with a saved run; exit 1 on change
    python scripts/paper_bits.py --write FILE     # save them
    python scripts/paper_bits.py --delivery --write tests/data/delivery_bits.json

tests/engine/test_paper_bits.py runs the check against tests/data/paper_bits.json (written before
the model-seams redesign).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

import quadrs


def digest(values: Any) -> str:
    """SHA-256 of the float64 bits of ``values`` (C order), with its shape."""
    a = np.ascontiguousarray(np.asarray(values, dtype=np.float64))
    h = hashlib.sha256(repr(a.shape).encode())
    h.update(a.tobytes())
    return h.hexdigest()[:32]


def frame_digests(prefix: str, frame: pd.DataFrame, columns: list[str]) -> dict[str, str]:
    """One digest per numeric column of ``frame`` (and its index)."""
    out = {f"{prefix}.index": digest(frame.index.to_numpy(dtype=np.float64))}
    for c in columns:
        out[f"{prefix}.{c}"] = digest(frame[c].to_numpy(dtype=np.float64))
    return out


# The columns that existed before the redesign: new columns may be added, these must not move.
TRACE = [
    "x", "y", "z", "phi", "theta", "psi", "zc", "vx", "vy", "vz", "p", "q", "r", "vzc",
    "x_ref", "y_ref", "z_ref", "psi_ref", "U1", "tau_phi", "tau_theta", "tau_psi",
    "wind_x", "wind_y", "wind_z", "e_o", "accel_c", "drag_z",
]  # fmt: skip
METRICS = [
    "iae", "itae", "max_abs", "rms", "tracking_rms", "peak_frequency", "peak_amplitude",
    "max_accel", "rms_accel",
]  # fmt: skip


def short(s: quadrs.Scenario, duration: float, gust: tuple[float, float]) -> quadrs.Scenario:
    """``s`` cut to ``duration`` s with one phase and the gust window ``gust``."""
    return s.override(
        {
            "integrator.duration": duration,
            "gust.start": gust[0],
            "gust.end": gust[1],
            "phases": [
                {"name": "A", "start": 0.0, "end": duration / 2},
                {"name": "B", "start": duration / 2, "end": duration},
            ],
        }
    )


#: The whole-flight phase every result carries after the scenario's own phases (new outputs:
#: its rows are left out of the recorded digests, which cover the scenario's phases).
FLIGHT = "flight"


def own_phases(frame: pd.DataFrame) -> pd.DataFrame:
    """The rows of the phases the scenario itself names, renumbered from 0."""
    return frame[frame["phase"] != FLIGHT].reset_index(drop=True)


def flight_case(s: quadrs.Scenario, controller: str, seed: int, realisation: int,
                every_column: bool = False) -> dict:  # fmt: skip
    """A flight's trace, metrics and spectra; ``every_column``: all the trace's and metrics'
    columns (the delivery preset), else the paper model's round-2 columns."""
    f = quadrs.simulate(s, controller, seed, realisation=realisation, record_every=37)
    trace = list(f.trace.columns) if every_column else TRACE
    metrics = list(quadrs._core.METRIC_NAMES) if every_column else METRICS
    out = frame_digests("trace", f.trace, trace)
    out.update(frame_digests("metrics", own_phases(f.metrics), metrics))
    out["diverged_at"] = digest([f.diverged_at])
    for phase, spec in f.spectra.items():
        out[f"spectrum.{phase}"] = digest(spec["amplitude"].to_numpy())
    return out


def batch_case(s: quadrs.Scenario, runs: int, seed: int, every_column: bool = False,
               **kw: Any) -> dict:  # fmt: skip
    mc = quadrs.monte_carlo(s, runs=runs, seed=seed, progress=False, workers=2, **kw)
    rows = own_phases(mc.runs.sort_values(["realisation", "controller", "phase"]))
    metrics = list(quadrs._core.METRIC_NAMES) if every_column else METRICS
    out = {
        f"runs.{c}": digest(rows[c].to_numpy(dtype=np.float64)) for c in [*metrics, *s.dispersions]
    }
    out["runs.diverged"] = digest(rows["diverged"].to_numpy(dtype=np.float64))
    spectra = getattr(mc, "spectra", None)
    if isinstance(spectra, pd.DataFrame):
        spectra = own_phases(spectra)
        for c in spectra.columns:
            if pd.api.types.is_float_dtype(spectra[c]):
                out[f"spectra.{c}"] = digest(spectra[c].to_numpy())
    return out


def linear_case(s: quadrs.Scenario, controller: str) -> dict:
    lin = quadrs.linearize(s, controller, inputs=("wind_x", "wind_z"), wind=(0.5, 0.0, 1.0))
    out = {f"lin.{m}": digest(getattr(lin, m)) for m in ("A", "B", "C", "D")}
    out["lin.equilibrium"] = digest(lin.equilibrium)
    rep = quadrs.stability(s, controller)
    poles = rep.poles.sort_values(["real", "imag"]).reset_index(drop=True)
    out["poles.real"] = digest(poles["real"].to_numpy())
    out["poles.imag"] = digest(poles["imag"].to_numpy())
    return out


def gust_case() -> dict:
    out = {}
    for model in ("dryden", "von_karman"):
        for comp in ("longitudinal", "lateral", "vertical"):
            w = quadrs.gust_series(
                component=comp, sigma=1.0, length_scale=2.0, airspeed=10.0, dt=0.01,
                steps=500, realisations=5, seed=3, model=model,
            )  # fmt: skip
            out[f"gust.{model}.{comp}"] = digest(w)
    return out


def cases() -> dict[str, Callable[[], dict]]:
    paper = quadrs.Scenario.paper()
    delivery = quadrs.Scenario.preset("delivery")
    lateral = short(
        quadrs.Scenario.preset("paper_stable_lateral").override(
            {
                "gust.components": ["longitudinal", "lateral", "vertical"],
                "initial.position": [0.3, -0.2, 0.0],
                "initial.attitude": [0.05, -0.03, 0.5],
                "trajectory.interpolation": "min_jerk",
                "integrator.dt": 1e-3,
            }
        ),
        12.0,
        (2.0, 10.0),
    )
    dispersed = short(paper, 6.0, (1.0, 5.0)).override(
        {
            "dispersions": {
                "payload.mass": {"dist": "uniform", "low": 0.15, "high": 0.3},
                "gust.w20": {"dist": "lognormal", "mu": 2.3, "sigma": 0.3},
                "controller.pd.kp[2]": {"dist": "normal", "mean": 1.5, "std": 0.1},
            }
        }
    )
    diverging = short(paper, 12.0, (2.0, 10.0)).override(
        {"gust.components": ["lateral", "vertical"], "integrator.dt": 1e-3}
    )
    return {
        "paper.pd": lambda: flight_case(paper, "pd", 3, 5),
        "paper.smc": lambda: flight_case(paper, "smc", 3, 5),
        "lateral.pd": lambda: flight_case(lateral, "pd", 1, 2),
        "lateral.smc": lambda: flight_case(lateral, "smc", 1, 2),
        "diverging.smc": lambda: flight_case(diverging, "smc", 0, 1),
        "batch.paper": lambda: batch_case(paper, 9, 1),
        "batch.lateral": lambda: batch_case(lateral, 7, 2),
        "batch.dispersed.random": lambda: batch_case(dispersed, 9, 4),
        "batch.dispersed.lhs": lambda: batch_case(dispersed, 6, 4, sampling="lhs"),
        "batch.diverging": lambda: batch_case(diverging, 5, 0),
        "linear.pd": lambda: linear_case(paper, "pd"),
        "linear.smc": lambda: linear_case(paper, "smc"),
        "gust": gust_case,
        # The delivery preset (cable, rotors, whole-flight wind, route): every column.
        # tests/data/delivery_bits.json; no ensemble spectra (their last bits follow the CPU).
        "delivery.pd": lambda: flight_case(delivery, "pd", 3, 5, every_column=True),
        "delivery.smc": lambda: flight_case(delivery, "smc", 3, 5, every_column=True),
        "batch.delivery": lambda: batch_case(
            delivery, 4, 1, every_column=True, controllers=("pd",), spectra=False
        ),
    }


#: The paper model's cases (the delivery preset's are computed when asked for by name).
PAPER_CASES = ("paper.pd", "paper.smc", "lateral.pd", "lateral.smc", "diverging.smc",
               "batch.paper", "batch.lateral", "batch.dispersed.random", "batch.dispersed.lhs",
               "batch.diverging", "linear.pd", "linear.smc", "gust")  # fmt: skip


def compute(only: list[str] | None = None) -> dict[str, dict[str, str]]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return {name: f() for name, f in cases().items() if name in (only or PAPER_CASES)}


def compare(want: dict[str, dict[str, str]], got: dict[str, dict[str, str]]) -> list[str]:
    """Every digest of ``want`` that ``got`` lacks or differs in (new outputs are fine)."""
    return [
        f"{case}: {key}" + (" missing" if key not in got.get(case, {}) else " changed")
        for case, digests in want.items()
        for key, d in digests.items()
        if got.get(case, {}).get(key) != d
    ]


#: Outputs whose last bits depend on the CPU, recorded per CPU class beside the reference: the
#: ensemble spectra are sums over realisations taken a lane-set at a time (four lanes on AVX2,
#: eight on AVX-512: another order of the same additions), and a lognormal dispersion's values
#: come from numpy's exp, which has its own AVX-512 kernel. Each flight, trace and per-flight
#: metric is the same on every CPU.
CPU_FILE = "paper_bits_cpu.json"


def cpu_class() -> str:
    """``engine-<SIMD path>/numpy-<avx512|avx2>``: what decides those outputs' last bits."""
    from numpy._core._multiarray_umath import __cpu_features__ as numpy_cpu

    numpy_path = "avx512" if numpy_cpu.get("AVX512_SKX") else "avx2"
    return f"engine-{quadrs._core.simd_path()}/numpy-{numpy_path}"


def reference(path: Path) -> dict[str, dict[str, str]]:
    """The recorded digests (``path``, written on an AVX2 machine) with this CPU class's own
    values of the CPU-dependent outputs (``CPU_FILE`` beside it), where recorded."""
    want = json.loads(path.read_text())
    cpu = path.with_name(CPU_FILE)
    if cpu.exists():
        for case, digests in json.loads(cpu.read_text()).get(cpu_class(), {}).items():
            want.setdefault(case, {}).update(digests)
    return want


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", type=Path, help="compare with a saved run; exit 1 on change")
    ap.add_argument("--write", type=Path, help="save the digests to this file")
    ap.add_argument("--delivery", action="store_true",
                    help="the delivery preset's cases instead of the paper model's")  # fmt: skip
    args = ap.parse_args(argv)
    want = reference(args.check) if args.check else None
    delivery = [name for name in cases() if "delivery" in name]
    got = compute(list(want) if want else (delivery if args.delivery else None))
    if args.write:
        args.write.write_text(json.dumps(got, indent=1, sort_keys=True) + "\n")
    if want is None:
        if not args.write:
            print(json.dumps(got, indent=1, sort_keys=True))
        return 0
    bad = compare(want, got)
    n = sum(len(d) for d in want.values())
    print(f"paper bits: {n - len(bad)} of {n} outputs identical")
    for line in bad:
        print("  " + line)
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
