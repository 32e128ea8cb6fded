"""rootfuse.arrow: Arrow tables and streams through the batch engine's fleet runner (in Rust),
and the same job on Spark (local[2]) in both layouts: per device, bit for bit the CLI's
estimates."""

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
    got = ra.estimate_table(table, "flagship", flags=True)
    # One estimate per input row, in input order, the device column as it was.
    assert got.num_rows == table.num_rows
    assert got.column("device").equals(table.column("device"))
    assert got.schema.field("flags").type == pa.uint8()
    _assert_same(got, cli_est)


def test_any_arrow_stream_and_record_batches(fleet):
    table, cli_est = fleet
    # A RecordBatchReader of small batches: block boundaries do not change a bit.
    reader = pa.RecordBatchReader.from_batches(table.schema, table.to_batches(max_chunksize=777))
    stream = ra.estimate_stream(reader, "flagship", flags=True)
    assert isinstance(stream, pa.RecordBatchReader)
    _assert_same(stream.read_all(), cli_est)
    batch = table.combine_chunks().to_batches()[0]
    assert ra.estimate_table(batch, "flagship", flags=True).num_rows == batch.num_rows
    # The Rust object speaks the Arrow PyCapsule interface, once.
    s = ra.estimate_arrow(table, "mahony")
    assert s.column_names[:3] == ["device", "t", "qw"]
    assert pa.table(s).num_rows == table.num_rows
    with pytest.raises(ValueError, match="already read"):
        pa.table(s)


def test_a_file_path_is_read_in_rust(fleet, tmp_path):
    table, cli_est = fleet
    parquet = tmp_path / "fleet.parquet"
    pq.write_table(table, parquet, row_group_size=1000)
    ipc = tmp_path / "fleet.arrow"
    with pa.ipc.new_file(ipc, table.schema) as writer:
        writer.write_table(table, max_chunksize=999)
    # A path (str or os.PathLike) of either format gives the CLI's estimates, in file order.
    for source in (parquet, str(ipc)):
        got = ra.estimate_table(source, "flagship", flags=True)
        assert got.num_rows == table.num_rows
        assert got.column("device").equals(table.column("device"))
        _assert_same(got, cli_est)
    _assert_same(ra.estimate_table(parquet, "flagship", flags=True, sort=True), cli_est)
    _assert_same(ra.estimate_stream(ipc, "flagship", flags=True).read_all(), cli_est)
    with pytest.raises(FileNotFoundError, match="missing.parquet"):
        ra.estimate_table(tmp_path / "missing.parquet", "mahony")
    six = tmp_path / "six.parquet"
    pq.write_table(table.drop_columns(["mx", "my", "mz"]), six)
    with pytest.raises(ValueError, match=r"six\.parquet: no magnetometer columns"):
        ra.estimate_table(six, "flagship", dof=9)
    # A CSV recording is pointed to the reader that takes it, not called a corrupt Parquet.
    csv = tmp_path / "rec.csv"
    csv.write_text("t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n")
    with pytest.raises(ValueError, match=r"rec\.csv: a CSV file: .*rootfuse\.read_csv"):
        ra.estimate_table(csv, "flagship")


def test_datasets_and_parquet_files_are_streamed(fleet, tmp_path):
    import pyarrow.dataset as ds

    table, cli_est = fleet
    parquet = tmp_path / "fleet.parquet"
    # Extra columns (the truth here) are not read: only the IMU columns are projected.
    pq.write_table(table.append_column("extra", pa.array(np.zeros(table.num_rows))), parquet, row_group_size=1000)
    for source in (ds.dataset(parquet), ds.dataset(parquet).scanner(), pq.ParquetFile(parquet)):
        got = ra.estimate_table(source, "flagship", flags=True)
        assert got.num_rows == table.num_rows, type(source)
        assert got.column("device").equals(table.column("device"))
        _assert_same(got, cli_est)
    _assert_same(ra.estimate_stream(pq.ParquetFile(parquet), "flagship", flags=True).read_all(), cli_est)


def test_float32_columns_and_options(fleet):
    table, _ = fleet
    f32 = table.set_column(table.column_names.index("gx"), "gx", table.column("gx").cast(pa.float32()))
    out = ra.estimate_table(f32, "mahony", bias=True, covariance=True)
    assert out.num_rows == table.num_rows
    # Mahony has no covariance: the columns are not there, as in the CLI's output.
    assert out.column_names == ["device", "t", "qw", "qx", "qy", "qz", "bx", "by", "bz"]
    six = ra.estimate_table(table.drop_columns(["mx", "my", "mz"]), "flagship", dof=6, precision="f32")
    assert six.num_rows == table.num_rows
    with pytest.raises(ValueError, match="9D"):
        ra.estimate_table(table.drop_columns(["mx", "my", "mz"]), "flagship", dof=9)


def test_rows_out_of_order_are_refused_or_sorted(fleet):
    table, cli_est = fleet
    shuffled = table.take(pa.array(np.random.default_rng(1).permutation(table.num_rows)))
    with pytest.raises(ValueError, match=r"row \d+, column `t` \(device \d+\).*sort=True"):
        ra.estimate_table(shuffled, "flagship")
    _assert_same(ra.estimate_table(shuffled, "flagship", flags=True, sort=True), cli_est)
    one = _by_device(table)[0]
    t = one.column("t").to_numpy().copy()
    t[5] = t[4]
    bad = one.set_column(one.column_names.index("t"), "t", pa.array(t))
    with pytest.raises(ValueError, match=r"row 5, column `t` \(device 0\).*does not increase"):
        ra.estimate_table(bad, "mahony")
    with pytest.raises(TypeError, match=r"column `gx` has type Utf8, expected a number \(float, integer, decimal\)"):
        ra.estimate_device(one.set_column(one.column_names.index("gx"), "gx", pa.array(["0"] * len(t))), "mahony")
    with pytest.raises(TypeError, match="Arrow stream"):
        ra.estimate_table(np.zeros(3), "mahony")


