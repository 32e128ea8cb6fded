#!/usr/bin/env bash
# Usage: fuzz/run.sh [SECONDS] [TARGET...]
# Runs every fuzz target (or the ones named) for SECONDS seconds each (default 60) on the stable toolchain without
# a sanitizer, then minimises each corpus. Crashes land in fuzz/artifacts/<target>/: minimise
# one with `cargo fuzz tmin --sanitizer none <target> <file>`, copy it into
# fuzz/corpus/<target>/ (the workspace test `fuzz_corpus` replays every file there) and fix
# the library.
set -euo pipefail
seconds="${1:-60}"
shift || true
cd "$(dirname "$0")/.."
if ! cargo fuzz --version >/dev/null 2>&1; then
    cargo install cargo-fuzz --locked
fi
targets=(csv_reader filter_update rls_forms batch_engine)
if [ "$#" -gt 0 ]; then
    targets=("$@")
fi
mkdir -p fuzz/target
status=0
for t in "${targets[@]}"; do
    mkdir -p "fuzz/corpus/$t"
    echo "== $t: ${seconds}s"
    # -max_len keeps inputs in the range the bodies read (they stop at a step cap anyway).
    if ! cargo fuzz run --sanitizer none --release "$t" "fuzz/corpus/$t" -- \
        -max_total_time="$seconds" -max_len=4096 -print_final_stats=1 2>&1 | tee "fuzz/target/$t.log"; then
        echo "!! $t found a crash (see fuzz/artifacts/$t/)"
        status=1
    fi
    grep -E 'stat::number_of_executed_units' "fuzz/target/$t.log" || true
done
for t in "${targets[@]}"; do
    # cmin renames what it keeps to content hashes and drops what adds no coverage; the named
    # regression inputs are documented (ROBUSTNESS.md), so they are put back afterwards.
    keep="$(mktemp -d)"
    find "fuzz/corpus/$t" -maxdepth 1 -name 'regression-*' -exec cp {} "$keep/" \;
    cargo fuzz cmin --sanitizer none --release "$t" "fuzz/corpus/$t" -- -max_len=4096 >/dev/null 2>&1 || true
    cp "$keep"/regression-* "fuzz/corpus/$t/" 2>/dev/null || true
    rm -rf "$keep"
done
exit "$status"
