"""The weibull and choice dispersions and a site's wind climate ([wind.climate]): each draws
its stated law (Kolmogorov-Smirnov, binomial intervals), the same seed draws the same values
whatever the chunking, and bad tables are refused naming the key."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

import quadrs
from quadrs.scenario.dispersion import describe, dispersed_keys, draw
from quadrs.scenario.keys import ScenarioError

N = 2_000
WEIBULL = {"dist": "weibull", "shape": 2.0, "scale": 6.0}
CHOICE = {"dist": "choice", "values": [0.2, 0.35, 0.5], "weights": [1.0, 2.0, 5.0]}
SECTORS = [
    {"heading": 0.0, "frequency": 20.0, "shape": 2.2, "scale": 5.0},
    {"heading": 90.0, "frequency": 50.0, "shape": 1.8, "scale": 7.0},
    {"heading": 225.0, "frequency": 30.0, "shape": 2.5, "scale": 3.0},
]


@pytest.fixture(scope="module")
def paper() -> quadrs.Scenario:
    return quadrs.Scenario.paper()


def _binomial_ok(count: int, n: int, p: float) -> bool:
    """Whether ``count`` of ``n`` lies in the central 99.9 % binomial range of p."""
    lo, hi = stats.binom.ppf([0.0005, 0.9995], n, p)
    return bool(lo <= count <= hi)


def test_a_weibull_dispersion_draws_its_law(paper) -> None:
    s = paper.override({"dispersions": {"gust.w20": WEIBULL}})
    x = draw(s, seed=11, first=0, count=N)["gust.w20"].to_numpy()
    assert stats.kstest(x, stats.weibull_min(2.0, scale=6.0).cdf).pvalue > 0.01
    # and a nearby law is told apart (the test can fail).
    assert stats.kstest(x, stats.weibull_min(2.0, scale=7.0).cdf).pvalue < 1e-6


def test_a_choice_dispersion_draws_each_value_at_its_weight(paper) -> None:
    s = paper.override({"dispersions": {"payload.mass": CHOICE}})
    x = draw(s, seed=3, first=0, count=N)["payload.mass"].to_numpy()
    assert set(np.unique(x)) == {0.2, 0.35, 0.5}
    for value, p in zip(CHOICE["values"], np.array(CHOICE["weights"]) / 8.0, strict=True):
        assert _binomial_ok(int((x == value).sum()), N, p), (value, (x == value).sum())
    law = stats.rv_discrete(values=([0, 1, 2], [1 / 8, 2 / 8, 5 / 8]))
    codes = np.searchsorted([0.2, 0.35, 0.5], x)
    table = np.bincount(codes, minlength=3)
    assert stats.chisquare(table, N * law.pmf([0, 1, 2])).pvalue > 0.001
    assert describe(s) == ["payload.mass ~ choice(values=[0.2, 0.35, 0.5], weights=[1, 2, 5])"]


def test_a_zero_weight_is_never_drawn(paper) -> None:
    spec = {"dist": "choice", "values": [1.0, 2.0, 3.0], "weights": [0.0, 1.0, 0.0]}
    s = paper.override({"dispersions": {"gust.w20": spec}})
    assert set(draw(s, seed=0, first=0, count=500)["gust.w20"]) == {2.0}


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ({"dist": "weibull", "shape": 0.0, "scale": 6.0}, "shape must be > 0"),
        ({"dist": "weibull", "shape": 2.0, "scale": -1.0}, "scale must be > 0"),
        ({"dist": "choice", "values": [], "weights": []}, "values must list at least one"),
        ({"dist": "choice", "values": [1.0, 2.0], "weights": [1.0]}, "one entry per value"),
        ({"dist": "choice", "values": [1.0, 2.0], "weights": [1.0, -1.0]}, "weights[1]"),
        ({"dist": "choice", "values": [1.0], "weights": [0.0]}, "sum to a finite number > 0"),
    ],
)
def test_a_bad_law_is_refused_naming_the_key(paper, spec, words) -> None:
    with pytest.raises(ScenarioError, match=r"gust\.w20") as e:
        paper.override({"dispersions": {"gust.w20": spec}})
    assert words in str(e.value)


def _climate(scenario: quadrs.Scenario, sectors=SECTORS) -> quadrs.Scenario:
    return scenario.override({"wind.climate.sectors": sectors})


#: Each sector of SECTORS reaches half-way to its neighbours: 0 deg from -67.5 (half-way to
#: 225 - 360 = -135) to 45, 90 from 45 to 157.5, 225 from 157.5 to 292.5.
EXTENTS = [(-67.5, 45.0), (45.0, 157.5), (157.5, 292.5)]


def _in_sector(heading: np.ndarray, i: int) -> np.ndarray:
    low, high = EXTENTS[i]
    return (heading >= low) & (heading < high)


def test_a_climate_reproduces_its_sectors_and_their_weibull_speeds(paper) -> None:
    s = _climate(paper)
    assert dispersed_keys(s) == ["wind.heading", "wind.speed"] and s.dispersed
    d = draw(s, seed=5, first=0, count=N)
    heading, speed = d["wind.heading"].to_numpy(), d["wind.speed"].to_numpy()
    for i, sector in enumerate(SECTORS):
        inside = _in_sector(heading, i)
        assert _binomial_ok(int(inside.sum()), N, sector["frequency"] / 100.0), sector
        law = stats.weibull_min(sector["shape"], scale=sector["scale"])
        assert stats.kstest(speed[inside], law.cdf).pvalue > 0.001, sector
    # The engine never sees the table, only the drawn keys.
    assert "climate" not in s.to_json()
    assert "climate" not in s.fixed().to_json() and not s.fixed().dispersed


def test_the_same_seed_draws_the_same_winds_whatever_the_slice(paper) -> None:
    s = _climate(paper)
    whole = draw(s, seed=9, first=0, count=300)
    part = draw(s, seed=9, first=120, count=50)
    np.testing.assert_array_equal(whole.iloc[120:170].to_numpy(), part.to_numpy())
    again = draw(s, seed=9, first=0, count=300)
    np.testing.assert_array_equal(whole.to_numpy(), again.to_numpy())
    other = draw(s, seed=10, first=0, count=300)
    assert not np.array_equal(whole.to_numpy(), other.to_numpy())


def test_a_latin_hypercube_stratifies_the_sectors(paper) -> None:
    """With lhs each sector gets its share to within one flight (the heading's column is
    stratified): far tighter than random sampling's binomial spread."""
    s = _climate(paper)
    d = draw(s, seed=1, first=0, count=200, runs=200, sampling="lhs")
    counts = [int(_in_sector(d["wind.heading"].to_numpy(), i).sum()) for i in range(3)]
    assert counts == pytest.approx([40, 100, 60], abs=1)


