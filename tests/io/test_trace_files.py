"""Trace files: a flight written to Parquet or CSV says what produced it and reads back whole;
a foreign or edited file is refused."""

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

import quadrs
from quadrs.io.integrity import CorruptRunError
from quadrs.runs.flight import Flight


@pytest.fixture(scope="module")
def flight(short: quadrs.Scenario) -> Flight:
    return quadrs.simulate(short, "pd", seed=7, realisation=3, record_every=5)


def test_parquet_round_trip_keeps_trace_metrics_and_provenance(flight: Flight, tmp_path: Path):
    path = tmp_path / "trace.parquet"
    flight.to_parquet(path)
    back = Flight.read_parquet(path)
    pd.testing.assert_frame_equal(back.trace, flight.trace)
    pd.testing.assert_frame_equal(back.metrics, flight.metrics)
    assert (back.controller, back.seed, back.realisation, back.record_every) == ("pd", 7, 3, 5)
    assert back.scenario == flight.scenario
    assert np.isnan(back.diverged_at) and not back.diverged
    meta = json.loads(pq.read_schema(path).metadata[b"quadrs"])
    assert meta["version"] == quadrs.__version__
    assert (meta["controller"], meta["seed"], meta["realisation"]) == ("pd", 7, 3)
    # The spectra are not saved, and asking for one says so instead of returning nothing.
    assert len(back.spectra) == 0
    with pytest.raises(KeyError, match="not saved"):
        back.spectra["P2"]


def test_read_back_flight_is_the_flight_its_metadata_describes(flight: Flight, tmp_path: Path):
    """Identity between paths: re-flying what the file says gives the file's trace."""
    path = tmp_path / "trace.parquet"
    flight.to_parquet(path)
    back = Flight.read_parquet(path)
    again = quadrs.simulate(
        back.scenario, back.controller, back.seed, realisation=back.realisation,
        record_every=back.record_every,
    )  # fmt: skip
    np.testing.assert_array_equal(again.trace.to_numpy(), back.trace.to_numpy())


@pytest.mark.parametrize(
    "edit",
    [
        lambda m: m.update(seed=8),
        lambda m: m.update(realisation=4),
        lambda m: m["trace"].update(record_every=1),
        lambda m: m.update(controller="smc"),
        lambda m: m.update(version="0.0.1"),
        lambda m: m.update(kind="monte carlo"),
        lambda m: m.update(metrics=[[1.0]]),
    ],
)
def test_edited_trace_metadata_is_refused(flight: Flight, tmp_path: Path, edit) -> None:
    path = tmp_path / "trace.parquet"
    flight.to_parquet(path)
    table = pq.read_table(path)
    meta = json.loads(table.schema.metadata[b"quadrs"])
    edit(meta)
    table = table.replace_schema_metadata({b"quadrs": json.dumps(meta).encode()})
    pq.write_table(table, path)
    with pytest.raises(CorruptRunError, match=r"trace\.parquet"):
        Flight.read_parquet(path)


def test_a_monte_carlo_file_is_not_read_as_a_trace(short: quadrs.Scenario, tmp_path: Path):
    path = tmp_path / "mc.parquet"
    quadrs.monte_carlo(short, runs=2, seed=0, controllers=("pd",), workers=1).to_parquet(path)
    with pytest.raises(CorruptRunError, match="not a quadrs flight trace"):
        Flight.read_parquet(path)


def test_csv_trace_has_no_float_noise(flight: Flight, tmp_path: Path) -> None:
    path = tmp_path / "trace.csv"
    flight.to_csv(path)
    text = path.read_text()
    back = pd.read_csv(path, index_col="t")
    # 12 significant digits: the values agree to that, and time steps print as typed.
    np.testing.assert_allclose(back.to_numpy(), flight.trace.to_numpy(), rtol=1e-11, atol=1e-300)
    assert list(back.columns) == list(flight.trace.columns)
    times = text.splitlines()[1:6]
    assert [t.split(",")[0] for t in times] == ["0", "0.01", "0.02", "0.03", "0.04"]
    assert not re.search(r"\d\.\d*0000000000\d", text), "float noise in the CSV"
