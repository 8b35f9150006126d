"""quadrs mission's answers for a safety case: the failure modes per flight hour, --target's
verdicts, and --safety-case's page, whose numbers are the printed ones and which quadrs report
rebuilds from the saved file."""

from __future__ import annotations

import re

import numpy as np
import pytest

import quadrs
from quadrs.cli.main import main
from quadrs.design.mission import mission_report
from quadrs.design.safety import safety_case
from quadrs.stats.rates import flight_rate
from tests.first_hour.test_fourth_round import SHORT_ROUTE  # a 20 m dog-leg, 30 s

RUNS = 6


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> dict:
    """One mission with a corridor some flights leave: its printed answer, its page, its file."""
    import quadrs.cli.mission as cm

    tmp = tmp_path_factory.mktemp("safety")
    route = tmp / "route.toml"
    route.write_text(quadrs.Scenario.preset("delivery").override(SHORT_ROUTE).to_toml())
    page, runs = tmp / "case.md", tmp / "runs.parquet"
    saved = cm._announce
    cm._announce = lambda *a: []  # type: ignore[assignment]
    try:
        import contextlib
        import io

        out = io.StringIO()
        with contextlib.redirect_stdout(out):
            code = main([
                "mission", "--scenario", str(route), "--runs", str(RUNS), "--seed", "3",
                "--set", "volume.flight_geography=0.3", "--set", "volume.flight_height_band=3.0",
                "--set", "volume.contingency=0.2", "--set", "wind.speed=4",
                "--target", "containment=1e-4", "--target", "control=1e3",
                "--safety-case", str(page), "--out", str(runs), "--no-progress",
            ])  # fmt: skip
    finally:
        cm._announce = saved  # type: ignore[assignment]
    assert code == 0
    return {"out": out.getvalue(), "page": page.read_text(), "runs": runs, "tmp": tmp}


def _page_rows(page: str) -> dict[str, list[str]]:
    """The failure modes table of the page: mode's first word -> its cells."""
    section = page.split("## Failure modes", 1)[1].split("##", 1)[0]
    rows = [ln for ln in section.splitlines() if ln.startswith("| ") and "---" not in ln]
    cells = [[c.strip() for c in ln.strip("|").split("|")] for ln in rows[1:]]
    return {c[0].split()[0].lower(): c[1:] for c in cells}


def _printed_rows(out: str) -> dict[str, list[str]]:
    """The per-flight-hour block quadrs mission printed: mode -> the numbers of its lines
    (each ``label: value``; the numbers of the values)."""
    block = out.split("Per flight hour (", 1)[1].split("\n\n", 1)[0]
    found: dict[str, list[str]] = {}
    mode = ""
    for line in block.splitlines():
        name, sep, value = line.strip().partition(": ")
        if not line.startswith(" ") and name in ("containment", "control", "parcel", "touchdown"):
            mode = name
            found[mode] = []
        elif not line.startswith(" "):
            mode = ""  # the head, a verdict
        if mode and sep:
            found[mode] += re.findall(r"-?\d[\d.e+-]*", value)
    return found


def test_the_pages_numbers_are_the_printed_ones(flown) -> None:
    page, printed = _page_rows(flown["page"]), _printed_rows(flown["out"])
    names = {"containment": "containment", "loss": "control", "parcel": "parcel"}
    for first, mode in names.items():
        numbers = re.findall(r"-?\d[\d.e+-]*", " ".join(page[first]))
        assert numbers and numbers == printed[mode], (mode, numbers, printed[mode])
    assert "not judged" in " ".join(page["hard"])  # the route lowers no parcel


def test_the_rates_are_the_flights_own(flown) -> None:
    """Containment: the flights that left the volume or diverged, over the hours flown."""
    mc = quadrs.MonteCarloResult.read_parquet(flown["runs"])
    runs = mc.runs.set_index("realisation")
    lost = (runs["left_volume"] > 0).groupby(level=0).any() | runs["diverged"].groupby(
        level=0).any()  # fmt: skip
    ended = runs["diverged_at"].groupby(level=0).min().fillna(30.0)
    expect = flight_rate(int(lost.sum()), RUNS, float((ended / 3600.0).sum()))
    case = safety_case(mc, mission_report(mc, 2 * 9.80665, "pd", metric="max_specific_force"))
    got = case.modes["containment"].rate
    assert got == expect
    assert 0 < expect.events  # the 0.3 m corridor is left
    cells = _page_rows(flown["page"])["containment"]
    assert cells[0] == f"{expect.events} of {RUNS}"
    assert f"{expect.upper:.3g}" == cells[3]


def test_the_targets_verdicts_are_printed_and_on_the_page(flown) -> None:
    out = flown["out"]
    assert "containment <= 0.0001 per flight hour: NOT MET" in out
    assert "control <= 1e+03 per flight hour: MET" in out
    targets = flown["page"].split("## Targets", 1)[1].split("##", 1)[0]
    assert "| containment | 0.0001 | not met |" in targets
    assert "| control | 1e+03 | met |" in targets


