"""Sobol' indices: the estimator wiring on a function with known indices, and known answers
from the model itself."""

import numpy as np
import pytest

import quadrs
from quadrs.design.sensitivity import GUST_FACTOR, sobol_design, sobol_indices


def test_ishigami_indices_through_the_same_code_path():
    """Ishigami (a = 7, b = 0.1) on [-pi, pi]^3: analytic S1 and ST."""
    names = ["x1", "x2", "x3"]
    u = sobol_design(names, 2048, seed=1)
    x = (2 * u - 1) * np.pi
    y = np.sin(x[:, 0]) + 7 * np.sin(x[:, 1]) ** 2 + 0.1 * x[:, 2] ** 4 * np.sin(x[:, 0])
    got = sobol_indices(names, y, seed=1).set_index("parameter")
    s1 = {"x1": 0.3139, "x2": 0.4424, "x3": 0.0}
    st = {"x1": 0.5576, "x2": 0.4424, "x3": 0.2437}
    for n in names:
        assert abs(got.loc[n, "S1"] - s1[n]) <= max(2 * got.loc[n, "S1_conf"], 0.03), n
        assert abs(got.loc[n, "ST"] - st[n]) <= max(2 * got.loc[n, "ST_conf"], 0.03), n


def test_constant_or_non_finite_outputs_give_nan_not_numbers():
    u = sobol_design(["a", "b"], 16, seed=0)
    assert sobol_indices(["a", "b"], np.ones(len(u)), 0)[["S1", "ST"]].isna().all().all()
    y = u[:, 0].copy()
    y[3] = np.nan
    assert sobol_indices(["a", "b"], y, 0)[["S1", "ST"]].isna().all().all()


def test_an_output_that_varies_only_off_the_a_and_b_rows_gives_nan_without_a_warning():
    """The estimators divide by the variance over the design's A and B rows: an output equal
    on all of them (a metric that only the mixed rows move) has no index, not SALib's 0, and
    no SALib warning reaches the user, also from bootstrap resamples of a mostly-constant
    output."""
    import warnings

    names = ["a", "b"]
    u = sobol_design(names, 16, seed=0)
    step = len(names) + 2
    y = np.zeros(len(u))
    y[1::step] = u[1::step, 0]  # only the rows of A with column a from B vary
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert sobol_indices(names, y, 0)[["S1", "ST"]].isna().all().all()
        mostly = np.zeros(len(u))
        mostly[:3] = 1.0  # one A, one mixed and one other row: most resamples see only zeros
        got = sobol_indices(names, mostly, 0)
    assert np.isfinite(got[["S1", "ST"]].to_numpy()).all()


@pytest.fixture(scope="module")
def analysis(short):
    """Payload mass, a gust intensity and a lateral gain of a vertical flight. The gust blows
    in P2 only."""
    s = short.override(
        {
            "dispersions": {
                "payload.natural_frequency": {"dist": "uniform", "low": 1.0, "high": 4.0},
                "gust.w20": {"dist": "uniform", "low": 2.0, "high": 20.0},
                "controller.pd.kp[0]": {"dist": "uniform", "low": 0.5, "high": 3.0},
            }
        }
    )
    return quadrs.sensitivity(s, runs=128, seed=0, progress=False)


def test_indices_are_tidy_and_cover_every_group(analysis):
    idx = analysis.indices
    assert list(idx.columns) == [
        "controller",
        "phase",
        "metric",
        "parameter",
        "S1",
        "S1_conf",
        "ST",
        "ST_conf",
    ]
    assert set(idx["parameter"]) == {
        "payload.natural_frequency",
        "gust.w20",
        "controller.pd.kp[0]",
        GUST_FACTOR,
    }
    phases = {"P1", "P2", "P3", "flight"}  # the paper's phases and the whole flight
    assert set(idx["controller"]) == {"pd", "smc"} and set(idx["phase"]) == phases
    # Every flight of the design is kept: N (k + 2) rows per controller and phase.
    assert analysis.samples["row"].nunique() == 128 * (4 + 2)


def test_what_cannot_act_gets_zero_and_the_dominant_key_total_one(analysis):
    idx = analysis.indices.set_index(["controller", "phase", "metric", "parameter"])
    for ctrl in ("pd", "smc"):
        # Take-off: before the gust window, so neither its intensity nor its realisation
        # acts, and a lateral gain never acts in a vertical flight.
        for p in ("gust.w20", GUST_FACTOR, "controller.pd.kp[0]"):
            row = idx.loc[(ctrl, "P1", "iae", p)]
            assert abs(row["ST"]) <= row["ST_conf"] + 1e-9, (ctrl, p)
            assert abs(row["S1"]) <= row["S1_conf"] + 1e-9, (ctrl, p)
        # ... so the attachment frequency explains all of the take-off variance.
        row = idx.loc[(ctrl, "P1", "iae", "payload.natural_frequency")]
        assert abs(row["ST"] - 1) <= max(row["ST_conf"], 0.02)
        # In the gust, its intensity matters: a total index significantly above zero.
        row = idx.loc[(ctrl, "P2", "iae", "gust.w20")]
        assert row["ST"] > row["ST_conf"] > 0


def test_sensitivity_round_trips_and_refuses_what_it_cannot_do(analysis, short, tmp_path):
    analysis.to_parquet(tmp_path / "sa.parquet")
    back = quadrs.SensitivityResult.read_parquet(tmp_path / "sa.parquet")
    assert back.scenario == analysis.scenario and back.runs == 128
    np.testing.assert_array_equal(back.indices["ST"], analysis.indices["ST"])
    # An edited file is refused, not believed.
    import json

    import pyarrow.parquet as pq

    table = pq.read_table(tmp_path / "sa.parquet")
    meta = json.loads(table.schema.metadata[b"quadrs_sensitivity"])
    meta["seed"] = 7
    edited = table.replace_schema_metadata(
        {**table.schema.metadata, b"quadrs_sensitivity": json.dumps(meta).encode()}
    )
    pq.write_table(edited, tmp_path / "edited.parquet")
    with pytest.raises(ValueError, match="run identity"):
        quadrs.SensitivityResult.read_parquet(tmp_path / "edited.parquet")
    with pytest.raises(quadrs.ScenarioError, match="dispersions"):
        quadrs.sensitivity(short, runs=8, progress=False)
    with pytest.raises(ValueError, match="power of two"):
        quadrs.sensitivity(analysis.scenario, runs=100, progress=False)
