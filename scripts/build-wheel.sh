#!/usr/bin/env bash
# A wheel for distribution: built for the x86-64 baseline, not for this CPU.
#
# The workspace builds with `-C target-cpu=native` (.cargo/config.toml); RUSTFLAGS overrides
# that setting, so the wheel's code uses only the x86-64 baseline (SSE2) and runs on any
# x86-64 CPU. Its own target dir keeps it apart from the native builds. The package checks at
# import that the CPU has every extension the build was compiled with (rootfuse.build_info()),
# so a native build copied to an older CPU fails with ImportError, not an illegal instruction.
# Output: target/wheels/rootfuse-*-cp39-abi3-*.whl (one wheel for every CPython >= 3.9).
set -euo pipefail
cd "$(dirname "$0")/.."
python=${PYTHON:-python3}
if [ ! -x .venv/bin/maturin ]; then
    [ -x .venv/bin/python ] || "$python" -m venv .venv
    .venv/bin/python -m pip install --quiet "maturin>=1.5,<2"
fi
RUSTFLAGS="-C target-cpu=x86-64" CARGO_TARGET_DIR=target/portable \
    .venv/bin/maturin build --release --manifest-path crates/rootfuse-py/Cargo.toml --out target/wheels "$@"
