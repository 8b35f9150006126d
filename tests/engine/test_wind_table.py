"""A measured wind (docs/model.md, "A measured wind"): ``[wind.table]`` rows read from a CSV
file in Python, interpolated linearly in the engine by time or by the quadrotor's altitude,
held at the end rows' values outside them, added to the mean wind and the turbulence."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import quadrs
from quadrs import _core
from tests.conftest import DELIVERY_DROP
from tests.engine import delivery_on_the_state

WIND = ["wind_x", "wind_y", "wind_z"]


def _scenario(tmp_path: Path, csv: str, by: str, extra: str = "") -> quadrs.Scenario:
    """The delivery preset over its drop point with a wind table from a CSV beside the file."""
    (tmp_path / "wind.csv").write_text(csv)
    drop = delivery_on_the_state().override(DELIVERY_DROP)
    text = drop.to_toml() + f'\n[wind.table]\nfile = "wind.csv"\nby = "{by}"\n{extra}'
    (tmp_path / "scenario.toml").write_text(text)
    return quadrs.Scenario.from_toml(tmp_path / "scenario.toml")


def test_a_constant_table_is_the_mean_wind_it_copies(tmp_path) -> None:
    """The delivery's 5 m/s wind unsheared, once as ``[wind]`` and once as a one-row table by
    time (the turbulence on, at the vehicle's altitude and airspeed through the mean air):
    the same flight, bit for bit."""
    drop = delivery_on_the_state().override(
        {**DELIVERY_DROP, "wind.shear": "none", "wind.heading": 0.0}
    )
    table = _scenario(tmp_path, "t,wind_x,wind_y,wind_z\n0,5,0,0\n", "time")
    table = table.override({"wind.speed": 0.0, "wind.shear": "none", "wind.heading": 0.0})
    assert table["wind.table.points"] == [[0.0, 5.0, 0.0, 0.0]]
    a = quadrs.simulate(drop, "pd", seed=2, record_every=20)
    b = quadrs.simulate(table, "pd", seed=2, record_every=20)
    assert a.status == b.status == "ok"
    np.testing.assert_array_equal(a.trace.to_numpy(), b.trace.to_numpy())
    # The metrics table mixes text and numbers (an object array, where NaN != NaN): compared
    # exactly, column by column, with NaN (a phase without the event) equal to NaN.
    pd.testing.assert_frame_equal(a.metrics, b.metrics, check_exact=True)


def test_an_altitude_table_is_interpolated_at_the_vehicles_height(tmp_path) -> None:
    """No other wind: the trace's wind at each step is numpy.interp of the table at the
    vehicle's z (held outside the rows: the drop descends from 7 m to 5 m through rows at
    5.5 and 6.5 m), to 1e-12."""
    csv = "z,wind_x,wind_y,wind_z\n5.5,1.0,-2.0,0.0\n6.0,3.0,0.5,0.25\n6.5,-1.0,1.5,-0.5\n"
    s = _scenario(tmp_path, csv, "altitude").override({"gust.enabled": False, "wind.speed": 0.0})
    f = quadrs.simulate(s, "pd", record_every=1)
    tr = f.trace.iloc[:-1]  # the last row holds the last step's wind
    z = tr["z"].to_numpy()
    assert z.max() > 6.5 and z.min() < 5.5
    rows = np.array(s["wind.table.points"])
    for i, column in enumerate(WIND):
        want = np.interp(z, rows[:, 0], rows[:, i + 1])
        np.testing.assert_allclose(tr[column].to_numpy(), want, rtol=0, atol=1e-12)


@pytest.mark.filterwarnings("ignore:wind.table covers")  # the end rows' hold is checked here
def test_a_time_table_adds_to_the_sheared_mean_wind(tmp_path) -> None:
    """By time, on top of the delivery's sheared 5 m/s crosswind (no turbulence): the trace's
    wind at every step is numpy.interp of the table at t plus the log profile at the vehicle's
    z (docs/model.md), to 1e-12; the table's end rows hold before and after them."""
    csv = "t,wind_x,wind_y,wind_z\n2,0,0,0\n4,1.5,-1.0,0.5\n10,0.5,2.0,0\n"
    s = _scenario(tmp_path, csv, "time").override({"gust.enabled": False})
    rows = np.array(s["wind.table.points"])
    f = quadrs.simulate(s, "pd", record_every=1)
    assert f.status == "ok"
    t = f.trace.index.to_numpy()[:-1]
    z = f.trace["z"].to_numpy()[:-1]
    z0, chi = s["wind.roughness"], np.radians(s["wind.heading"])
    speed = s["wind.speed"] * np.log(z / z0) / np.log(6.096 / z0)
    mean = np.stack([speed * np.cos(chi), speed * np.sin(chi), 0 * speed], axis=1)
    table = np.stack([np.interp(t, rows[:, 0], rows[:, i]) for i in (1, 2, 3)], axis=1)
    np.testing.assert_allclose(f.trace[WIND].to_numpy()[:-1], mean + table, rtol=0, atol=1e-12)
    assert t[-1] > 10.0 and np.abs(table[t < 2.0]).max() == 0.0


