"""The Spark deployment of docs/fleets.md, run as written: rootfuse built as a wheel, installed into a
fresh virtual environment packed with venv-pack, shipped with `spark-submit --archives`,
`PYSPARK_PYTHON` pointing into it, on a small fleet, in both layouts. The master is
`local-cluster[1,2,1024]` (one executor process with 2 cores and 1 GB, started by
spark-submit): `local[2]` runs the tasks inside the driver's JVM, which does not unpack
`--archives` into their working directory ("Cannot run program ./environment/bin/python"
with Spark 4.3), so only a real executor, as on a cluster, tests the deployment.
Each device's estimates equal the CLI's bit for bit. Slow (a venv with pyarrow and pandas from
PyPI, two JVM jobs); in CI it must run (Java 17 is on the machine, scripts/test-all.sh installs
the rest and hands over the wheel it built, ROOTFUSE_WHEEL)."""

import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest

pa = pytest.importorskip("pyarrow", reason="pyarrow not installed: Spark deployment not tested")
import pyarrow.parquet as pq  # noqa: E402

import rootfuse.arrow as ra  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[3]
BIN = pathlib.Path(sys.executable).parent

JOB = """
import sys
from pyspark.sql import SparkSession
import rootfuse.arrow as ra

source, out, layout = sys.argv[1:4]
spark = SparkSession.builder.appName("rootfuse-deploy").getOrCreate()
df = spark.read.parquet(source)
ra.run_spark(df, "flagship", layout=layout, flags=True, buckets=2).write.parquet(out)
spark.stop()
"""


def _missing():
    for tool in ("spark-submit", "venv-pack", "maturin"):
        if not (BIN / tool).exists() and shutil.which(tool) is None:
            return f"{tool} not installed"
    if shutil.which("java") is None and not os.environ.get("JAVA_HOME"):
        return "no Java for Spark"
    return None


def _spark_work():
    """Where a local-cluster worker leaves its application folders: SPARK_HOME/work."""
    import pyspark

    return pathlib.Path(pyspark.__file__).parent / "work"


def _tool(name):
    return str(BIN / name) if (BIN / name).exists() else shutil.which(name)


def _wheel(out):
    """The wheel scripts/test-all.sh built and installed for this test run (ROOTFUSE_WHEEL),
    so the deployment ships the extension the other tests ran; run alone, a wheel as
    `maturin build` makes it."""
    given = os.environ.get("ROOTFUSE_WHEEL")
    if given:
        return pathlib.Path(given)
    subprocess.run(
        [_tool("maturin"), "build", "--quiet", "--manifest-path", str(REPO / "crates/rootfuse-py/Cargo.toml"),
         "--out", str(out)],
        check=True,
        capture_output=True,
    )
    (wheel,) = out.glob("rootfuse-*.whl")
    return wheel


@pytest.fixture(scope="module")
def packed_env(tmp_path_factory):
    """rootfuse's wheel in a fresh venv with what the executors need, packed."""
    why = _missing()
    if why is not None:
        if os.environ.get("CI"):
            pytest.fail(f"the Spark deployment must run in CI: {why}")
        pytest.skip(f"Spark deployment not tested: {why}")
    d = tmp_path_factory.mktemp("deploy")
    wheel = _wheel(d / "wheels")
    env = d / "env"
    subprocess.run([sys.executable, "-m", "venv", str(env)], check=True)
    # What an executor imports: rootfuse (numpy) and Spark's Arrow functions (pyarrow, pandas).
    subprocess.run(
        [str(env / "bin" / "python"), "-m", "pip", "install", "--quiet", str(wheel),
         "pyarrow>=15", "pandas>=2.2,<3"],
        check=True,
        capture_output=True,
    )
    archive = d / "env.tar.gz"
    subprocess.run([_tool("venv-pack"), "-p", str(env), "-o", str(archive), "-q"], check=True, capture_output=True)
    return archive


@pytest.mark.parametrize("layout", ["bucket", "clustered"])
def test_spark_submit_with_packed_venv(packed_env, cli, tmp_path, layout):
    source = tmp_path / "fleet.parquet"
    subprocess.run([cli, "simulate", "--devices", "5", "--seconds", "3", "--out", str(source)], check=True,
                   capture_output=True)
    cli_out = tmp_path / "cli"
    subprocess.run([cli, "run", str(source), "--filter", "flagship", "--flags", "--out", str(cli_out)],
                   check=True, capture_output=True)
    if layout == "clustered":
        clustered = tmp_path / "clustered.parquet"
        ra.cluster_by_device(pq.read_table(source), clustered, group=4)
        source = clustered
    job = tmp_path / "job.py"
    job.write_text(JOB)
    out = tmp_path / "spark_out"
    env = dict(os.environ)
    env.update(
        # The driver runs this interpreter; the executors the packed one, unpacked by Spark
        # into their working directory under the name after '#'.
        PYSPARK_DRIVER_PYTHON=sys.executable,
        PYSPARK_PYTHON="./environment/bin/python",
        SPARK_LOCAL_IP="127.0.0.1",
    )
    # A local-cluster worker puts its application folders (each with the unpacked
    # environment, ~0.3 GB) in SPARK_HOME/work whatever SPARK_WORKER_DIR says: inside the
    # venv's pyspark. The ones this run adds are removed after it.
    before = set(_spark_work().glob("app-*"))
    try:
        proc = subprocess.run(
            [_tool("spark-submit"), "--master", "local-cluster[1,2,1024]", "--archives",
             f"{packed_env}#environment", "--conf", "spark.ui.enabled=false", "--conf",
             "spark.driver.host=127.0.0.1", str(job), str(source), str(out), layout],
            env=env, cwd=tmp_path, capture_output=True, text=True, timeout=600,
        )
    finally:
        for app in set(_spark_work().glob("app-*")) - before:
            shutil.rmtree(app, ignore_errors=True)
    assert proc.returncode == 0, proc.stderr[-4000:]
    got = pq.read_table(out)
    want = pq.read_table(cli_out / "fleet.parquet")
    assert got.num_rows == want.num_rows
    for d in range(5):
        g = got.filter(pa.compute.equal(got.column("device"), d)).sort_by("t")
        w = want.filter(pa.compute.equal(want.column("device"), d)).sort_by("t")
        for name in ("t", "qw", "qx", "qy", "qz"):
            np.testing.assert_array_equal(g.column(name).to_numpy().view(np.uint64),
                                          w.column(name).to_numpy().view(np.uint64), err_msg=f"{d} {name}")
