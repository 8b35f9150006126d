"""Power spectral densities (docs/model.md section 5): Welch's estimate for traces and
generated gusts, the periodogram of the engine's amplitude spectra, and the ensemble mean of
a Monte Carlo's. Signal processing only: the figures that draw them are in
:mod:`quadrs.plots`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt
import pandas as pd

from quadrs.runs.flight import Flight

__all__ = [
    "amplitude_to_psd",
    "ensemble_psd_frame",
    "gust_spectrum_frame",
    "phase_psd",
    "phase_window",
    "welch_psd",
]


def welch_psd(
    signal: npt.ArrayLike, rate: float, resolution: float | None = None
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """One-sided power spectral density of a uniformly sampled signal (units^2/Hz), by Welch's
    method: Hann-windowed segments of ``1 / resolution`` s (default, and at most, the whole
    record), 50 % overlap, each segment's mean removed, averaged. Density scaling
    (scipy.signal.welch's): sum(psd) * df is the signal's variance, exactly for the mean of
    the windowed segments' squares and in expectation for a stationary signal. ``signal``
    may be 2-D (one row per realisation: one PSD per row). Returns ``(frequency, psd)``."""
    from scipy.signal import welch

    x = np.asarray(signal, dtype=float)
    if not rate > 0:
        raise ValueError(f"rate must be a positive sample rate (Hz), got {rate!r}")
    n = x.shape[-1]
    if n < 2:
        raise ValueError(f"signal needs at least 2 samples for a PSD, got {n}")
    if resolution is not None and not resolution > 0:
        raise ValueError(f"resolution must be a positive frequency step (Hz), got {resolution!r}")
    seg = n if resolution is None else min(n, max(2, round(rate / resolution)))
    f, p = welch(x, fs=rate, window="hann", nperseg=seg, detrend="constant", scaling="density")
    return f, p


def amplitude_to_psd(
    frequency: npt.ArrayLike, amplitude: npt.ArrayLike, rate: float | None = None
) -> npt.NDArray[np.float64]:
    """The one-sided PSD (m^2/Hz) of the engine's amplitude spectrum (single-sided
    ``2 |X_k| / N``, mean removed, rectangular window): the periodogram
    ``A_k^2 / (2 df)``, with ``A^2 / df`` at 0 Hz and at the Nyquist bin (``rate / 2``, when the
    sample ``rate`` is given), so that ``sum(psd) * df`` is the variance of the sampled
    signal (Parseval). Works elementwise on ensemble mean squares too."""
    f = np.asarray(frequency, dtype=float)
    a2 = np.asarray(amplitude, dtype=float) ** 2
    if f.size < 2:
        return np.full(f.shape, np.nan)
    df = float(f[1] - f[0])
    psd = a2 / (2 * df)
    edge = np.isclose(f, 0.0)
    if rate is not None:
        edge |= np.isclose(f, rate / 2)
    psd[edge] = a2[edge] / df
    return psd


def phase_window(flight: Flight, phase: str) -> tuple[float, float]:
    """(start, end) in s of the phase named ``phase`` of ``flight``'s scenario (its own
    phases, or a route's legs and holds under ``phases = "legs"``)."""
    windows = flight.scenario.phase_windows
    if phase not in windows:
        raise ValueError(f"phase must be one of {list(windows)}, got {phase!r}")
    return windows[phase]


