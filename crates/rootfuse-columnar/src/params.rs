//! [`DeviceParams`]: a table of per-device filter parameters, read from CSV, Parquet or Arrow
//! IPC: a `device` column (integer or string, as in the fleet), then one column per
//! parameter.

use crate::error::ColumnarError;
use crate::{DEVICE, Format};
use arrow::array::{Array, AsArray, RecordBatch};
use arrow::datatypes::{DataType, Float64Type};
use std::path::{Path, PathBuf};

/// One device's row of a [`DeviceParams`] table.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceParamRow {
    /// Where the row is, for messages: `line 3` (CSV) or `row 1` (0-based, Parquet/Arrow).
    pub place: String,
    /// The device as the fleet names it (an integer device as its decimal text).
    pub device: String,
    /// One value per [`DeviceParams::names`]; `None` (an empty or null cell) keeps that
    /// parameter as given for the whole run.
    pub values: Vec<Option<f64>>,
}

/// Per-device filter parameters: the table `rootfuse run --device-params FILE` reads.
///
/// ```
/// let dir = std::env::temp_dir().join(format!("rootfuse-params-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let path = dir.join("params.csv");
/// std::fs::write(&path, "device,kp,ki\n7,0.8,\nleft,1.5,0.01\n").unwrap();
/// let table = rootfuse_columnar::DeviceParams::read(&path).unwrap();
/// assert_eq!(table.names, ["kp", "ki"]);
/// assert_eq!(table.rows[0].device, "7");
/// assert_eq!(table.rows[0].values, [Some(0.8), None]);
/// assert_eq!(table.rows[1].place, "line 3");
/// std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceParams {
    /// The file read.
    pub file: PathBuf,
    /// The parameter names, in column order.
    pub names: Vec<String>,
    /// One row per device, in file order.
    pub rows: Vec<DeviceParamRow>,
}

impl DeviceParams {
    /// Reads `path`: CSV by its `.csv` extension, otherwise Parquet or Arrow IPC (told by
    /// the extension, see [`Format::of_path`]). Every value must be a number (or empty /
    /// null); a device may appear once, a parameter column once. Errors name the file, the row or line and the column.
    pub fn read(path: impl AsRef<Path>) -> Result<Self, ColumnarError> {
        let path = path.as_ref();
        match Format::of_path(path) {
            Some(Format::Csv) => read_csv(path),
            Some(Format::Parquet) | Some(Format::Arrow) => read_columnar(path),
            None => Err(bad(
                path,
                "",
                "",
                "the file must end in .csv, .parquet or .arrow".into(),
            )),
        }
        .and_then(Self::check_unique)
    }

    fn check_unique(self) -> Result<Self, ColumnarError> {
        // A parameter in two columns would have one value silently win over the other.
        if let Some((_, name)) = self
            .names
            .iter()
            .enumerate()
            .find(|(i, n)| self.names[..*i].contains(n))
        {
            return Err(bad(
                &self.file,
                "",
                name,
                "the table has this column twice; give each parameter one column".into(),
            ));
        }
        let mut seen = std::collections::HashSet::new();
        for r in &self.rows {
            if !seen.insert(r.device.as_str()) {
                return Err(bad(
                    &self.file,
                    &r.place,
                    DEVICE,
                    format!("device {} appears twice", r.device),
                ));
            }
        }
        Ok(self)
    }
}

fn bad(file: &Path, place: &str, column: &str, problem: String) -> ColumnarError {
    ColumnarError::Param {
        file: file.to_owned(),
        place: if place.is_empty() {
            String::new()
        } else {
            format!("{place}, ")
        },
        column: column.to_string(),
        problem,
    }
}

