"""The batch engine's speed behind each door, side by side in one run: NumPy (`run_many`),
Arrow (`rootfuse.arrow.estimate_table`) and the CLI, as ratios (the issue "Fleets at the
engine's speed through every door").

    cargo build --release -p rootfuse-cli
    (cd crates/rootfuse-py && VIRTUAL_ENV=$PWD/../../.venv ../../.venv/bin/maturin develop --release)
    .venv/bin/python benches/python/fleet_doors.py [--channels 4096] [--samples 2000] [--rows 1e7] [--docs]

1. `run_many` on C x N channels of tiled BROAD data (trial 07, or a simulated recording when
   the folder is absent) against `rootfuse throughput` lanes-f32x8-threads (synthetic data in
   cache, filters only), Mahony 6D and the flagship 9D. The reference is the slower of the
   CLI's time and the time NumPy needs to read the same input arrays once (`sum` over each):
   Mahony from float64 arrays is bound by reading its input, not by the filter.
   Targets: final state >= 0.9, quaternion series >= 0.5 (float64 series, and float32 ones
   with `dtype="float32"`, and into float32 `out=` arrays reused from call to call), float32
   input no slower than float64. One row without a target: the final state given sample
   times `t=` (a `(C, N)` array) against the same call given one step `dt`.
2. `estimate_table` on a fleet Parquet of `--rows` rows (flagship, reading counted) against
   `rootfuse run` on that file, samples per CPU-second (user + system, every thread): given
   the file's path (read in Rust), given a pyarrow Table read whole first, and given a
   `pyarrow.dataset` (its batches streamed as pyarrow reads them). Target >= 0.9.

Every time is the best of `--repeats` interleaved runs. `--docs [PAGE]` rewrites the table
between the `fleet_doors` markers in PAGE (default docs/performance.md), under one line naming
the machine, the commit and the command. Spark is measured by spark_fleet_bench.py.
"""

import argparse
import json
import os
import pathlib
import platform
import subprocess
import sys
import tempfile
import time

import numpy as np

import docs_page
import rootfuse as rf

REPO = pathlib.Path(__file__).resolve().parents[2]
CLI = REPO / "target" / "release" / "rootfuse"
BROAD = pathlib.Path(os.environ.get("ROOTFUSE_BROAD_DIR", REPO.parent / "shared" / "broad_csv"))


def load_trial():
    path = BROAD / "07_undisturbed_fast_rotation_B.csv"
    if path.exists():
        rec = rf.read_csv(path)
        return rec, path.name
    rec = rf.simulate("fast-rotation", seed=1, duration_s=120.0, rate_hz=286.0)
    return rec, "simulated fast-rotation 120 s"


def cli_throughput(filt, dof, channels, samples):
    out = subprocess.run(
        [str(CLI), "throughput", "--filter", filt, "--dof", str(dof), "--channels", str(channels),
         "--samples", str(samples), "--json"],
        check=True, capture_output=True, text=True).stdout
    rep = json.loads(out[out.index("{"):])
    return next(r for r in rep["results"] if r["mode"] == "lanes-f32x8-threads")["ns_per_update"]


