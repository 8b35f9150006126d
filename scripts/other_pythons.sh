#!/usr/bin/env bash
# Install and smoke-test quadrs on the lowest supported Python (3.10) and the newest installed
# one, so that requires-python stays true: one abi3 wheel, built once, into a throwaway venv
# each; the Rust dependencies are shared with the main build through target/. Pythons not found are reported
# and skipped. Usage: scripts/other_pythons.sh [PYTHON ...] (default: pyenv's 3.10 and 3.13).
set -euo pipefail
cd "$(dirname "$0")/.."
root="${PYENV_ROOT:-$HOME/.pyenv}/versions"
pythons=("$@")
if [ ${#pythons[@]} -eq 0 ]; then
    lowest=$(ls -d "$root"/3.10.*/bin/python3 2>/dev/null | sort -V | tail -1 || true)
    newest=$(ls -d "$root"/3.*/bin/python3 2>/dev/null | sort -V | tail -1 || true)
    pythons=("$lowest" "$newest")
fi
smoke='
import warnings, quadrs
s = quadrs.Scenario.paper().override({"integrator.duration": 2.0, "integrator.dt": 0.01,
    "phases": [{"name": "P1", "start": 0.0, "end": 2.0}]})
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    f = quadrs.simulate(s, "pd")
    mc = quadrs.monte_carlo(s, runs=2, progress=False)
rows = 2 * 2 * len(s.phase_names)  # realisations x controllers x phases (with "flight")
assert f.metrics["iae"].gt(0).all() and len(mc.runs) == rows, (f.metrics, mc.runs)
print("quadrs", quadrs.__version__, "ok on", __import__("sys").version.split()[0])
'
for py in "${pythons[@]}"; do
    if [ -z "$py" ] || [ ! -x "$py" ]; then
        echo "other_pythons: no interpreter at '${py}', skipped" >&2
        continue
    fi
    venv=$(mktemp -d)
    "$py" -m venv "$venv"
    "$venv/bin/python" -m pip install -q --upgrade pip
    # The engine is an abi3 wheel (one for every CPython >= 3.10): build it once, with the
    # first Python, and install that same wheel into every other one.
    # QUADRS_WHEEL (set by scripts/test.sh) is a wheel built already.
    wheel="${wheel:-${QUADRS_WHEEL:-}}"
    if [ -z "${wheel:-}" ]; then
        wheels=$(mktemp -d)
        "$venv/bin/python" -m pip wheel -q --no-deps -w "$wheels" .
        wheel=$(ls "$wheels"/quadrs-*.whl)
    fi
    "$venv/bin/python" -m pip install -q "$wheel"
    (cd "$venv" && "$venv/bin/python" -c "$smoke" && "$venv/bin/quadrs" --version)
    rm -rf "$venv"
done
