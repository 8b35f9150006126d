"""Risk answers: the payload-acceleration metrics, exceedance and quantile intervals, run counts."""

import math

import numpy as np
import pandas as pd
import pytest
from scipy import stats

import quadrs
from quadrs import Scenario
from quadrs.cli.main import main
from quadrs.stats import risk


# -- the acceleration metrics --------------------------------------------------------------------
def payload_acceleration(s: Scenario, tr: pd.DataFrame) -> np.ndarray:
    """d2zc/dt2 from the payload's equation of motion (MODEL.md section 1), in numpy, with every
    parameter read from the scenario (kc from mc and fn here, not from the engine)."""
    mc = float(s["payload.mass"])
    kc = mc * (2 * math.pi * float(s["payload.natural_frequency"])) ** 2
    cc = float(s["payload.damping"])
    k_drag = 0.5 * float(s["gust.air_density"]) * float(s["payload.drag_area"])
    g = float(s["environment.gravity"])
    z, zc, vz, vzc, wz = (tr[c].to_numpy() for c in ("z", "zc", "vz", "vzc", "wind_z"))
    spring = kc * (z - zc) + cc * (vz - vzc)
    drag = -k_drag * (vzc - wz) * np.abs(vzc - wz)
    return (-mc * g + spring + drag) / mc


@pytest.mark.parametrize("controller", ["pd", "smc"])
def test_max_accel_is_the_peak_of_the_recomputed_acceleration(
    short: Scenario, controller: str
) -> None:
    s = short.override({"payload.damping": 0.3, "gust.w20": 20.0})
    f = quadrs.simulate(s, controller, seed=3, record_every=1)
    assert not f.diverged
    tr = f.trace
    azc = payload_acceleration(s, tr)
    assert np.abs(azc).max() > 0.1  # a real signal, not zeros
    # accel_c is the magnitude; in a vertical flight, |d2zc/dt2|.
    np.testing.assert_allclose(tr["accel_c"].to_numpy(), np.abs(azc), rtol=1e-9, atol=1e-9)
    dt = float(s["integrator.dt"])
    t = tr.index.to_numpy()
    for phase in s["phases"]:
        m = f.metrics.set_index("phase").loc[phase["name"]]
        inside = (t >= phase["start"] - dt / 2) & (t <= phase["end"] + dt / 2)
        a = azc[inside]
        assert m["max_accel"] == pytest.approx(np.abs(a).max(), rel=1e-9)
        # RMS: the trapezoidal rule on the step grid, as for e_o.
        mean_sq = np.trapezoid(a**2, t[inside]) / (phase["end"] - phase["start"])
        assert m["rms_accel"] == pytest.approx(math.sqrt(mean_sq), rel=1e-9)


def test_acceleration_is_zero_in_a_hover_without_gust(still_hover: Scenario) -> None:
    s = still_hover
    for controller in ("pd", "smc"):
        f = quadrs.simulate(s, controller, record_every=50)
        assert abs(f.metrics["max_accel"].iloc[0]) < 1e-9
        assert abs(f.metrics["rms_accel"].iloc[0]) < 1e-9
        assert np.abs(f.trace["accel_c"].to_numpy()).max() < 1e-9


def test_acceleration_reaches_runs_and_summary(short: Scenario) -> None:
    mc = quadrs.monte_carlo(short, runs=4, seed=0, progress=False, workers=1)
    assert {"max_accel", "rms_accel"} <= set(mc.runs.columns)
    for _, row in mc.runs[mc.runs["realisation"] == 2].iterrows():
        f = quadrs.simulate(short, row["controller"], seed=0, realisation=2)
        m = f.metrics.set_index("phase").loc[row["phase"]]
        assert row["max_accel"] == pytest.approx(m["max_accel"], rel=1e-12)
        assert row["rms_accel"] == pytest.approx(m["rms_accel"], rel=1e-12)
    summ = mc.summary()
    assert "max_accel" in summ.index.get_level_values("metric")
    assert "rms_accel" in summ.index.get_level_values("metric")


