"""rootfuse over Apache Arrow: IMU rows in ``pyarrow`` tables, record batches or any Arrow
stream, the columns and units of the CSV and Parquet formats (``docs/conventions.md``):
``t`` (s), ``gx, gy, gz`` (rad/s), ``ax, ay, az`` (m/s²), optionally ``mx, my, mz`` and
``device`` (integer or string); numbers (floats, integers such as raw counts, decimals,
a dictionary of them; ``t`` also a timestamp, read in seconds).

Everything runs in Rust: the Arrow data goes through the Arrow C stream interface (no copy
through Python) into the batch engine's fleet runner, which runs the devices in SIMD lanes,
and the estimates come back as an Arrow stream. It is the code ``rootfuse run`` uses on a
Parquet or Arrow file, so each device's estimates equal the CLI's bit for bit.

Rows of one device must come in time order; devices may interleave in any way. Lanes are
busy when the rows of many devices are near each other (time-major order, as
``rootfuse simulate`` writes, or :func:`cluster_by_device`); a table whose rows are in no
order is put in time order with ``sort=True``.

Spark (4.x): :func:`run_spark` in two layouts, both running many devices per call in lanes:

- ``layout="clustered"``: data rewritten once by :func:`cluster_by_device` (each group of
  devices in one Parquet row group, time-major within it) runs with ``mapInArrow``, no
  shuffle (:func:`batches_function`);
- ``layout="bucket"``: any layout; rows are shuffled into device buckets with ``groupBy`` and
  each call runs a bucket's devices (:func:`table_function`).
"""

import itertools
import os
import warnings
from typing import Any, Callable, Dict, Iterable, Iterator, List, Optional

# pyarrow ships no type information; an absent pyarrow fails at import, not here.
import pyarrow as pa  # type: ignore[import-untyped, import-not-found, unused-ignore]

from ._rootfuse import EstimateStream, Filter, estimate_arrow

DEVICE = "device"
_GYR = ("gx", "gy", "gz")
_ACC = ("ax", "ay", "az")
_MAG = ("mx", "my", "mz")
_COV = ("p_xx", "p_xy", "p_xz", "p_yy", "p_yz", "p_zz")
#: Devices per group written by :func:`cluster_by_device`: a multiple of the SIMD lanes of
#: both precisions (8 channels per ``f32x8``, 4 per ``f64x4``), twice over for the engine's
#: interleaved small filters.
GROUP_DEVICES = 16


def estimate_names(
    filter_has_covariance: bool, *, bias: bool = False, covariance: bool = False, flags: bool = False
):
    """The estimate columns after ``device`` as the CLI writes them."""
    names = ["t", "qw", "qx", "qy", "qz"]
    if bias:
        names += ["bx", "by", "bz"]
    if covariance and filter_has_covariance:
        names += list(_COV)
    if flags:
        names.append("flags")
    return names


def _as_stream(source: Any) -> Any:
    """A pyarrow RecordBatch becomes a one-batch table; a ``pyarrow.dataset`` Dataset or
    Scanner and a ``pyarrow.parquet.ParquetFile`` become a stream of their record batches as
    pyarrow reads them (never a whole table); anything else (a stream, a path) is passed on."""
    if isinstance(source, pa.RecordBatch):
        return pa.Table.from_batches([source])
    if not hasattr(source, "__arrow_c_stream__"):
        if callable(getattr(source, "scanner", None)):  # a Dataset: read only the IMU columns
            return source.scanner(columns=_imu_columns(source.schema.names)).to_reader()
        if callable(getattr(source, "to_reader", None)):  # a Scanner
            return source.to_reader()
        if callable(getattr(source, "iter_batches", None)) and hasattr(source, "schema_arrow"):  # a ParquetFile
            columns = _imu_columns(source.schema_arrow.names)
            schema = pa.schema([source.schema_arrow.field(c) for c in columns])
            return pa.RecordBatchReader.from_batches(schema, source.iter_batches(columns=columns))
    return source


def _imu_columns(names: List[str]) -> List[str]:
    """The columns of ``names`` a filter reads, in their order."""
    return [c for c in (DEVICE, "t", *_GYR, *_ACC, *_MAG) if c in names]


def _is_path(source: Any) -> bool:
    return isinstance(source, (str, os.PathLike))


def _read_file(path: Any) -> pa.Table:
    """A Parquet or Arrow IPC (file or stream) fleet file read whole by pyarrow, for the
    callers that must reorder its rows first."""
    import pyarrow.parquet as pq  # type: ignore[import-untyped, import-not-found, unused-ignore]

    with open(path, "rb") as f:
        magic = f.read(6)
    if magic[:4] == b"PAR1":
        return pq.read_table(path)
    if magic == b"ARROW1":
        return pa.ipc.open_file(path).read_all()
    return pa.ipc.open_stream(path).read_all()


