"""Figures: each returns a Figure holding the data it claims, and saves valid PNG and SVG."""

import re
import xml.etree.ElementTree as ET
from pathlib import Path
from types import SimpleNamespace

import matplotlib.image
import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure
from matplotlib.text import Text

import quadrs
from quadrs import Scenario, plots
from quadrs.paper import pipeline as paper
from quadrs.runs.sweep import SweepResult

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def assert_images(stem: Path) -> None:
    """``stem.png`` is a real, non-empty PNG and ``stem.svg`` parses as SVG."""
    png, svg = stem.with_suffix(".png"), stem.with_suffix(".svg")
    assert png.read_bytes()[:8] == PNG_SIGNATURE
    img = matplotlib.image.imread(png)
    assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
    assert img.std() > 0  # not a blank canvas
    root = ET.parse(svg).getroot()
    assert root.tag.endswith("svg")


@pytest.fixture(scope="module")
def flights(short: Scenario) -> dict[str, quadrs.Flight]:
    return {c: quadrs.simulate(short, c, seed=3) for c in ("pd", "smc")}


@pytest.fixture(scope="module")
def mc(short: Scenario) -> quadrs.MonteCarloResult:
    with pytest.warns(quadrs.StabilityWarning):
        return quadrs.monte_carlo(short, runs=6, seed=0, workers=2, progress=False)


def lines_of(ax) -> list:
    return [line for line in ax.get_lines() if len(line.get_xdata()) > 2]


def test_altitude_shows_reference_vehicle_and_payload(flights, tmp_path) -> None:
    fig = plots.altitude(flights, path=tmp_path / "alt")
    assert isinstance(fig, Figure) and len(fig.axes) == 2
    ref, z, zc = lines_of(fig.axes[0])[:3]
    tr = flights["pd"].trace
    np.testing.assert_allclose(ref.get_ydata(), tr["z_ref"])
    np.testing.assert_allclose(z.get_ydata(), tr["z"])
    np.testing.assert_allclose(zc.get_ydata(), tr["zc"])
    assert_images(tmp_path / "alt")


def test_oscillation_per_phase_pd_against_smc(flights, tmp_path) -> None:
    fig = plots.oscillation(flights, path=tmp_path / "osc")
    assert [ax.get_title() for ax in fig.axes] == [
        f"relative oscillation, {p}" for p in ("P1", "P2", "P3")
    ]
    p2 = fig.axes[1]
    pd_line, smc_line = lines_of(p2)
    assert pd_line.get_linestyle() == "--" and smc_line.get_linestyle() == "-"
    t = pd_line.get_xdata()
    assert t.min() >= 2.0 and t.max() <= 4.0
    e = flights["smc"].trace["e_o"]
    np.testing.assert_allclose(smc_line.get_ydata(), e[(e.index >= 2) & (e.index <= 4)])
    # the gust window [2.5, 3.5] s is marked by two vertical lines inside P2
    vertical = [ln for ln in p2.get_lines() if len(set(ln.get_xdata())) == 1]
    assert sorted(ln.get_xdata()[0] for ln in vertical) == [2.5, 3.5]
    assert_images(tmp_path / "osc")


def test_spectra_limited_to_fmax(flights, tmp_path) -> None:
    fig = plots.spectra(flights, ["P2"], fmax=5.0, path=tmp_path / "sp")
    assert len(fig.axes) == 1
    ax = fig.axes[0]
    assert ax.get_xlim() == (0.0, 5.0)
    for line, f in zip(lines_of(ax), flights.values(), strict=True):
        assert line.get_xdata().max() <= 5.0
        sp = f.spectra["P2"]
        np.testing.assert_allclose(line.get_ydata(), sp[sp["frequency"] <= 5.0]["amplitude"])
    assert_images(tmp_path / "sp")


def test_gust_force_from_the_trace(flights, short, tmp_path) -> None:
    fig = plots.gust_force(flights["pd"], path=tmp_path / "gust")
    wind_ax, force_ax = fig.axes
    (line,) = lines_of(force_ax)
    t = line.get_xdata()
    assert t.min() >= 2.5 - 0.1 - 1e-9 and t.max() <= 3.5 + 0.1 + 1e-9
    tr = flights["pd"].trace.loc[t]
    rel = tr["vz"] - tr["wind_z"]
    rho, cda = short["gust.air_density"], short["vehicle.drag_area"]
    np.testing.assert_allclose(line.get_ydata(), -0.5 * rho * cda * rel * rel.abs())
    assert np.abs(lines_of(wind_ax)[0].get_ydata()).max() > 0  # the gust blows
    assert_images(tmp_path / "gust")


