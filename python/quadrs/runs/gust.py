"""Turbulence alone: many seeded realisations of one Dryden (or von Karman) component."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from quadrs import _core
from quadrs.engine.calls import default_workers

COMPONENTS = ("longitudinal", "lateral", "vertical")
MODELS = ("dryden", "von_karman")


def gust_scales(altitude: float, w20: float) -> dict[str, tuple[float, float]]:
    """MIL-F-8785C low-altitude (sigma m/s, scale length m) per component, from the altitude
    (m; converted to feet for the standard's formulas) and the wind at 20 ft (m/s)."""
    sigma, length = _core.low_altitude_scales(altitude, w20)
    return {c: (sigma[i], length[i]) for i, c in enumerate(COMPONENTS)}


def gust_series(
    component: str = "vertical",
    sigma: float = 1.0,
    length_scale: float = 2.0,
    airspeed: float = 10.0,
    dt: float = 0.01,
    steps: int = 10_000,
    realisations: int = 1,
    seed: int = 0,
    *,
    model: str = "dryden",
    first: int = 0,
    workers: int | None = None,
) -> npt.NDArray[np.float64]:
    """Stationary gust velocity (m/s), shape (realisations, steps), sampled every ``dt`` s.

    Exact discretisation: variance sigma^2 and the analytic autocorrelation at any ``dt``.
    Row r is realisation ``first + r`` of ``seed`` and does not depend on ``workers``; it
    equals the gust a flight with a single ``component`` sees from the gust onset.
    """
    if component not in COMPONENTS:
        raise ValueError(f"component must be one of {COMPONENTS}, got {component!r}")
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    from quadrs.engine.calls import I64_MAX, MAX_WORKERS, U64_MAX, check_int

    steps = check_int("steps", steps, 0, I64_MAX)
    realisations = check_int("realisations", realisations, 0, I64_MAX)
    seed = check_int("seed", seed)
    first = check_int("first", first, 0, U64_MAX - max(realisations - 1, 0))
    workers = check_int("workers", default_workers() if workers is None else workers, 1,
                        MAX_WORKERS)  # fmt: skip
    spec = (model, component, sigma, length_scale, airspeed, dt)
    return _core.gust_series(spec, int(steps), int(realisations), seed, first, workers)


def gust_psd(
    frequency: npt.ArrayLike,
    component: str = "vertical",
    sigma: float = 1.0,
    length_scale: float = 2.0,
    airspeed: float = 10.0,
    dt: float = 0.01,
    *,
    model: str = "dryden",
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """One-sided PSD ((m/s)^2/Hz) of one gust component at ``frequency`` (Hz).

    Returns ``(realised, target)``: the spectrum of the continuous forming filter that
    :func:`gust_series` discretises exactly, and the formula it stands for (the Dryden PSD,
    identical to ``realised``; or the exact MIL-F-8785C von Karman PSD, which the rational
    approximant follows to a few per cent). Both integrate to sigma^2 over 0..inf Hz.
    """
    if component not in COMPONENTS:
        raise ValueError(f"component must be one of {COMPONENTS}, got {component!r}")
    if model not in MODELS:
        raise ValueError(f"model must be one of {MODELS}, got {model!r}")
    f = np.ascontiguousarray(frequency, dtype=np.float64)
    if f.ndim != 1:
        raise ValueError(f"frequency must be a 1-D array of Hz, got shape {f.shape}")
    return _core.gust_psd((model, component, sigma, length_scale, airspeed, dt), f)