def _time_order(table: pa.Table) -> pa.Table:
    """The rows in time order (ties by device), each device's rows then in time order and
    the devices interleaved by time, which keeps the lanes busy."""
    if table.num_rows < 2:
        return table
    keys = [("t", "ascending")]
    if DEVICE in table.column_names:
        keys.append((DEVICE, "ascending"))
    return table.sort_by(keys)


def device_params_dict(table: Any) -> Optional[Dict[str, Dict[str, float]]]:
    """Per-device parameters as ``{device: {name: value}}`` from a dict (returned as it is) or
    a table (a ``pyarrow.Table``, or anything ``pyarrow.table`` takes, such as a pandas
    DataFrame) with a ``device`` column and one column per parameter; a null cell leaves that
    parameter at its default for that device."""
    if table is None or isinstance(table, dict):
        return table
    try:
        table = pa.table(table)
    except (TypeError, ValueError, pa.ArrowException) as e:
        raise TypeError(
            "device_params: expected {device: {name: value}} or a table with a `device` column "
            f"(a pyarrow Table, a pandas DataFrame), got {type(table).__name__} ({e})"
        ) from None
    if DEVICE not in table.column_names:
        raise ValueError("device_params: missing required column `device`")
    names = [n for n in table.column_names if n != DEVICE]
    out: Dict[str, Dict[str, float]] = {}
    for row, rec in enumerate(table.to_pylist()):
        label = rec[DEVICE]
        if label is None:
            raise ValueError(f"device_params: row {row}, column `device`: device is null")
        label = str(label)
        if label in out:
            raise ValueError(f"device_params: row {row}, column `device`: device {label!r} is given twice")
        values = {}
        for name in names:
            v = rec[name]
            if v is None:
                continue
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise TypeError(f"device_params: row {row}, column `{name}`: expected a number, got {v!r}")
            values[name] = float(v)
        out[label] = values
    return out


def _estimates(source: Any, filter: str, options: Dict[str, Any]) -> EstimateStream:
    options = dict(options)
    if "device_params" in options:
        options["device_params"] = device_params_dict(options["device_params"])
    return estimate_arrow(_as_stream(source), filter, **options)


def estimate_stream(source: Any, filter: str, **options: Any) -> pa.RecordBatchReader:
    """Estimates of an Arrow stream, computed as they are read: a ``pyarrow.RecordBatchReader``
    with one row per input row, in input order: ``device`` (if the input has it, same type),
    ``t``, ``qw..qz`` (sensor to earth, ENU), then as asked ``bx..bz`` (``bias=True``, rad/s),
    ``p_xx..p_zz`` (``covariance=True``, rad², filters with a covariance), ``flags``
    (``flags=True``, uint8). Memory stays flat for a stream of any length.

    ``source``: a pyarrow ``Table``, ``RecordBatch`` or ``RecordBatchReader``, any object
    with ``__arrow_c_stream__``, a ``pyarrow.dataset`` Dataset or Scanner or a
    ``pyarrow.parquet.ParquetFile`` (streamed batch by batch as pyarrow reads them, only the
    IMU columns of a Dataset or ParquetFile), or the path (``str`` or ``os.PathLike``) of a Parquet or
    Arrow IPC fleet file, which is read in Rust exactly as ``rootfuse run`` reads it (the
    fastest way in: nothing is materialised in Python first; a file that cannot be opened
    raises at the call, naming it, ``FileNotFoundError`` for a missing one). ``options``: ``precision`` ("f64" default, or "f32"),
    ``dof``, ``bias``, ``covariance``, ``flags``, ``device_params`` (per-device parameters:
    ``{device: {name: value}}`` or a table, see :func:`device_params_dict`; devices not in it
    run with the other options) and the filter's parameters. A bad row
    (time not increasing for its device, not finite) raises ``pyarrow.ArrowInvalid`` (a
    ``ValueError``) when it is reached, naming the record batch, row, column and device."""
    return pa.RecordBatchReader.from_stream(_estimates(source, filter, options))


