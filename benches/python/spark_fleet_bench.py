"""Spark's cost of running a fleet through rootfuse, as ratios measured in one run: each
layout of `rootfuse.arrow.run_spark` against the same Spark job with a function that returns
zeros of the same schema (Spark's own floor: scan, shuffle, Arrow both ways, write), against
the CLI (`rootfuse run` on the same Parquet), and `local[1]` against `local[2]`.

    cargo build --release -p rootfuse-cli
    (cd crates/rootfuse-py && VIRTUAL_ENV=$PWD/../../.venv ../../.venv/bin/maturin develop --release)
    .venv/bin/python benches/python/spark_fleet_bench.py [--devices 50] [--seconds 600] [--repeats 2]

Figures are CPU seconds (user + system) of every process of the Spark job (the JVM, the
Python driver and workers, reaped children included), measured as the difference before and
after each job in one warm SparkSession (one untimed pass first), best of `--repeats`
interleaved passes. The clustered layout reads the fleet rewritten once by
`cluster_by_device` (not counted). Devices 0, N/2 and N-1 of every rootfuse job are checked
equal to the CLI's estimates bit for bit.
"""

import argparse
import json
import os
import pathlib
import shutil
import subprocess
import sys
import time

REPO = pathlib.Path(__file__).resolve().parents[2]
JOBS = ("bucket", "bucket zeros", "clustered", "clustered zeros")


def tree_cpu(root):
    """CPU seconds (user + system, reaped children's included) of `root` and every process
    under it: the JVM and Python workers that /usr/bin/time on the driver does not see."""
    parent, cpu = {}, {}
    tick = os.sysconf("SC_CLK_TCK")
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = open(f"/proc/{entry}/stat").read()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2 :].split()
        pid = int(entry)
        parent[pid] = int(fields[1])
        cpu[pid] = sum(int(v) for v in fields[11:15]) / tick
    total = 0.0
    for pid, c in cpu.items():
        p = pid
        while p in parent and p != root and p > 1:
            p = parent[p]
        if p == root:
            total += c
    return total


def zeros_functions(ra, filter_name):
    """`batches_function` and `table_function` stand-ins that return zeros in the estimates'
    schema: what Spark costs without the filter."""
    import numpy as np
    import pyarrow as pa

    names = ra.spark_schema(filter_name).split(", ")[1:]
    names = [n.split()[0] for n in names]

    def zeros(batch):
        n = batch.num_rows
        cols = [batch.column(ra.DEVICE).cast(pa.int64()), batch.column("t")]
        cols += [pa.array(np.zeros(n)) for _ in names[1:]]
        return pa.RecordBatch.from_arrays(cols, names=[ra.DEVICE, *names])

    def batches_function(_filter, **_options):
        def fn(batches):
            for b in batches:
                yield zeros(b)
        return fn

    def table_function(_filter, **_options):
        def fn(table):
            table = table.drop_columns([c for c in table.column_names if c == "_rootfuse_bucket"])
            return pa.Table.from_batches([zeros(b) for b in table.combine_chunks().to_batches()])
        return fn

    return batches_function, table_function


def spark_jobs(args):
    """The Spark side, in its own process: every job of JOBS `--repeats` times, interleaved,
    after one untimed pass; prints the best CPU and wall seconds of each as JSON."""
    from pyspark.sql import SparkSession

    import rootfuse.arrow as ra

    os.environ["PYSPARK_PYTHON"] = sys.executable
    os.environ["SPARK_LOCAL_IP"] = "127.0.0.1"
    spark = (
        SparkSession.builder.master(args.master)
        .appName("rootfuse-fleet-bench")
        .config("spark.ui.enabled", "false")
        .config("spark.driver.host", "127.0.0.1")
        .config("spark.driver.bindAddress", "127.0.0.1")
        .config("spark.driver.memory", args.driver_memory)
        .config("spark.local.dir", str(args.scratch / "spark-local"))
        .getOrCreate()
    )
    spark.sparkContext.setLogLevel("ERROR")
    real = (ra.batches_function, ra.table_function)
    zeros = zeros_functions(ra, args.filter)
    sources = {"bucket": args.scratch / "fleet.parquet", "clustered": args.scratch / "clustered.parquet"}
    best = {job: {"cpu_s": float("inf"), "wall_s": float("inf")} for job in JOBS}
    me = os.getpid()
    for rep in range(args.repeats + 1):
        for job in JOBS:
            layout = job.split()[0]
            # run_spark looks both functions up at call time: the stand-ins replace the
            # filter and nothing else of the job.
            ra.batches_function, ra.table_function = zeros if job.endswith("zeros") else real
            df = spark.read.parquet(str(sources[layout]))
            est = ra.run_spark(df, args.filter, layout=layout)
            out = args.scratch / "spark-out" / job.replace(" ", "-")
            cpu0, t0 = tree_cpu(me), time.perf_counter()
            est.write.mode("overwrite").parquet(str(out))
            wall, cpu = time.perf_counter() - t0, tree_cpu(me) - cpu0
            if rep > 0:
                best[job]["cpu_s"] = min(best[job]["cpu_s"], cpu)
                best[job]["wall_s"] = min(best[job]["wall_s"], wall)
    ra.batches_function, ra.table_function = real
    spark.stop()
    print(json.dumps(best))


