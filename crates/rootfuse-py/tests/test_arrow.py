"""rootfuse.arrow on pyarrow tables, and the same job on Spark (local[2]) with
groupBy("device").applyInArrow: per device, bit for bit the CLI's f64 estimates."""

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow", reason="pyarrow not installed: rootfuse.arrow not tested")
import pyarrow.parquet as pq  # noqa: E402

import rootfuse.arrow as ra  # noqa: E402

DEVICES = 6
SECONDS = 4


@pytest.fixture(scope="module")
def fleet(cli, tmp_path_factory):
    """A simulated fleet and the CLI's flagship estimates of it (f64, with flags)."""
    d = tmp_path_factory.mktemp("fleet")
    path = d / "fleet.parquet"
    subprocess.run(
        [cli, "simulate", "--devices", str(DEVICES), "--seconds", str(SECONDS), "--out", str(path)],
        check=True,
        capture_output=True,
    )
    out = d / "out"
    subprocess.run(
        [cli, "run", str(path), "--filter", "flagship", "--flags", "--out", str(out)],
        check=True,
        capture_output=True,
    )
    return pq.read_table(path), pq.read_table(out / "fleet.parquet")


def _by_device(table):
    keys = table.column("device").to_numpy()
    return {int(k): table.filter(pa.compute.equal(table.column("device"), k)) for k in np.unique(keys)}


def _assert_same(got, want):
    got, want = _by_device(got), _by_device(want)
    assert sorted(got) == sorted(want) == list(range(DEVICES))
    for d in want:
        for name in ("t", "qw", "qx", "qy", "qz"):
            a = got[d].column(name).to_numpy().view(np.uint64)
            b = want[d].column(name).to_numpy().view(np.uint64)
            np.testing.assert_array_equal(a, b, err_msg=f"device {d}, column {name}")
        flags_got = got[d].column("flags").to_numpy().astype(np.uint8)
        np.testing.assert_array_equal(flags_got, want[d].column("flags").to_numpy())


def test_table_equals_cli_bit_for_bit(fleet):
    table, cli_est = fleet
    _assert_same(ra.estimate_table(table, "flagship", flags=True), cli_est)


def test_record_batch_and_float32_columns(fleet):
    table, cli_est = fleet
    batch = table.combine_chunks().to_batches()[0]
    assert ra.estimate_table(batch, "flagship", flags=True).num_rows == batch.num_rows
    # float32 columns are accepted (the estimates then belong to the rounded data).
    f32 = table.set_column(
        table.column_names.index("gx"), "gx", table.column("gx").cast(pa.float32())
    )
    assert ra.estimate_table(f32, "mahony").num_rows == table.num_rows


def test_rows_out_of_order_are_sorted_and_bad_time_refused(fleet):
    table, cli_est = fleet
    shuffled = table.take(pa.array(np.random.default_rng(1).permutation(table.num_rows)))
    _assert_same(ra.estimate_table(shuffled, "flagship", flags=True), cli_est)
    one = _by_device(table)[0]
    t = one.column("t").to_numpy().copy()
    t[5] = t[4]
    bad = one.set_column(one.column_names.index("t"), "t", pa.array(t))
    with pytest.raises(ValueError, match="column `t`"):
        ra.estimate_device(bad, "mahony")
    with pytest.raises(TypeError, match="column `gx` has type int64"):
        ra.estimate_device(one.set_column(one.column_names.index("gx"), "gx", pa.array(np.zeros(len(t), dtype=np.int64))), "mahony")


def _spark_ready():
    try:
        import pyspark  # noqa: F401
    except ImportError:
        return "pyspark not installed"
    if shutil.which("java") is None and not os.environ.get("JAVA_HOME"):
        return "no Java for Spark"
    return None


@pytest.mark.skipif(_spark_ready() is not None, reason=f"Spark not tested: {_spark_ready()}")
def test_spark_apply_in_arrow_equals_cli(fleet, tmp_path):
    from pyspark.sql import SparkSession

    table, cli_est = fleet
    path = tmp_path / "fleet.parquet"
    pq.write_table(table, path)
    # Executors run this interpreter (and so this build of rootfuse).
    os.environ["PYSPARK_PYTHON"] = sys.executable
    # Local mode on the loopback interface only.
    os.environ["SPARK_LOCAL_IP"] = "127.0.0.1"
    spark = (
        SparkSession.builder.master("local[2]")
        .appName("rootfuse-test")
        .config("spark.ui.enabled", "false")
        .config("spark.driver.host", "127.0.0.1")
        .config("spark.driver.bindAddress", "127.0.0.1")
        .config("spark.sql.shuffle.partitions", "2")
        .getOrCreate()
    )
    try:
        df = spark.read.parquet(str(path))
        est = ra.run_spark(df, "flagship", flags=True)
        got = est.toArrow()
    finally:
        spark.stop()
    _assert_same(got, cli_est)
