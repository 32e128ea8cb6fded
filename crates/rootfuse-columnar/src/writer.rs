//! [`EstimateWriter`]: estimates written block by block as Parquet, Arrow IPC or CSV.

use crate::error::ColumnarError;
use crate::reader::{Devices, FleetChunk};
use crate::{DEVICE, Format};
use arrow::array::{ArrayRef, BooleanArray, Float64Array, RecordBatch, UInt8Array};
use arrow::datatypes::{DataType, Field, Schema, SchemaRef};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;
use parquet::schema::types::ColumnPath;
use rootfuse_batch::{BlockEstimates, Columns};
use rootfuse_io::{AtomicFile, CsvEstimateWriter};
use std::path::Path;
use std::sync::Arc;

/// Rows per Parquet row group written: bounds the writer's buffer (a row group is encoded in
/// memory before it is written) to a few tens of MB.
pub const ROW_GROUP_ROWS: usize = 1 << 18;

/// Writer settings of every Parquet file written here: Snappy, row groups of
/// [`ROW_GROUP_ROWS`], and dictionary encoding for the device column only. Float columns of
/// sensor readings and estimates hardly ever repeat a value: a dictionary for them costs a
/// hash-table insert per value (a fifth of a Mahony fleet run's time) before the encoder
/// gives up on it at the dictionary page limit.
pub(crate) fn parquet_properties() -> WriterProperties {
    WriterProperties::builder()
        .set_compression(Compression::SNAPPY)
        .set_max_row_group_row_count(Some(ROW_GROUP_ROWS))
        .set_dictionary_enabled(false)
        .set_column_dictionary_enabled(ColumnPath::from(DEVICE), true)
        .build()
}

/// Where an estimate column's values come from (its name resolved once per block).
#[derive(Clone, Copy)]
enum Source {
    Time,
    /// `qw, qx, qy, qz`.
    Quat(usize),
    /// `bx, by, bz`.
    Bias(usize),
    /// `p_xx, p_xy, p_xz, p_yy, p_yz, p_zz`.
    Covariance(usize),
    Flags,
}

impl Source {
    /// The source of the column `name` (one of [`estimate_names`]; anything else is `flags`).
    fn of(name: &str) -> Self {
        let find = |list: &[&str]| list.iter().position(|n| *n == name);
        if name == "t" {
            Self::Time
        } else if let Some(k) = find(&["qw", "qx", "qy", "qz"]) {
            Self::Quat(k)
        } else if let Some(k) = find(&["bx", "by", "bz"]) {
            Self::Bias(k)
        } else if let Some(k) = find(&["p_xx", "p_xy", "p_xz", "p_yy", "p_yz", "p_zz"]) {
            Self::Covariance(k)
        } else {
            debug_assert_eq!(name, "flags", "not an estimate column");
            Self::Flags
        }
    }
}

/// The estimate columns after `t` for `columns` (`qw..qz`, then `bx..bz`, `p_xx..p_zz`,
/// `flags` as asked), as [`rootfuse_io::write_estimates`] names them.
pub fn estimate_names(columns: Columns, covariance: bool) -> Vec<&'static str> {
    let mut names = vec!["t", "qw", "qx", "qy", "qz"];
    if columns.bias {
        names.extend(["bx", "by", "bz"]);
    }
    if columns.covariance && covariance {
        names.extend(["p_xx", "p_xy", "p_xz", "p_yy", "p_yz", "p_zz"]);
    }
    if columns.flags {
        names.push("flags");
    }
    names
}

/// `device` (when the input had one, of its type), then `names`: float64, `flags` uint8.
fn estimate_schema(device: Option<&DataType>, names: &[&str]) -> SchemaRef {
    let mut fields: Vec<Field> = Vec::new();
    if let Some(ty) = device {
        fields.push(Field::new(DEVICE, ty.clone(), false));
    }
    for &name in names {
        let ty = if name == "flags" {
            DataType::UInt8
        } else {
            DataType::Float64
        };
        fields.push(Field::new(name, ty, false));
    }
    Arc::new(Schema::new(fields))
}

