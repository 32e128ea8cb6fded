#!/usr/bin/env bash
# Every test: the Rust workspace, then the Python package in a local virtual environment
# (.venv at the repository root, created on first use: maturin, numpy, pytest, pyarrow, Spark
# from PyPI). Exits non-zero if anything fails. Needs only the Rust toolchain, Python >= 3.9
# with pip (and venv), and Java 17 for the Spark tests.
#
# Each crate is compiled once: `cargo test --workspace` builds every library, test and the
# CLI; maturin then builds the extension (one dev-profile wheel) on top of that build, and
# the same wheel serves pytest and the Spark deployment test. Seconds per phase at the end.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
source scripts/lib/phases.sh
logs="$repo/target/test-all"
mkdir -p "$logs"

phase "Python: virtual environment .venv (pip, in the background)"
python=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$python" -m venv .venv
fi
# Spark 4 (applyInArrow, which needs pandas) for the fleet tests; venv-pack packs the
# environment test_spark_deploy.py ships to Spark's executor; vqf is the peer the accuracy
# tests run beside the flagship (pinned: the tests pin ratios to its numbers). Downloads overlap the Rust build.
(
    .venv/bin/python -m pip install --quiet --upgrade pip &&
    .venv/bin/python -m pip install --quiet "maturin>=1.5,<2" numpy pytest mypy pyarrow \
        "pyspark>=4.0,<5" "pandas>=2.2,<3" venv-pack "vqf==2.1.2"
) >"$logs/pip.log" 2>&1 &
pip_job=$!

phase "cargo test --workspace: build"
cargo test --workspace --no-run 2>&1 | tee "$logs/cargo-build.log"

phase "cargo test --workspace: run"
rust_status=0
cargo test --workspace --no-fail-fast || rust_status=$?

phase "Python: waiting for pip"
wait "$pip_job" || { cat "$logs/pip.log"; echo "pip install failed" >&2; exit 1; }

phase "Python: the wheel (maturin build, dev profile)"
rm -rf target/wheels/dev
VIRTUAL_ENV="$repo/.venv" .venv/bin/maturin build --profile dev \
    --manifest-path crates/rootfuse-py/Cargo.toml --out target/wheels/dev 2>&1 | tee "$logs/maturin.log"
wheel=$(ls target/wheels/dev/rootfuse-*.whl)
.venv/bin/python -m pip install --quiet --force-reinstall --no-deps "$wheel"
# Nothing compiled twice: the crates maturin compiled must be new to this run.
.venv/bin/python scripts/lib/compiled_once.py "$logs/cargo-build.log" "$logs/maturin.log"

phase "Python: pytest"
# The bit-for-bit tests compare with the CLI that `cargo test --workspace` built.
export ROOTFUSE_BIN="$repo/target/debug/rootfuse" ROOTFUSE_REQUIRE_CLI=1
export ROOTFUSE_WHEEL="$repo/$wheel"
export ROOTFUSE_BROAD_DIR=${ROOTFUSE_BROAD_DIR:-$repo/../shared/broad_csv}
py_status=0
.venv/bin/python -m pytest -q crates/rootfuse-py/tests || py_status=$?

phases_summary "scripts/test-all.sh"
[ "$rust_status" -eq 0 ] || { echo "cargo test failed" >&2; exit "$rust_status"; }
exit "$py_status"