def best(fns, repeats):
    """Best time of each function, runs interleaved."""
    times = {k: float("inf") for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t0 = time.perf_counter()
            fn()
            times[k] = min(times[k], time.perf_counter() - t0)
    return times


def numpy_rows(args, rows):
    rec, name = load_trial()
    C, N = args.channels, args.samples
    base = min(len(rec["t"]), N)
    idx = (np.arange(C)[:, None] * 37 + np.arange(N)[None, :]) % base
    dt = float(np.median(np.diff(rec["t"])))
    times = np.ascontiguousarray(np.broadcast_to(np.arange(N) * dt, (C, N)))
    updates = C * N
    for filt, dof in (("mahony", 6), ("flagship", 9)):
        arrays = {
            "float64": [np.ascontiguousarray(rec[k][idx]) for k in (("gyr", "acc") if dof == 6 else ("gyr", "acc", "mag"))],
        }
        arrays["float32"] = [a.astype(np.float32) for a in arrays["float64"]]
        cli = cli_throughput(filt, dof, C, N)
        fns = {}
        for dtype, arrs in arrays.items():
            fns[f"read {dtype}"] = lambda arrs=arrs: [a.sum() for a in arrs]
            mag = arrs[2] if dof == 9 else None
            fns[f"final {dtype}"] = lambda arrs=arrs, mag=mag: rf.run_many(
                filt, arrs[0], arrs[1], mag, dt, dof=dof, precision="f32", series=False)
            if dtype == "float32":
                # The same channels with their sample times, a (C, N) array, not one step.
                fns["times float32"] = lambda arrs=arrs, mag=mag: rf.run_many(
                    filt, arrs[0], arrs[1], mag, t=times, dof=dof, precision="f32", series=False)
            fns[f"series {dtype}"] = lambda arrs=arrs, mag=mag: rf.run_many(
                filt, arrs[0], arrs[1], mag, dt, dof=dof, precision="f32", series=True,
                bias=False, flags=False)
            fns[f"series32 {dtype}"] = lambda arrs=arrs, mag=mag: rf.run_many(
                filt, arrs[0], arrs[1], mag, dt, dof=dof, precision="f32", series=True,
                bias=False, flags=False, dtype="float32")
            # The same series into arrays of the caller's, reused from run to run: the first
            # run maps their pages, the best of the runs is a reuse.
            reused = {"quat": np.empty((C, N, 4), np.float32)}
            fns[f"series32out {dtype}"] = lambda arrs=arrs, mag=mag, reused=reused: rf.run_many(
                filt, arrs[0], arrs[1], mag, dt, dof=dof, precision="f32", series=True,
                bias=False, flags=False, out=reused)
        t = best(fns, args.repeats)
        ns = {k: v * 1e9 / updates for k, v in t.items()}
        for dtype in ("float64", "float32"):
            ref = max(cli, ns[f"read {dtype}"])
            for what, target in (("final", 0.9), ("series", 0.5), ("series32", 0.5),
                                 ("series32out", 0.5)):
                ours = ns[f"{what} {dtype}"]
                label = {"final": "final state", "series": "quaternion series",
                         "series32": "quaternion series, `dtype=\"float32\"`",
                         "series32out": "float32 quaternion series into `out=` arrays reused"}[what]
                rows.append((f"`run_many` {filt} {dof}D, {dtype} in, {label}", ours, ref,
                             ref / ours, target,
                             f"ref = max(CLI {cli:.1f}, NumPy read {ns[f'read {dtype}']:.1f})"))
        rows.append((f"`run_many` {filt} {dof}D, float32 in, sample times `t=` (C, N), final state",
                     ns["times float32"], ns["final float32"],
                     ns["final float32"] / ns["times float32"], None,
                     "reference: the same call with one step `dt`"))
        rows.append((f"`run_many` {filt} {dof}D: float32 vs float64 input, final state",
                     ns["final float32"], ns["final float64"],
                     ns["final float64"] / ns["final float32"], 1.0, "ratio >= 1: float32 no slower"))
    return name


def cpu_of(cmd):
    """CPU seconds (user + system, all threads and children) of a command."""
    before = os.times()
    subprocess.run(cmd, check=True, capture_output=True)
    after = os.times()
    return (after.children_user - before.children_user) + (after.children_system - before.children_system)


# The file given as a path: read in Rust as the CLI reads it.
ESTIMATE = """
import sys, rootfuse.arrow as ra
out = ra.estimate_table(sys.argv[1], "flagship")
assert out.num_rows == int(sys.argv[2])
"""

# The same file read whole by pyarrow first, then the table estimated.
ESTIMATE_TABLE = """
import sys, pyarrow.parquet as pq, rootfuse.arrow as ra
cols = ["device", "t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz"]
table = pq.read_table(sys.argv[1], columns=cols)
out = ra.estimate_table(table, "flagship")
assert out.num_rows == int(sys.argv[2])
"""

# The same file as a pyarrow dataset: its batches streamed into Rust as pyarrow reads them.
ESTIMATE_DATASET = """
import sys, pyarrow.dataset as ds, rootfuse.arrow as ra
out = ra.estimate_table(ds.dataset(sys.argv[1]), "flagship")
assert out.num_rows == int(sys.argv[2])
"""


def arrow_rows(args, rows, work):
    n = int(args.rows)
    devices = 100
    seconds = n / devices / 100.0
    fleet = work / "fleet.parquet"
    subprocess.run([str(CLI), "simulate", "--devices", str(devices), "--seconds", str(seconds),
                    "--out", str(fleet)], check=True, capture_output=True)
    cli_cpu, path_cpu, table_cpu, dataset_cpu = (float("inf"),) * 4
    for _ in range(args.repeats):
        out = work / "out"
        cli_cpu = min(cli_cpu, cpu_of([str(CLI), "run", str(fleet), "--filter", "flagship",
                                       "--out", str(out), "--force"] if _cli_has_force() else
                                      [str(CLI), "run", str(fleet), "--filter", "flagship", "--out", str(out)]))
        subprocess.run(["rm", "-rf", str(out)], check=True)
        path_cpu = min(path_cpu, cpu_of([sys.executable, "-c", ESTIMATE, str(fleet), str(n)]))
        table_cpu = min(table_cpu, cpu_of([sys.executable, "-c", ESTIMATE_TABLE, str(fleet), str(n)]))
        dataset_cpu = min(dataset_cpu, cpu_of([sys.executable, "-c", ESTIMATE_DATASET, str(fleet), str(n)]))
    rows.append((f"`estimate_table(path)` flagship, {n:.0e} rows from Parquet (CPU s)", path_cpu, cli_cpu,
                 cli_cpu / path_cpu, 0.9, "samples per CPU-second vs `rootfuse run` on the file"))
    rows.append((f"`estimate_table(pq.read_table(path))` flagship, {n:.0e} rows (CPU s)", table_cpu, cli_cpu,
                 cli_cpu / table_cpu, 0.9, "pyarrow reads the whole table first"))
    rows.append((f"`estimate_table(pyarrow.dataset.dataset(path))` flagship, {n:.0e} rows (CPU s)", dataset_cpu,
                 cli_cpu, cli_cpu / dataset_cpu, 0.9, "pyarrow streams its batches as it reads them"))


def _cli_has_force():
    out = subprocess.run([str(CLI), "run", "--help"], capture_output=True, text=True).stdout
    return "--force" in out


def table(rows, data):
    lines = [f"Data: {data}; best of the runs, ns per channel-update (CPU s for the Arrow row).", "",
             "| door | ours | reference | ratio | target | note |", "|---|---|---|---|---|---|"]
    for what, ours, ref, ratio, target, note in rows:
        if target is None:
            lines.append(f"| {what} | {ours:.2f} | {ref:.2f} | {ratio:.2f} | none | {note} |")
            continue
        mark = "met" if ratio >= target else "**missed**"
        lines.append(f"| {what} | {ours:.2f} | {ref:.2f} | {ratio:.2f} | >= {target} ({mark}) | {note} |")
    return "\n".join(lines)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--channels", type=int, default=4096)
    p.add_argument("--samples", type=int, default=2000)
    p.add_argument("--rows", type=float, default=1e7)
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--skip-arrow", action="store_true")
    p.add_argument("--docs", nargs="?", const="docs/performance.md", metavar="PAGE",
                   help="rewrite the fleet_doors table in PAGE (default docs/performance.md)")
    args = p.parse_args()
    if not CLI.exists():
        sys.exit(f"{CLI} missing: cargo build --release -p rootfuse-cli")
    rows = []
    data = numpy_rows(args, rows)
    if not args.skip_arrow:
        with tempfile.TemporaryDirectory(dir=REPO / "target") as d:
            arrow_rows(args, rows, pathlib.Path(d))
    commit = docs_page.commit()
    command = (f"benches/python/fleet_doors.py --channels {args.channels} --samples {args.samples} "
               f"--rows {args.rows:g} --repeats {args.repeats}" + (" --skip-arrow" if args.skip_arrow else ""))
    source = f"{platform.node()}, commit {commit}, `{command}`."
    text = source + "\n\n" + table(rows, f"{args.channels} x {args.samples} channels of {data}")
    print(text)
    if args.docs:
        docs_page.write_between_markers(args.docs, "fleet_doors", text)


if __name__ == "__main__":
    main()
