"""Fixed workloads for instruction counts (docs/performance.md, "The model seams").

Run under callgrind, whose counts repeat exactly on a busy machine where wall-clock rates do
not:

    valgrind --tool=callgrind --toggle-collect='*fly_avx2*' python benches/instructions.py loop
    valgrind --tool=callgrind --separate-threads=yes python benches/instructions.py dispersed
    callgrind_annotate callgrind.out.<pid>[-02] | grep TOTALS    # -02: the engine's worker

Modes: ``loop`` (4 realisations of a 4 s flight, one AVX2 lane-set), ``gust_off`` and
``gust_three`` (the same with the gust off, and with all three components), ``long`` (8 x 4 s),
``fixed`` (160 x 0.2 s), ``dispersed`` (160 x 0.2 s, three non-gust keys dispersed),
``dispersed_gust`` (the same plus ``gust.w20``). Every mode: the paper preset with the gust on
throughout, PD, one worker, no spectra. Prints the mode and its realisation-steps.

The mission modes (``benches/throughput.py --mission``'s cases, issue 36): 8 whole flights (one
AVX-512 lane-set, two AVX2 ones), PD, one worker, no spectra:
``delivery`` (as shipped), ``delivery_fixed`` (turbulence at 30 m and 10 m/s, no mean wind),
``delivery_mean`` (the mean wind only), ``delivery_calm`` (no wind), and ``paper_calm`` (the
paper preset with the gust off); count them with
``--toggle-collect='*fly_avx512*'`` (or ``fly_avx2`` on a CPU without AVX-512).
"""

from __future__ import annotations

import sys
import warnings

import quadrs

DISPERSIONS = {
    "payload.mass": {"dist": "uniform", "low": 0.18, "high": 0.26},
    "payload.natural_frequency": {"dist": "normal", "mean": 2.0, "std": 0.2},
    "vehicle.inertia[2]": {"dist": "triangular", "low": 0.04, "mode": 0.05, "high": 0.07},
}
MODES = {"loop": (4.0, 4), "gust_off": (4.0, 4), "gust_three": (4.0, 4), "long": (4.0, 8)}
MODES |= {"fixed": (0.2, 160)}
MODES |= {"dispersed": (0.2, 160), "dispersed_gust": (0.2, 160)}
#: The mission modes: the delivery preset's wind taken apart, and the paper preset calm.
MISSION = {
    "delivery": {},
    "delivery_fixed": {"gust.altitude": 30.0, "gust.airspeed": 10.0, "wind.speed": 0.0},
    "delivery_mean": {"gust.enabled": False},
    "delivery_calm": {"gust.enabled": False, "wind.speed": 0.0},
}
MODES |= {name: (0.0, 8) for name in [*MISSION, "paper_calm"]}


def mission(mode: str) -> None:
    """A mission mode: 8 whole flights, PD, one worker, no spectra."""
    runs = MODES[mode][1]
    if mode == "paper_calm":
        s = quadrs.Scenario.paper().override({"gust.enabled": False})
    else:
        s = quadrs.Scenario.preset("delivery").override(MISSION[mode])
    quadrs.monte_carlo(s, runs=runs, seed=0, controllers=("pd",), workers=1, progress=False,
                       spectra=False)  # fmt: skip
    print(mode, runs * s.steps)


def main(mode: str) -> None:
    if mode not in MODES:
        raise SystemExit(f"mode must be one of {sorted(MODES)}, got {mode!r}")
    warnings.simplefilter("ignore")
    if mode in MISSION or mode == "paper_calm":
        mission(mode)
        return
    duration, runs = MODES[mode]
    s = quadrs.Scenario.paper().override(
        {
            "integrator.duration": duration,
            "gust.start": 0.0,
            "gust.end": duration,
            "phases": [{"name": "all", "start": 0.0, "end": duration}],
        }
    )
    if mode == "gust_off":
        s = s.override({"gust.enabled": False})
    elif mode == "gust_three":
        s = s.override({"gust.components": ["longitudinal", "lateral", "vertical"]})
    if mode.startswith("dispersed"):
        d = dict(DISPERSIONS)
        if mode == "dispersed_gust":
            d["gust.w20"] = {"dist": "lognormal", "mu": 2.3, "sigma": 0.3}
        s = s.override({"dispersions": d})
    warnings.simplefilter("ignore")
    # the loop case keeps monte_carlo's default spectra, as docs/performance.md tabulates it
    quadrs.monte_carlo(s, runs=runs, seed=0, controllers=("pd",), workers=1, progress=False,
                       spectra=mode == "loop")  # fmt: skip
    print(mode, runs * s.steps)


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "loop")
