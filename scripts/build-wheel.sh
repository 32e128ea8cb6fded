#!/usr/bin/env bash
# A wheel for distribution: built for the x86-64 baseline, not for this CPU.
#
# The workspace builds with `-C target-cpu=native` (.cargo/config.toml); RUSTFLAGS overrides
# that setting, so the wheel's code uses only the x86-64 baseline (SSE2) and runs on any
# x86-64 CPU. Its own target dir keeps it apart from the native builds. The package checks at
# import that the CPU has every extension the build was compiled with (rootfuse.build_info()),
# so a native build copied to an older CPU fails with ImportError, not an illegal instruction.
# It is linked by zig (the `ziglang` package) against glibc 2.17 and tagged manylinux2014
# (`manylinux_2_17_x86_64`): it installs on any x86-64 Linux since CentOS 7, not only on
# systems as new as the build machine (a plain build here is tagged manylinux_2_35).
# Output: target/wheels/rootfuse-*-cp39-abi3-manylinux_2_17_x86_64*.whl (one wheel for every
# CPython >= 3.9).
set -euo pipefail
cd "$(dirname "$0")/.."
python=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$python" -m venv .venv
.venv/bin/python -m pip install --quiet "maturin>=1.5,<2" ziglang
# maturin finds zig through `python3 -m ziglang`, so the venv's python must come first.
PATH="$(pwd)/.venv/bin:$PATH" RUSTFLAGS="-C target-cpu=x86-64" CARGO_TARGET_DIR=target/portable \
    .venv/bin/maturin build --release --zig --compatibility manylinux2014 \
    --manifest-path crates/rootfuse-py/Cargo.toml --out target/wheels "$@"
