"""A simulated fleet through `rootfuse run` (the CLI) and through Spark `local[2]`
(`rootfuse.arrow.run_spark`, `groupBy("device").applyInArrow`) on the same machine, one after
the other: wall and CPU time, peak memory (largest single process), and Spark's throughput
as a fraction of the CLI's. A few devices are checked equal bit for bit between the two.

    cargo build --release -p rootfuse-cli
    (cd crates/rootfuse-py && VIRTUAL_ENV=$PWD/../../.venv ../../.venv/bin/maturin develop --release)
    .venv/bin/python benches/python/spark_fleet_bench.py [--devices 200] [--seconds 600]

The issue's fleet is 1000 devices x 600 s x 100 Hz (6e7 rows, 6.7 GB of Parquet, and
Spark's shuffle and both outputs as much again): give --devices 1000 where the disk allows.
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


def timed(cmd):
    """Runs `cmd` under /usr/bin/time: (wall s, cpu s, peak RSS MB, stdout)."""
    with open(os.devnull, "w") as devnull:
        proc = subprocess.run(
            ["/usr/bin/time", "-f", "%e %U %S %M", "-o", "/dev/stderr", *cmd],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            check=False,
        )
    if proc.returncode != 0:
        sys.exit(f"failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr}")
    wall, user, sys_s, rss = proc.stderr.strip().splitlines()[-1].split()
    return float(wall), float(user) + float(sys_s), int(rss) / 1024, proc.stdout


def process_tree(root):
    """CPU seconds (user + system, the reaped children's included) and peak RSS MB of each
    process under `root` (itself included): Spark's JVM and its Python workers, which
    /usr/bin/time on the driver does not see."""
    parent, found = {}, {}
    tick = os.sysconf("SC_CLK_TCK")
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = open(f"/proc/{entry}/stat").read()
            fields = stat[stat.rindex(")") + 2 :].split()
            hwm = [l for l in open(f"/proc/{entry}/status") if l.startswith("VmHWM:")]
        except OSError:
            continue
        pid = int(entry)
        parent[pid] = int(fields[1])
        cpu = sum(int(v) for v in fields[11:15]) / tick
        comm = stat[stat.index("(") + 1 : stat.rindex(")")]
        found[pid] = (cpu, int(hwm[0].split()[1]) / 1024 if hwm else 0.0, comm)
    tree = []
    for pid in found:
        p = pid
        while p in parent and p != root and p > 1:
            p = parent[p]
        if p == root:
            tree.append(found[pid])
    return tree


def spark_job(args):
    """The Spark side, run in its own process: prints its timings as JSON."""
    t0 = time.perf_counter()
    from pyspark.sql import SparkSession

    import rootfuse.arrow as ra

    os.environ["PYSPARK_PYTHON"] = sys.executable
    os.environ["SPARK_LOCAL_IP"] = "127.0.0.1"
    spark = (
        SparkSession.builder.master("local[2]")
        .appName("rootfuse-fleet-bench")
        .config("spark.ui.enabled", "false")
        .config("spark.driver.host", "127.0.0.1")
        .config("spark.driver.bindAddress", "127.0.0.1")
        .config("spark.driver.memory", args.driver_memory)
        .config("spark.local.dir", str(args.scratch / "spark-local"))
        .config("spark.sql.shuffle.partitions", str(args.partitions))
        .getOrCreate()
    )
    spark.sparkContext.setLogLevel("ERROR")
    t1 = time.perf_counter()
    df = spark.read.parquet(str(args.scratch / "fleet.parquet"))
    if args.floor:
        # The same job with a function that returns zeros in the estimates' shape instead
        # of running the filter: Spark's own cost (scan, shuffle, Arrow both ways, write).
        import numpy as np
        import pyarrow as pa

        def zeros(table):
            n = table.num_rows
            cols = {"device": table.column("device"), "t": table.column("t")}
            cols.update({c: np.zeros(n) for c in ("qw", "qx", "qy", "qz")})
            return pa.table(cols)

        used = ["device", "t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz"]
        schema = ra.spark_schema(args.filter)
        est = df.select(*used).groupBy("device").applyInArrow(zeros, schema)
    else:
        est = ra.run_spark(df, args.filter)
    est.write.mode("overwrite").parquet(str(args.scratch / "spark-out"))
    t2 = time.perf_counter()
    tree = process_tree(os.getpid())
    spark.stop()
    print(json.dumps({
        "startup_s": t1 - t0,
        "job_s": t2 - t1,
        "cpu_s": sum(c for c, _, _ in tree),
        "jvm_cpu_s": sum(c for c, _, comm in tree if comm == "java"),
        "rss_max_mb": max(r for _, r, _ in tree),
        "rss_sum_mb": sum(r for _, r, _ in tree),
    }))


def check_equal(args, devices):
    """Devices `devices` of the Spark output equal the CLI's bit for bit."""
    import numpy as np
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    cols = ["device", "t", "qw", "qx", "qy", "qz"]
    cli = pq.read_table(args.scratch / "cli-out" / "fleet.parquet", columns=cols)
    spark = pq.read_table(args.scratch / "spark-out", columns=cols)
    assert cli.num_rows == spark.num_rows, (cli.num_rows, spark.num_rows)
    for d in devices:
        a = cli.filter(pc.equal(cli["device"], d)).sort_by("t")
        b = spark.filter(pc.equal(spark["device"], d)).sort_by("t")
        for c in cols[1:]:
            x, y = a[c].to_numpy(), b[c].to_numpy()
            assert x.size > 0 and np.array_equal(x, y), f"device {d}, column {c} differs"


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--devices", type=int, default=200)
    p.add_argument("--seconds", type=float, default=600)
    p.add_argument("--rate", type=float, default=100)
    p.add_argument("--filter", default="flagship")
    p.add_argument("--bin", type=pathlib.Path, default=REPO / "target/release/rootfuse")
    p.add_argument("--scratch", type=pathlib.Path, default=pathlib.Path("/tmp/rootfuse-spark-bench"))
    p.add_argument("--partitions", type=int, default=4, help="spark.sql.shuffle.partitions")
    p.add_argument("--driver-memory", default="2g")
    p.add_argument("--keep", action="store_true", help="keep the scratch folder")
    p.add_argument("--floor", action="store_true",
                   help="also run the Spark job with a function that returns zeros (Spark's own cost)")
    p.add_argument("--spark-job", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.spark_job:
        spark_job(args)
        return
    shutil.rmtree(args.scratch, ignore_errors=True)
    args.scratch.mkdir(parents=True)
    try:
        fleet = args.scratch / "fleet.parquet"
        wall, _, _, _ = timed(
            [str(args.bin), "simulate", "--devices", str(args.devices), "--seconds",
             str(args.seconds), "--rate", str(args.rate), "--out", str(fleet)]
        )
        rows = int(args.devices * args.seconds * args.rate)
        print(f"fleet: {args.devices} devices x {args.seconds:g} s x {args.rate:g} Hz = {rows:.3g} rows, "
              f"{fleet.stat().st_size / 1e9:.2f} GB Parquet (simulated in {wall:.1f} s)")
        cli_wall, cli_cpu, cli_rss, _ = timed(
            [str(args.bin), "run", str(fleet), "--filter", args.filter, "--out", str(args.scratch / "cli-out")]
        )
        print(f"CLI   `run --filter {args.filter}`: wall {cli_wall:.1f} s, cpu {cli_cpu:.1f} s, "
              f"peak RSS {cli_rss:.0f} MB, {rows / cli_wall:.3g} samples/s")
        job = [sys.executable, __file__, "--spark-job", "--scratch", str(args.scratch), "--filter",
               args.filter, "--partitions", str(args.partitions), "--driver-memory", args.driver_memory]
        sp_wall, _, _, out = timed(job)
        t = json.loads(out.strip().splitlines()[-1])
        print(f"Spark local[2]: wall {sp_wall:.1f} s (start-up {t['startup_s']:.1f} s, job {t['job_s']:.1f} s), "
              f"cpu {t['cpu_s']:.1f} s (JVM {t['jvm_cpu_s']:.1f} s, the rest Python driver and workers), peak RSS {t['rss_max_mb']:.0f} MB "
              f"largest process, {t['rss_sum_mb']:.0f} MB summed, {rows / t['job_s']:.3g} samples/s in the job")
        print(f"Spark throughput / CLI throughput: {cli_wall / t['job_s']:.2f} (wall, job), "
              f"{cli_wall / sp_wall:.2f} (wall, whole process with start-up), "
              f"{cli_cpu / t['cpu_s']:.2f} (CPU time)")
        check_equal(args, [0, args.devices // 2, args.devices - 1])
        print("devices 0, N/2, N-1: Spark's estimates equal the CLI's bit for bit")
        if args.floor:
            f_wall, _, _, out = timed(job + ["--floor"])
            f = json.loads(out.strip().splitlines()[-1])
            print(f"Spark floor (zeros instead of the filter): job {f['job_s']:.1f} s, "
                  f"cpu {f['cpu_s']:.1f} s (JVM {f['jvm_cpu_s']:.1f} s)")
    finally:
        if not args.keep:
            shutil.rmtree(args.scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