# -- exceedance intervals ----------------------------------------------------------------------
def test_clopper_pearson_covers_at_the_nominal_rate() -> None:
    """2000 seeded Bernoulli samples through the code path of MonteCarloResult.exceedance: the
    95% interval covers the true p in 93-97% of them, and agrees with the exact coverage."""
    n, p, trials = 150, 0.08, 2000
    rng = np.random.default_rng(12)
    covered = 0
    for _ in range(trials):
        values = rng.random(n)  # value > 1 - p with probability p
        e = risk.exceedance_stats(values, 1 - p)
        covered += e.ci_low <= p <= e.ci_high
    rate = covered / trials
    # The exact coverage of Clopper-Pearson at (n, p), from the binomial pmf.
    ks = np.arange(n + 1)
    bounds = [risk.exceedance_interval(k, n)[1:] for k in ks]
    inside = [lo <= p <= hi for lo, hi in bounds]
    exact = float(stats.binom.pmf(ks, n, p)[inside].sum())
    se = math.sqrt(exact * (1 - exact) / trials)
    assert 0.93 <= rate <= 0.97, rate
    assert abs(rate - exact) < 4 * se, (rate, exact)


def test_threshold_below_or_above_every_value() -> None:
    n = 40
    values = np.random.default_rng(0).normal(size=n)
    low = risk.exceedance_stats(values, values.min() - 1)
    assert (low.k, low.probability, low.ci_high) == (n, 1.0, 1.0)
    assert low.ci_low == pytest.approx(0.025 ** (1 / n), rel=1e-12)
    high = risk.exceedance_stats(values, values.max() + 1)
    assert (high.k, high.probability, high.ci_low) == (0, 0.0, 0.0)
    assert high.ci_high == pytest.approx(1 - 0.025 ** (1 / n), rel=1e-12)


def test_diverged_runs_count_as_exceedances() -> None:
    values = np.array([0.1, np.nan, 0.3, np.nan, 5.0])
    diverged = np.array([False, True, False, False, False])
    e = risk.exceedance_stats(values, 1.0, diverged)
    # run 1 diverged (exceeds), run 3 undefined (left out), run 4 exceeds.
    assert (e.n, e.k, e.diverged, e.undefined) == (4, 2, 1, 1)


def test_runs_needed_reaches_the_width() -> None:
    for p, h in [(0.1, 0.01), (0.02, 0.005), (0.5, 0.02), (0.0, 0.01)]:
        n = int(risk.runs_needed(p, h))
        _, lo, hi = risk.exceedance_interval(round(p * n), n)
        assert (hi - lo) / 2 <= h
        # ... and a tenth fewer runs would not (the answer is not grossly conservative).
        m = int(0.9 * n)
        _, lo, hi = risk.exceedance_interval(round(p * m), m)
        assert (hi - lo) / 2 > h, (p, h, n)
    # Normal approximation as a sanity check at moderate p: n ~ z^2 p (1-p) / h^2.
    approx = stats.norm.ppf(0.975) ** 2 * 0.1 * 0.9 / 0.01**2
    assert risk.runs_needed(0.1, 0.01) == pytest.approx(approx, rel=0.05)
    assert abs(risk.runs_needed(0.2, 0.1, relative=True) - risk.runs_needed(0.2, 0.02)) <= 1
    assert math.isinf(risk.runs_needed(0.0, 0.1, relative=True))


def test_paired_difference_covers_at_the_nominal_rate() -> None:
    """Newcombe's paired interval on correlated pairs (a exceeds more often when b does)."""
    n, trials = 200, 2000
    # Joint law of (a, b): both 0.06, only a 0.04, only b 0.08, neither 0.82.
    probs = np.array([0.06, 0.04, 0.08, 0.82])
    truth = (0.06 + 0.04) - (0.06 + 0.08)
    rng = np.random.default_rng(5)
    covered = 0
    for _ in range(trials):
        cell = rng.choice(4, size=n, p=probs)
        a, b = np.isin(cell, (0, 1)), np.isin(cell, (0, 2))
        r = risk.paired_exceedance(a, b)
        covered += r.ci_low <= truth <= r.ci_high
    assert 0.93 <= covered / trials <= 0.97, covered / trials
    r = risk.paired_exceedance(a, b)
    assert r.both + r.only_a + r.only_b + r.neither == n
    assert r.mcnemar_p == pytest.approx(stats.binomtest(r.only_a, r.only_a + r.only_b).pvalue)