def estimate_table(table: Any, filter: str, *, sort: bool = False, **options: Any) -> pa.Table:
    """Estimates of a fleet table (or record batch, any Arrow stream, a ``pyarrow.dataset``
    Dataset or a ``ParquetFile`` streamed as pyarrow reads it, or the path of a Parquet or
    Arrow IPC file, read in Rust) as a ``pyarrow.Table``: :func:`estimate_stream` read
    whole. With ``sort=True`` the rows are first put in time order (for rows that come in no
    particular order, such as a Spark group; a file is then read whole by pyarrow first), and
    the estimates follow that order. Raises ``ValueError`` naming the row and column for a time
    stamp that is not finite or does not increase for its device."""
    if sort:
        table = _time_order(_read_file(table) if _is_path(table) else pa.table(_as_stream(table)))
    stream = _estimates(table, filter, options)
    try:
        out = pa.RecordBatchReader.from_stream(stream).read_all()
    except (pa.ArrowException, OSError) as e:
        message = str(e)
        if "does not increase" in message and not sort:
            message += " (rows of a device must come in time order: sort=True puts them in order)"
        raise ValueError(message) from None
    summary = stream.summary()
    if options.get("device_params") is not None and summary is not None:
        notes = []
        if summary["devices_with_defaults"]:
            notes.append(f"{summary['devices_with_defaults']} device(s) not in device_params ran with the defaults")
        if summary["unseen_devices"]:
            notes.append(f"device(s) of device_params without rows: {summary['unseen_devices']}")
        if notes:
            warnings.warn("; ".join(notes), stacklevel=2)
    return out


def estimate_device(table: Any, filter: str, **options: Any) -> pa.Table:
    """Estimates of one device's rows (any order: they are sorted by time first). The same as
    :func:`estimate_table` with ``sort=True``."""
    return estimate_table(table, filter, sort=True, **options)


def cluster_by_device(
    table: pa.Table, where: Any, *, group: int = GROUP_DEVICES, compression: str = "snappy"
) -> int:
    """The one-time rewrite that clusters a fleet by device for :func:`run_spark` with
    ``layout="clustered"``: writes ``table`` as Parquet to ``where`` (a path or file) with the
    devices in groups of ``group`` (in order of first appearance), each group one row group
    whose rows are time-major (sorted by time, ties by device). A reader that splits the file
    at row groups (Spark does) then never splits a device, and every record batch holds the
    rows of ``group`` devices side by side, which run in SIMD lanes. Returns the number of
    row groups (groups) written."""
    import numpy as np
    import pyarrow.compute as pc  # type: ignore[import-untyped, import-not-found, unused-ignore]
    import pyarrow.parquet as pq  # type: ignore[import-untyped, import-not-found, unused-ignore]

    if group < 1:
        raise ValueError(f"group: expected a positive number of devices, got {group}")
    if DEVICE not in table.column_names:
        raise ValueError("missing required column `device`: a fleet table names each row's device")
    # Dense device numbers in order of first appearance.
    keys = table.column(DEVICE).combine_chunks()
    uniques = pc.unique(keys)
    index = pc.index_in(keys, value_set=uniques).to_numpy()
    first = np.full(len(uniques), len(index), dtype=np.int64)
    np.minimum.at(first, index, np.arange(len(index)))
    rank = np.empty(len(uniques), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(uniques))
    bucket = rank[index] // group
    groups = 0
    with pq.ParquetWriter(where, table.schema, compression=compression) as writer:
        order = np.argsort(bucket, kind="stable")
        bounds = np.searchsorted(bucket[order], np.arange(bucket.max(initial=-1) + 2))
        for g in range(len(bounds) - 1):
            rows = order[bounds[g] : bounds[g + 1]]
            if rows.size == 0:
                continue
            part = _time_order(table.take(pa.array(rows)))
            writer.write_table(part, row_group_size=max(part.num_rows, 1))
            groups += 1
    return groups


def spark_schema(
    filter: str,
    *,
    device_type: str = "long",
    bias: bool = False,
    covariance: bool = False,
    flags: bool = False,
    dof: Optional[int] = None,
) -> str:
    """The Spark DDL schema of the estimates (``device_type``: the Spark type of the device
    column, ``long`` or ``string``). ``flags`` is ``tinyint``: Spark has no unsigned bytes."""
    has_cov = Filter(filter, dof=dof).covariance is not None
    names = estimate_names(has_cov, bias=bias, covariance=covariance, flags=flags)
    types = ["tinyint" if n == "flags" else "double" for n in names]
    return ", ".join([f"{DEVICE} {device_type}"] + [f"{n} {t}" for n, t in zip(names, types)])


def _for_spark(batch: pa.RecordBatch) -> pa.RecordBatch:
    """``flags`` as int8 (the same bits) and ``device`` as Spark's ``long`` when integer."""
    columns, names = [], batch.schema.names
    for name, col in zip(names, batch.columns):
        if name == "flags":
            col = col.cast(pa.int8())
        elif name == DEVICE and pa.types.is_integer(col.type) and col.type != pa.int64():
            col = col.cast(pa.int64())
        columns.append(col)
    return pa.RecordBatch.from_arrays(columns, names=names)


