//! [`FleetReader`] on the Arrow IPC stream format (told from the file format by content) and
//! on parts without rows.
use arrow::array::{ArrayRef, Float64Array, RecordBatch, StringArray};
use arrow::record_batch::RecordBatchWriter;
use parquet::arrow::ArrowWriter;
use rootfuse_columnar::{ColumnarError, Devices, FleetReader, ImuGaps, Part};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A scratch directory removed when the test ends.
struct Scratch(PathBuf);

impl Scratch {
    fn new(name: &str) -> Self {
        let dir =
            std::env::temp_dir().join(format!("rootfuse-columnar-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn join(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Three devices (string names), interleaved, 9D, with values that differ row by row so
/// that a misplaced row or column shows.
fn fleet_batch(rows: usize) -> RecordBatch {
    let names = ["left", "right", "tail"];
    let device: Vec<&str> = (0..rows).map(|r| names[r % 3]).collect();
    let col = |k: usize| -> ArrayRef {
        Arc::new(Float64Array::from(
            (0..rows)
                .map(|r| ((r * 7 + k * 13) % 29) as f64 * 0.1 - 1.0)
                .collect::<Vec<_>>(),
        ))
    };
    let t: ArrayRef = Arc::new(Float64Array::from(
        (0..rows).map(|r| (r / 3) as f64 * 0.01).collect::<Vec<_>>(),
    ));
    let mut columns: Vec<(&str, ArrayRef)> = vec![
        ("device", Arc::new(StringArray::from(device)) as ArrayRef),
        ("t", t),
    ];
    for (k, name) in ["gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz"]
        .into_iter()
        .enumerate()
    {
        columns.push((name, col(k)));
    }
    RecordBatch::try_from_iter(columns).unwrap()
}

/// `batch` in pieces of `sizes` rows (0 for a record batch without rows).
fn pieces(batch: &RecordBatch, sizes: &[usize]) -> Vec<RecordBatch> {
    let mut start = 0;
    sizes
        .iter()
        .map(|&n| {
            let b = batch.slice(start, n);
            start += n;
            b
        })
        .collect()
}

fn write_ipc_file(path: &Path, batches: &[RecordBatch]) {
    let file = std::fs::File::create(path).unwrap();
    let w = arrow::ipc::writer::FileWriter::try_new(file, &batches[0].schema()).unwrap();
    write_all(w, batches);
}

fn write_ipc_stream(path: &Path, batches: &[RecordBatch]) {
    let file = std::fs::File::create(path).unwrap();
    let w = arrow::ipc::writer::StreamWriter::try_new(file, &batches[0].schema()).unwrap();
    write_all(w, batches);
}

fn write_all(mut w: impl RecordBatchWriter, batches: &[RecordBatch]) {
    for b in batches {
        w.write(b).unwrap();
    }
    w.close().unwrap();
}

/// Every block of `path` with its place, the device labels and the skipped parts.
type Read = (
    Vec<(Part, u64, rootfuse_batch::FleetBlock)>,
    Vec<String>,
    Vec<usize>,
);

fn read_all(path: &Path) -> Result<Read, ColumnarError> {
    let mut reader = FleetReader::open(path, ImuGaps::Keep)?;
    let mut devices = Devices::default();
    let mut blocks = Vec::new();
    while let Some(chunk) = reader.next_chunk(&mut devices)? {
        assert_eq!(
            chunk.device_column.as_ref().map(|c| c.len()),
            Some(chunk.block.len())
        );
        blocks.push((chunk.part, chunk.first_row, chunk.block));
    }
    let labels = (0..devices.len() as u32)
        .map(|d| devices.label(d).to_string())
        .collect();
    Ok((blocks, labels, reader.empty_parts().to_vec()))
}

/// The same record batches as an IPC stream (named `.arrows`, or `.arrow` as pyarrow's stream
/// writer leaves it) and as an IPC file read back as the same blocks, places and devices.
#[test]
fn ipc_stream_reads_as_the_ipc_file() {
    let dir = Scratch::new("stream");
    let batches = pieces(&fleet_batch(90), &[40, 0, 35, 15]);
    let file = dir.join("fleet-file.arrow");
    write_ipc_file(&file, &batches);
    let expected = read_all(&file).unwrap();
    assert_eq!(expected.0.len(), 3, "three blocks with rows");
    assert_eq!(expected.1, ["left", "right", "tail"]);
    assert_eq!(
        expected.2,
        [1],
        "the empty record batch is skipped and listed"
    );
    let rows: usize = expected.0.iter().map(|b| b.2.len()).sum();
    assert_eq!(rows, 90);
    for name in ["fleet.arrows", "stream-named.arrow", "fleet.ipc"] {
        let stream = dir.join(name);
        write_ipc_stream(&stream, &batches);
        assert!(!std::fs::read(&stream).unwrap().starts_with(b"ARROW1"));
        let got = read_all(&stream).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(got.0, expected.0, "{name}");
        assert_eq!(got.1, expected.1, "{name}");
        assert_eq!(got.2, expected.2, "{name}");
    }
}

/// A cut stream is an error naming the file, wherever it is cut: inside a message, right
/// after the schema, or after the last whole record batch (only the end-of-stream marker
/// lost, which the decoder alone would take for a complete stream).
#[test]
fn truncated_ipc_stream_is_an_error_naming_the_file() {
    let dir = Scratch::new("truncated");
    let batches = pieces(&fleet_batch(60), &[30, 30]);
    let whole = dir.join("whole.arrows");
    write_ipc_stream(&whole, &batches);
    let bytes = std::fs::read(&whole).unwrap();
    // The end-of-stream marker: continuation token, then a zero length.
    assert_eq!(
        &bytes[bytes.len() - 8..],
        &[0xff, 0xff, 0xff, 0xff, 0, 0, 0, 0]
    );
    let cuts = [
        ("marker-lost", bytes.len() - 8, Some("record batch 2")),
        ("half-marker", bytes.len() - 4, Some("record batch 2")),
        ("mid-batch", bytes.len() - 100, Some("record batch 1")),
        ("mid-schema", 20, None),
        ("empty", 0, None),
    ];
    for (name, len, part) in cuts {
        let path = dir.join(&format!("{name}.arrows"));
        std::fs::write(&path, &bytes[..len]).unwrap();
        let err = match read_all(&path) {
            Ok(_) => panic!("{name}: a stream cut at byte {len} was read as complete"),
            Err(e) => e,
        };
        let msg = err.to_string();
        assert!(
            msg.starts_with(&format!("{}: ", path.display())),
            "{name}: {msg}"
        );
        assert!(
            msg.contains("not a readable Arrow IPC stream file"),
            "{name}: {msg}"
        );
        if let Some(part) = part {
            assert!(msg.contains(part), "{name}: {msg}");
        }
    }
    // Bytes that are neither format under an Arrow name.
    let path = dir.join("text.arrow");
    std::fs::write(&path, b"t,gx,gy,gz\n0,1,2,3\n").unwrap();
    let msg = read_all(&path).err().unwrap().to_string();
    assert!(
        msg.starts_with(&format!(
            "{}: not a readable Arrow IPC stream file",
            path.display()
        )),
        "{msg}"
    );
}

/// A Parquet row group without rows is skipped and listed; the rows around it are read as
/// written, with their row groups named as Parquet tools count them.
#[test]
fn empty_parquet_row_group_is_skipped_and_listed() {
    let dir = Scratch::new("empty-group");
    let batch = fleet_batch(30);
    let path = dir.join("gap.parquet");
    write_parquet_with_empty_group(&path, &batch.slice(0, 12), &batch.slice(12, 18));
    let meta = parquet::file::reader::FileReader::metadata(
        &parquet::file::reader::SerializedFileReader::new(std::fs::File::open(&path).unwrap())
            .unwrap(),
    )
    .clone();
    let group_rows: Vec<i64> = meta.row_groups().iter().map(|g| g.num_rows()).collect();
    assert_eq!(group_rows, [12, 0, 18], "the file has the empty row group");
    let (blocks, labels, empty) = read_all(&path).unwrap();
    assert_eq!(empty, [1]);
    assert_eq!(labels, ["left", "right", "tail"]);
    let places: Vec<(Part, u64, usize)> = blocks.iter().map(|b| (b.0, b.1, b.2.len())).collect();
    assert_eq!(
        places,
        [(Part::RowGroup(0), 0, 12), (Part::RowGroup(2), 12, 18)]
    );
    let t: Vec<f64> = blocks.iter().flat_map(|b| b.2.t.clone()).collect();
    let expected: Vec<f64> = (0..30).map(|r| (r / 3) as f64 * 0.01).collect();
    assert_eq!(t, expected);
    // A file of empty row groups only has no rows to read.
    let path = dir.join("all-empty.parquet");
    write_parquet_with_empty_group(&path, &batch.slice(0, 0), &batch.slice(0, 0));
    let (blocks, _, empty) = read_all(&path).unwrap();
    assert!(blocks.is_empty());
    assert_eq!(empty, [0]);
}

/// `first` as row group 0 (skipped when empty), a row group without rows, then `last` (when
/// not empty). `ArrowWriter` drops empty batches, so the empty group is written through the
/// file writer underneath it.
fn write_parquet_with_empty_group(path: &Path, first: &RecordBatch, last: &RecordBatch) {
    let file = std::fs::File::create(path).unwrap();
    let mut w = ArrowWriter::try_new(file, first.schema(), None).unwrap();
    w.write(first).unwrap();
    w.flush().unwrap();
    let (mut file_writer, factory) = w.into_serialized_writer().unwrap();
    let row_groups = file_writer.flushed_row_groups().len();
    let mut group = file_writer.next_row_group().unwrap();
    while let Some(column) = group.next_column().unwrap() {
        column.close().unwrap();
    }
    group.close().unwrap();
    if last.num_rows() > 0 {
        let mut writers = factory.create_column_writers(row_groups + 1).unwrap();
        let mut leaves = Vec::new();
        for (field, array) in last.schema().fields().iter().zip(last.columns()) {
            leaves.extend(parquet::arrow::arrow_writer::compute_leaves(field, array).unwrap());
        }
        for (writer, leaf) in writers.iter_mut().zip(&leaves) {
            writer.write(leaf).unwrap();
        }
        let mut group = file_writer.next_row_group().unwrap();
        for writer in writers {
            writer
                .close()
                .unwrap()
                .append_to_row_group(&mut group)
                .unwrap();
        }
        group.close().unwrap();
    }
    file_writer.close().unwrap();
}

/// An Arrow IPC file (the file format, memory-mapped and decoded through its footer) cut at
/// any length is an error naming the file; with any byte of its footer changed it is an
/// error naming the file or reads; never a panic.
#[test]
fn cut_or_damaged_ipc_file_is_an_error_not_a_panic() {
    let dir = Scratch::new("cut-file");
    let batches = pieces(&fleet_batch(60), &[30, 30]);
    let whole = dir.join("whole.arrow");
    write_ipc_file(&whole, &batches);
    let bytes = std::fs::read(&whole).unwrap();
    assert_eq!(read_all(&whole).unwrap().1, ["left", "right", "tail"]);
    let path = dir.join("damaged.arrow");
    for len in 0..bytes.len() {
        std::fs::write(&path, &bytes[..len]).unwrap();
        let err = read_all(&path)
            .err()
            .unwrap_or_else(|| panic!("cut at {len} read"));
        assert!(
            err.to_string()
                .starts_with(&format!("{}: ", path.display())),
            "{err}"
        );
    }
    // The footer and the trailer after it.
    let footer_len =
        u32::from_le_bytes(bytes[bytes.len() - 10..bytes.len() - 6].try_into().unwrap());
    let footer_start = bytes.len() - 10 - footer_len as usize;
    for i in footer_start..bytes.len() {
        for flip in [0x01u8, 0xff] {
            let mut damaged = bytes.clone();
            damaged[i] ^= flip;
            std::fs::write(&path, &damaged).unwrap();
            // A change the format does not notice (padding, an unused field, a column's
            // name) may read rows; what matters is no panic, and an error naming the file
            // otherwise.
            let read = (|| -> Result<(), ColumnarError> {
                let mut reader = FleetReader::open(&path, ImuGaps::Keep)?;
                let mut devices = Devices::default();
                while reader.next_chunk(&mut devices)?.is_some() {}
                Ok(())
            })();
            if let Err(e) = read {
                assert!(
                    e.to_string().starts_with(&format!("{}: ", path.display())),
                    "{e}"
                );
            }
        }
    }
}

/// A fleet as loggers and pandas store it, read as the float fleet with the same values:
/// `t` a timestamp in ms, the gyroscope in int16 counts (converted by `with_units`), the
/// accelerometer int32, the magnetometer a dictionary of floats, and a null count as NaN.
/// A column that is no number is refused by type; a missing one lists the columns there are.
#[test]
fn integer_timestamp_and_dictionary_columns_read_as_numbers() {
    use arrow::array::{
        DictionaryArray, Int16Array, Int32Array, TimestampMillisecondArray, UInt8Array,
    };
    use rootfuse_attitude::units::Units;
    let dir = Scratch::new("types");
    let rows = 60;
    let floats = fleet_batch(rows);
    // Counts whose conversion is exact in f64: a gyroscope factor of 1/8, i.e. 0.125.
    let counts = |k: usize| -> Vec<i32> {
        (0..rows)
            .map(|r| ((r * 7 + k * 13) % 29) as i32 - 10)
            .collect()
    };
    let value = |c: i32| f64::from(c) * 0.125;
    let mut expected_cols: Vec<(&str, ArrayRef)> = vec![
        ("device", floats.column(0).clone()),
        (
            "t",
            Arc::new(Float64Array::from(
                (0..rows).map(|r| (r / 3) as f64 * 0.01).collect::<Vec<_>>(),
            )),
        ),
    ];
    let mut stored_cols: Vec<(&str, ArrayRef)> = vec![
        ("device", floats.column(0).clone()),
        (
            "t",
            Arc::new(TimestampMillisecondArray::from(
                (0..rows).map(|r| (r / 3) as i64 * 10).collect::<Vec<_>>(),
            )),
        ),
    ];
    for (k, name) in ["gx", "gy", "gz"].into_iter().enumerate() {
        let c = counts(k);
        let mut gyr: Vec<Option<i16>> = c.iter().map(|&v| Some(v as i16)).collect();
        let mut exp: Vec<f64> = c.iter().map(|&v| value(v)).collect();
        if k == 1 {
            gyr[4] = None;
            exp[4] = f64::NAN;
        }
        stored_cols.push((name, Arc::new(Int16Array::from(gyr))));
        expected_cols.push((name, Arc::new(Float64Array::from(exp))));
    }
    for (k, name) in ["ax", "ay", "az"].into_iter().enumerate() {
        let c = counts(k + 3);
        stored_cols.push((name, Arc::new(Int32Array::from(c.clone()))));
        expected_cols.push((
            name,
            Arc::new(Float64Array::from(
                c.iter().map(|&v| f64::from(v)).collect::<Vec<_>>(),
            )),
        ));
    }
    for name in ["mx", "my", "mz"] {
        let keys = UInt8Array::from((0..rows).map(|r| (r % 3) as u8).collect::<Vec<_>>());
        let values = Arc::new(Float64Array::from(vec![-20.5, 3.0, 41.25]));
        let dict = DictionaryArray::try_new(keys, values.clone()).unwrap();
        stored_cols.push((name, Arc::new(dict)));
        expected_cols.push((
            name,
            Arc::new(Float64Array::from(
                (0..rows).map(|r| values.value(r % 3)).collect::<Vec<_>>(),
            )),
        ));
    }
    let stored = dir.join("stored.arrow");
    write_ipc_file(&stored, &[RecordBatch::try_from_iter(stored_cols).unwrap()]);
    let plain = dir.join("plain.arrow");
    write_ipc_file(
        &plain,
        &[RecordBatch::try_from_iter(expected_cols).unwrap()],
    );
    let read = |path: &Path, units: &str| {
        let units: Units = units.parse().unwrap();
        let mut reader = FleetReader::open(path, ImuGaps::Keep)
            .unwrap()
            .with_units(units);
        let mut devices = Devices::default();
        let mut blocks = Vec::new();
        while let Some(chunk) = reader.next_chunk(&mut devices).unwrap() {
            blocks.push(format!("{:?}", chunk.block));
        }
        blocks
    };
    // Debug text compares NaN with NaN, as `==` on the blocks would not.
    assert_eq!(read(&stored, "gyro=0.125"), read(&plain, ""));
    // A timestamp says its own unit: a time unit for the fleet's other files leaves it be.
    assert_eq!(read(&stored, "gyro=0.125,time=ms"), read(&plain, ""));
    // A string column is no number; a missing column lists the columns there are.
    let text: ArrayRef = Arc::new(StringArray::from(vec!["1"; rows]));
    let mut cols: Vec<(&str, ArrayRef)> = (0..floats.num_columns())
        .map(|i| {
            (
                [
                    "device", "t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz",
                ][i],
                floats.column(i).clone(),
            )
        })
        .collect();
    cols[2].1 = text;
    let bad = dir.join("text.arrow");
    write_ipc_file(&bad, &[RecordBatch::try_from_iter(cols.clone()).unwrap()]);
    let e = read_all(&bad).unwrap_err().to_string();
    assert!(
        e.contains("column `gx` has type Utf8, expected a number"),
        "{e}"
    );
    cols.remove(2);
    let bad = dir.join("missing.arrow");
    write_ipc_file(&bad, &[RecordBatch::try_from_iter(cols).unwrap()]);
    let e = read_all(&bad).unwrap_err().to_string();
    assert!(
        e.contains("missing required column `gx` (the file has `device`, `t`, `gy`"),
        "{e}"
    );
}
