"""rootfuse over Apache Arrow: IMU rows in ``pyarrow`` tables or record batches, the columns
and units of the CSV and Parquet formats (``docs/conventions.md``): ``t`` (s), ``gx, gy, gz``
(rad/s), ``ax, ay, az`` (m/s²), optionally ``mx, my, mz`` and ``device``; float32 or float64.

Pure Python on top of :class:`rootfuse.Filter` (the Rust filters): a float64 column without
nulls in one chunk reaches NumPy without a copy; the (N, 3) sensor arrays the filter takes
are one copy of three columns each. Results equal ``rootfuse run`` (the CLI) per device,
bit for bit, in f64 and f32 alike.

Spark (4.x): :func:`run_spark` runs a fleet with ``groupBy("device").applyInArrow``, one
device per call of :func:`estimate_device`; the same function plugs into Ray Data
(``ds.groupby("device").map_groups(fn, batch_format="pyarrow")``) or Dask
(``ddf.groupby("device").apply(...)`` on ``pa.Table.from_pandas``).
"""

from typing import Any, Callable, Dict, Optional

import numpy as np
import pyarrow as pa

from ._rootfuse import Filter

DEVICE = "device"
_GYR = ("gx", "gy", "gz")
_ACC = ("ax", "ay", "az")
_MAG = ("mx", "my", "mz")
_COV = ("p_xx", "p_xy", "p_xz", "p_yy", "p_yz", "p_zz")


def _floats(table: pa.Table, name: str) -> np.ndarray:
    """Column ``name`` as float64 NumPy, nulls as NaN (dropped packets); zero-copy for one
    float64 chunk without nulls."""
    if name not in table.column_names:
        raise KeyError(f"missing required column `{name}`")
    col = table.column(name)
    if not pa.types.is_floating(col.type):
        raise TypeError(f"column `{name}` has type {col.type}, expected float32 or float64")
    if col.null_count:
        col = col.fill_null(float("nan"))
    if col.num_chunks == 1:
        values = col.chunk(0).to_numpy(zero_copy_only=False)
    else:
        values = col.to_numpy()
    return np.asarray(values, dtype=np.float64)


def _vectors(table: pa.Table, names) -> np.ndarray:
    return np.column_stack([_floats(table, n) for n in names])


def estimate_names(
    filter_has_covariance: bool, *, bias: bool = False, covariance: bool = False, flags: bool = False
):
    """The estimate columns after ``t`` as the CLI writes them."""
    names = ["t", "qw", "qx", "qy", "qz"]
    if bias:
        names += ["bx", "by", "bz"]
    if covariance and filter_has_covariance:
        names += list(_COV)
    if flags:
        names.append("flags")
    return names


def estimate_device(
    table: pa.Table,
    filter: str,
    *,
    precision: str = "f64",
    dof: Optional[int] = None,
    bias: bool = False,
    covariance: bool = False,
    flags: bool = False,
    sort: bool = True,
    **params: float,
) -> pa.Table:
    """Estimates of one device's rows: ``device`` (if the table has it), ``t``, ``qw..qz``,
    optionally ``bx..bz``, ``p_xx..p_zz``, ``flags`` (uint8). With ``sort`` the rows are put in
    time order first (Spark hands a group over in no particular order); time stamps must then
    be distinct. Raises ``ValueError`` for a time stamp that is not finite or repeats."""
    if sort and table.num_rows > 1:
        t = _floats(table, "t")
        order = np.argsort(t, kind="stable")
        if np.any(order[1:] < order[:-1]):
            table = table.take(pa.array(order))
    t = _floats(table, "t")
    if not np.all(np.isfinite(t)):
        raise ValueError(f"row {int(np.argmin(np.isfinite(t)))}, column `t`: time is not finite")
    if t.size > 1 and not np.all(np.diff(t) > 0):
        row = int(np.argmin(np.diff(t) > 0)) + 1
        raise ValueError(f"row {row}, column `t`: time {t[row]} does not increase")
    f = Filter(filter, dof=dof, precision=precision, **params)
    has_mag = any(n in table.column_names for n in _MAG)
    mag = _vectors(table, _MAG) if has_mag else None
    out = f.update_batch(_vectors(table, _GYR), _vectors(table, _ACC), mag, t=t)
    q = out["quat"]
    columns: Dict[str, Any] = {}
    if DEVICE in table.column_names:
        columns[DEVICE] = table.column(DEVICE)
    columns["t"] = t
    for k, name in enumerate(("qw", "qx", "qy", "qz")):
        columns[name] = q[:, k]
    if bias:
        for k, name in enumerate(("bx", "by", "bz")):
            columns[name] = out["bias"][:, k]
    if covariance and out.get("covariance") is not None:
        p = out["covariance"]
        for name, (r, c) in zip(_COV, [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]):
            columns[name] = p[:, r, c]
    if flags:
        columns["flags"] = pa.array(out["flags"], type=pa.uint8())
    return pa.table(columns)