def test_mass_compensation_panels(short, tmp_path) -> None:
    flights = {
        (comp, m): quadrs.simulate(
            short.override({"payload.mass": m, "controller.mass_compensation": comp}), "pd"
        )
        for comp in (False, True)
        for m in (0.1, 0.4)
    }
    fig = plots.mass_compensation(flights, path=tmp_path / "mass")
    assert len(fig.axes) == 2
    for ax in fig.axes:
        assert len(lines_of(ax)) == 3  # reference + two masses
    # without compensation the heavier payload sags further below the reference at t = 4 s
    low, high = lines_of(fig.axes[0])[1:]
    assert (
        low.get_ydata()[np.searchsorted(low.get_xdata(), 3.9)]
        > high.get_ydata()[np.searchsorted(high.get_xdata(), 3.9)]
    )
    assert_images(tmp_path / "mass")


def test_ensemble_spectra_mean_and_band(mc, tmp_path) -> None:
    fig = plots.ensemble_spectra(mc.spectra, fmax=10.0, path=tmp_path / "ens")
    assert len(fig.axes) == 3
    ax = fig.axes[1]
    assert len(lines_of(ax)) == 2 and len(ax.collections) == 2  # two means, two bands
    sel = mc.spectra[(mc.spectra["phase"] == "P2") & (mc.spectra["controller"] == "pd")]
    sel = sel[sel["frequency"] <= 10.0]
    np.testing.assert_allclose(lines_of(ax)[0].get_ydata(), sel["mean"])
    assert_images(tmp_path / "ens")


@pytest.mark.parametrize("kind", ["box", "violin"])
def test_distributions_grid(mc, tmp_path, kind) -> None:
    fig = plots.distributions(mc.runs, kind=kind, path=tmp_path / kind)
    assert len(fig.axes) == 2 * 3
    assert [t.get_text() for t in fig.axes[0].get_xticklabels()] == ["PD", "SMC"]
    assert_images(tmp_path / kind)
    with pytest.raises(ValueError, match="kind"):
        plots.distributions(mc.runs, kind="pie")


@pytest.fixture(scope="module")
def swept(short: Scenario) -> SweepResult:
    return quadrs.sweep(
        short, {"payload.natural_frequency": [1.0, 2.0, 4.0]}, runs=2, progress=False
    )


def test_max_amplitude_from_a_sweep(swept, tmp_path) -> None:
    summ = swept.summary()
    fig = plots.max_amplitude(summ, path=tmp_path / "amp")
    # one panel per phase, titled in words (was "max_abs, P1": issue 15 bans raw names)
    peak = "Peak |relative displacement|"
    assert [ax.get_title() for ax in fig.axes] == [f"{peak}, P1", f"{peak}, P3"]
    pd_line = lines_of(fig.axes[0])[0]
    np.testing.assert_allclose(pd_line.get_xdata(), [1.0, 2.0, 4.0])
    want = summ.xs(("max_abs", "P1"), level=("metric", "phase"))["pd_mean"]
    np.testing.assert_allclose(pd_line.get_ydata(), want.to_numpy())
    assert "Hz" in fig.axes[0].get_xlabel()
    assert_images(tmp_path / "amp")


def test_save_writes_png_and_svg(flights, tmp_path) -> None:
    fig = plots.altitude(flights["smc"])
    files = plots.save(fig, tmp_path / "deep" / "dir" / "x.png")
    assert [f.name for f in files] == ["x.png", "x.svg"]
    assert_images(tmp_path / "deep" / "dir" / "x")


