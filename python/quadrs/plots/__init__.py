"""Figures: those a reader of the paper will recognise (its Figs. 4-16) and their Monte Carlo
versions, and those of routes, rotors, wind, slung payloads and missions. Each is made in the
module beside this one named by what it shows (``flight``, ``batch``, ``risk``,
``sensitivity``, ``gust``, ``route``, ``rotors``, ``wind``, ``payload``, ``mission``) and
offered here.

Every function returns a :class:`matplotlib.figure.Figure` built without pyplot (no global
figure state, rendered by Agg), and saves it as PNG and SVG when given ``path`` (a path
without suffix: ``path.png`` and ``path.svg`` are written). ``ax=`` draws into existing Axes
instead (one Axes, or a sequence with one per panel in row-major order; the function says
how many panels it draws) and returns their Figure. Line styles follow the paper: PD dashed
blue, SMC solid red, reference solid red, payload dashed black. Labels are plain English
(:data:`PLAIN_LABELS`), never the code's identifiers.

Spectral densities are one-sided, in units^2/Hz, and integrate over 0..fs/2 to the variance
of the (mean-removed) signal: :func:`welch_psd` for traces and generated gusts,
:func:`amplitude_to_psd` for the engine's amplitude spectra (docs/model.md section 5).
"""

from __future__ import annotations

from quadrs.plots import base as _base
from quadrs.plots.batch import (
    Curve,
    distributions,
    ensemble_psd,
    ensemble_spectra,
    max_amplitude,
    sweep_metric,
)
from quadrs.plots.flight import altitude, gust_force, mass_compensation, oscillation, psd, spectra
from quadrs.plots.gust import gust_spectrum, gust_transmissibility
from quadrs.plots.mission import mission_risk
from quadrs.plots.payload import lowering_path, payload_path, swing_tension
from quadrs.plots.risk import exceedance_curves
from quadrs.plots.rotors import rotors
from quadrs.plots.route import altitude_profile, ground_track
from quadrs.plots.sensitivity import dispersion_scatter, sobol_bars
from quadrs.plots.wind import gust_spectra, gust_spectra_frame, wind_met
from quadrs.present import labels as _labels
from quadrs.runs import psd as _psd

__all__ = [
    "FMAX",
    "FORMATS",
    "PLAIN_LABELS",
    "SHORT_NAMES",
    "Curve",
    "altitude",
    "altitude_profile",
    "amplitude_to_psd",
    "dispersion_scatter",
    "distributions",
    "ensemble_psd",
    "ensemble_psd_frame",
    "ensemble_spectra",
    "exceedance_curves",
    "ground_track",
    "gust_force",
    "gust_spectra",
    "gust_spectra_frame",
    "gust_spectrum",
    "gust_spectrum_frame",
    "gust_transmissibility",
    "lowering_path",
    "mass_compensation",
    "max_amplitude",
    "mission_risk",
    "new_figure",
    "oscillation",
    "payload_path",
    "psd",
    "rotors",
    "save",
    "sobol_bars",
    "spectra",
    "sweep_metric",
    "swing_tension",
    "welch_psd",
    "wind_met",
]

#: Public names re-exported from where they now live (the figure machinery in
#: quadrs.plots.base, the signal processing in quadrs.runs.psd): ``plots.save`` and the rest stay.
FMAX = _base.FMAX
FORMATS = _base.FORMATS
PLAIN_LABELS = _labels.PLAIN_LABELS
SHORT_NAMES = _base.SHORT_NAMES
new_figure = _base.new_figure
save = _base.save
amplitude_to_psd = _psd.amplitude_to_psd
ensemble_psd_frame = _psd.ensemble_psd_frame
gust_spectrum_frame = _psd.gust_spectrum_frame
welch_psd = _psd.welch_psd