def estimate_table(table: pa.Table, filter: str, **options: Any) -> pa.Table:
    """Estimates of a fleet table (or record batch): grouped by ``device`` (devices in order of
    first appearance, each device's rows in time order), or one device without that column.
    ``options`` as for :func:`estimate_device`."""
    if isinstance(table, pa.RecordBatch):
        table = pa.Table.from_batches([table])
    if DEVICE not in table.column_names or table.num_rows == 0:
        return estimate_device(table, filter, **options)
    keys = table.column(DEVICE).to_numpy(zero_copy_only=False)
    _, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    parts = []
    for group in np.argsort(first, kind="stable"):
        rows = np.flatnonzero(inverse == group)
        parts.append(estimate_device(table.take(pa.array(rows)), filter, **options))
    return pa.concat_tables(parts)


def spark_schema(
    filter: str,
    *,
    device_type: str = "long",
    bias: bool = False,
    covariance: bool = False,
    flags: bool = False,
    dof: Optional[int] = None,
) -> str:
    """The Spark DDL schema of :func:`estimate_device`'s output (``device_type``: the Spark
    type of the device column, ``long`` or ``string``)."""
    has_cov = Filter(filter, dof=dof).covariance is not None
    names = estimate_names(has_cov, bias=bias, covariance=covariance, flags=flags)
    types = ["tinyint" if n == "flags" else "double" for n in names]
    return ", ".join([f"{DEVICE} {device_type}"] + [f"{n} {t}" for n, t in zip(names, types)])


def device_function(filter: str, **options: Any) -> Callable[[pa.Table], pa.Table]:
    """``fn(table) -> table`` for ``applyInArrow`` (Spark), ``map_groups`` (Ray Data) and the
    like: the estimates of one device's rows (:func:`estimate_device` with ``options``).
    Spark has no unsigned bytes: ``flags`` is returned as int8 (the bits are the same)."""

    def fn(table: pa.Table) -> pa.Table:
        out = estimate_device(table, filter, **options)
        if "flags" in out.column_names:
            i = out.column_names.index("flags")
            out = out.set_column(i, "flags", out.column("flags").cast(pa.int8()))
        return out

    return fn


def run_spark(df: Any, filter: str, *, device_type: str = "long", **options: Any) -> Any:
    """A Spark DataFrame of IMU rows (any partitioning) → a DataFrame of estimates, one
    device per group: ``df.groupBy("device").applyInArrow(device_function(...), schema)``
    on the columns the filter reads (others, such as truth, are left out before the shuffle).
    Needs Spark 4 (``applyInArrow``) and this package installed on the executors."""
    schema_options = {k: options[k] for k in ("bias", "covariance", "flags", "dof") if k in options}
    schema = spark_schema(filter, device_type=device_type, **schema_options)
    # Only the columns the filter reads go through Spark's shuffle (a simulated fleet's truth
    # columns are a quarter of its bytes); with Parquet input the others are not even read.
    used = [c for c in (DEVICE, "t", *_GYR, *_ACC, *_MAG) if c in df.columns]
    return df.select(*used).groupBy(DEVICE).applyInArrow(device_function(filter, **options), schema)


__all__ = [
    "DEVICE",
    "device_function",
    "estimate_device",
    "estimate_names",
    "estimate_table",
    "run_spark",
    "spark_schema",
]