def check_equal(args, job, devices):
    """Devices `devices` of a job's output equal the CLI's bit for bit."""
    import numpy as np
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    cols = ["device", "t", "qw", "qx", "qy", "qz"]
    cli = pq.read_table(args.scratch / "cli-out" / "fleet.parquet", columns=cols)
    spark = pq.read_table(args.scratch / "spark-out" / job, columns=cols)
    assert cli.num_rows == spark.num_rows, (job, cli.num_rows, spark.num_rows)
    for d in devices:
        a = cli.filter(pc.equal(cli["device"], d)).sort_by("t")
        b = spark.filter(pc.equal(spark["device"], d)).sort_by("t")
        for c in cols[1:]:
            x, y = a[c].to_numpy(), b[c].to_numpy()
            assert x.size > 0 and np.array_equal(x, y), f"{job}: device {d}, column {c} differs"


def cli_cpu(cmd):
    """CPU seconds (user + system, all threads) of a command."""
    before = os.times()
    subprocess.run(cmd, check=True, capture_output=True)
    after = os.times()
    return (after.children_user - before.children_user) + (after.children_system - before.children_system)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--devices", type=int, default=50)
    p.add_argument("--seconds", type=float, default=600)
    p.add_argument("--rate", type=float, default=100)
    p.add_argument("--filter", default="flagship")
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--masters", default="local[2],local[1]")
    p.add_argument("--bin", type=pathlib.Path, default=REPO / "target/release/rootfuse")
    p.add_argument("--scratch", type=pathlib.Path, default=REPO / "target" / "spark-bench")
    p.add_argument("--driver-memory", default="2g")
    p.add_argument("--keep", action="store_true", help="keep the scratch folder")
    p.add_argument("--spark-jobs", action="store_true", help=argparse.SUPPRESS)
    p.add_argument("--master", default="local[2]", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.spark_jobs:
        spark_jobs(args)
        return
    import pyarrow.parquet as pq

    import rootfuse.arrow as ra

    shutil.rmtree(args.scratch, ignore_errors=True)
    args.scratch.mkdir(parents=True)
    try:
        fleet = args.scratch / "fleet.parquet"
        subprocess.run([str(args.bin), "simulate", "--devices", str(args.devices), "--seconds",
                        str(args.seconds), "--rate", str(args.rate), "--out", str(fleet)],
                       check=True, capture_output=True)
        rows = int(args.devices * args.seconds * args.rate)
        ra.cluster_by_device(pq.read_table(fleet), str(args.scratch / "clustered.parquet"))
        run = [str(args.bin), "run", str(fleet), "--filter", args.filter, "--out", str(args.scratch / "cli-out")]
        cli = min(cli_cpu(run + ["--force"]) for _ in range(args.repeats))
        print(f"fleet: {args.devices} devices x {args.seconds:g} s x {args.rate:g} Hz = {rows:.3g} rows, "
              f"{args.filter}; CLI `rootfuse run`: {cli:.2f} CPU-s")
        results = {}
        for master in args.masters.split(","):
            job = [sys.executable, __file__, "--spark-jobs", "--master", master, "--scratch",
                   str(args.scratch), "--filter", args.filter, "--repeats", str(args.repeats),
                   "--driver-memory", args.driver_memory]
            out = subprocess.run(job, check=True, capture_output=True, text=True).stdout
            results[master] = json.loads(out.strip().splitlines()[-1])
            for name in ("bucket", "clustered"):
                check_equal(args, name, [0, args.devices // 2, args.devices - 1])
        print("| master | layout | rootfuse CPU-s (wall s) | zeros CPU-s (wall s) | rootfuse / zeros | CLI / rootfuse |")
        print("|---|---|---|---|---|---|")
        for master, r in results.items():
            for layout in ("bucket", "clustered"):
                ours, zero = r[layout], r[f"{layout} zeros"]
                print(f"| `{master}` | {layout} | {ours['cpu_s']:.2f} ({ours['wall_s']:.2f}) | "
                      f"{zero['cpu_s']:.2f} ({zero['wall_s']:.2f}) | {ours['cpu_s'] / zero['cpu_s']:.2f} | "
                      f"{cli / ours['cpu_s']:.3f} |")
        if len(results) > 1:
            (a, ra_), (b, rb) = list(results.items())[:2]
            for layout in ("bucket", "clustered"):
                print(f"{layout}: CPU-s {b} / {a} = {rb[layout]['cpu_s'] / ra_[layout]['cpu_s']:.2f}, "
                      f"wall {b} / {a} = {rb[layout]['wall_s'] / ra_[layout]['wall_s']:.2f}")
        print("devices 0, N/2, N-1 of every rootfuse job equal the CLI's bit for bit")
    finally:
        if not args.keep:
            shutil.rmtree(args.scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
