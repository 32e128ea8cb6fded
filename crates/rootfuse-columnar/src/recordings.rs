//! [`FleetFileWriter`]: whole recordings (a simulated fleet, say) as one Parquet or Arrow file.

use crate::error::ColumnarError;
use crate::reader::BLOCK_ROWS;
use crate::writer::parquet_properties;
use crate::{DEVICE, Format};
use arrow::array::{ArrayRef, Float64Array, Int64Array, RecordBatch};
use arrow::datatypes::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::ArrowWriter;
use rootfuse_attitude::Recording;
use rootfuse_io::AtomicFile;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The columns of a fleet file after `device`, in the order [`FleetFileWriter::write_rows`]
/// takes them.
pub const FLEET_COLUMNS: [&str; 14] = [
    "t", "gx", "gy", "gz", "ax", "ay", "az", "mx", "my", "mz", "qw", "qx", "qy", "qz",
];

enum Sink {
    Parquet(ArrowWriter<AtomicFile>),
    Arrow(arrow::ipc::writer::FileWriter<AtomicFile>),
}

/// Recordings written as rows of one fleet file: `device` (int64), `t`, `gx..gz`, `ax..az`,
/// `mx..mz` and the truth `qw..qz` (float64; NaN where a recording has none), atomically.
///
/// [`write_group`](Self::write_group) interleaves its recordings time-major (row `k` of every
/// recording, then row `k + 1`), so that a reader's block holds many devices at once and the
/// batch engine's lanes are busy; groups follow each other.
pub struct FleetFileWriter {
    sink: Sink,
    schema: SchemaRef,
    path: PathBuf,
    rows: u64,
}

impl FleetFileWriter {
    /// Creates `path` as Parquet (Snappy) or Arrow IPC (CSV is refused: it holds one
    /// recording per file).
    pub fn create(path: impl AsRef<Path>, format: Format) -> Result<Self, ColumnarError> {
        let path = path.as_ref();
        let write_error = |e: &dyn std::fmt::Display| ColumnarError::Write {
            file: path.to_owned(),
            message: e.to_string(),
        };
        let mut fields = vec![Field::new(DEVICE, DataType::Int64, false)];
        fields.extend(
            FLEET_COLUMNS
                .iter()
                .map(|&n| Field::new(n, DataType::Float64, false)),
        );
        let schema = Arc::new(Schema::new(fields));
        let sink = match format {
            Format::Parquet => Sink::Parquet(
                ArrowWriter::try_new(
                    AtomicFile::create(path)?,
                    schema.clone(),
                    Some(parquet_properties()),
                )
                .map_err(|e| write_error(&e))?,
            ),
            Format::Arrow => Sink::Arrow(
                arrow::ipc::writer::FileWriter::try_new(AtomicFile::create(path)?, &schema)
                    .map_err(|e| write_error(&e))?,
            ),
            Format::Csv => {
                return Err(write_error(
                    &"a fleet file is Parquet or Arrow (.parquet, .arrow); CSV holds one recording per file",
                ));
            }
        };
        Ok(Self {
            sink,
            schema,
            path: path.to_owned(),
            rows: 0,
        })
    }

    /// Rows written so far.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Writes `recs` as devices `first_device..`, interleaved time-major.
    pub fn write_group(
        &mut self,
        first_device: i64,
        recs: &[Recording],
    ) -> Result<(), ColumnarError> {
        // (recording, row) in time-major order.
        let longest = recs.iter().map(Recording::len).max().unwrap_or(0);
        let order: Vec<(usize, usize)> = (0..longest)
            .flat_map(|k| {
                (0..recs.len())
                    .filter(move |&i| k < recs[i].len())
                    .map(move |i| (i, k))
            })
            .collect();
        for rows in order.chunks(BLOCK_ROWS) {
            let device: Vec<i64> = rows.iter().map(|&(i, _)| first_device + i as i64).collect();
            let values: Vec<[f64; 14]> = rows
                .iter()
                .map(|&(i, k)| std::array::from_fn(|c| value(&recs[i], k, c)))
                .collect();
            self.write_rows(&device, &values)?;
        }
        Ok(())
    }

    /// Writes rows as one record batch: `device[r]`, then `values[r]` in the order of
    /// [`FLEET_COLUMNS`] (NaN for an absent magnetometer or truth). A caller that generates
    /// rows as it goes (`rootfuse simulate`) writes blocks of at most
    /// [`BLOCK_ROWS`](crate::BLOCK_ROWS) rows this way instead of holding whole recordings
    /// for [`write_group`](Self::write_group). `device` and `values` must have the same
    /// length.
    pub fn write_rows(
        &mut self,
        device: &[i64],
        values: &[[f64; 14]],
    ) -> Result<(), ColumnarError> {
        if device.len() != values.len() {
            return Err(self.write_error(&format_args!(
                "{} device values for {} rows",
                device.len(),
                values.len()
            )));
        }
        let mut arrays: Vec<ArrayRef> = vec![Arc::new(Int64Array::from(device.to_vec()))];
        for c in 0..14 {
            let column = Float64Array::from_iter_values(values.iter().map(|v| v[c]));
            arrays.push(Arc::new(column));
        }
        let batch =
            RecordBatch::try_new(self.schema.clone(), arrays).map_err(|e| self.write_error(&e))?;
        let result = match &mut self.sink {
            Sink::Parquet(w) => w.write(&batch).map_err(|e| e.to_string()),
            Sink::Arrow(w) => w.write(&batch).map_err(|e| e.to_string()),
        };
        result.map_err(|e| self.write_error(&e))?;
        self.rows += values.len() as u64;
        Ok(())
    }

    /// Completes the file and renames it into place.
    pub fn finish(self) -> Result<(), ColumnarError> {
        let error = |e: &dyn std::fmt::Display| ColumnarError::Write {
            file: self.path.clone(),
            message: e.to_string(),
        };
        match self.sink {
            Sink::Parquet(w) => w.into_inner().map_err(|e| error(&e))?.finish()?,
            Sink::Arrow(mut w) => {
                w.finish().map_err(|e| error(&e))?;
                w.into_inner().map_err(|e| error(&e))?.finish()?;
            }
        }
        Ok(())
    }

    fn write_error(&self, e: &dyn std::fmt::Display) -> ColumnarError {
        ColumnarError::Write {
            file: self.path.clone(),
            message: e.to_string(),
        }
    }
}

/// Column `c` of [`FLEET_COLUMNS`] at row `k` (NaN for an absent magnetometer or truth).
fn value(rec: &Recording, k: usize, c: usize) -> f64 {
    match c {
        0 => rec.t[k],
        1..=3 => rec.gyr[k].to_array()[c - 1],
        4..=6 => rec.acc[k].to_array()[c - 4],
        7..=9 => rec
            .mag
            .as_ref()
            .map_or(f64::NAN, |m| m[k].to_array()[c - 7]),
        _ => rec
            .truth
            .as_ref()
            .map_or(f64::NAN, |q| q[k].to_array()[c - 10]),
    }
}
