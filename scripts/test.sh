#!/usr/bin/env bash
# Install everything the tests need into .venv (the engine as a built wheel, not editable), then run every check: Rust format, lints and
# unit tests; the Python package built with maturin; ruff, mypy, the stub check, the
# documentation site (mkdocs build --strict: warnings are errors) and pytest;
# then the package built, installed and smoke-tested on the lowest supported and the newest
# installed Python (scripts/other_pythons.sh; QUADRS_SKIP_OTHER_PYTHONS=1 skips it).
set -euo pipefail
cd "$(dirname "$0")/.."
# Elapsed time at each stage, so a slow stage shows in the CI log.
stage() { echo "== $(date -u +%T) (+${SECONDS}s) $*"; }

stage "install"
python3 -m venv .venv
.venv/bin/python -m pip install -q --upgrade pip
# The engine is built once: the abi3 wheel this venv installs is the same file
# scripts/other_pythons.sh installs into the other Pythons. It is optimised without LTO (the
# dev-opt profile; LTO changes no arithmetic, so every number the tests check is the shipped
# build's, and the build takes minutes less); QUADRS_TEST_PROFILE=release tests the shipped
# profile instead. The Rust unit tests below reuse its dependencies.
rm -rf target/ci-wheel
MATURIN_PEP517_ARGS="--profile ${QUADRS_TEST_PROFILE:-dev-opt}" \
    .venv/bin/python -m pip wheel -q --no-deps -w target/ci-wheel .
wheel=$(ls target/ci-wheel/quadrs-*.whl)
.venv/bin/python -m pip install -q "${wheel}[test,dask,docs]"
.venv/bin/python -m pip install -q --no-deps --force-reinstall "$wheel"
export QUADRS_WHEEL="$wheel"

stage "rust checks and tests"
cargo fmt --check
cargo clippy --all-targets -q -- -D warnings
# Unit tests at optimisation without LTO (same arithmetic, minutes less to link); the doc
# comments hold no examples, so no doctest build.
cargo test --profile dev-opt --lib -q

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
.venv/bin/python -m pytest -q --durations=15 "$@"
if [ -z "${QUADRS_SKIP_OTHER_PYTHONS:-}" ]; then
    stage "other pythons"
    bash scripts/other_pythons.sh
fi
stage "done"