def phase_psd(
    flight: Flight, phase: str, method: str = "welch", resolution: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The PSD of ``flight``'s e_o over ``phase``: ``"welch"`` (:func:`welch_psd` of the
    trace) or ``"periodogram"`` (:func:`amplitude_to_psd` of the engine's spectrum).
    Returns ``(frequency, psd)``."""
    if method == "periodogram":
        sp = flight.spectra[phase]
        rate = float(flight.scenario["metrics.spectrum_rate"])
        return sp["frequency"].to_numpy(float), amplitude_to_psd(
            sp["frequency"], sp["amplitude"], rate
        )
    lo, hi = phase_window(flight, phase)
    e = flight.trace["e_o"]
    part = e[(e.index >= lo) & (e.index <= hi)]
    t = part.index.to_numpy(float)
    if len(t) < 3:
        raise ValueError(f"phase {phase!r} holds {len(t)} trace samples, too few for a PSD")
    step = np.diff(t)
    if np.ptp(step) > 1e-6 * step.mean():
        raise ValueError(f"the trace of phase {phase!r} is not uniformly sampled")
    return welch_psd(part.to_numpy(float), 1.0 / float(step.mean()), resolution)


def ensemble_psd_frame(spectra_frame: pd.DataFrame) -> pd.DataFrame:
    """``spectra_frame`` (``MonteCarloResult.spectra``) with a column ``psd``: the ensemble-mean
    periodogram (m^2/Hz) per controller, phase and frequency. From the mean and the (n - 1)
    standard deviation of the amplitudes, E[A^2] = mean^2 + std^2 (n - 1) / n exactly, so
    ``psd`` is the mean of the realisations' :func:`amplitude_to_psd` (the Nyquist bin, far
    above any plotted range, is taken as interior)."""
    out = spectra_frame.copy()
    n = out["n"].to_numpy(float)
    mean = out["mean"].to_numpy(float)
    std = np.nan_to_num(out["std"].to_numpy(float))  # n = 1: no spread, E[A^2] = A^2
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_sq = mean**2 + std**2 * np.where(n > 0, (n - 1) / n, np.nan)
    psd = np.full(len(out), np.nan)
    for _, idx in out.groupby(["controller", "phase"], sort=False).indices.items():
        psd[idx] = amplitude_to_psd(out["frequency"].to_numpy(float)[idx], np.sqrt(mean_sq[idx]))
    out["psd"] = psd
    return out


def gust_spectrum_frame(
    component: str = "vertical",
    sigma: float = 1.0,
    length_scale: float = 2.0,
    airspeed: float = 10.0,
    dt: float = 0.01,
    steps: int = 8192,
    realisations: int = 64,
    seed: int = 0,
    *,
    models: Sequence[str] = ("dryden", "von_karman"),
    resolution: float | None = None,
    workers: int | None = None,
) -> pd.DataFrame:
    """The generated gust's spectrum against the formula, per model: the Welch PSD
    (:func:`welch_psd`, ``(m/s)^2/Hz``) of each of ``realisations`` series of
    :func:`quadrs.runs.gust.gust_series` (``steps`` samples every ``dt`` s), averaged (column
    ``welch``, with its standard error ``welch_se`` over realisations), beside
    :func:`quadrs.runs.gust.gust_psd` at the same frequencies: ``filter`` (the forming filter the
    series discretises) and ``formula`` (the Dryden or exact von Karman PSD). ``resolution``
    defaults to 1 / (1024 dt) Hz. The sampled series' PSD is the aliased filter PSD: compare
    well below the Nyquist frequency 1 / (2 dt)."""
    from quadrs.runs.gust import gust_psd, gust_series

    if not dt > 0:
        raise ValueError(f"dt must be positive (s), got {dt!r}")
    resolution = 1.0 / (min(1024, steps) * dt) if resolution is None else resolution
    parts = []
    for model in models:
        x = gust_series(
            component, sigma, length_scale, airspeed, dt, steps, realisations, seed,
            model=model, workers=workers,
        )  # fmt: skip
        f, p = welch_psd(x, 1.0 / dt, resolution)
        p = np.atleast_2d(p)
        realised, target = gust_psd(f, component, sigma, length_scale, airspeed, dt, model=model)
        se = p.std(axis=0, ddof=1) / np.sqrt(len(p)) if len(p) > 1 else np.full(len(f), np.nan)
        parts.append(
            pd.DataFrame(
                {
                    "model": model,
                    "frequency": f,
                    "welch": p.mean(axis=0),
                    "welch_se": se,
                    "filter": realised,
                    "formula": target,
                }
            )
        )
    out = pd.concat(parts, ignore_index=True)
    out.attrs = {
        "component": component, "sigma": sigma, "length_scale": length_scale,
        "airspeed": airspeed, "dt": dt, "realisations": realisations,
    }  # fmt: skip
    return out
