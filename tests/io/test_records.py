"""One record per concept: the chunk a batch yields (here or on Dask), the run a file records,
the spectra saved as a table inside it, the key a ScenarioError names, the engine's names."""

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import quadrs
from quadrs import MonteCarloResult, Scenario, _core
from quadrs.io.integrity import CorruptRunError
from quadrs.io.parquet import write_frame
from quadrs.runs.chunk import Design, SpectrumSums, fly_chunk
from quadrs.runs.distributed import run_chunk

pytestmark = pytest.mark.filterwarnings(
    "ignore::quadrs.StabilityWarning", "ignore::quadrs.StepSizeWarning"
)


@pytest.fixture(scope="module")
def mc(short: Scenario) -> MonteCarloResult:
    return quadrs.monte_carlo(short, runs=6, seed=3, workers=2, progress=False)


# -- the chunk record -------------------------------------------------------------------------
def test_a_dask_task_yields_the_record_a_local_chunk_does(short: Scenario) -> None:
    """run_chunk (what a Dask worker runs) and fly_chunk (the local path) give the same
    record, spectra as arrays (no JSON round trip), bit for bit."""
    design = Design()
    here = fly_chunk(short, ("pd", "smc"), 5, 2, 4, 2, True, design)
    there = run_chunk(short.to_toml(), ("pd", "smc"), 5, 2, 4, 1, True, design)
    assert (here.first, here.count, here.interrupted) == (there.first, there.count, False)
    pd.testing.assert_frame_equal(here.runs, there.runs)
    assert isinstance(there.spectra, SpectrumSums)
    for a, b in zip(here.spectra.total, there.spectra.total, strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(here.spectra.count, [4, 4])
    # the frequency grid is the scenario's own, as a single flight reports it
    flight = quadrs.simulate(short, "pd", seed=5, realisation=2)
    for phase, grid in zip(short.phase_names, there.spectra.frequencies, strict=True):
        np.testing.assert_array_equal(grid, flight.spectra[phase]["frequency"])


# -- spectra saved as a table, in the result's own file ---------------------------------------
def test_spectra_are_a_table_embedded_in_the_result_file(
    mc: MonteCarloResult, tmp_path: Path
) -> None:
    path = tmp_path / "runs.parquet"
    mc.to_parquet(path)
    assert [p.name for p in tmp_path.iterdir()] == ["runs.parquet"]  # one result, one file
    schema = pq.read_schema(path).metadata
    assert len(schema[b"quadrs"]) < 8_000, len(schema[b"quadrs"])  # the run, not the spectra
    ref = json.loads(schema[b"quadrs"])["spectra"]
    table = pq.read_table(pa.BufferReader(schema[b"quadrs_spectra"])).to_pandas()
    assert list(table.columns) == ["phase", "controller", "frequency", "total", "total_sq"]
    assert ref["count"] == [6, 6]
    back = MonteCarloResult.read_parquet(path)
    pd.testing.assert_frame_equal(back.spectra, mc.spectra)
    quadrs.monte_carlo(mc.scenario, runs=2, seed=3, workers=2, progress=False).to_parquet(path)
    assert [p.name for p in tmp_path.iterdir()] == ["runs.parquet"]
    assert MonteCarloResult.read_parquet(path).spectrum_sums.count.tolist() == [2, 2]


def test_files_of_the_previous_format_are_refused_clearly(
    mc: MonteCarloResult, tmp_path: Path
) -> None:
    """Spectra as JSON in the metadata, or in a table beside the file, and no content digest:
    such a file cannot be told from an edited one, so it is refused, saying why."""
    old = tmp_path / "old.parquet"
    meta = mc.record.metadata(interrupted=False, spectra=mc.spectrum_sums.to_json())
    table = pa.Table.from_pandas(mc.runs, preserve_index=False)
    pq.write_table(table.replace_schema_metadata({b"quadrs": json.dumps(meta).encode()}), old)
    with pytest.raises(CorruptRunError, match="no content digest"):
        MonteCarloResult.read_parquet(old)


def test_a_foreign_spectrum_table_is_refused(
    mc: MonteCarloResult, short: Scenario, tmp_path: Path
) -> None:
    from quadrs.runs.chunk import SPECTRA_KEY, spectra_attachment

    other = quadrs.monte_carlo(short, runs=6, seed=4, workers=2, progress=False)
    ours, _ = spectra_attachment(mc.spectrum_sums, mc.record)
    _, theirs = spectra_attachment(other.spectrum_sums, other.record)
    path = tmp_path / "runs.parquet"
    # Written (and sealed) by quadrs, but naming our table while holding theirs.
    write_frame(mc.runs, path, b"quadrs", mc.record.metadata(interrupted=False, spectra=ours),
                attachments={SPECTRA_KEY: theirs})  # fmt: skip
    with pytest.raises(CorruptRunError, match="not the one it was written with"):
        MonteCarloResult.read_parquet(path)
    write_frame(mc.runs, path, b"quadrs", mc.record.metadata(interrupted=False, spectra=ours))
    with pytest.raises(CorruptRunError, match="spectrum table is missing"):
        MonteCarloResult.read_parquet(path)


def test_a_checkpoint_keeps_its_spectra_in_its_parts(short: Scenario, tmp_path: Path) -> None:
    out = tmp_path / "run"
    ck = quadrs.monte_carlo(short, runs=8, seed=1, chunk=4, workers=2, progress=False, out=out)
    whole = quadrs.monte_carlo(short, runs=8, seed=1, workers=2, progress=False)
    assert sorted(p.name.split("-")[0] for p in out.glob("*.parquet")) == ["part", "part"]
    for part in out.glob("part-*.parquet"):
        assert len(pq.read_schema(part).metadata[b"quadrs_part"]) < 2_000
    pd.testing.assert_frame_equal(ck.spectra, whole.spectra, rtol=1e-12)
    pd.testing.assert_frame_equal(MonteCarloResult.read_parquet(out).spectra, ck.spectra)


def test_a_checkpoint_part_of_the_previous_format_is_refused_clearly(
    short: Scenario, tmp_path: Path
) -> None:
    """Checkpoint parts written before parts carried a content digest."""
    from quadrs.runs.store import RunStore

    out = tmp_path / "run"
    new = quadrs.monte_carlo(short, runs=4, seed=2, workers=2, progress=False, out=out)
    store = RunStore(out)
    (part,) = store.parts()
    runs = pq.read_table(part).to_pandas()
    meta = {"run": store.run, "spectra": new.spectrum_sums.to_json()}
    table = pa.Table.from_pandas(runs, preserve_index=False)
    pq.write_table(table.replace_schema_metadata({b"quadrs_part": json.dumps(meta).encode()}),
                   part)  # fmt: skip
    with pytest.raises(CorruptRunError, match="no content digest"):
        MonteCarloResult.read_parquet(out)


# -- the run record ---------------------------------------------------------------------------
def test_every_result_file_records_its_run_the_same_way(
    mc: MonteCarloResult, short: Scenario, tmp_path: Path
) -> None:
    sw = quadrs.sweep(short, {"gust.w20": [5.0]}, runs=2, progress=False)
    common = {"version", "seed", "controllers", "scenario", "spectra", "run"}
    for result, key, extra in ((mc, b"quadrs", "sampling"), (sw, b"quadrs_sweep", "grid")):
        path = tmp_path / f"{extra}.parquet"
        result.to_parquet(path)
        meta = json.loads(pq.read_schema(path).metadata[key])
        assert common | {extra} <= set(meta)
        assert meta["run"] == result.record.run
        assert meta["version"] == quadrs.__version__


# -- names from the engine, keys in errors ----------------------------------------------------
def test_controller_names_come_from_the_engine() -> None:
    from quadrs.cli.main import build_parser
    from quadrs.engine.calls import CONTROLLERS, PAPER_CONTROLLERS

    assert CONTROLLERS == tuple(_core.CONTROLLER_NAMES)
    assert {"pd", "smc", "se3"} <= set(CONTROLLERS)
    args = build_parser().parse_args(["mc"])
    assert args.controllers == PAPER_CONTROLLERS == ("pd", "smc")  # the paper's pair by default
    assert build_parser().parse_args(["mc", "--controllers", "se3"]).controllers == ("se3",)


@pytest.mark.parametrize(
    ("changes", "key"),
    [
        ({"payload.mass": -1.0}, "payload.mass"),
        ({"gust.w20": -3.0}, "gust.w20"),
        ({"integrator.dt": 0.0}, "integrator.dt"),
        ({"phases[0].end": -1.0}, "phases[0].end"),
        ({"vehicle.nonsense": 1.0}, "vehicle.nonsense"),
        ({"gust.w20": float("nan")}, "gust.w20"),
        ({"base": 3}, "base"),
    ],
)
def test_scenario_error_names_its_key(paper: Scenario, changes: dict, key: str) -> None:
    with pytest.raises(quadrs.ScenarioError) as info:
        if "base" in changes:
            Scenario.from_toml_string("base = 3\n")
        else:
            paper.override(changes)
    assert info.value.key == key, str(info.value)
    assert key.split("[")[0] in str(info.value)


def test_scenario_error_without_a_key(paper: Scenario) -> None:
    assert quadrs.ScenarioError("free text").key is None
    with pytest.raises(quadrs.ScenarioError) as info:
        Scenario.from_toml_string("not toml [")
    assert info.value.key is None


def test_list_columns_are_bound_to_the_digest_too():
    """Lists of numbers (a rare-event result's failure samples) count bit for bit."""
    import pyarrow as pa

    from quadrs.io.parquet import _rows_digest

    a = pa.table({"xi": pa.array([[0.1, 0.2], [0.3]]), "k": [1, 2]})
    b = pa.table({"xi": pa.array([[0.1, 0.2], [0.30000000000000004]]), "k": [1, 2]})
    c = pa.table({"xi": pa.array([[0.1], [0.2, 0.3]]), "k": [1, 2]})
    assert _rows_digest(a) == _rows_digest(pa.table({"xi": [[0.1, 0.2], [0.3]], "k": [1, 2]}))
    assert len({_rows_digest(a), _rows_digest(b), _rows_digest(c)}) == 3