# -- power spectral densities ---------------------------------------------------------------
def test_welch_psd_integrates_to_the_variance() -> None:
    """Parseval: a sinusoid of amplitude A has variance A^2/2, white noise sigma^2; the PSD
    is one-sided (0..fs/2) and per Hz."""
    rate, t = 100.0, np.arange(20_000) / 100.0
    sine = 3.0 * np.sin(2 * np.pi * 2.3 * t + 0.4) + 7.0  # the mean is removed
    f, p = plots.welch_psd(sine, rate)  # one window over the whole record
    assert f[-1] == pytest.approx(rate / 2)
    assert p.sum() * f[1] == pytest.approx(4.5, rel=1e-9)
    f, p = plots.welch_psd(sine, rate, resolution=0.5)  # 2 s Hann segments, 50 % overlap
    assert p.sum() * f[1] == pytest.approx(4.5, rel=0.01)
    assert f[np.argmax(p)] == pytest.approx(2.5, abs=0.5)
    noise = np.random.default_rng(1).normal(0.0, 2.0, size=(8, 20_000))
    f, p = plots.welch_psd(noise, rate, resolution=0.5)
    # white: flat at sigma^2 / (fs / 2) = 0.08 per Hz; integral sigma^2 (8 x 199 segments)
    assert p.mean(axis=0)[1:-1].mean() == pytest.approx(4.0 / 50.0, rel=0.01)
    assert (p.sum(axis=1) * f[1]).mean() == pytest.approx(noise.var(axis=1).mean(), rel=0.01)
    with pytest.raises(ValueError, match="rate"):
        plots.welch_psd(sine, 0.0)
    with pytest.raises(ValueError, match="resolution"):
        plots.welch_psd(sine, rate, resolution=-1.0)


