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


def main(mode: str) -> None:
    if mode not in MODES:
        raise SystemExit(f"mode must be one of {sorted(MODES)}, got {mode!r}")
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