def test_quantile_interval_covers_the_true_quantile() -> None:
    n, q, trials = 80, 0.9, 800
    truth = stats.expon.ppf(q)
    rng = np.random.default_rng(9)
    covered = 0
    for _ in range(trials):
        _, _est, lo, hi = risk.quantile_interval(rng.exponential(size=n), q)
        covered += lo <= truth <= hi
    # Order-statistic intervals are exact-or-conservative: at least nominal, not far above.
    rate = covered / trials
    se = math.sqrt(0.95 * 0.05 / trials)
    assert 0.95 - 3 * se <= rate <= 0.985, rate


def test_quantile_treats_diverged_as_infinite() -> None:
    values = np.r_[np.arange(1.0, 11.0), np.inf]
    n, est, _lo, _hi = risk.quantile_interval(values, 0.5)
    assert (n, est) == (11, 6.0)
    _, est, _, hi = risk.quantile_interval(values, 0.95)
    assert est == np.inf and hi == np.inf


# -- on results --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def batch(short: Scenario) -> quadrs.MonteCarloResult:
    return quadrs.monte_carlo(short.override({"gust.w20": 20.0}), runs=24, seed=1, progress=False)


def test_result_exceedance_matches_a_direct_count(batch: quadrs.MonteCarloResult) -> None:
    runs = batch.runs
    threshold = float(runs["max_accel"].median())
    table = batch.exceedance("max_accel", threshold)
    assert list(table["controller"].unique()) == ["pd", "smc"]
    assert set(table["phase"]) == {"P1", "P2", "P3", "flight"}
    for r in table.itertuples():
        sel = runs[(runs["controller"] == r.controller) & (runs["phase"] == r.phase)]
        k = int((sel["max_accel"] > threshold).sum() + sel["diverged"].sum())
        assert (r.n, r.exceedances) == (len(sel), k)
        ci = stats.binomtest(k, len(sel)).proportion_ci(method="exact")
        assert (r.ci_low, r.ci_high) == pytest.approx((ci.low, ci.high))
        assert r.runs_needed == risk.runs_needed(k / len(sel))
    low = batch.exceedance("max_accel", float(runs["max_accel"].min()) - 1)
    assert (low["probability"] == 1).all()
    assert low["ci_low"].to_numpy() == pytest.approx(0.025 ** (1 / 24))


def test_result_paired_exceedance_and_quantile(batch: quadrs.MonteCarloResult) -> None:
    runs = batch.runs
    threshold = float(runs["max_accel"].median())
    paired = batch.exceedance("max_accel", threshold, paired=True)
    single = batch.exceedance("max_accel", threshold).set_index(["controller", "phase"])
    for r in paired.itertuples():
        assert r.p_smc == pytest.approx(single.loc[("smc", r.phase), "probability"])
        assert r.p_pd == pytest.approx(single.loc[("pd", r.phase), "probability"])
        assert r.ci_low <= r.difference <= r.ci_high
    qt = batch.quantile("max_accel", 0.5)
    for r in qt.itertuples():
        sel = runs[(runs["controller"] == r.controller) & (runs["phase"] == r.phase)]
        assert r.quantile == np.quantile(sel["max_accel"], 0.5, method="inverted_cdf")
        assert r.ci_low <= r.quantile <= r.ci_high
    diff = batch.quantile("max_accel", 0.5, paired=True)
    assert set(diff.columns) >= {"quantile_difference", "ci_low", "ci_high", "n_pairs"}
    with pytest.raises(ValueError, match="metric must be one of"):
        batch.exceedance("nope", 1.0)
    with pytest.raises(ValueError, match="threshold must be finite"):
        batch.exceedance("max_accel", float("nan"))
    with pytest.raises(ValueError, match="q must be in"):
        batch.quantile("max_accel", 1.5)