enum Sink {
    Parquet(ArrowWriter<AtomicFile>),
    Arrow(arrow::ipc::writer::FileWriter<AtomicFile>),
    Csv(CsvEstimateWriter),
    /// Record batches kept for the caller ([`EstimateWriter::take_batches`]).
    Memory(Vec<RecordBatch>),
}

/// Estimate rows written as they come, to a temporary file renamed into place by
/// [`finish`](Self::finish) (dropped unfinished, nothing is left behind).
///
/// Columns: `device` (when the input had one: Parquet and Arrow keep its type, CSV writes it
/// as text), then [`estimate_names`] (float64; `flags` uint8 in Parquet and Arrow).
pub struct EstimateWriter {
    sink: Sink,
    schema: SchemaRef,
    path: std::path::PathBuf,
}

impl EstimateWriter {
    /// Creates `path` in `format`; `device` is the input's device column type (`None`: no
    /// device column), `names` from [`estimate_names`].
    pub fn create(
        path: impl AsRef<Path>,
        format: Format,
        device: Option<&DataType>,
        names: &[&str],
    ) -> Result<Self, ColumnarError> {
        let path = path.as_ref();
        let schema = estimate_schema(device, names);
        let write_error = |e: &dyn std::fmt::Display| ColumnarError::Write {
            file: path.to_owned(),
            message: e.to_string(),
        };
        let sink = match format {
            Format::Csv => Sink::Csv(CsvEstimateWriter::create(
                path,
                device.map(|_| DEVICE),
                names,
            )?),
            Format::Parquet => {
                let file = AtomicFile::create(path)?;
                Sink::Parquet(
                    ArrowWriter::try_new(file, schema.clone(), Some(parquet_properties()))
                        .map_err(|e| write_error(&e))?,
                )
            }
            Format::Arrow => {
                let file = AtomicFile::create(path)?;
                Sink::Arrow(
                    arrow::ipc::writer::FileWriter::try_new(file, &schema)
                        .map_err(|e| write_error(&e))?,
                )
            }
        };
        Ok(Self {
            sink,
            schema,
            path: path.to_owned(),
        })
    }

    /// Estimates kept in memory as record batches (one per [`write`](Self::write)), for the
    /// caller to take with [`take_batches`](Self::take_batches): the columns and types of the
    /// Parquet and Arrow files. `device` and `names` as for [`create`](Self::create).
    pub fn in_memory(device: Option<&DataType>, names: &[&str]) -> Self {
        Self {
            sink: Sink::Memory(Vec::new()),
            schema: estimate_schema(device, names),
            path: std::path::PathBuf::from("<memory>"),
        }
    }

    /// The schema of the estimates written.
    pub fn schema(&self) -> SchemaRef {
        self.schema.clone()
    }

    /// The record batches written since the last call (always empty for a file).
    pub fn take_batches(&mut self) -> Vec<RecordBatch> {
        match &mut self.sink {
            Sink::Memory(batches) => std::mem::take(batches),
            _ => Vec::new(),
        }
    }