def test_a_sectors_headings_are_drawn_uniform_across_its_width(paper) -> None:
    """Within each sector the heading is uniform from half-way to one neighbour to half-way
    to the other (Kolmogorov-Smirnov over its share of 2,000 draws), independent of the
    speed; an atlas's twelve sectors each span their heading +- 15 deg."""
    from quadrs.scenario.climate import sector_extents

    d = draw(_climate(paper), seed=5, first=0, count=N)
    heading, speed = d["wind.heading"].to_numpy(), d["wind.speed"].to_numpy()
    assert heading.min() >= -67.5 and heading.max() <= 292.5
    for i, (low, high) in enumerate(EXTENTS):
        inside = heading[_in_sector(heading, i)]
        assert stats.kstest(inside, stats.uniform(low, high - low).cdf).pvalue > 0.001, i
        # the heading within a sector says nothing of the speed
        near = _in_sector(heading, i)
        assert abs(stats.spearmanr(heading[near], speed[near])[0]) < 0.15, i
    low, high = sector_extents(np.arange(0.0, 360.0, 30.0))
    np.testing.assert_array_equal(high - low, 30.0)
    np.testing.assert_array_equal(low, np.arange(0.0, 360.0, 30.0) - 15.0)
    lone = draw(_climate(paper, SECTORS[1:2]), seed=5, first=0, count=50)
    assert (lone["wind.heading"] == 90.0).all()  # a lone sector has no neighbours


def test_two_sectors_at_one_heading_are_refused(paper) -> None:
    twice = [SECTORS[0], {**SECTORS[1], "heading": 360.0}]
    with pytest.raises(ScenarioError, match=r"sectors\[1\]\.heading: 360 deg is sector 0's"):
        _climate(paper, twice)


@pytest.mark.parametrize(
    ("sectors", "key"),
    [
        (
            [{"heading": 0.0, "frequency": 1.0, "shape": 0.0, "scale": 5.0}],
            "wind.climate.sectors[0].shape",
        ),
        (
            [SECTORS[0], {"heading": 0.0, "frequency": -1.0, "shape": 2.0, "scale": 5.0}],
            "wind.climate.sectors[1].frequency",
        ),
        ([{"heading": 0.0, "frequency": 1.0, "shape": 2.0}], "wind.climate.sectors[0].scale"),
        (
            [{"heading": 0.0, "frequency": 1.0, "shape": 2.0, "scale": 5.0, "gust": 1.0}],
            "wind.climate.sectors[0].gust",
        ),
        ([], "wind.climate.sectors"),
    ],
)
def test_a_bad_climate_is_refused_naming_the_key(paper, sectors, key) -> None:
    with pytest.raises(ScenarioError, match=key.replace("[", r"\[").replace("]", r"\]")) as e:
        _climate(paper, sectors)
    assert e.value.key == key


def test_a_climate_and_a_dispersion_of_its_keys_are_refused_together(paper) -> None:
    with pytest.raises(ScenarioError, match=r"dispersions\.wind\.speed") as e:
        _climate(paper).override({"dispersions": {"wind.speed": WEIBULL}})
    assert e.value.key == "dispersions.wind.speed"


def test_a_climate_batch_flies_its_drawn_winds(paper) -> None:
    short = _climate(paper.override({"integrator.duration": 2.0, "integrator.dt": 0.002,
                                     "phases": [{"name": "P1", "start": 0.0, "end": 2.0}],
                                     "gust.start": 0.5, "gust.end": 1.0}))  # fmt: skip
    mc = quadrs.monte_carlo(short, runs=4, seed=2, controllers=("pd",), progress=False,
                            spectra=False)  # fmt: skip
    one = mc.runs.drop_duplicates("realisation")
    np.testing.assert_array_equal(one["wind.speed"].to_numpy(),
                                  draw(short, 2, 0, 4)["wind.speed"].to_numpy())  # fmt: skip
    fixed = mc.scenario_of(3)
    assert fixed["wind.speed"] == one["wind.speed"].iloc[3]
    assert "climate" not in fixed.to_dict().get("wind", {})


def test_the_command_line_takes_a_choice_and_a_weibull() -> None:
    from quadrs.cli.scenario_args import parse_distribution

    assert parse_distribution("choice([0.2, 0.5], [3, 1])") == {
        "dist": "choice", "values": [0.2, 0.5], "weights": [3, 1]}  # fmt: skip
    assert parse_distribution("choice(weights=[1,1], values=[1,2])") == {
        "dist": "choice", "weights": [1, 1], "values": [1, 2]}  # fmt: skip
    assert parse_distribution("weibull(2, 6.5)") == {"dist": "weibull", "shape": 2, "scale": 6.5}