def test_sweep_exceedance_per_point(short: Scenario) -> None:
    sw = quadrs.sweep(
        short, {"payload.natural_frequency": [2.0, 4.0]}, runs=3, seed=0, progress=False
    )
    table = sw.exceedance("max_accel", 1.0)
    assert len(table) == 2 * 2 * 4  # P1-P3 and the whole flight
    for fn, part in table.groupby("payload.natural_frequency"):
        sub = sw.runs[sw.runs["payload.natural_frequency"] == fn]
        mc = quadrs.MonteCarloResult(sw.scenario, 0, sw.controllers, sub.drop(columns=[
            "payload.natural_frequency"]))  # fmt: skip
        want = mc.exceedance("max_accel", 1.0)
        assert part["exceedances"].tolist() == want["exceedances"].tolist()
    assert len(sw.quantile("rms_accel", 0.5, paired=True)) == 2 * 4


# -- command line ------------------------------------------------------------------------------
SHORT_ARGS = [
    "--set", "integrator.duration=6.0", "--set", "integrator.dt=0.002",
    "--set", "trajectory.waypoints=[[0,0,0,2,0],[4,0,0,0,0]]",
    "--set", 'phases=[{name="P1",start=0,end=3},{name="P2",start=3,end=6}]',
    "--set", "gust.start=2.5", "--set", "gust.end=3.5", "--no-progress",
]  # fmt: skip


def test_cli_limit_prints_the_exceedance_table(tmp_path, capsys) -> None:
    out = tmp_path / "runs.parquet"
    argv = ["mc", *SHORT_ARGS, "--runs", "6", "--out", str(out)]
    assert main([*argv, "--limit", "max_accel=0.5", "--limit", "rms_accel=0.1"]) == 0
    text = capsys.readouterr().out
    assert "P(metric > threshold)" in text and "runs for ±1 pp" in text
    assert "max_accel" in text and "rms_accel" in text and "SMC - PD" in text
    plots = tmp_path / "plots"
    assert main(["report", str(out), "--limit", "max_accel=0.5", "--plots", str(plots)]) == 0
    again = capsys.readouterr().out
    assert "P(metric > threshold)" in again
    assert (plots / "exceedance_max_accel.png").exists()


@pytest.mark.parametrize("limit", ["nope=1", "max_accel", "max_accel=abc", "max_accel=nan", "=2"])
def test_cli_bad_limit_exits_2_with_one_line(limit: str, capsys) -> None:
    assert main(["mc", "--runs", "2", "--limit", limit]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--limit" in err


def test_exceedance_curve_plot_draws_the_empirical_survival() -> None:
    from quadrs import plots

    rng = np.random.default_rng(2)
    n = 50
    values = rng.exponential(size=n)
    runs = pd.DataFrame(
        {
            "realisation": np.arange(n),
            "controller": "pd",
            "phase": "P2",
            "max_accel": values,
            "diverged": np.arange(n) < 2,  # two diverged: they exceed everything
        }
    )
    runs.loc[runs["diverged"], "max_accel"] = np.nan
    fig = plots.exceedance_curves(runs, "max_accel", thresholds=[1.0])
    ax = fig.axes[0]
    assert ax.get_yscale() == "log"
    assert ax.get_xlabel() == "Payload acceleration peak (m/s²)"
    assert "2 diverged" in ax.get_legend().get_texts()[0].get_text()
    x, y = ax.lines[0].get_xdata(), ax.lines[0].get_ydata()
    for xi, yi in zip(x, y, strict=True):
        direct = (np.nansum(runs["max_accel"] > xi) + 2) / n
        assert yi == pytest.approx(direct)
    assert y.min() == pytest.approx(2 / n)  # the diverged floor


def test_a_phase_where_every_flight_gives_one_value_says_so_instead_of_a_curve() -> None:
    """A released parcel's swing is 0 in every flight: no step 1e-12 wide, the panel says it;
    the phase beside it still has its curve."""
    from quadrs import plots

    n = 20
    swing = np.random.default_rng(3).uniform(0.1, 0.5, n)
    runs = pd.DataFrame(
        {
            "realisation": np.tile(np.arange(n), 2),
            "controller": "pd",
            "phase": np.repeat(["transit", "away"], n),
            "max_swing": np.r_[swing, np.zeros(n)],
            "diverged": False,
        }
    )
    fig = plots.exceedance_curves(runs, "max_swing", phases=["transit", "away"])
    transit, away = fig.axes
    assert transit.lines and transit.get_legend() is not None
    assert not away.lines and away.get_legend() is None
    said = [t.get_text() for t in away.texts]
    assert said == ["PD: 0 deg in every one of its 20 flights"]