fn read_csv(path: &Path) -> Result<DeviceParams, ColumnarError> {
    let io = |e: csv::Error| bad(path, "", "", format!("cannot read: {e}"));
    let mut reader = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(io)?;
    let header: Vec<String> = reader
        .headers()
        .map_err(io)?
        .iter()
        .map(str::to_string)
        .collect();
    let device = header
        .iter()
        .position(|h| h == DEVICE)
        .ok_or_else(|| bad(path, "line 1", DEVICE, "missing required column".into()))?;
    let names: Vec<String> = header.iter().filter(|h| *h != DEVICE).cloned().collect();
    let mut rows = Vec::new();
    for (i, record) in reader.records().enumerate() {
        let place = format!("line {}", i + 2);
        let record = record.map_err(|e| bad(path, &place, "", e.to_string()))?;
        let label = record.get(device).unwrap_or("").to_string();
        if label.is_empty() {
            return Err(bad(path, &place, DEVICE, "the device is empty".into()));
        }
        let mut values = Vec::with_capacity(names.len());
        for (c, h) in header.iter().enumerate() {
            if c == device {
                continue;
            }
            let cell = record.get(c).unwrap_or("");
            values.push(if cell.is_empty() {
                None
            } else {
                Some(cell.parse::<f64>().map_err(|_| {
                    bad(path, &place, h, format!("expected a number, got {cell:?}"))
                })?)
            });
        }
        rows.push(DeviceParamRow {
            place,
            device: label,
            values,
        });
    }
    Ok(DeviceParams {
        file: path.to_owned(),
        names,
        rows,
    })
}

fn read_columnar(path: &Path) -> Result<DeviceParams, ColumnarError> {
    let text = |e: &dyn std::fmt::Display| bad(path, "", "", format!("cannot read: {e}"));
    let file = std::fs::File::open(path).map_err(|e| text(&e))?;
    let batches: Vec<RecordBatch> = if Format::of_path(path) == Some(Format::Parquet) {
        parquet::arrow::arrow_reader::ParquetRecordBatchReaderBuilder::try_new(file)
            .and_then(|b| b.build())
            .map_err(|e| text(&e))?
            .collect::<Result<_, _>>()
            .map_err(|e| text(&e))?
    } else {
        arrow::ipc::reader::FileReader::try_new(std::io::BufReader::new(file), None)
            .map_err(|e| text(&e))?
            .collect::<Result<_, _>>()
            .map_err(|e| text(&e))?
    };
    let mut names = Vec::new();
    let mut rows = Vec::new();
    let mut first = 0usize;
    for batch in &batches {
        let schema = batch.schema();
        let device = schema
            .index_of(DEVICE)
            .map_err(|_| bad(path, "", DEVICE, "missing required column".into()))?;
        if names.is_empty() {
            names = schema
                .fields()
                .iter()
                .map(|f| f.name().clone())
                .filter(|n| n != DEVICE)
                .collect();
        }
        let labels = arrow::compute::cast(batch.column(device), &DataType::Utf8).map_err(|_| {
            bad(
                path,
                "",
                DEVICE,
                "expected an integer or string column".into(),
            )
        })?;
        let labels = labels.as_string::<i32>();
        let mut columns = Vec::new();
        for (c, f) in schema.fields().iter().enumerate() {
            if c == device {
                continue;
            }
            let numeric = f.data_type().is_numeric();
            let values = arrow::compute::cast(batch.column(c), &DataType::Float64)
                .ok()
                .filter(|_| numeric)
                .ok_or_else(|| {
                    bad(
                        path,
                        "",
                        f.name(),
                        format!("has type {}, expected numbers", f.data_type()),
                    )
                })?;
            columns.push(values);
        }
        for r in 0..batch.num_rows() {
            let place = format!("row {}", first + r);
            if labels.is_null(r) {
                return Err(bad(path, &place, DEVICE, "the device is null".into()));
            }
            let values = columns
                .iter()
                .map(|col| {
                    let col = col.as_primitive::<Float64Type>();
                    (!col.is_null(r)).then(|| col.value(r))
                })
                .collect();
            rows.push(DeviceParamRow {
                place,
                device: labels.value(r).to_string(),
                values,
            });
        }
        first += batch.num_rows();
    }
    Ok(DeviceParams {
        file: path.to_owned(),
        names,
        rows,
    })
}
