"""Several laws through the same gusts (quadrs.design.mission_compare, ``quadrs mission --controller
pd,smc``): each law's answer is its own mission report, the paired ratios and differences equal
direct computations on the runs, swapping the reference inverts the ratio exactly, and the
command prints the comparison and refuses a law the engine lacks."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs.cli.main import main
from quadrs.design.mission import mission_report
from quadrs.design.mission_compare import compare_laws
from tests.conftest import SHORT


@pytest.fixture(scope="module")
def mc() -> quadrs.MonteCarloResult:
    s = quadrs.Scenario.preset("paper_stable_lateral").override({**SHORT, "gust.w20": 25.0})
    return quadrs.monte_carlo(s, runs=60, seed=3, controllers=("pd", "smc"), progress=False,
                              spectra=False)  # fmt: skip


def column(mc: quadrs.MonteCarloResult, law: str, phase: str, name: str) -> pd.Series:
    sel = mc.runs[(mc.runs.controller == law) & (mc.runs.phase == phase)]
    return sel.set_index("realisation")[name].sort_index()


def test_the_paired_table_is_the_direct_computation(mc: quadrs.MonteCarloResult) -> None:
    limit = float(column(mc, "pd", "P2", "max_accel").median())
    c = compare_laws(mc, limit)
    assert c.controllers == ("pd", "smc")
    for law in c.controllers:
        own = mission_report(mc, limit, law)
        pd.testing.assert_frame_equal(c.reports[law].acceleration, own.acceleration)
    for phase in ("P1", "P2", "P3"):
        a, b = column(mc, "smc", phase, "max_accel"), column(mc, "pd", phase, "max_accel")
        row = c.paired.loc[(phase, "smc")]
        assert row["n_pairs"] == 60
        assert row["ratio"] == pytest.approx(100 * a.mean() / b.mean(), rel=1e-12)
        assert row["ratio_low"] <= row["ratio"] <= row["ratio_high"]  # equal without gust
        assert row["p_difference"] == pytest.approx((a > limit).mean() - (b > limit).mean())
        ta, tb = column(mc, "smc", phase, "max_tracking"), column(mc, "pd", phase, "max_tracking")
        assert row["track_ratio"] == pytest.approx(100 * ta.mean() / tb.mean(), rel=1e-12)
        assert c.means.loc[phase, ("smc", "metric")] == pytest.approx(a.mean(), rel=1e-12)


def test_swapping_the_reference_inverts_the_ratio(mc: quadrs.MonteCarloResult) -> None:
    ab = compare_laws(mc, 3.0, ("pd", "smc")).paired
    ba = compare_laws(mc, 3.0, ("smc", "pd")).paired
    for phase in ("P1", "P2", "P3"):
        x, y = ab.loc[(phase, "smc")], ba.loc[(phase, "pd")]
        assert x["ratio"] * y["ratio"] == pytest.approx(1e4, rel=1e-12)
        assert x["p_difference"] == pytest.approx(-y["p_difference"], abs=1e-15)


def test_one_law_has_no_paired_section_and_bad_laws_are_refused(
    mc: quadrs.MonteCarloResult,
) -> None:
    one = compare_laws(mc, 3.0, ("smc",))
    assert one.paired.empty and "Paired against" not in one.to_text()
    with pytest.raises(ValueError, match="controllers must be among"):
        compare_laws(mc, 3.0, ("pd", "lqr"))
    with pytest.raises(ValueError, match="must differ"):
        compare_laws(mc, 3.0, ("pd", "pd"))
    text = compare_laws(mc, 3.0).to_text(width=100)
    assert all(len(line) <= 100 for line in text.splitlines())
    assert not math.isnan(float(compare_laws(mc, 3.0).paired["ratio"].iloc[0]))


def test_the_command_compares_the_laws(capsys: pytest.CaptureFixture[str]) -> None:
    args = ["mission", "--preset", "paper", "--runs", "6", "--limit", "5", "--no-progress"]
    for key, value in SHORT.items():
        args += ["--set", f"{key}={_toml(value)}"]
    assert main([*args, "--controller", "pd,smc"]) == 0
    out = capsys.readouterr().out
    assert "PD, SMC on the same 6 gust realisations (paired)" in out
    assert "Paired against PD" in out and "smc accel %" in out
    for bad, says in (("pd,pd", "each law once"), ("pd,lqr", "'lqr' is not a control law")):
        assert main([*args, "--controller", bad]) == 2
        err = capsys.readouterr().err.strip()
        assert says in err and len(err.splitlines()) == 1


def _toml(value: object) -> str:
    if isinstance(value, list) and value and isinstance(value[0], dict):
        return "[" + ",".join("{" + ",".join(f"{k}={_toml(v)}" for k, v in d.items()) + "}"
                              for d in value) + "]"  # fmt: skip
    if isinstance(value, str):
        return f'"{value}"'
    return str(value).replace("'", '"')


def test_the_pairs_share_their_gusts(mc: quadrs.MonteCarloResult) -> None:
    """Pairing is what narrows the interval: the same realisation's wind for both laws, so
    their per-realisation peaks correlate (an unpaired comparison would not see that)."""
    a, b = column(mc, "smc", "P2", "max_accel"), column(mc, "pd", "P2", "max_accel")
    assert np.corrcoef(a, b)[0, 1] > 0.5


def test_the_in_flight_and_touchdown_rows_are_their_own(tmp_path: object) -> None:
    """The comparison's ``in flight`` and ``touchdown`` rows are the parcel's peak over the
    phases its parcel was off the ground in and over those it met the ground in, per law,
    paired by realisation (before: both read as the whole flight's, the touchdown's 9 g in the
    ``in flight`` mean)."""
    from tests.first_hour.test_fifth_round import DROP_HERE

    s = quadrs.Scenario.preset("delivery").override(DROP_HERE)
    mc = quadrs.monte_carlo(s, runs=4, seed=0, controllers=("pd", "se3"), progress=False,
                            spectra=False)  # fmt: skip
    c = compare_laws(mc, 2 * 9.80665, metric="max_specific_force")
    for law in ("pd", "se3"):
        runs = mc.runs[(mc.runs.controller == law) & (mc.runs.phase != "flight")]
        wide = runs.set_index(["realisation", "phase"]).unstack("phase")
        contact = wide["touchdown_peak_force"].notna() | wide["touchdown_speed"].notna()
        force = wide["max_specific_force"]
        in_flight = force.where(~contact).max(axis=1).mean()
        touchdown = force.where(contact).max(axis=1).mean()
        assert c.means.loc["in flight", (law, "metric")] == pytest.approx(in_flight, rel=1e-12)
        assert c.means.loc["touchdown", (law, "metric")] == pytest.approx(touchdown, rel=1e-12)
        assert in_flight < 2 * 9.80665 < touchdown
    assert c.paired.loc[("in flight", "se3"), "n_pairs"] == 4
