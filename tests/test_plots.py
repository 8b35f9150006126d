"""Figures: each returns a Figure holding the data it claims, and saves valid PNG and SVG."""

import xml.etree.ElementTree as ET
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest
from matplotlib.figure import Figure

import quadrs
from quadrs import Scenario, plots

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


def test_max_amplitude_from_a_sweep(short, tmp_path) -> None:
    res = quadrs.sweep(
        short, {"payload.natural_frequency": [1.0, 2.0, 4.0]}, runs=2, progress=False
    )
    summ = res.summary()
    fig = plots.max_amplitude(summ, path=tmp_path / "amp")
    assert [ax.get_title() for ax in fig.axes] == ["max_abs, P1", "max_abs, P3"]
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