def batches_function(filter: str, **options: Any) -> Callable[[Iterable[pa.RecordBatch]], Iterator[pa.RecordBatch]]:
    """``fn(batches) -> batches`` for Spark's ``mapInArrow``: every record batch of a
    partition through one fleet runner (devices keep their state from batch to batch), the
    estimates streamed back batch by batch. A device must not span partitions: lay the data
    out with :func:`cluster_by_device`."""

    def fn(batches: Iterable[pa.RecordBatch]) -> Iterator[pa.RecordBatch]:
        batches = iter(batches)
        first = next(batches, None)
        if first is None:
            return
        reader = pa.RecordBatchReader.from_batches(first.schema, itertools.chain([first], batches))
        for batch in estimate_stream(reader, filter, **options):
            yield _for_spark(batch)

    return fn


def table_function(filter: str, **options: Any) -> Callable[[pa.Table], pa.Table]:
    """``fn(table) -> table`` for ``groupBy(...).applyInArrow`` (Spark), ``map_groups`` (Ray
    Data) and the like: the estimates of all the devices in a group's rows (put in time order
    first: a shuffle delivers them in no particular order), in SIMD lanes."""

    def fn(table: pa.Table) -> pa.Table:
        out = estimate_table(table, filter, sort=True, **options)
        return pa.Table.from_batches([_for_spark(b) for b in out.to_batches()]) if out.num_rows else out

    return fn


# The function of the earlier per-device API: one group of rows, estimates of its devices.
device_function = table_function


def run_spark(
    df: Any,
    filter: str,
    *,
    layout: str = "bucket",
    device_type: Optional[str] = None,
    buckets: Optional[int] = None,
    **options: Any,
) -> Any:
    """A Spark DataFrame of IMU rows → a DataFrame of estimates (:func:`spark_schema`), each
    device's equal to the CLI's bit for bit. Only the columns the filter reads are passed on.
    ``device_type`` (``long`` or ``string``) follows the DataFrame's ``device`` column unless
    given.

    - ``layout="bucket"`` (any layout): rows go to ``buckets`` device buckets by a hash of
      the device (``groupBy(...).applyInArrow``), and each call runs its bucket's devices in
      lanes. ``buckets`` defaults to one per 16 devices (counted with one pass over the
      device column).
    - ``layout="clustered"``: ``mapInArrow`` without a shuffle, for data written by
      :func:`cluster_by_device` (a device never spans partitions)."""
    from pyspark.sql import functions as F  # type: ignore[import-untyped, import-not-found, unused-ignore]

    schema_options = {k: options[k] for k in ("bias", "covariance", "flags", "dof") if k in options}
    if device_type is None:
        # Integer devices come back as long (`_for_spark`), string ones as they are.
        names = {f.name: f.dataType.simpleString() for f in df.schema.fields}
        device_type = "string" if names.get(DEVICE) == "string" else "long"
    schema = spark_schema(filter, device_type=device_type, **schema_options)
    used = _imu_columns(df.columns)
    df = df.select(*used)
    if layout == "clustered":
        return df.mapInArrow(batches_function(filter, **options), schema)
    if layout != "bucket":
        raise ValueError(f'layout: expected "bucket" or "clustered", got {layout!r}')
    if buckets is None:
        devices = df.select(DEVICE).distinct().count()
        buckets = max(1, -(-devices // GROUP_DEVICES))
    bucket = F.pmod(F.xxhash64(F.col(DEVICE)), F.lit(int(buckets)))
    return (
        df.withColumn("_rootfuse_bucket", bucket)
        .groupBy("_rootfuse_bucket")
        .applyInArrow(_drop_bucket(table_function(filter, **options)), schema)
    )


def _drop_bucket(fn: Callable[[pa.Table], pa.Table]) -> Callable[[pa.Table], pa.Table]:
    def wrapped(table: pa.Table) -> pa.Table:
        if "_rootfuse_bucket" in table.column_names:
            table = table.drop_columns(["_rootfuse_bucket"])
        return fn(table)

    return wrapped


__all__ = [
    "DEVICE",
    "EstimateStream",
    "GROUP_DEVICES",
    "batches_function",
    "cluster_by_device",
    "device_function",
    "device_params_dict",
    "estimate_device",
    "estimate_names",
    "estimate_stream",
    "estimate_table",
    "run_spark",
    "spark_schema",
    "table_function",
]
