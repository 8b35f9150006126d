#!/usr/bin/env bash
# Install everything the tests need into .venv (the engine as a built wheel, not editable),
# then run every check: Rust format, lints and unit tests; the Python package built with
# maturin; ruff, mypy, the stub check, the documentation site (mkdocs build --strict: warnings
# are errors) and pytest (a worker per core); then the package installed and smoke-tested on
# the lowest supported and the newest installed Python (scripts/other_pythons.sh;
# QUADRS_SKIP_OTHER_PYTHONS=1 skips it).
#
# Once the wheel is built, the Rust unit tests and the other Pythons run in the background
# beside the Python checks and pytest; their output is printed, and their status checked, at
# the end. The tests marked slow
# (pyproject.toml) run with `--slow` (or QUADRS_SLOW=1); other arguments go to pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "--slow" ]; then
    QUADRS_SLOW=1
    shift
fi
# Elapsed time at each stage, so a slow stage shows in the CI log.
stage() { echo "== $(date -u +%T) (+${SECONDS}s) $*"; }

# A fresh clone gains nothing from incremental compilation (it only writes its caches).
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
background=()
logs=()
finish_background() { # wait for each background check, print its log, fail if it failed
    local failed=0 i
    for i in ${background[@]+"${!background[@]}"}; do
        if ! wait "${background[$i]}"; then failed=1; fi
        cat "${logs[$i]}"
    done
    background=()
    return "$failed"
}
# stop what still runs in the background if a check fails first
trap 'for p in ${background[@]+"${background[@]}"}; do kill "$p" 2>/dev/null || true; done' EXIT

stage "install"
python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip

# The Rust lints start at once, in the background, in their own target directory (no lock
# shared with the wheel's build), and then the Rust unit tests' build (they run later, beside
# pytest), both at the lowest priority: the wheel, then pytest, are the critical path, and the
# Rust checks take the CPU they leave (measured on 2 cores: 858 s in all; 905 s with clippy at
# normal priority, 953 s with the unit tests built after the wheel). Unit tests unoptimised
# (the `unit` profile, Cargo.toml: the cheapest build; optimisation changes no arithmetic);
# the doc comments hold no examples, so no doctest build.
cargo fmt --check
rust_target="$PWD/target/rust-checks"
logs+=("$(mktemp)")
(
    renice -n 19 "$BASHPID" >/dev/null 2>&1 || true
    s=$SECONDS
    CARGO_TARGET_DIR="$rust_target" cargo clippy --all-targets -q -- -D warnings
    echo "== clippy (background) took $((SECONDS - s)) s"
    s=$SECONDS
    CARGO_TARGET_DIR="$rust_target" cargo test --profile unit --lib -q --no-run
    echo "== rust unit tests' build (background) took $((SECONDS - s)) s"
) >"${logs[-1]}" 2>&1 &
background+=($!)
rust_build=$!

# The Python dependencies install while the engine builds (downloads and unpacking, not CPU).
requirements=$(mktemp)
deps_log=$(mktemp)
.venv/bin/python scripts/requirements.py test dask docs >"$requirements"
.venv/bin/python -m pip install -q -r "$requirements" >"$deps_log" 2>&1 &
deps=$!

# The engine is built once: the abi3 wheel this venv installs is the same file
# scripts/other_pythons.sh installs into the other Pythons. It is optimised without LTO (the
# dev-opt profile; LTO changes no arithmetic, so every number the tests check is the shipped
# build's, and the build takes minutes less); QUADRS_TEST_PROFILE=release tests the shipped
# profile instead.
rm -rf target/ci-wheel
MATURIN_PEP517_ARGS="--profile ${QUADRS_TEST_PROFILE:-dev-opt}" \
    .venv/bin/python -m pip wheel -q --no-deps -w target/ci-wheel .
wheel=$(ls target/ci-wheel/quadrs-*.whl)
if ! wait "$deps"; then cat "$deps_log"; exit 1; fi
.venv/bin/python -m pip install -q "${wheel}[test,dask,docs]"
.venv/bin/python -m pip install -q --no-deps --force-reinstall "$wheel"
export QUADRS_WHEEL="$wheel"

logs+=("$(mktemp)")
(
    s=$SECONDS
    # Once built (above, after clippy): run them, pytest first.
    renice -n 10 "$BASHPID" >/dev/null 2>&1 || true
    while kill -0 "$rust_build" 2>/dev/null; do sleep 1; done
    CARGO_TARGET_DIR="$rust_target" cargo test --profile unit --lib -q
    echo "== rust unit tests (background) took $((SECONDS - s)) s"
) >"${logs[-1]}" 2>&1 &
background+=($!)
if [ -z "${QUADRS_SKIP_OTHER_PYTHONS:-}" ]; then
    logs+=("$(mktemp)")
    (
        echo "== other pythons (background)"
        bash scripts/other_pythons.sh
    ) >"${logs[-1]}" 2>&1 &
    background+=($!)
fi

stage "python checks"
.venv/bin/ruff check python tests benches examples scripts
.venv/bin/ruff format --check python tests benches examples scripts
.venv/bin/python -m mypy python/quadrs
.venv/bin/python -m mypy.stubtest quadrs._core --allowlist tests/stubtest-allowlist.txt
# The documentation site, warnings as errors (about 10 s): broken links, bad docstrings.
NO_MKDOCS_2_WARNING=1 .venv/bin/mkdocs build --strict --quiet --site-dir "$(mktemp -d)"
# Which engine path this machine runs: the cross-path tests run every path it supports.
.venv/bin/python -c "import quadrs; print('quadrs engine path:', quadrs._core.simd_path())"
stage "pytest"
# The tests marked slow (pyproject.toml) run with --slow. One pytest worker per core
# (pytest-xdist), a test file to a worker: its module fixtures are made once.
if [ -n "${QUADRS_SLOW:-}" ]; then only=(); else only=(-m "not slow"); fi
.venv/bin/python -m pytest -q -n auto --dist loadfile --durations=30 ${only[@]+"${only[@]}"} "$@"
stage "background checks"
finish_background
stage "done"