def test_cluster_by_device_groups_devices_in_row_groups(fleet, tmp_path):
    table, cli_est = fleet
    path = tmp_path / "clustered.parquet"
    assert ra.cluster_by_device(table, path, group=4) == 2
    f = pq.ParquetFile(path)
    assert f.metadata.num_row_groups == 2
    seen = []
    for g in range(2):
        part = f.read_row_group(g)
        devices = set(part.column("device").to_pylist())
        assert len(devices) <= 4 and not devices & set(seen)
        seen += devices
        t = part.column("t").to_numpy()
        assert np.all(np.diff(t) >= 0), "time-major within a group"
    # What mapInArrow does with each partition: its batches through one runner.
    fn = ra.batches_function("flagship", flags=True)
    out = pa.Table.from_batches(list(fn(f.iter_batches(batch_size=500))))
    assert out.schema.field("flags").type == pa.int8()
    _assert_same(out, cli_est)


def test_device_params_run_each_device_with_its_own(fleet):
    """Per-device parameters: each device equals its own run with its parameters, bit for bit,
    whatever chunk it shares (max_dt is structural: device 4 gets a chunk of its own)."""
    table, _ = fleet
    params = {0: {"gyr_noise": 0.02}, "3": {"tau_acc": 1.0}, 4: {"max_dt": 0.5}, 99: {"gyr_noise": 0.01}}
    with pytest.warns(UserWarning, match=r"3 device\(s\) not in device_params.*\['99'\]"):
        got = ra.estimate_table(table, "flagship", device_params=params)
    by = _by_device(got)
    for d in range(DEVICES):
        own = params.get(d) or params.get(str(d)) or {}
        want = ra.estimate_table(_by_device(table)[d], "flagship", **own)
        for name in ("qw", "qx", "qy", "qz"):
            np.testing.assert_array_equal(by[d].column(name).to_numpy().view(np.uint64),
                                          want.column(name).to_numpy().view(np.uint64), err_msg=f"device {d}")
    # The same as a table (null: that parameter's default), and the stream's own summary.
    t = pa.table({"device": [0, 3, 4, 99], "gyr_noise": [0.02, None, None, 0.01],
                  "tau_acc": [None, 1.0, None, None], "max_dt": [None, None, 0.5, None]})
    s = ra.estimate_arrow(table, "flagship", device_params=ra.device_params_dict(t))
    assert s.summary() is None
    again = pa.table(s)
    assert again.equals(got)
    summary = s.summary()
    assert summary["devices"] == DEVICES and summary["devices_with_defaults"] == 3
    assert summary["unseen_devices"] == ["99"] and summary["rows"] == table.num_rows
    with pytest.raises(ValueError, match=r'device_params\["1"\]: kp: unknown parameter'):
        ra.estimate_table(table, "flagship", device_params={1: {"kp": 1.0}})
    with pytest.raises(TypeError, match=r"row 0, column `gyr_noise`: expected a number"):
        ra.device_params_dict(pa.table({"device": [1], "gyr_noise": ["a"]}))


def _spark_ready():
    try:
        import pyspark  # noqa: F401
    except ImportError:
        return "pyspark not installed"
    if shutil.which("java") is None and not os.environ.get("JAVA_HOME"):
        return "no Java for Spark"
    return None


@pytest.fixture(scope="module")
def spark():
    why = _spark_ready()
    if why is not None:
        if os.environ.get("CI"):
            pytest.fail(f"Spark must run in CI: {why}")
        pytest.skip(f"Spark not tested: {why}")
    from pyspark.sql import SparkSession

    # Executors run this interpreter (and so this build of rootfuse), on loopback only.
    os.environ["PYSPARK_PYTHON"] = sys.executable
    os.environ["SPARK_LOCAL_IP"] = "127.0.0.1"
    session = (
        SparkSession.builder.master("local[2]")
        .appName("rootfuse-test")
        .config("spark.ui.enabled", "false")
        .config("spark.driver.host", "127.0.0.1")
        .config("spark.driver.bindAddress", "127.0.0.1")
        .config("spark.sql.shuffle.partitions", "2")
        .getOrCreate()
    )
    yield session
    session.stop()


@pytest.mark.parametrize("layout", ["bucket", "clustered"])
def test_spark_layouts_equal_cli(spark, fleet, tmp_path, layout):
    table, cli_est = fleet
    path = tmp_path / "fleet.parquet"
    if layout == "clustered":
        ra.cluster_by_device(table, path, group=4)
    else:
        pq.write_table(table, path)
    df = spark.read.parquet(str(path))
    got = ra.run_spark(df, "flagship", layout=layout, flags=True, buckets=2).toArrow()
    _assert_same(got, cli_est)


def test_spark_string_devices_need_no_device_type(spark, fleet, tmp_path):
    """A string ``device`` column: the output schema follows the input's (it assumed long and
    failed on the executor)."""
    table, cli_est = fleet
    named = table.set_column(
        table.column_names.index("device"), "device", pa.compute.cast(table.column("device"), pa.string())
    )
    path = tmp_path / "named.parquet"
    pq.write_table(named, path)
    got = ra.run_spark(spark.read.parquet(str(path)), "flagship", flags=True, buckets=2).toArrow()
    assert pa.types.is_string(got.schema.field("device").type) or pa.types.is_large_string(
        got.schema.field("device").type
    )
    numbered = got.set_column(
        got.column_names.index("device"), "device", pa.compute.cast(got.column("device"), pa.int64())
    )
    _assert_same(numbered, cli_est)