def test_a_batch_row_is_the_single_flight(tmp_path) -> None:
    """The lane-set path (a batch) and a single flight fly a table's wind to the same bits;
    a table's number disperses like any key."""
    csv = "z,wind_x,wind_y,wind_z\n4,1.0,-2.0,0.0\n8,3.0,0.5,0.25\n"
    s = _scenario(tmp_path, csv, "altitude")
    mc = quadrs.monte_carlo(s, runs=4, seed=9, controllers=("pd",), progress=False)
    runs = mc.runs
    for i in range(4):
        single = quadrs.simulate(s, "pd", seed=9, realisation=i)
        row = runs[(runs["realisation"] == i) & (runs["phase"] == "flight")].iloc[0]
        flight = single.metrics.set_index("phase").loc["flight"]
        for metric in ("tracking_rms", "max_accel", "max_swing"):
            assert row[metric] == flight[metric], (i, metric)
    dispersed = s.override(
        {"dispersions": {"wind.table.points[1][1]": {"dist": "uniform", "low": 0.0, "high": 6.0}}}
    )
    mc = quadrs.monte_carlo(dispersed, runs=2, seed=9, controllers=("pd",), progress=False)
    assert mc.runs["wind.table.points[1][1]"].nunique() == 2


@pytest.mark.parametrize(
    ("csv", "says"),
    [
        ("x,wind_x,wind_y,wind_z\n0,1,2,3\n", "column 1 is 'x', expected 't' (by = \"time\")"),
        ("t,wind_x,wind_y\n0,1,2\n", "column 4 is missing, expected 'wind_z'"),
        ("t,wind_x,wind_z,wind_y\n0,1,2,3\n", "column 3 is 'wind_z', expected 'wind_y'"),
        ("t,wind_x,wind_y,wind_z\n0,1,two,3\n", "line 2 column wind_y: not a finite number"),
        ("t,wind_x,wind_y,wind_z\n0,1,2,3\n0,1,2,3\n", "line 3 column t: must be greater"),
        ("t,wind_x,wind_y,wind_z\n0,1,2\n", "line 2: 3 values, expected 4"),
        ("t,wind_x,wind_y,wind_z\n", "has a header and no rows"),
        ("", "is empty"),
        ("t,wind_x,wind_y,wind_z\n0,1,nan,3\n", "not a finite number, got 'nan'"),
    ],
)
def test_a_malformed_table_is_one_line_naming_the_file_and_column(tmp_path, csv, says) -> None:
    with pytest.raises(quadrs.ScenarioError) as e:
        _scenario(tmp_path, csv, "time")
    message = str(e.value)
    assert says in message, message
    assert "wind.csv" in message and "\n" not in message
    assert e.value.key == "wind.table.file"


def test_a_missing_file_and_the_command_line(tmp_path) -> None:
    """A missing file is named; on the command line a bad table is exit 2, one line."""
    with pytest.raises(quadrs.ScenarioError, match=r"wind\.csv.*cannot be read"):
        quadrs.Scenario.from_dict(
            {
                "base": "delivery",
                "wind": {"table": {"file": str(tmp_path / "wind.csv"), "by": "time"}},
            }
        )
    _scenario(tmp_path, "z,wind_x,wind_y,wind_z\n0,1,2,3\n", "altitude")
    (tmp_path / "wind.csv").write_text("z,wind_x,wind_y,wind_z\n0,1,2,3\n-1,0,0,0\n")
    r = subprocess.run(
        [sys.executable, "-m", "quadrs.cli", "scenario", "keys", "--scenario",
         str(tmp_path / "scenario.toml")],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert r.returncode == 2, r.stdout
    assert "line 3 column z" in r.stderr and r.stderr.strip().count("\n") == 0


def test_the_table_keys_have_units_and_labels() -> None:
    for key in ("wind.table.by", "wind.table.points"):
        assert _core.KEY_UNITS[key].strip() and _core.KEY_LABELS[key].strip()