def test_engine_spectrum_as_psd_integrates_to_the_variance(short) -> None:
    """Independent paths: the engine's amplitude spectrum of P2, as a PSD, integrates to the
    variance of e_o block-averaged (at metrics.spectrum_rate) from the full trace."""
    flight = quadrs.simulate(short, "pd", 3, record_every=1)
    sp = flight.spectra["P2"]
    f = sp["frequency"].to_numpy()
    dt, rate = short["integrator.dt"], short["metrics.spectrum_rate"]
    d = round(1 / (rate * dt))  # steps per block
    n = round(1 / (f[1] * d * dt))  # blocks in the phase
    e = flight.trace["e_o"].to_numpy()
    blocks = e[: len(e) // d * d].reshape(-1, d).mean(axis=1)
    first = int(np.ceil(round(2.0 / dt) / d))  # first block wholly inside P2 = [2, 4] s
    variance = blocks[first : first + n].var()
    psd = plots.amplitude_to_psd(f, sp["amplitude"], rate)
    assert psd.sum() * f[1] == pytest.approx(variance, rel=1e-9)
    assert variance > 0


def test_ensemble_psd_is_the_mean_of_the_flights_periodograms(mc, short) -> None:
    """From the ensemble's amplitude mean and std alone, the mean PSD of its realisations."""
    frame = plots.ensemble_psd_frame(mc.spectra)
    for ctrl in ("pd", "smc"):
        sel = frame[(frame["phase"] == "P2") & (frame["controller"] == ctrl)]
        assert sel["n"].iloc[0] == 6
        each = [quadrs.simulate(short, ctrl, 0, realisation=r).spectra["P2"] for r in range(6)]
        want = np.mean([plots.amplitude_to_psd(s["frequency"], s["amplitude"]) for s in each], 0)
        np.testing.assert_allclose(sel["psd"], want, rtol=1e-7, atol=1e-30)


def test_psd_figures_log_log_in_m2_per_hz(flights, mc, tmp_path) -> None:
    fig = plots.psd(flights, ["P2"], fmax=20.0, path=tmp_path / "psd")
    (ax,) = fig.axes
    assert ax.get_xscale() == ax.get_yscale() == "log"
    assert "m²/Hz" in ax.get_ylabel()
    pd_line = lines_of(ax)[0]
    e = flights["pd"].trace["e_o"]
    part = e[(e.index >= 2) & (e.index <= 4)].to_numpy()
    f, p = plots.welch_psd(part, 1 / short_dt(flights), resolution=0.2)
    keep = (f > 0) & (f <= 20)
    np.testing.assert_allclose(pd_line.get_ydata(), p[keep])
    assert_images(tmp_path / "psd")
    fig = plots.psd(flights, ["P2"], method="periodogram")
    sp = flights["smc"].spectra["P2"]
    sp = sp[(sp["frequency"] > 0) & (sp["frequency"] <= plots.FMAX)]
    want = sp["amplitude"] ** 2 / (2 * sp["frequency"].iloc[0])
    np.testing.assert_allclose(lines_of(fig.axes[0])[1].get_ydata(), want)
    with pytest.raises(ValueError, match="method"):
        plots.psd(flights, method="fft")
    fig = plots.ensemble_psd(mc.spectra, ["P2"], path=tmp_path / "epsd")
    frame = plots.ensemble_psd_frame(mc.spectra)
    sel = frame[(frame["phase"] == "P2") & (frame["controller"] == "smc")]
    sel = sel[(sel["frequency"] > 0) & (sel["frequency"] <= plots.FMAX)]
    np.testing.assert_allclose(lines_of(fig.axes[0])[1].get_ydata(), sel["psd"])
    assert fig.axes[0].get_yscale() == "log"
    assert_images(tmp_path / "epsd")


def short_dt(flights) -> float:
    t = next(iter(flights.values())).trace.index.to_numpy()
    return float(np.diff(t).mean())


def test_generated_gust_spectrum_follows_the_formula(tmp_path) -> None:
    """Ensemble Welch PSD of 64 gust series within 15 % of the Dryden and of the exact von
    Karman formula from 0.2 to 10 Hz (averaged over groups of 8 bins: about 1 % noise; the von
    Karman rational filter itself is within about 10 % of the formula there, docs/gust.md)."""
    frame = plots.gust_spectrum_frame(sigma=1.0, length_scale=2.0, airspeed=10.0, dt=0.01)
    for model, g in frame.groupby("model"):
        f = g["frequency"].to_numpy()
        band = (f >= 2 * f[1]) & (f <= 10.0)
        welch, formula = g["welch"].to_numpy()[band], g["formula"].to_numpy()[band]
        m = len(welch) // 8 * 8
        ratio = welch[:m].reshape(-1, 8).mean(1) / formula[:m].reshape(-1, 8).mean(1)
        assert np.abs(ratio - 1).max() < 0.15, (model, ratio)
        assert g["welch"].sum() * f[1] == pytest.approx(1.0, abs=0.03)  # sigma^2
        if model == "dryden":
            np.testing.assert_allclose(g["filter"], g["formula"], rtol=1e-12)
    small = plots.gust_spectrum_frame(realisations=8, steps=2048)
    fig = plots.gust_spectrum(small, path=tmp_path / "gust_psd")
    assert len(fig.axes) == 2
    assert all(ax.get_xscale() == ax.get_yscale() == "log" for ax in fig.axes)
    dry = small[(small["model"] == "dryden") & (small["frequency"] > 0)]
    dry = dry[dry["frequency"] <= 10.0]
    welch_line, formula_line = lines_of(fig.axes[0])
    np.testing.assert_allclose(welch_line.get_ydata(), dry["welch"])
    np.testing.assert_allclose(formula_line.get_ydata(), dry["formula"])
    assert len(lines_of(fig.axes[1])) == 3  # von Karman: generated, formula, rational filter
    assert_images(tmp_path / "gust_psd")


# -- sweeps: one distribution per grid point ------------------------------------------------
@pytest.mark.parametrize("kind", ["box", "violin"])
def test_distributions_per_grid_point(swept, kind) -> None:
    fig = plots.distributions(swept.runs, ("max_abs",), kind=kind, by=swept.keys)
    assert len(fig.axes) == 3  # one metric, three phases
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == ["1", "2", "4"]
    assert "natural frequency (Hz)" in ax.get_xlabel()
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["PD", "SMC"]
    if kind == "violin":  # P2's IAE has a spread at every grid point (the gust)
        from matplotlib.collections import PolyCollection

        p2 = plots.distributions(swept.runs, ("iae",), kind=kind, by=swept.keys).axes[1]
        bodies = [c for c in p2.collections if isinstance(c, PolyCollection)]
        assert len(bodies) == 3 * 2 and not p2.patches  # one per (grid point, controller)
        return
    boxes = ax.patches
    assert len(boxes) == 3 * 2  # one per (grid point, controller), not pooled
    runs = swept.runs[(swept.runs["phase"] == "P1") & ~swept.runs["diverged"]]
    for box, (fn, ctrl) in zip(
        sorted(boxes, key=lambda b: b.get_path().vertices[:, 0].mean()),
        [(fn, c) for fn in (1.0, 2.0, 4.0) for c in ("pd", "smc")],
        strict=True,
    ):
        at = runs[(runs["payload.natural_frequency"] == fn) & (runs["controller"] == ctrl)]
        y = box.get_path().vertices[:, 1]
        np.testing.assert_allclose([y.min(), y.max()], np.percentile(at["max_abs"], [25, 75]))
    with pytest.raises(ValueError, match="by"):
        plots.distributions(swept.runs, by="payload.nope")


# -- every figure: words, legends, ax= -----------------------------------------------------
def _fake_sensitivity() -> SimpleNamespace:
    rows = [
        {"metric": "iae", "phase": ph, "controller": c, "parameter": k,
         "S1": 0.3, "S1_conf": 0.1, "ST": 0.5, "ST_conf": 0.1}
        for ph in ("P1", "P2") for c in ("pd", "smc") for k in ("payload.mass", "gust.w20")
    ]  # fmt: skip
    return SimpleNamespace(indices=pd.DataFrame(rows), parameters=["payload.mass", "gust.w20"])


def _fake_dispersed(mc) -> SimpleNamespace:
    runs = mc.runs.assign(**{"payload.mass": 0.1 + 0.01 * mc.runs["realisation"]})
    return SimpleNamespace(
        runs=runs, dispersed_keys=["payload.mass"], scenario=mc.scenario,
        controllers=mc.controllers,
    )  # fmt: skip


def figure_makers(flights, mc, swept, short) -> dict:
    """Every public plot function: name -> (number of panels, callable taking ax=)."""
    masses = {
        (comp, m): quadrs.simulate(
            short.override({"payload.mass": m, "controller.mass_compensation": comp}), "smc"
        )
        for comp in (False, True)
        for m in (0.1, 0.4)
    }
    summ = swept.summary()
    return {
        "altitude": (2, lambda ax=None: plots.altitude(flights, ax=ax)),
        "gust_force": (2, lambda ax=None: plots.gust_force(flights, ax=ax)),
        "oscillation": (3, lambda ax=None: plots.oscillation(flights, ax=ax)),
        "spectra": (1, lambda ax=None: plots.spectra(flights, ["P2"], ax=ax)),
        "psd": (3, lambda ax=None: plots.psd(flights, ax=ax)),
        "mass_compensation": (2, lambda ax=None: plots.mass_compensation(masses, ax=ax)),
        "ensemble_spectra": (3, lambda ax=None: plots.ensemble_spectra(mc.spectra, ax=ax)),
        "ensemble_psd": (3, lambda ax=None: plots.ensemble_psd(mc.spectra, ax=ax)),
        "distributions": (6, lambda ax=None: plots.distributions(mc.runs, ax=ax)),
        "sweep distributions": (
            3,
            lambda ax=None: plots.distributions(swept.runs, ("max_abs",), by=swept.keys, ax=ax),
        ),
        "sweep_metric": (3, lambda ax=None: plots.sweep_metric(summ, "iae", ax=ax)),
        "max_amplitude": (2, lambda ax=None: plots.max_amplitude(summ, ax=ax)),
        "exceedance_curves": (
            4,  # P1, P2, P3 and the whole flight
            lambda ax=None: plots.exceedance_curves(mc.runs, "max_abs", [0.01], ax=ax),
        ),
        "dispersion_scatter": (
            3,
            lambda ax=None: plots.dispersion_scatter(_fake_dispersed(mc), "max_abs", ax=ax),
        ),
        "sobol_bars": (2, lambda ax=None: plots.sobol_bars(_fake_sensitivity(), ax=ax)),
        "gust_spectrum": (
            2,
            lambda ax=None: plots.gust_spectrum(realisations=4, steps=1024, ax=ax),
        ),
        "gust_transmissibility": (
            1,
            lambda ax=None: plots.gust_transmissibility(short, freqs_hz=[0.1, 1, 10], ax=ax),
        ),
    }


@pytest.fixture(scope="module")
def figures(flights, mc, swept, short) -> dict:
    makers = figure_makers(flights, mc, swept, short)
    return {name: make() for name, (_, make) in makers.items()}


#: What a reader should never see: code identifiers (snake_case, e_o, max_abs), carets.
RAW = re.compile(r"_|\^")


def test_every_text_reads_as_english(figures) -> None:
    bad = {}
    for name, fig in figures.items():
        fig.canvas.draw()  # tick labels exist only once drawn
        # log-axis tick labels are mathtext ($10^{-1}$): rendered as powers, not carets
        texts = [t.get_text() for t in fig.findobj(Text) if not t.get_text().startswith("$")]
        raw = [t for t in texts if RAW.search(t)]
        if raw:
            bad[name] = raw
    assert not bad


def test_no_two_panels_share_a_title(figures) -> None:
    for name, fig in figures.items():
        titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
        assert len(titles) == len(set(titles)), (name, titles)


def test_every_legend_shows_every_line(figures) -> None:
    """Each legend has one entry per labelled artist, and every data line (and every kind of
    marker line) is in it: unlabelled lines only repeat a labelled line's style."""
    for name, fig in figures.items():
        for ax in fig.axes:
            legend = ax.get_legend()
            if legend is None:
                continue
            shown = [t.get_text() for t in legend.get_texts()]
            handles, labels = ax.get_legend_handles_labels()
            if handles:  # proxy legends (per-grid distributions) list their own handles
                assert shown == labels, (name, ax.get_title())
            inside = {id(a) for c in ax.containers for a in c.get_children()}
            styled = {
                (str(ln.get_color()), ln.get_linestyle())
                for ln in ax.get_lines()
                if ln.get_label() in shown
            }
            for ln in ax.get_lines():
                if id(ln) in inside or ln.get_label() in shown:
                    continue
                assert len(ln.get_xdata()) <= 2, (name, ax.get_title(), ln.get_label())
                if name not in ("sobol_bars", "distributions", "sweep distributions"):
                    # axis marks (zero lines, box whiskers) aside, a mark repeats a shown style
                    assert (str(ln.get_color()), ln.get_linestyle()) in styled, (name, ln)


def test_ax_draws_into_the_given_axes(flights, mc, swept, short, tmp_path) -> None:
    for name, (n, make) in figure_makers(flights, mc, swept, short).items():
        host = plots.new_figure(n, 1)
        axes = host.axes
        fig = make(ax=axes[0] if n == 1 else axes)
        assert fig is host, name
        assert all(ax.has_data() for ax in axes), name
        assert len(host.axes) == n, name  # nothing added beside them
        with pytest.raises(ValueError, match="ax must"):
            make(ax=plots.new_figure(n + 1, 1).axes)
    fig = plots.new_figure(1, 2)
    plots.spectra(flights, ["P2"], path=tmp_path / "into", ax=fig.axes[1])
    assert_images(tmp_path / "into")
    assert not fig.axes[0].has_data() and fig.axes[1].has_data()


# -- the paper's report ---------------------------------------------------------------------
def test_paper_fig16_for_both_controllers(short) -> None:
    fig = paper.mass_figure(short, [0.1, 0.4], seed=0)
    titles = [ax.get_title() for ax in fig.axes]
    assert len(titles) == len(set(titles)) == 4
    assert [t.split(",")[0] for t in titles] == ["PD", "SMC", "PD", "SMC"]
    assert all(len(lines_of(ax)) == 3 for ax in fig.axes)  # reference + two masses


def test_paper_flight_figures_have_distinct_titles(short, tmp_path, monkeypatch) -> None:
    """fig08 (gust against calm) and fig10 (PD against SMC) used to share a title."""
    seen: dict[str, Figure] = {}
    monkeypatch.setattr(plots, "save", lambda fig, path: [seen.setdefault(Path(path).name, fig)])
    monkeypatch.setattr(paper, "_csv", lambda frame, path, index=True: path)
    paper.flight_figures(short, 3, tmp_path)
    titles = {name: tuple(ax.get_title() for ax in fig.axes) for name, fig in seen.items()}
    assert titles["fig08_spectrum_gust_vs_calm_P2"] != titles["fig10_spectrum_P2"]
    flat = [t for ts in titles.values() for t in ts if t]
    assert len(flat) == len(set(flat)), flat
    assert "psd_flights" in seen
