"""Files as users have them: one BROAD recording written the ways people write IMU data (other
units, delimiters, decimal commas, encodings, pandas' habits, every Parquet and Arrow codec,
folders), each run through the `rootfuse` CLI, with what must happen. `test_user_files.py` runs
every case; run as a script, this writes the table of docs/user-files.md from the same cases:

    python crates/rootfuse-py/tests/user_files.py --cli target/debug/rootfuse \\
        --broad ../shared/broad_csv --docs docs/user-files.md
"""

import argparse
import dataclasses
import os
import pathlib
import re
import subprocess
import sys
import tempfile
from typing import Callable, List, Optional

import numpy as np

TRIAL = "02_undisturbed_slow_rotation_B"
# The first 20,000 samples (70 s of slow rotation with rest): enough motion to judge every unit.
ROWS = 20_000
GYR = ["gx", "gy", "gz"]
ACC = ["ax", "ay", "az"]
MAG = ["mx", "my", "mz"]
DEG = 180.0 / np.pi
G = 9.80665


@dataclasses.dataclass
class Case:
    """One file variant: `make(df, dir)` writes it and returns what to pass to `rootfuse run`."""

    name: str
    what: str
    make: Callable
    args: List[str]
    exit: int
    says: str = ""
    same: bool = False  # the estimate equals the plain CSV's bit for bit
    filter: str = "flagship"


def _csv(**kw):
    def make(df, d):
        p = d / "in.csv"
        df.to_csv(p, index=kw.pop("index", False), **kw)
        return [p]

    return make


def _scaled(columns, factor, **kw):
    def make(df, d):
        df = df.copy()
        df[columns] = df[columns] * factor
        return _csv(**kw)(df, d)

    return make


def _set(column, value):
    def make(df, d):
        df = df.copy()
        df[column] = value
        return _csv()(df, d)

    return make


def _text(transform, encoding="utf-8"):
    def make(df, d):
        p = d / "in.csv"
        p.write_bytes(transform(df.to_csv(index=False)).encode(encoding))
        return [p]

    return make


def _table(df):
    import pyarrow as pa

    cols = {"device": np.zeros(len(df), dtype=np.int32)}
    cols.update({c: df[c].to_numpy() for c in ["t"] + GYR + ACC + MAG})
    return pa.table(cols)


def _parquet(codec):
    def make(df, d):
        import pyarrow.parquet as pq

        p = d / "in.parquet"
        pq.write_table(_table(df), p, compression=codec)
        return [p]

    return make


def _feather(codec):
    def make(df, d):
        import pyarrow.feather as feather

        p = d / "in.arrow"
        feather.write_feather(_table(df), p, compression=codec)
        return [p]

    return make


def _float32(df, d):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = _table(df)
    t = t.cast(pa.schema([pa.field(f.name, pa.float32() if f.name not in ("t", "device") else f.type)
                          for f in t.schema]))
    p = d / "in.parquet"
    pq.write_table(t, p)
    return [p]


def _stream(df, d):
    import pyarrow as pa

    t = _table(df)
    p = d / "in.arrows"
    with pa.OSFile(str(p), "wb") as sink, pa.ipc.new_stream(sink, t.schema) as w:
        w.write_table(t, max_chunksize=4096)
    return [p]


def _pandas_feather(df, d):
    p = d / "in.feather"
    _table(df).to_pandas().to_feather(p)
    return [p]


def _two_devices_no_column(df, d):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t = _table(df).drop(["device"])
    p = d / "in.parquet"
    pq.write_table(pa.concat_tables([t, t]), p)
    return [p]


def _folder_index(df, d):
    folder = d / "trials"
    folder.mkdir()
    for name in ("a", "b", "c"):
        df.to_csv(folder / f"{name}.csv", index=False)
    (folder / "index.csv").write_text("trial\na\nb\n")
    return [folder]


