"""The SIMD paths through the whole stack: every path this CPU supports gives the same bits (the
default mode; the paper's body and the delivery preset's rigid body), and forcing a path it
cannot run is a clear error, never a crash. Each path runs in its own process (QUADRS_SIMD is
read once per process)."""

import os
import subprocess
import sys

import pytest

from quadrs import _core

PATHS = ("baseline", "avx2", "avx512")

#: Run a short dispersed Monte Carlo and a single flight; print the path and a hash of the bits.
CODE = """
import hashlib, warnings
import numpy as np, quadrs
from quadrs import _core
from tests.conftest import DELIVERY_DROP, SHORT
warnings.simplefilter("ignore")
sc = quadrs.Scenario.paper().override(SHORT)
d = sc.override({"dispersions": {"payload.mass": {"dist": "uniform", "low": 0.18, "high": 0.26}}})
h = hashlib.sha256()
for s in (sc, d):
    mc = quadrs.monte_carlo(s, runs=11, seed=4, workers=2, progress=False)
    h.update(np.ascontiguousarray(mc.runs.select_dtypes("number").to_numpy()).tobytes())
fl = quadrs.simulate(sc, "pd", seed=4, realisation=3)
h.update(np.ascontiguousarray(fl.metrics.select_dtypes("number").to_numpy()).tobytes())
# The rigid body (the delivery preset's) over its drop point in turbulence: a dispersed batch
# and a traced flight with every law.
rigid = quadrs.Scenario.preset("delivery").override(DELIVERY_DROP)
cd = {"dist": "uniform", "low": 0.03, "high": 0.09}
rd = rigid.override({"dispersions": {"vehicle.drag_coefficients[1]": cd}})
for s in (rigid, rd):
    mc = quadrs.monte_carlo(s, runs=9, seed=5, workers=2, progress=False)
    h.update(np.ascontiguousarray(mc.runs.select_dtypes("number").to_numpy()).tobytes())
for law in ("pd", "smc", "se3", "px4"):
    fl = quadrs.simulate(rigid, law, seed=5, realisation=2, record_every=7)
    h.update(np.ascontiguousarray(fl.trace.to_numpy()).tobytes())
print(_core.simd_path(), h.hexdigest())
"""


def run(simd: str) -> subprocess.CompletedProcess[str]:
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = {**os.environ, "QUADRS_SIMD": simd}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [root, env.get("PYTHONPATH")]))
    return subprocess.run(
        [sys.executable, "-c", CODE], env=env, capture_output=True, text=True, cwd=root
    )


def test_every_supported_path_gives_the_same_bits() -> None:
    digests, skipped = {}, []
    for path in PATHS:
        out = run(path)
        if out.returncode != 0:
            assert "cannot run" in out.stderr and "QUADRS_SIMD" in out.stderr, out.stderr
            skipped.append(path)
            continue
        got_path, digest = out.stdout.split()[-2:]
        assert got_path == path
        digests[path] = digest
    print(f"paths run: {sorted(digests)}; skipped (this CPU cannot run them): {skipped}")
    assert "baseline" in digests and len(set(digests.values())) == 1, digests
    assert _core.simd_path() in digests


@pytest.mark.parametrize("value", ["avx9", "neon"])
def test_a_path_that_is_none_is_refused_by_name(value: str) -> None:
    out = run(value)
    assert out.returncode != 0
    assert "ValueError" in out.stderr and f'QUADRS_SIMD="{value}"' in out.stderr, out.stderr


def test_the_cli_refuses_a_bad_path_in_one_line() -> None:
    """A bad QUADRS_SIMD is bad input: exit 2 and one line naming it, no traceback."""
    env = {**os.environ, "QUADRS_SIMD": "avx9"}
    out = subprocess.run(
        [sys.executable, "-m", "quadrs.cli", "mc", "--runs", "4"],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert out.returncode == 2, out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and 'QUADRS_SIMD="avx9"' in lines[0], out.stderr
    assert "Traceback" not in out.stderr