    /// Writes the estimates of rows `rows` of one block (rows not
    /// [`kept`](BlockEstimates::kept) are left out).
    pub fn write(
        &mut self,
        chunk: &FleetChunk,
        devices: &Devices,
        est: &BlockEstimates,
        rows: std::ops::Range<usize>,
    ) -> Result<(), ColumnarError> {
        let block = &chunk.block;
        let names: Vec<&str> = self
            .schema
            .fields()
            .iter()
            .map(|f| f.name().as_str())
            .filter(|n| *n != DEVICE)
            .collect();
        let kept: Vec<usize> = rows.clone().filter(|&r| est.kept[r]).collect();
        // Each column's source resolved once, not by its name at every row.
        let sources: Vec<Source> = names.iter().map(|n| Source::of(n)).collect();
        let value = |source: Source, r: usize| -> f64 {
            match source {
                Source::Time => block.t[r],
                Source::Quat(k) => est.quat[r].to_array()[k],
                Source::Bias(k) => est.bias.get(r).map_or(0.0, |b| b.to_array()[k]),
                Source::Covariance(k) => est.covariance.get(r).map_or(f64::NAN, |p| p[k]),
                Source::Flags => f64::from(est.flags.get(r).copied().unwrap_or(0)),
            }
        };
        let write_error = |e: &dyn std::fmt::Display| ColumnarError::Write {
            file: self.path.clone(),
            message: e.to_string(),
        };
        if let Sink::Csv(w) = &mut self.sink {
            let mut row = Vec::with_capacity(names.len());
            for &r in &kept {
                row.clear();
                row.extend(sources.iter().map(|&source| value(source, r)));
                w.write_row(devices.label(block.device[r]), &row)?;
            }
            return Ok(());
        }
        let mut arrays: Vec<ArrayRef> = Vec::new();
        if self.schema.field_with_name(DEVICE).is_ok() {
            let col = chunk
                .device_column
                .as_ref()
                .ok_or_else(|| ColumnarError::Write {
                    file: self.path.clone(),
                    message: "a block without the device column".into(),
                })?;
            let col = col.slice(rows.start, rows.len());
            let mask = BooleanArray::from(est.kept[rows].to_vec());
            arrays.push(arrow::compute::filter(&col, &mask).map_err(|e| write_error(&e))?);
        }
        for &source in &sources {
            // `t` and the quaternion, every file's columns, are read without `value`'s match
            // at every row (a Mahony fleet run took 3–6 % longer through it).
            let array: ArrayRef = match source {
                Source::Flags => Arc::new(UInt8Array::from_iter_values(
                    kept.iter().map(|&r| est.flags[r]),
                )),
                Source::Time => Arc::new(Float64Array::from_iter_values(
                    kept.iter().map(|&r| block.t[r]),
                )),
                Source::Quat(k) => Arc::new(Float64Array::from_iter_values(
                    kept.iter().map(|&r| est.quat[r].to_array()[k]),
                )),
                _ => Arc::new(Float64Array::from_iter_values(
                    kept.iter().map(|&r| value(source, r)),
                )),
            };
            arrays.push(array);
        }
        let batch =
            RecordBatch::try_new(self.schema.clone(), arrays).map_err(|e| write_error(&e))?;
        match &mut self.sink {
            Sink::Parquet(w) => w.write(&batch).map_err(|e| write_error(&e)),
            Sink::Arrow(w) => w.write(&batch).map_err(|e| write_error(&e)),
            Sink::Memory(batches) => {
                batches.push(batch);
                Ok(())
            }
            Sink::Csv(_) => Ok(()),
        }
    }

    /// Completes the file and renames it into place.
    pub fn finish(self) -> Result<(), ColumnarError> {
        Ok(self.close()?.commit()?)
    }

    /// Completes the file without putting it in place: it waits under its temporary name
    /// until [`Staged::commit`](rootfuse_io::Staged::commit) (removed if dropped), so that a
    /// run writes all its outputs or none.
    pub fn close(self) -> Result<rootfuse_io::Staged, ColumnarError> {
        let path = self.path;
        let write_error = |e: &dyn std::fmt::Display| ColumnarError::Write {
            file: path.clone(),
            message: e.to_string(),
        };
        Ok(match self.sink {
            Sink::Csv(w) => w.close()?,
            Sink::Parquet(w) => w.into_inner().map_err(|e| write_error(&e))?.close()?,
            Sink::Arrow(mut w) => {
                w.finish().map_err(|e| write_error(&e))?;
                w.into_inner().map_err(|e| write_error(&e))?.close()?
            }
            Sink::Memory(_) => rootfuse_io::Staged::nothing(path),
        })
    }
}