def _folder_mixed(df, d):
    folder = d / "mixed"
    folder.mkdir()
    df.to_csv(folder / "a.csv", index=False)
    _parquet("snappy")(df, folder)
    return [folder]


def _one_empty(df, d):
    df = df.copy()
    df.loc[100, "gx"] = np.nan
    return _csv()(df, d)


def _not_increasing(df, d):
    df = df.copy()
    df.loc[500, "t"] = df.loc[499, "t"]
    return _csv()(df, d)


def _reordered(df, d):
    df = df.copy()
    df["temperature"] = 21.5
    df["note"] = "ok"
    return _csv()(df[list(reversed(df.columns))], d)


def _spaced(df, d):
    return _csv()(df.rename(columns={c: f" {c} " for c in df.columns}), d)


def _bools(df, d):
    df = df.copy()
    df["use"] = df["use"].astype(bool)
    return _csv()(df, d)


CASES = [
    Case("plain", "the BROAD CSV as it is (s, rad/s, m/s², µT)", _csv(), [], 0),
    # Units.
    Case("time-ms", "time in milliseconds", _scaled("t", 1e3), [], 2, "look like ms: run with --units time=ms"),
    Case("time-us", "time in microseconds", _scaled("t", 1e6), [], 2, "look like us: run with --units time=us"),
    Case("time-ns", "time in nanoseconds", _scaled("t", 1e9), [], 2, "look like ns: run with --units time=ns"),
    Case("time-ms-declared", "time in milliseconds, declared", _scaled("t", 1e3), ["--units", "time=ms"], 0),
    Case("acc-g", "accelerometer in g (the flagship uses its direction)", _scaled(ACC, 1 / G), [], 0,
         "look like g: run with --units acc=g"),
    Case("acc-g-ekf", "accelerometer in g, `ekf` (gates on |a| − g)", _scaled(ACC, 1 / G), [], 2,
         "the filter gated every correction", filter="ekf"),
    Case("acc-g-declared", "accelerometer in g, declared, `ekf`", _scaled(ACC, 1 / G), ["--units", "acc=g"], 0,
         filter="ekf"),
    Case("acc-mg", "accelerometer in milli-g (the flagship uses its direction)", _scaled(ACC, 1e3 / G), [], 0,
         "look like mg: run with --units acc=mg"),
    Case("acc-counts", "accelerometer in raw counts (16384 per g)", _scaled(ACC, 16384 / G), [], 2,
         "no unit fits (raw counts?): run with --units acc=<factor to m/s2>"),
    Case("acc-counts-declared", "accelerometer in raw counts, factor given", _scaled(ACC, 16384 / G),
         ["--units", f"acc={G / 16384!r}"], 0),
    Case("gyro-deg", "gyroscope in °/s", _scaled(GYR, DEG), [], 2,
         "look like deg/s: run with --units gyro=deg/s (a gyroscope in the wrong unit makes every estimate wrong"),
    Case("gyro-deg-declared-rad", "gyroscope in °/s, declared as rad/s (the check stays a warning)", _scaled(GYR, DEG),
         ["--units", "gyro=rad/s"], 0, "look like deg/s: run with --units gyro=deg/s"),
    Case("gyro-deg-strict", "gyroscope in °/s, `--strict`", _scaled(GYR, DEG), ["--strict"], 2,
         "look like deg/s: run with --units gyro=deg/s (--strict)"),
    Case("gyro-deg-declared", "gyroscope in °/s, declared", _scaled(GYR, DEG), ["--units", "gyro=deg/s"], 0),
    Case("mag-nT", "magnetometer in nT", _scaled(MAG, 1e3), [], 2,
         "every magnetometer correction was skipped"),
    Case("mag-nT-declared", "magnetometer in nT, declared", _scaled(MAG, 1e3), ["--units", "mag=nT"], 0),
    Case("mag-nT-6d", "magnetometer in nT, `--dof 6` (not used)", _scaled(MAG, 1e3), ["--dof", "6"], 0),
    Case("mag-gauss", "magnetometer in gauss (the filters use its direction)", _scaled(MAG, 0.01), [], 0,
         "look like G: run with --units mag=G"),
    Case("mag-counts", "magnetometer in raw counts (0.15 µT each)", _scaled(MAG, 1 / 0.15), [], 0,
         "magnetometer: the median |m| is"),
    Case("acc-zero", "an accelerometer that reads zero", _set(ACC, 0.0), [], 2,
         "every accelerometer correction was skipped"),
    Case("mag-zero", "a magnetometer that reads zero", _set(MAG, 0.0), [], 2,
         "every magnetometer correction was skipped"),
    Case("gx-null", "an empty `gx` column", _set("gx", np.nan), [], 2, "every sample was skipped"),
    # Layouts, delimiters, encodings.
    Case("semicolon", "semicolon-separated", _csv(sep=";"), [], 0, same=True),
    Case("decimal-comma", "semicolons and decimal commas", _csv(sep=";", decimal=","), [], 0, same=True),
    Case("tab", "tab-separated", _csv(sep="\t"), [], 0, same=True),
    Case("bom", "UTF-8 with a byte-order mark", _text(lambda s: "\ufeff" + s), [], 0, same=True),
    Case("crlf", "Windows line endings", _csv(lineterminator="\r\n"), [], 0, same=True),
    Case("utf16", "UTF-16 (little-endian, byte-order mark)", _text(lambda s: s, "utf-16"), [], 2,
         "the file is UTF-16 little-endian, not UTF-8: save it as UTF-8"),
    Case("utf16be", "UTF-16 big-endian", _text(lambda s: "\ufeff" + s, "utf-16-be"), [], 2,
         "the file is UTF-16 big-endian, not UTF-8"),
    Case("pandas-index", "pandas' `to_csv()` with its index column", _csv(index=True), [], 0, same=True),
    Case("empty-truth", "truth cells left empty (pandas' NaN)", _csv(na_rep=""), [], 0, same=True),
    Case("empty-imu-cell", "one empty gyroscope cell (a dropped sample)", _one_empty, [], 0,
         "missing IMU values (NaN or infinite): 1 sample(s)"),
    Case("empty-imu-cell-strict", "one empty gyroscope cell, `--strict`", _one_empty, ["--strict"], 2,
         "column `gx` (#2): IMU value (empty cell) is missing"),
    Case("use-bool", "`use` as True/False", _bools, [], 0, same=True),
    Case("reordered", "columns reversed, extra text and number columns", _reordered, [], 0, same=True),
    Case("spaced-header", "spaces around the column names", _spaced, [], 0, same=True),
    Case("named-time", "time in a column named `time`", lambda df, d: _csv()(df.rename(columns={"t": "time"}), d),
         [], 2, "missing required column `t` (the header has `time`"),
    Case("partial-mag", "`mz` missing", lambda df, d: _csv()(df.drop(columns=["mz"]), d), [], 2,
         "missing required column `mz`"),
    Case("time-repeats", "a repeated time stamp", _not_increasing, [], 2, "does not increase"),
    # Parquet and Arrow: every codec.
    *[Case(f"parquet-{c}", f"Parquet, {c}", _parquet(c), [], 0, same=True)
      for c in ("none", "snappy", "gzip", "brotli", "lz4", "zstd")],
    *[Case(f"arrow-{c}", f"Arrow IPC file, {c}", _feather(c), [], 0, same=True)
      for c in ("uncompressed", "lz4", "zstd")],
    Case("feather-pandas", "pandas' `to_feather()` (LZ4)", _pandas_feather, [], 0, same=True),
    Case("arrow-stream", "Arrow IPC stream", _stream, [], 0, same=True),
    Case("parquet-float32", "Parquet with float32 sensor columns", _float32, [], 0),
    Case("fleet-no-device", "two devices' rows, no `device` column", _two_devices_no_column, [], 2,
         "the file has no `device` column"),
    # Folders.
    Case("folder-index", "a folder whose index.csv lists 2 of 3 recordings", _folder_index, [], 0,
         "left out 1: c.csv (not listed in index.csv)"),
    Case("folder-mixed", "a folder of a CSV recording and a Parquet fleet", _folder_mixed, [], 0,
         "left out 1: in.parquet (Parquet/Arrow fleets do not run beside CSV recordings)"),
]


