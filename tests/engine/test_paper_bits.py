"""The paper model's numbers do not change by one bit (docs/model.md, "Paper model unchanged").

tests/data/paper_bits.json holds a digest of every output of a fixed set of paper-model cases
(traces, metrics, Monte Carlo rows fixed and dispersed, spectra, gust series, linearisations,
poles), written by ``scripts/paper_bits.py --write`` before the third round's model-seams
redesign. Any change of any bit of any of those numbers fails here, naming the output.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("paper_bits", ROOT / "scripts" / "paper_bits.py")
assert spec and spec.loader
paper_bits = importlib.util.module_from_spec(spec)
spec.loader.exec_module(paper_bits)


def test_paper_model_numbers_are_bit_identical_to_the_recorded_ones():
    want = paper_bits.reference(ROOT / "tests" / "data" / "paper_bits.json")
    got = paper_bits.compute()
    assert paper_bits.compare(want, got) == []


def test_the_comparison_can_fail():
    want = json.loads((ROOT / "tests" / "data" / "paper_bits.json").read_text())
    tampered = {case: dict(d) for case, d in want.items()}
    tampered["paper.pd"]["trace.z"] = "0" * 32
    del tampered["gust"]["gust.dryden.vertical"]
    assert sorted(paper_bits.compare(want, tampered)) == [
        "gust: gust.dryden.vertical missing",
        "paper.pd: trace.z changed",
    ]


def test_only_the_cpu_dependent_outputs_are_recorded_per_cpu():
    """The per-CPU digests may cover only the ensemble spectra (sums taken a lane-set at a
    time) and the batches with a lognormal dispersion (numpy's exp): never a flight, a trace,
    a linearisation or a gust series."""
    per_cpu = json.loads((ROOT / "tests" / "data" / paper_bits.CPU_FILE).read_text())
    for cases in per_cpu.values():
        for case, digests in cases.items():
            assert case.startswith("batch."), case
            for key in digests:
                assert key.startswith("spectra.") or case.startswith("batch.dispersed."), key


def test_delivery_preset_numbers_are_bit_identical_to_the_recorded_ones():
    """The delivery preset's flights (PD, SMC) and a batch, every trace and metric column,
    recorded after round 4 made the closing row hold the last step's wind
    (``scripts/paper_bits.py --delivery --write tests/data/delivery_bits.json``); the same on
    every SIMD path (checked with QUADRS_SIMD=avx2 and baseline when written)."""
    want = paper_bits.reference(ROOT / "tests" / "data" / "delivery_bits.json")
    assert {"delivery.pd", "delivery.smc", "batch.delivery"} <= set(want)
    got = paper_bits.compute(list(want))
    assert paper_bits.compare(want, got) == []
