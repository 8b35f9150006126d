"""Uncertain parameters: validation, sampling designs, per-realisation values in the engine."""

import numpy as np
import pandas as pd
import pytest
from scipy import stats

import quadrs
from quadrs.runs.flight import METRIC_COLUMNS
from quadrs.scenario.dispersion import distribution, draw

UNIFORM_MASS = {"dist": "uniform", "low": 0.1, "high": 0.4}
DISPERSIONS = {
    "payload.mass": UNIFORM_MASS,
    "payload.natural_frequency": {"dist": "normal", "mean": 2.0, "std": 0.2},
    "vehicle.inertia[2]": {"dist": "triangular", "low": 0.04, "mode": 0.05, "high": 0.07},
    "gust.w20": {"dist": "lognormal", "mu": 2.3, "sigma": 0.3},
}
METRICS = list(METRIC_COLUMNS)


@pytest.fixture(scope="module")
def dispersed(short: quadrs.Scenario) -> quadrs.Scenario:
    return short.override({"dispersions": DISPERSIONS})


def _bits(frame: pd.DataFrame) -> np.ndarray:
    return frame[METRICS].to_numpy(dtype=np.float64).view(np.uint64)


def test_a_batch_row_is_the_single_flight_of_its_drawn_values(dispersed):
    mc = quadrs.monte_carlo(dispersed, runs=9, seed=4, progress=False, spectra=False)
    assert set(DISPERSIONS) <= set(mc.runs.columns)
    one = mc.runs.drop_duplicates("realisation")
    assert one["payload.mass"].nunique() == 9  # every realisation flew its own vehicle
    for i in (0, 5, 8):
        fixed = mc.scenario_of(i)
        assert not fixed.dispersed and fixed["payload.mass"] == one["payload.mass"].iloc[i]
        for ctrl in ("pd", "smc"):
            flight = quadrs.simulate(fixed, ctrl, seed=4, realisation=i)
            rows = mc.runs[(mc.runs.realisation == i) & (mc.runs.controller == ctrl)]
            np.testing.assert_array_equal(_bits(rows), _bits(flight.metrics))
            # simulate() of the dispersed scenario flies the same draws (random sampling).
            again = quadrs.simulate(dispersed, ctrl, seed=4, realisation=i)
            np.testing.assert_array_equal(_bits(again.metrics), _bits(flight.metrics))


def test_a_key_the_flight_never_uses_leaves_every_number_unchanged(short):
    """Common random numbers: dispersing a lateral gain of a vertical flight changes nothing,
    so the gust of every realisation is the fixed run's."""
    d = short.override(
        {"dispersions": {"controller.pd.kp[0]": {"dist": "uniform", "low": 0.5, "high": 3}}}
    )
    a = quadrs.monte_carlo(short, runs=6, seed=2, progress=False, spectra=False)
    b = quadrs.monte_carlo(d, runs=6, seed=2, progress=False, spectra=False)
    np.testing.assert_array_equal(_bits(a.runs), _bits(b.runs))
    assert b.runs["controller.pd.kp[0]"].nunique() == 6


@pytest.mark.parametrize(
    "spec",
    [
        UNIFORM_MASS,
        {"dist": "normal", "mean": 2.0, "std": 0.2},
        {"dist": "truncnorm", "mean": 0.2, "std": 0.1, "low": 0.15, "high": 0.5},
        {"dist": "lognormal", "mu": 2.3, "sigma": 0.3},
        {"dist": "triangular", "low": 0.04, "mode": 0.05, "high": 0.07},
    ],
)
def test_random_marginals_follow_their_distribution(short, spec):
    s = short.override({"dispersions": {"payload.damping": spec}})
    values = draw(s, seed=11, first=0, count=4000)["payload.damping"].to_numpy()
    dist = distribution(spec)
    # Kolmogorov-Smirnov at a fixed seed; also the mean within 4 standard errors.
    assert stats.kstest(values, dist.cdf).pvalue > 1e-3
    assert abs(values.mean() - dist.mean()) < 4 * dist.std() / np.sqrt(len(values))


def test_random_draws_depend_only_on_seed_key_and_realisation(dispersed, short):
    whole = draw(dispersed, seed=3, first=0, count=50)
    part = draw(dispersed, seed=3, first=17, count=20)
    pd.testing.assert_frame_equal(part, whole.iloc[17:37])
    alone = draw(short.override({"dispersions": {"payload.mass": UNIFORM_MASS}}), 3, 0, 50)
    np.testing.assert_array_equal(alone["payload.mass"], whole["payload.mass"])
    other = draw(dispersed, seed=4, first=0, count=50)
    assert not np.allclose(other["payload.mass"], whole["payload.mass"])