def recording(broad: pathlib.Path):
    import pandas as pd

    return pd.read_csv(broad / f"{TRIAL}.csv", nrows=ROWS)


@dataclasses.dataclass
class Outcome:
    exit: int
    message: str
    quat: Optional[np.ndarray]


def run(case: Case, df, cli: str, d: pathlib.Path) -> Outcome:
    inputs = case.make(df, d)
    out = d / "out"
    proc = subprocess.run(
        [cli, "run", *map(str, inputs), "--filter", case.filter, "--out", str(out), *case.args],
        capture_output=True, text=True, timeout=300,
    )
    lines = [line for line in proc.stderr.splitlines() if line.startswith(("error:", "warning:", "note:"))]
    lines += [line for line in proc.stdout.splitlines() if line.startswith("missing IMU")]
    return Outcome(proc.returncode, "\n".join(lines), estimate(out))


def estimate(out: pathlib.Path) -> Optional[np.ndarray]:
    """The quaternions of the one estimate in `out`, or None."""
    # The output folder also holds rootfuse's hidden ledger of what it wrote.
    files = sorted(f for f in out.glob("*") if not f.name.startswith(".")) if out.is_dir() else []
    if len(files) != 1:
        return None
    if files[0].suffix == ".csv":
        import pandas as pd

        return pd.read_csv(files[0])[["qw", "qx", "qy", "qz"]].to_numpy()
    import pyarrow.feather as feather
    import pyarrow.parquet as pq

    table = pq.read_table(files[0]) if files[0].suffix == ".parquet" else feather.read_table(files[0])
    return np.stack([table.column(c).to_numpy() for c in ("qw", "qx", "qy", "qz")], 1)


