#!/usr/bin/env bash
# Peak memory of `rootfuse simulate` and of `rootfuse run` on the Arrow IPC layouts that used
# to hold a whole record batch (issue 26, item 6), 1e7 rows (10 devices x 10000 s x 100 Hz):
#   simulate to Parquet; run on that Parquet; run on the same rows as an Arrow IPC file and
#   as an Arrow IPC stream, each written as ONE record batch (the `one_batch` example).
# Whole-process peak RSS from /usr/bin/time (GNU time's %M, as `time -v` reports it).
#
# Usage: scripts/fleet-memory.sh [BIN] [SCRATCH]   (BIN default target/release/rootfuse;
# SCRATCH default /tmp/rootfuse-fleet-memory, about 4 GB, removed at the end)
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/rootfuse}
scratch=${2:-/tmp/rootfuse-fleet-memory}
rm -rf "$scratch"
mkdir -p "$scratch"
trap 'rm -rf "$scratch"' EXIT
one_batch=${ONE_BATCH:-target/release/examples/one_batch}
[ -x "$one_batch" ] || cargo build --release -p rootfuse-columnar --example one_batch >/dev/null 2>&1

measure() {
    local label=$1
    shift
    /usr/bin/time -f '%e %U %S %M' -o "$scratch/time" "$@" >"$scratch/stdout" 2>"$scratch/stderr"
    read -r wall user sys rss <"$scratch/time"
    printf '%-44s wall %7.2f s  cpu %7.2f s  peak RSS %5.0f MB  %s\n' "$label" "$wall" \
        "$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')" \
        "$(awk -v k="$rss" 'BEGIN { print k / 1024 }')" "$(head -1 "$scratch/stdout")"
}

measure "simulate 10 x 10000 s, Parquet" \
    "$bin" simulate --devices 10 --seconds 10000 --out "$scratch/fleet.parquet"
measure "simulate 10 x 10000 s, Arrow IPC" \
    "$bin" simulate --devices 10 --seconds 10000 --out "$scratch/fleet-sim.arrow"
rm -f "$scratch/fleet-sim.arrow"
"$one_batch" "$scratch/fleet.parquet" "$scratch/one.arrow" >/dev/null
"$one_batch" "$scratch/fleet.parquet" "$scratch/one.arrows" --stream >/dev/null
measure "run Parquet (row groups), Mahony 9D" \
    "$bin" run "$scratch/fleet.parquet" --filter mahony --out "$scratch/o-parquet"
measure "run Arrow IPC file, one batch of 1e7 rows" \
    "$bin" run "$scratch/one.arrow" --filter mahony --out "$scratch/o-file"
measure "run Arrow IPC stream, one batch of 1e7 rows" \
    "$bin" run "$scratch/one.arrows" --filter mahony --out "$scratch/o-stream"
