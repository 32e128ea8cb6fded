#!/usr/bin/env bash
# Every test: the Rust workspace, then the Python package in a local virtual environment
# (.venv at the repository root, created on first use: maturin, numpy and pytest from PyPI,
# the package built from crates/rootfuse-py). Exits non-zero if anything fails.
# Needs only the Rust toolchain and Python >= 3.9 with pip (and venv).
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)

echo "== cargo test --workspace"
cargo test --workspace

echo "== Python: virtual environment .venv"
python=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
    "$python" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet "maturin>=1.5,<2" numpy pytest pyarrow
# Spark 4 (applyInArrow, which needs pandas) for the fleet test in local[2] mode; about 490 MB,
# 1-3 min to install.
# venv-pack packs the virtual environment that test_spark_deploy.py ships to Spark's executor
# (the README's deployment, run as written).
.venv/bin/python -m pip install --quiet "pyspark>=4.0,<5" "pandas>=2.2,<3" venv-pack
echo "== Python: building and installing crates/rootfuse-py (maturin develop)"
# The dev profile shares target/ with the cargo test above, so only the extension itself is
# compiled here; `pip install ./crates/rootfuse-py` (release) is what users run.
VIRTUAL_ENV="$repo/.venv" .venv/bin/maturin develop --quiet --manifest-path crates/rootfuse-py/Cargo.toml

echo "== Python: pytest"
# The bit-for-bit tests compare with the CLI that `cargo test --workspace` just built.
cargo build --quiet -p rootfuse-cli
export ROOTFUSE_BIN="$repo/target/debug/rootfuse" ROOTFUSE_REQUIRE_CLI=1
export ROOTFUSE_BROAD_DIR=${ROOTFUSE_BROAD_DIR:-$repo/../shared/broad_csv}
.venv/bin/python -m pytest -q crates/rootfuse-py/tests