@pytest.mark.parametrize("sampling", ["lhs", "sobol"])
def test_designs_are_stratified(dispersed, sampling):
    runs = 64
    values = draw(dispersed, seed=5, first=0, count=runs, runs=runs, sampling=sampling)
    for key, spec in DISPERSIONS.items():
        u = distribution(spec).cdf(values[key].to_numpy())
        # One point in each of the `runs` equal strata of every marginal.
        cells = np.floor(u * runs).astype(int)
        assert sorted(cells) == list(range(runs)), key


@pytest.mark.parametrize("sampling", ["random", "lhs", "sobol"])
def test_rows_do_not_depend_on_workers_or_chunks(dispersed, sampling, tmp_path):
    kw = {"runs": 14, "seed": 9, "progress": False, "spectra": False, "sampling": sampling}
    ref = quadrs.monte_carlo(dispersed, workers=1, **kw)
    two = quadrs.monte_carlo(dispersed, workers=2, chunk=4, **kw)
    pd.testing.assert_frame_equal(ref.runs, two.runs)
    # Checkpointed, killed after the first chunks (simulated by a smaller first call), resumed.
    out = tmp_path / sampling
    part = quadrs.monte_carlo(dispersed, workers=2, chunk=4, out=out, **kw)
    pd.testing.assert_frame_equal(
        ref.runs, part.runs[ref.runs.columns].reset_index(drop=True), check_dtype=False
    )
    assert part.sampling == sampling
    for f in sorted(out.glob("part-*.parquet"))[1:]:
        f.unlink()
    resumed = quadrs.monte_carlo(dispersed, workers=1, chunk=4, out=out, resume=True, **kw)
    pd.testing.assert_frame_equal(
        ref.runs, resumed.runs[ref.runs.columns].reset_index(drop=True), check_dtype=False
    )


def test_resuming_a_design_with_another_batch_is_refused(dispersed, tmp_path):
    kw = {"seed": 1, "progress": False, "spectra": False, "sampling": "lhs", "out": tmp_path}
    quadrs.monte_carlo(dispersed, runs=8, **kw)
    with pytest.raises(ValueError, match="sampling design"):
        quadrs.monte_carlo(dispersed, runs=16, resume=True, **kw)


def test_dispersed_results_round_trip_through_parquet(dispersed, tmp_path):
    mc = quadrs.monte_carlo(dispersed, runs=5, seed=1, progress=False, sampling="sobol")
    mc.to_parquet(tmp_path / "runs.parquet")
    back = quadrs.MonteCarloResult.read_parquet(tmp_path / "runs.parquet")
    assert back.scenario == dispersed and back.sampling == "sobol"
    pd.testing.assert_frame_equal(back.runs, mc.runs)
    assert quadrs.Scenario.from_toml_string(dispersed.to_toml()) == dispersed
    table = mc.dispersions()
    assert list(table["key"]) == sorted(DISPERSIONS)
    assert (table["min"] <= table["mean"]).all() and (table["mean"] <= table["max"]).all()
    assert "payload.mass ~ uniform(low=0.1, high=0.4)" in mc.summary().attrs["dispersions"]


@pytest.mark.parametrize(
    ("key", "spec", "says"),
    [
        ("payload.mass", {"dist": "cauchy", "loc": 0}, "dist"),
        ("payload.mass", {"dist": "normal", "mean": 0.2, "sd": 0.1}, "sd"),
        ("payload.mass", {"dist": "normal", "mean": 0.2}, "std"),
        ("payload.mass", {"dist": "normal", "mean": 0.2, "std": 0.0}, "std must be > 0"),
        ("payload.mass", {"dist": "uniform", "low": 0.4, "high": 0.1}, "low must be < high"),
        ("payload.mass", {"dist": "triangular", "low": 0, "mode": 2, "high": 1}, "mode"),
        ("payload.massive", UNIFORM_MASS, "not a key"),
        ("payload.stiffness", UNIFORM_MASS, "not a key"),  # the preset gives the frequency
        ("vehicle.inertia[3]", UNIFORM_MASS, "not a key"),
        ("integrator.dt", UNIFORM_MASS, "cannot be dispersed"),
        ("phases[1].end", UNIFORM_MASS, "cannot be dispersed"),
        ("trajectory.waypoints[1][0]", UNIFORM_MASS, "cannot be dispersed"),
        ("gust.model", UNIFORM_MASS, "not a number"),
    ],
)
def test_bad_dispersions_are_refused_naming_the_key(short, key, spec, says):
    with pytest.raises(quadrs.ScenarioError, match=says) as e:
        short.override({"dispersions": {key: spec}})
    assert key.split("[")[0] in str(e.value)


