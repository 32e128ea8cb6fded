//! Small fleet tables written with Arrow and Parquet directly, for the tests that need a file
//! `rootfuse simulate` cannot write (a bad column, other device labels).
// Each test file uses its own subset of these.
#![allow(dead_code)]
use arrow::array::{ArrayRef, Float64Array, Int64Array, RecordBatch};
use parquet::arrow::ArrowWriter;
use std::path::Path;
use std::sync::Arc;

/// A float64 column.
pub fn floats(v: &[f64]) -> ArrayRef {
    Arc::new(Float64Array::from(v.to_vec()))
}

/// A two-device fleet at rest (devices 0 and 1), time-major at 100 Hz: columns by name.
pub fn fleet_columns(rows: usize) -> Vec<(&'static str, ArrayRef)> {
    let device: Vec<i64> = (0..rows).map(|r| (r % 2) as i64).collect();
    let t: Vec<f64> = (0..rows).map(|r| (r / 2) as f64 * 0.01).collect();
    let zero = vec![0.0; rows];
    let g = vec![9.81; rows];
    vec![
        ("device", Arc::new(Int64Array::from(device)) as ArrayRef),
        ("t", floats(&t)),
        ("gx", floats(&zero)),
        ("gy", floats(&zero)),
        ("gz", floats(&zero)),
        ("ax", floats(&zero)),
        ("ay", floats(&zero)),
        ("az", floats(&g)),
    ]
}

/// Writes `columns` as one Parquet file with row groups of `row_group` rows.
pub fn write_parquet(path: &Path, columns: Vec<(&'static str, ArrayRef)>, row_group: usize) {
    let batch = RecordBatch::try_from_iter(columns).unwrap();
    let props = parquet::file::properties::WriterProperties::builder()
        .set_max_row_group_row_count(Some(row_group))
        .build();
    let mut w = ArrowWriter::try_new(
        std::fs::File::create(path).unwrap(),
        batch.schema(),
        Some(props),
    )
    .unwrap();
    w.write(&batch).unwrap();
    w.close().unwrap();
}

/// `columns` with the column `name` replaced by `array`.
pub fn replace(
    mut columns: Vec<(&'static str, ArrayRef)>,
    name: &str,
    array: ArrayRef,
) -> Vec<(&'static str, ArrayRef)> {
    let slot = columns.iter_mut().find(|(n, _)| *n == name).unwrap();
    slot.1 = array;
    columns
}
