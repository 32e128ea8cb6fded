#!/usr/bin/env bash
# Fleet I/O figures of README's "Fleets" table: peak memory of `rootfuse run` for 1e6 and 1e7
# rows (CSV and Parquet: streaming keeps it flat), and end-to-end samples/s of the same data as
# Parquet and as CSV. Whole-process figures from /usr/bin/time -v.
#
# Usage: scripts/fleet-bench.sh [BIN] [SCRATCH]   (BIN default target/release/rootfuse;
# SCRATCH default /tmp/rootfuse-fleet-bench, about 4 GB, removed at the end)
# Optional: FLAGSHIP_FLEET=1 also runs the 1000 devices x 10 min x 100 Hz flagship fleet.
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/rootfuse}
scratch=${2:-/tmp/rootfuse-fleet-bench}
rm -rf "$scratch"
mkdir -p "$scratch"
trap 'rm -rf "$scratch"' EXIT

measure() { # label, command...: prints label, wall s, peak RSS MB and the run's summary line
    local label=$1
    shift
    /usr/bin/time -v "$@" >"$scratch/stdout" 2>"$scratch/time"
    local wall rss
    wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$scratch/time")
    rss=$(awk -F': ' '/Maximum resident set size/ {printf "%.0f", $2 / 1024}' "$scratch/time")
    printf '%-44s wall %8s  peak RSS %6s MB  %s\n' "$label" "$wall" "$rss" "$(head -1 "$scratch/stdout")"
}

# A fleet file as CSV recordings, one per device (pyarrow from .venv, which
# scripts/test-all.sh makes): to_csv FLEET OUT.csv (one device) or to_csv FLEET DIR (many).
to_csv() {
    .venv/bin/python - "$1" "$2" <<'PY'
import os, sys
import pyarrow.compute as pc, pyarrow.csv as pcsv, pyarrow.parquet as pq
table = pq.read_table(sys.argv[1]).drop(["qw", "qx", "qy", "qz"])
devices = sorted(set(table["device"].to_pylist()))
for k in devices:
    rows = table.filter(pc.equal(table["device"], k)).drop(["device"])
    out = sys.argv[2] if len(devices) == 1 else os.path.join(sys.argv[2], f"dev{k:04}.csv")
    pcsv.write_csv(rows, out, pcsv.WriteOptions(quoting_header="none"))
PY
}

# 1e6 and 1e7 rows as fleets of 100 devices at 100 Hz.
for rows in 1000000 10000000; do
    seconds=$((rows / 100 / 100))
    fleet="$scratch/fleet-$rows.parquet"
    "$bin" simulate --devices 100 --seconds "$seconds" --rate 100 --out "$fleet" >/dev/null
    measure "parquet -> parquet, mahony, $rows rows" \
        "$bin" run "$fleet" --filter mahony --out "$scratch/o-parquet-$rows"
    measure "parquet -> csv, mahony, $rows rows" \
        "$bin" run "$fleet" --filter mahony --format csv --out "$scratch/o-csv-$rows"
done
# The same 1e6 and 1e7 samples as one CSV recording (the run used to read it whole).
for rows in 1000000 10000000; do
    seconds=$((rows / 100))
    csv="$scratch/one-$rows.csv"
    "$bin" simulate --devices 1 --seconds "$seconds" --rate 100 --out "$scratch/one.parquet" >/dev/null
    to_csv "$scratch/one.parquet" "$csv"
    measure "csv -> csv, mahony, one recording of $rows" \
        "$bin" run "$csv" --filter mahony --out "$scratch/o-one-$rows"
    measure "csv --offline, sqrt-eskf, one recording of $rows" \
        "$bin" run "$csv" --filter sqrt-eskf --offline --out "$scratch/o-off-$rows"
    rm -f "$csv"
done
# CSV in and out vs Parquet in and out on the same fleet (1e7 rows).
"$bin" simulate --devices 100 --seconds 1000 --rate 100 --out "$scratch/same.parquet" >/dev/null
mkdir -p "$scratch/csv-in"
to_csv "$scratch/same.parquet" "$scratch/csv-in"
measure "parquet in+out, mahony, 1e7 rows, 100 devices" \
    "$bin" run "$scratch/same.parquet" --filter mahony --out "$scratch/p-out"
measure "csv in+out, mahony, 1e7 rows, 100 files" \
    "$bin" run "$scratch/csv-in" --filter mahony --out "$scratch/c-out"
if [ "${FLAGSHIP_FLEET:-0}" = 1 ]; then
    "$bin" simulate --devices 1000 --seconds 600 --rate 100 --out "$scratch/big.parquet" >/dev/null
    measure "flagship, 1000 devices x 600 s x 100 Hz" \
        "$bin" run "$scratch/big.parquet" --filter flagship --out "$scratch/big-out"
fi