def test_report_rebuilds_the_page_from_the_saved_file(flown, capsys) -> None:
    again = flown["tmp"] / "again.md"
    assert main(["report", str(flown["runs"]), "--safety-case", str(again)]) == 0
    assert again.read_text() == flown["page"]
    out = capsys.readouterr().out
    assert _printed_rows(out) == _printed_rows(flown["out"])


def test_a_target_not_yet_shown_says_how_many_more_flights(flown, capsys) -> None:
    """Control: none of the flights diverged; 1 per flight hour is below the bound of a few
    minutes of flight (3 / hours), so more flights would show it."""
    mc = quadrs.MonteCarloResult.read_parquet(flown["runs"])
    assert not mc.runs["diverged"].any()
    assert main(["report", str(flown["runs"]), "--target", "control=1"]) == 0
    out = capsys.readouterr().out
    text = " ".join(out.split())  # the verdict wraps at the terminal's width
    line = text[text.index("control <= 1 per flight hour") :]
    assert line.startswith("control <= 1 per flight hour: NOT YET SHOWN")
    more = int(re.search(r"about ([\d,]+) more flights", line)[1].replace(",", ""))  # type: ignore[index]
    # the zero-event bound 2.996 / hours reaches 1 at 2.996 hours: 360 flights of 30 s.
    assert more == int(np.ceil(-np.log(0.05) / 1.0 / (30.0 / 3600.0))) - RUNS


def test_a_bad_target_or_page_is_refused(tmp_path, capsys) -> None:
    assert main(["mission", "--target", "crash=1e-4"]) == 2
    assert "the mode must be one of containment" in capsys.readouterr().err
    code = main(["mission", "--runs", "1", "--safety-case", str(tmp_path / "case.txt")])
    assert code == 2
    assert "expected a file ending in .md" in capsys.readouterr().err


def test_the_bound_is_one_sided_95_whatever_the_reports_confidence(flown) -> None:
    """A safety case files the one-sided 95 % bound: a report asked at 80 % does not lower
    it; the printed block and the page say the level."""
    from scipy import stats

    mc = quadrs.MonteCarloResult.read_parquet(flown["runs"])
    report = mission_report(mc, 2 * 9.80665, "pd", metric="max_specific_force", confidence=0.8)
    rate = safety_case(mc, report).modes["containment"].rate
    assert rate is not None and rate.confidence == 0.95
    assert rate.upper == pytest.approx(stats.chi2.ppf(0.95, 2 * rate.events + 2) / 2 / rate.hours,
                                       rel=1e-12)  # fmt: skip
    assert "upper bound per flight hour (one-sided 95 %):" in flown["out"]
    assert "| upper bound per flight hour (one-sided 95 %) |" in flown["page"]
    assert max(len(line) for line in flown["out"].splitlines()) <= 100


def test_the_winds_that_make_the_risk_are_printed_as_on_the_page(tmp_path, capsys) -> None:
    """Over a wind climate the answer prints the bands of the drawn mean wind, short: each
    band's flights and share and each mode's events there, the page's numbers."""
    import quadrs.cli.mission as cm

    climate = [{"heading": 0.0, "frequency": 1.0, "shape": 2.0, "scale": 3.0},
               {"heading": 90.0, "frequency": 1.0, "shape": 2.0, "scale": 6.0}]  # fmt: skip
    route = tmp_path / "route.toml"
    scenario = quadrs.Scenario.preset("delivery").override(SHORT_ROUTE)
    route.write_text(scenario.override({"wind.climate.sectors": climate}).to_toml())
    page = tmp_path / "case.md"
    saved = cm._announce
    cm._announce = lambda *a: []  # type: ignore[assignment]
    try:
        code = main(["mission", "--scenario", str(route), "--runs", "8", "--seed", "3",
                     "--set", "volume.flight_geography=0.3", "--set",
                     "volume.flight_height_band=3.0", "--safety-case", str(page),
                     "--no-progress"])  # fmt: skip
    finally:
        cm._announce = saved  # type: ignore[assignment]
    assert code == 0
    out = capsys.readouterr().out
    block = out.split("Which winds make the risk", 1)[1].split("\n\n", 1)[0]
    printed = [ln for ln in block.splitlines() if ln.startswith("  [")]
    table = page.read_text().split("## Which winds make the risk", 1)[1].split("##", 1)[0]
    rows = [ln for ln in table.splitlines() if ln.startswith("| [")]
    assert len(printed) == len(rows) >= 2
    for line, row in zip(printed, rows, strict=True):
        cells = [c.strip() for c in row.strip("|").split("|")]  # band, flights, share, ...
        assert line.startswith(f"  {cells[0]}: {cells[1]} flight")
        assert f"({cells[2]})" in line
        assert f"containment {cells[3]} ({cells[5]})" in line
    assert sum(int(r.split("|")[2]) for r in rows) == 8
    assert max(len(line) for line in out.splitlines()) <= 100