def shown(message: str) -> str:
    """The first message line, without the temporary folder, for the table."""
    first = message.splitlines()[0] if message else ""
    first = re.sub(r"/\S*/(in|trials|mixed)", r"\1", first)
    return first.replace("|", "\\|")


def table(cli: str, broad: pathlib.Path) -> str:
    df = recording(broad)
    rows = ["| file | options | exit | what rootfuse says |", "|---|---|---|---|"]
    for case in CASES:
        with tempfile.TemporaryDirectory() as tmp:
            got = run(case, df, cli, pathlib.Path(tmp))
        options = " ".join(case.args + ([f"--filter {case.filter}"] if case.filter != "flagship" else []))
        rows.append(f"| {case.what.replace('|', chr(92) + '|')} | `{options}` | {got.exit} | {shown(got.message) or '(nothing)'} |"
                    .replace("``", ""))
    return "\n".join(rows) + "\n"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--cli", default="target/debug/rootfuse")
    p.add_argument("--broad", default=os.environ.get("ROOTFUSE_BROAD_DIR", "../shared/broad_csv"))
    p.add_argument("--docs", default="docs/user-files.md")
    a = p.parse_args(argv)
    text = table(a.cli, pathlib.Path(a.broad))
    docs = pathlib.Path(a.docs)
    page = docs.read_text()
    begin, end = "<!-- user_files:begin -->\n", "<!-- user_files:end -->"
    head, rest = page.split(begin)
    _, tail = rest.split(end)
    docs.write_text(head + begin + text + end + tail)
    print(f"{len(CASES)} cases written to {docs}")


if __name__ == "__main__":
    sys.exit(main())