def test_a_draw_the_scenario_refuses_names_key_and_realisation(short):
    s = short.override(
        {"dispersions": {"payload.mass": {"dist": "normal", "mean": 0.1, "std": 0.1}}}
    )
    with pytest.raises(quadrs.ScenarioError, match=r"realisation \d+ .*payload\.mass must be > 0"):
        quadrs.monte_carlo(s, runs=40, seed=0, progress=False)


def test_realisations_a_dispersion_makes_diverge_are_flagged_and_the_rest_kept(short):
    # The vehicle climbs to 2 m: a runaway bound below that flags the flight as diverged.
    s = short.override(
        {"dispersions": {"divergence.max_distance": {"dist": "uniform", "low": 1.0, "high": 3.0}}}
    )
    mc = quadrs.monte_carlo(s, runs=24, seed=0, progress=False, spectra=False)
    one = mc.runs[mc.runs.phase == "P1"]
    low = one["divergence.max_distance"] < 1.9
    high = one["divergence.max_distance"] > 2.3
    assert low.any() and high.any()
    assert one.loc[low, "diverged"].all() and not one.loc[high, "diverged"].any()
    assert np.isfinite(one.loc[high, METRICS[:4]].to_numpy()).all()


def test_cli_disperses_samples_and_ranks(tmp_path, capsys):
    from quadrs.cli.main import main, parse_distribution
    from tests.cli.test_main import SHORT

    assert parse_distribution("normal(mean=2, std=0.2)") == {
        "dist": "normal",
        "mean": 2,
        "std": 0.2,
    }
    out = tmp_path / "runs.parquet"
    disperse = ["--disperse", "payload.mass=uniform(0.15, 0.3)"]
    args = ["mc", *SHORT, *disperse, "--runs", "8", "--sampling", "lhs", "--no-progress"]
    assert main([*args, "--out", str(out), "--plots", str(tmp_path / "figs")]) == 0
    text = capsys.readouterr().out
    assert (
        "Dispersed (lhs sampling" in text and "payload.mass ~ uniform(low=0.15, high=0.3)" in text
    )
    mc = quadrs.MonteCarloResult.read_parquet(out)
    assert mc.sampling == "lhs" and mc.runs["payload.mass"].between(0.15, 0.3).all()
    assert (tmp_path / "figs" / "dispersion_iae.png").exists()

    sa = ["sensitivity", *SHORT, *disperse, "--disperse", "gust.w20=triangular(5, 10, 15)"]
    assert main([*sa, "--runs", "16", "--phase", "P2", "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "Sobol' indices of iae" in text and "gust.w20" in text
    assert max(len(line) for line in text.splitlines()) <= 100
    for bad in (["--disperse", "payload.mass=cauchy(0, 1)"], ["--disperse", "payload.mass"]):
        assert main(["mc", *SHORT, *bad, "--runs", "4", "--no-progress"]) == 2
    assert main([*sa, "--runs", "12", "--no-progress"]) == 2  # not a power of two
    assert main([*sa, "--metric", "nope", "--no-progress"]) == 2


def test_every_named_distribution_is_what_the_engine_and_the_sampler_take() -> None:
    """``dispersion.DISTRIBUTIONS`` (the command line's vocabulary) against the engine's
    validation and the sampler: each one's parameters are exactly what both need."""
    from quadrs.scenario.dispersion import DISTRIBUTIONS, distribution

    value = {"low": 0.1, "high": 0.4, "mean": 0.2, "std": 0.02, "mu": -1.6, "sigma": 0.1}
    value |= {"mode": 0.25, "shape": 2.0, "scale": 0.25, "values": [0.2, 0.3], "weights": [1, 3]}
    paper = quadrs.Scenario.paper()
    for name, params in DISTRIBUTIONS.items():
        spec = {"dist": name, **{p: value[p] for p in params}}
        s = paper.override({"dispersions": {"payload.mass": spec}})
        assert s.dispersed and 0.05 < distribution(spec).mean() < 0.5
        for p in params:
            short = {k: v for k, v in spec.items() if k != p}
            with pytest.raises(quadrs.ScenarioError, match=f"`{p}`"):
                paper.override({"dispersions": {"payload.mass": short}})
