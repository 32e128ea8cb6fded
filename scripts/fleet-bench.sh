#!/usr/bin/env bash
# Fleet I/O figures of docs/fleets.md's "Fleet I/O" table, whole-process figures from /usr/bin/time:
# 1. Parquet in and out against CSV in and out on the same 1e6 samples (100 devices: one
#    Parquet file vs 100 CSV files), PAIRS interleaved pairs (P C P C ...), each pair's
#    ratio of wall and CPU time, and the medians;
# 2. peak memory of `rootfuse run` for 1e6 and 1e7 rows, Parquet (100 devices) and CSV (one
#    recording), which streaming keeps flat; and `--offline` on the 1e6-row CSV.
#
# Usage: scripts/fleet-bench.sh [BIN] [SCRATCH]   (BIN default target/release/rootfuse;
# SCRATCH default /tmp/rootfuse-fleet-bench, about 3 GB, removed at the end)
# Environment: PAIRS (default 5); FILTER (default mahony); FLAGSHIP_FLEET=1 also runs the
# 1000 devices x 10 min x 100 Hz flagship fleet (5.9 GB of Parquet).
set -euo pipefail
cd "$(dirname "$0")/.."
bin=${1:-target/release/rootfuse}
scratch=${2:-/tmp/rootfuse-fleet-bench}
pairs=${PAIRS:-5}
filter=${FILTER:-mahony}
rm -rf "$scratch"
mkdir -p "$scratch"
trap 'rm -rf "$scratch"' EXIT

# measure LABEL COMMAND...: runs it once, prints label, wall s, CPU s, peak RSS MB and the
# run's summary line; leaves "wall cpu" in $scratch/last.
measure() {
    local label=$1
    shift
    /usr/bin/time -f '%e %U %S %M' -o "$scratch/time" "$@" >"$scratch/stdout" 2>"$scratch/stderr"
    read -r wall user sys rss <"$scratch/time"
    local cpu
    cpu=$(awk -v u="$user" -v s="$sys" 'BEGIN { printf "%.2f", u + s }')
    echo "$wall $cpu" >"$scratch/last"
    printf '%-48s wall %7.2f s  cpu %7.2f s  peak RSS %5.0f MB  %s\n' "$label" "$wall" "$cpu" \
        "$(awk -v k="$rss" 'BEGIN { print k / 1024 }')" "$(head -1 "$scratch/stdout")"
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

echo "== Parquet in+out vs CSV in+out, $filter, the same 1e6 samples (100 devices x 100 s x 100 Hz)"
"$bin" simulate --devices 100 --seconds 100 --rate 100 --out "$scratch/same.parquet" >/dev/null
mkdir -p "$scratch/csv-in"
to_csv "$scratch/same.parquet" "$scratch/csv-in"
: >"$scratch/pairs"
for i in $(seq "$pairs"); do
    measure "pair $i: parquet in+out, one file" \
        "$bin" run "$scratch/same.parquet" --filter "$filter" --out "$scratch/p-out"
    p=$(cat "$scratch/last")
    measure "pair $i: csv in+out, 100 files" \
        "$bin" run "$scratch/csv-in" --filter "$filter" --out "$scratch/c-out"
    echo "$p $(cat "$scratch/last")" >>"$scratch/pairs"
done
# Per pair: CSV time / Parquet time = how many times the samples/s of CSV Parquet reaches.
summary() { # column: "median (min, max)" of that column of the per-pair ratios
    sort -g -k"$1" "$scratch/ratios" | awk -v k="$1" '{ v[NR] = $k }
        END { printf "%.2fx (min %.2f, max %.2f)", v[int((NR + 1) / 2)], v[1], v[NR] }'
}
awk '{ printf "%.4f %.4f\n", $3 / $1, $4 / $2 }' "$scratch/pairs" >"$scratch/ratios"
echo "Parquet samples/s over CSV samples/s, $pairs pairs: wall $(summary 1), cpu $(summary 2)"
rm -rf "$scratch/csv-in" "$scratch/p-out" "$scratch/c-out" "$scratch/same.parquet"

echo "== peak memory, 1e6 and 1e7 rows"
for rows in 1000000 10000000; do
    seconds=$((rows / 100 / 100))
    fleet="$scratch/fleet-$rows.parquet"
    "$bin" simulate --devices 100 --seconds "$seconds" --rate 100 --out "$fleet" >/dev/null
    measure "parquet -> parquet, $filter, $rows rows" \
        "$bin" run "$fleet" --filter "$filter" --out "$scratch/o-parquet-$rows"
    measure "parquet -> csv, $filter, $rows rows" \
        "$bin" run "$fleet" --filter "$filter" --format csv --out "$scratch/o-csv-$rows"
    rm -rf "$fleet" "$scratch/o-parquet-$rows" "$scratch/o-csv-$rows"
done
# The same 1e6 and 1e7 samples as one CSV recording (streamed: peak RSS does not grow with it).
for rows in 1000000 10000000; do
    seconds=$((rows / 100))
    csv="$scratch/one-$rows.csv"
    "$bin" simulate --devices 1 --seconds "$seconds" --rate 100 --out "$scratch/one.parquet" >/dev/null
    to_csv "$scratch/one.parquet" "$csv"
    rm -f "$scratch/one.parquet"
    measure "csv -> csv, $filter, one recording of $rows" \
        "$bin" run "$csv" --filter "$filter" --out "$scratch/o-one-$rows"
    if [ "$rows" = 1000000 ]; then
        measure "csv --offline, sqrt-eskf, one recording of $rows" \
            "$bin" run "$csv" --filter sqrt-eskf --offline --out "$scratch/o-off-$rows"
    fi
    rm -rf "$csv" "$scratch/o-one-$rows" "$scratch/o-off-$rows"
done
if [ "${FLAGSHIP_FLEET:-0}" = 1 ]; then
    "$bin" simulate --devices 1000 --seconds 600 --rate 100 --out "$scratch/big.parquet" >/dev/null
    measure "flagship, 1000 devices x 600 s x 100 Hz" \
        "$bin" run "$scratch/big.parquet" --filter flagship --out "$scratch/big-out"
fi
