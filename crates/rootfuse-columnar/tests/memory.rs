//! [`FleetReader`] on an Arrow IPC file and stream written as ONE record batch: the reader's
//! memory does not grow with the batch. Arrow's `FileReader`/`StreamReader` read a whole
//! batch into memory, so 1e7 rows took about 1 GB (`rootfuse run`, issue 26). Alone in its
//! test binary, so that no other test's memory is counted.
#![cfg(target_os = "linux")]
use arrow::array::{ArrayRef, Float64Array, Int64Array, RecordBatch};
use arrow::record_batch::RecordBatchWriter;
use rootfuse_columnar::{BLOCK_ROWS, Devices, FleetReader, ImuGaps};
use std::path::Path;
use std::sync::Arc;

/// Rows of the one batch: 1e6 rows of 12 columns are 96 MB of values.
const ROWS: usize = 1_000_000;

/// This process's resident set, bytes (`VmRSS`).
fn rss() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap();
    let line = status.lines().find(|l| l.starts_with("VmRSS:")).unwrap();
    let kb: u64 = line.split_whitespace().nth(1).unwrap().parse().unwrap();
    kb * 1024
}

fn write_one_batch(path: &Path, stream: bool) {
    let col = |k: usize| -> ArrayRef {
        Arc::new(Float64Array::from_iter_values(
            (0..ROWS).map(|r| ((r * 7 + k * 13) % 29) as f64 * 0.1 - 1.0),
        ))
    };
    let mut columns: Vec<(&str, ArrayRef)> = vec![
        (
            "device",
            Arc::new(Int64Array::from_iter_values(
                (0..ROWS).map(|r| (r % 10) as i64),
            )),
        ),
        (
            "t",
            Arc::new(Float64Array::from_iter_values(
                (0..ROWS).map(|r| (r / 10) as f64 * 0.01),
            )),
        ),
    ];
    for (k, name) in ["gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz"]
        .into_iter()
        .enumerate()
    {
        columns.push((name, col(k)));
    }
    columns.push(("qw", col(20)));
    let batch = RecordBatch::try_from_iter(columns).unwrap();
    let file = std::fs::File::create(path).unwrap();
    fn write(mut w: impl RecordBatchWriter, batch: &RecordBatch) {
        w.write(batch).unwrap();
        w.close().unwrap();
    }
    if stream {
        write(
            arrow::ipc::writer::StreamWriter::try_new(file, &batch.schema()).unwrap(),
            &batch,
        );
    } else {
        write(
            arrow::ipc::writer::FileWriter::try_new(file, &batch.schema()).unwrap(),
            &batch,
        );
    }
}

/// Reading a one-batch file of 100 MB raises the resident set by less than 40 MB (a few
/// blocks of [`BLOCK_ROWS`] rows), in both IPC formats; the blocks are bounded and cover
/// every row.
#[test]
fn one_batch_ipc_is_read_in_bounded_memory() {
    let dir = std::env::temp_dir().join(format!("rootfuse-columnar-memory-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (name, stream) in [("one.arrow", false), ("one.arrows", true)] {
        let path = dir.join(name);
        write_one_batch(&path, stream);
        let size = std::fs::metadata(&path).unwrap().len();
        assert!(size > 96_000_000, "{name}: {size} bytes");
        let before = rss();
        let mut peak = before;
        let mut reader = FleetReader::open(&path, ImuGaps::Keep).unwrap();
        let mut devices = Devices::default();
        let mut rows = 0;
        while let Some(chunk) = reader.next_chunk(&mut devices).unwrap() {
            assert!(chunk.block.len() <= BLOCK_ROWS);
            assert_eq!(chunk.first_row, rows as u64);
            rows += chunk.block.len();
            peak = peak.max(rss());
        }
        drop(reader);
        assert_eq!(rows, ROWS, "{name}");
        assert_eq!(devices.len(), 10);
        let grown = peak.saturating_sub(before);
        assert!(
            grown < 40 << 20,
            "{name}: reading a {size}-byte one-batch file raised the resident set by {grown} bytes"
        );
        std::fs::remove_file(&path).unwrap();
    }
    let _ = std::fs::remove_dir_all(&dir);
}
