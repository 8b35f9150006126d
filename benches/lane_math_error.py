"""The lane-valued functions' error table (exp, expm1, ln, pow, atan2 and the near-zero series
of the turbulence filters; docs/performance.md, "Transcendental functions in lane values"), and
the check that every lane path gives the same bits.

    python benches/lane_math_error.py            # 20,000 points per range (about a minute)
    python benches/lane_math_error.py --points 2000

For each function and argument range (the wind's own first, then wider ones), the engine's
values (``quadrs._core.lane_math``) are measured against the exact value from mpmath at 160
bits: the error in units of the last place of the correctly rounded result (ulp), the worst
over the points (random, fixed seed, and the range's ends). ``paths`` says that every lane path
this CPU runs (scalar ``f64``, SSE2 ``F64x4``, AVX2 ``F64x4Avx``, AVX-512 ``F64x8Avx512``) gave
bit-identical results at every point. Needs ``pip install mpmath`` (a bench dependency).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable

import mpmath
import numpy as np

from quadrs import _core

mpmath.mp.prec = 160

#: Paths lane_math knows; those this CPU lacks are skipped (said in the output).
PATHS = ("scalar", "sse2", "avx2", "avx512")

#: (function, y for pow, label, low, high, spacing): "lin" uniform, "log" log-uniform.
RANGES: list[tuple[str, float, str, float, float, str]] = [
    # The wind's: k = V dt / L; for 2k <= 1/32 (every step in flight) the short series (the
    # *_near0): expm1(-k), and from it e^-k = 1 + expm1(-k), e^-2k = (e^-k)^2 and expm1(-2k) =
    # expm1(-k) (2 + expm1(-k)) (the DERIVED rows), the tail of e^2k from its cube; beyond it
    # the general functions; ln(h / z0) of the shear; pow(d, -0.4) (d^-1.2 is its cube),
    # d = 0.177 + 0.000823 h_ft over 10..1000 ft.
    ("expm1_near0", 0.0, "expm1(-k)", -0.015625, -1e-9, "lin"),
    ("expm1_near0", 0.0, "expm1(-k), tiny k", -1e-3, -1e-12, "log"),
    ("e^-k", 0.0, "1 + expm1(-k)", -0.015625, -1e-9, "lin"),
    ("e^-2k", 0.0, "(1 + expm1(-k))^2", -0.015625, -1e-9, "lin"),
    ("expm1(-2k)", 0.0, "expm1(-k) (2 + expm1(-k))", -0.015625, -1e-9, "lin"),
    ("expm1(-2k)", 0.0, "the same, tiny k", -1e-3, -1e-12, "log"),
    ("tail3_near0", 0.0, "e^2k - 1 - 2k - 2k^2", 1e-6, 0.03125, "lin"),
    ("tail3_near0", 0.0, "the same, tiny k", 1e-9, 1e-3, "log"),
    ("exp", 0.0, "exp(-k), long steps", -50.0, -0.015, "lin"),
    ("expm1", 0.0, "expm1(-2k), long steps", -40.0, -0.03, "lin"),
    ("ln", 0.0, "ln(h / z0), the shear", 1.0, 1e5, "log"),
    ("pow", -0.4, "pow(d, -0.4), the scales", 0.1852, 1.0, "lin"),
    # Beyond.
    ("exp", 0.0, "exp, whole range", -745.0, 709.7, "lin"),
    ("exp", 0.0, "exp, near 0", -1.0, 1.0, "lin"),
    ("expm1", 0.0, "expm1, whole range", -40.0, 709.7, "lin"),
    ("expm1", 0.0, "expm1, near 0", -1.0, 1.0, "lin"),
    ("ln", 0.0, "ln, normal numbers", 1e-300, 1e300, "log"),
    ("ln", 0.0, "ln, near 1", 0.9, 1.1, "lin"),
    ("ln", 0.0, "ln, subnormals", 5e-324, 2.2e-308, "log"),
    ("pow", -2.5, "pow(x, -2.5)", 1e-3, 1e3, "log"),
    ("pow", 11.3, "pow(x, 11.3)", 1e-3, 1e3, "log"),
    # The rigid body's Euler angles, atan2(x, y) = the angle of (y, x): roll and pitch near
    # level (y near 1), the yaw and the other quadrants; then near the axes.
    ("atan2", 1.0, "atan2(s, 1), roll near level", -1.0, 1.0, "lin"),
    ("atan2", -0.8, "atan2(s, -0.8), left half", -10.0, 10.0, "lin"),
    ("atan2", 1.0, "atan2(s, 1), tiny s", 1e-300, 1e-3, "log"),
    ("atan2", 1e-3, "atan2(s, 1e-3), near pi/2", -1e3, 1e3, "lin"),
    ("atan2", -1.0, "atan2(s, -1), near pi", -1e-3, 1e-3, "lin"),
]

EXACT: dict[str, Callable[[mpmath.mpf, float], mpmath.mpf]] = {
    "exp": lambda x, y: mpmath.exp(x),
    "expm1": lambda x, y: mpmath.expm1(x),
    "ln": lambda x, y: mpmath.log(x),
    "pow": lambda x, y: mpmath.power(x, mpmath.mpf(y)),
    "atan2": lambda x, y: mpmath.atan2(x, mpmath.mpf(y)),
    "e^-k": lambda x, y: mpmath.exp(x),
    "e^-2k": lambda x, y: mpmath.exp(2 * x),
    "expm1(-2k)": lambda x, y: mpmath.expm1(2 * x),
    "expm1_near0": lambda x, y: mpmath.expm1(x),
    "tail3_near0": lambda x, y: mpmath.expm1(x) - x - x * x / 2,
}

#: What the turbulence filters compute from a lane function's values (numpy's double arithmetic
#: is the engine's, operation for operation): name -> (lane function, how).
DERIVED: dict[str, tuple[str, Callable[[np.ndarray], np.ndarray]]] = {
    "e^-k": ("expm1_near0", lambda m: 1.0 + m),
    "e^-2k": ("expm1_near0", lambda m: (1.0 + m) * (1.0 + m)),
    "expm1(-2k)": ("expm1_near0", lambda m: m * (2.0 + m)),
}


def points(low: float, high: float, spacing: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if spacing == "log":
        sign = -1.0 if high < 0 else 1.0
        a, b = sorted((math.log(abs(low)), math.log(abs(high))))
        x = sign * np.exp(rng.uniform(a, b, n))
    else:
        x = rng.uniform(low, high, n)
    return np.concatenate([[low, high], x])


def ulp_error(got: float, exact: mpmath.mpf) -> float:
    """|got - exact| over the spacing of doubles at the correctly rounded result."""
    rounded = float(exact)
    if rounded == 0.0 or not math.isfinite(rounded):
        return 0.0 if got == rounded else math.inf
    return float(abs(mpmath.mpf(got) - exact) / math.ulp(rounded))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--points", type=int, default=20_000, help="random points per range")
    args = ap.parse_args()
    rng = np.random.default_rng(51)
    runnable = []
    for path in PATHS:
        try:
            _core.lane_math("exp", np.zeros(1), path)
            runnable.append(path)
        except ValueError as e:
            print(f"(skipped {path}: {e})", file=sys.stderr)
    print(f"{'function':<11} {'range':<28} {'low':>10} {'high':>10} {'points':>7} "
          f"{'max ulp':>8}  paths")  # fmt: skip
    worst: dict[str, float] = {}
    same = True
    for name, y, label, low, high, spacing in RANGES:
        x = points(low, high, spacing, args.points, rng)
        function, how = DERIVED.get(name, (name, lambda v: v))
        values = {p: how(_core.lane_math(function, x, p, y)) for p in runnable}
        ref = values["scalar"]
        agree = all(np.array_equal(v.view(np.uint64), ref.view(np.uint64)) for v in values.values())
        same &= agree
        err = max(ulp_error(float(g), EXACT[name](mpmath.mpf(float(xi)), y))
                  for xi, g in zip(x, ref, strict=True))  # fmt: skip
        worst[name] = max(worst.get(name, 0.0), err)
        print(f"{name:<11} {label:<28} {low:>10.4g} {high:>10.4g} {len(x):>7} {err:>8.3f}  "
              f"{'same bits on ' + '/'.join(runnable) if agree else 'PATHS DIFFER'}")  # fmt: skip
    print("worst: " + ", ".join(f"{k} {v:.3f} ulp" for k, v in worst.items()))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
