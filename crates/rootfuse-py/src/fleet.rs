//! Fleets over Arrow: any Arrow stream (a pyarrow `Table` or `RecordBatchReader`, anything
//! with `__arrow_c_stream__`, the Arrow PyCapsule interface) through the batch engine's
//! [`FleetRunner`], estimates as an Arrow stream. The same reader, runner and writer as
//! `rootfuse run` on a Parquet or Arrow file (`rootfuse_columnar`), so each device's
//! estimates equal the CLI's bit for bit.

use crate::arrays::{DofArg, type_name};
use crate::filter::{precision, spec_from};
use arrow::array::{RecordBatch, RecordBatchReader};
use arrow::datatypes::SchemaRef;
use arrow::error::ArrowError;
use arrow::ffi_stream::{FFI_ArrowArrayStream, RecordBatchStreamReader};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyCapsule, PyDict};
use rootfuse_attitude::OrientationFilter;
use rootfuse_batch::{Columns, FleetRunner, OnError, RejectionTotals};
use rootfuse_columnar::{
    ColumnarError, Devices, EstimateWriter, FleetBlocks, FleetReader, ImuGaps, estimate_names,
};
use std::collections::VecDeque;
use std::ffi::CStr;
use std::sync::{Arc, Mutex};

/// The capsule name of the Arrow PyCapsule interface for streams.
const STREAM: &CStr = c"arrow_array_stream";

/// What messages call an Arrow stream given from Python.
const SOURCE: &str = "<arrow stream>";

/// Imports `obj`'s Arrow C stream (`obj.__arrow_c_stream__()`).
fn import_stream(obj: &Bound<'_, PyAny>) -> PyResult<RecordBatchStreamReader> {
    if !obj.hasattr("__arrow_c_stream__")? {
        return Err(PyTypeError::new_err(format!(
            "source: expected an Arrow stream (a pyarrow Table or RecordBatchReader, or any object with __arrow_c_stream__), got {}",
            obj.get_type().name().map_or("?".into(), |n| n.to_string())
        )));
    }
    let capsule = obj.call_method0("__arrow_c_stream__")?;
    let capsule = capsule.cast_into::<PyCapsule>().map_err(|_| {
        PyTypeError::new_err("source: __arrow_c_stream__ did not return a PyCapsule")
    })?;
    let pointer = capsule.pointer_checked(Some(STREAM))?;
    // SAFETY: by the Arrow PyCapsule interface, a capsule named "arrow_array_stream" holds an
    // `ArrowArrayStream` (checked by name just above). `from_raw` moves the stream out and
    // leaves a released one behind, which the capsule's destructor then ignores.
    unsafe { RecordBatchStreamReader::from_raw(pointer.as_ptr().cast::<FFI_ArrowArrayStream>()) }
        .map_err(|e| PyValueError::new_err(format!("source: not a readable Arrow stream: {e}")))
}

/// The fleet being estimated: input blocks in, estimate batches out, lazily.
struct Estimates {
    reader: FleetReader,
    /// Devices `0..planned` have parameters of their own.
    planned: usize,
    summary: Arc<Mutex<Option<Summary>>>,
    devices: Devices,
    runner: FleetRunner,
    blocks: FleetBlocks,
    writer: EstimateWriter,
    ready: VecDeque<RecordBatch>,
    done: bool,
}

impl Iterator for Estimates {
    type Item = Result<RecordBatch, ArrowError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(batch) = self.ready.pop_front() {
                return Some(Ok(batch));
            }
            if self.done {
                return None;
            }
            let step = self.blocks.next_block(
                &mut self.reader,
                &mut self.devices,
                &mut self.runner,
                OnError::Stop,
                |_| {},
            );
            let written = step.and_then(|block| match block {
                Some((chunk, est)) => {
                    let rows = 0..chunk.block.len();
                    self.writer.write(&chunk, &self.devices, &est, rows)?;
                    self.ready.extend(self.writer.take_batches());
                    Ok(())
                }
                None => {
                    self.done = true;
                    self.finish();
                    Ok(())
                }
            });
            if let Err(e) = written {
                self.done = true;
                return Some(Err(external(e)));
            }
        }
    }
}

impl Estimates {
    /// What the run did, for [`EstimateStream::summary`].
    fn finish(&mut self) {
        let unseen: Vec<String> = self.devices.unseen().map(str::to_string).collect();
        let mut rejections = RejectionTotals::default();
        for d in 0..self.devices.len() {
            rejections += self.runner.rejections(d as u32);
        }
        let summary = Summary {
            rows: self.reader.rows_read(),
            devices: self.devices.len() - unseen.len(),
            with_defaults: self.devices.len() - self.planned,
            unseen,
            rejections,
        };
        if let Ok(mut slot) = self.summary.lock() {
            *slot = Some(summary);
        }
    }
}

/// What a fleet run did (see [`EstimateStream::summary`]).
#[derive(Clone, Debug)]
struct Summary {
    rows: u64,
    devices: usize,
    with_defaults: usize,
    unseen: Vec<String>,
    rejections: RejectionTotals,
}

fn external(e: ColumnarError) -> ArrowError {
    ArrowError::ExternalError(Box::new(e))
}

impl RecordBatchReader for Estimates {
    fn schema(&self) -> SchemaRef {
        self.writer.schema()
    }
}

/// Estimates of a fleet as an Arrow stream, computed as they are read (one block of
/// `rootfuse_columnar::BLOCK_ROWS` rows at a time, so memory stays flat for a stream of any
/// length). Read it once, with anything that takes the Arrow PyCapsule interface:
/// `pyarrow.RecordBatchReader.from_stream(s)`, `pyarrow.table(s)`, polars, DuckDB.
#[pyclass(module = "rootfuse._rootfuse")]
pub struct EstimateStream {
    /// Taken when the stream is handed over (a Mutex: a Python object must be shareable
    /// between threads, the reader inside is only sendable).
    estimates: Mutex<Option<Estimates>>,
    schema: SchemaRef,
    summary: Arc<Mutex<Option<Summary>>>,
}

#[pymethods]
impl EstimateStream {
    /// The Arrow PyCapsule interface: hands the stream over (once).
    #[pyo3(signature = (requested_schema=None))]
    fn __arrow_c_stream__<'py>(
        &mut self,
        py: Python<'py>,
        requested_schema: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyCapsule>> {
        // The estimates have one schema; a consumer that asked for another casts itself.
        let _ = requested_schema;
        let estimates = self
            .estimates
            .lock()
            .ok()
            .and_then(|mut e| e.take())
            .ok_or_else(|| {
                PyValueError::new_err(
                    "this EstimateStream was already read: run the estimate again",
                )
            })?;
        let stream = FFI_ArrowArrayStream::new(Box::new(estimates));
        PyCapsule::new(py, stream, Some(STREAM.to_owned()))
    }

    /// The column names of the estimates: `device` (when the input has one), `t`, `qw..qz`,
    /// then `bx..bz`, `p_xx..p_zz`, `flags` as asked.
    #[getter]
    fn column_names(&self) -> Vec<String> {
        self.schema
            .fields()
            .iter()
            .map(|f| f.name().clone())
            .collect()
    }

    /// After the whole stream was read: `{"rows", "devices", "devices_with_defaults",
    /// "unseen_devices", "rejections"}` (devices seen; how many of them ran with the defaults
    /// because `device_params` does not name them; the devices of `device_params` no row
    /// named; the filters' skip counts summed over devices). `None` before the end.
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(s) = self.summary.lock().ok().and_then(|s| s.clone()) else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("rows", s.rows)?;
        d.set_item("devices", s.devices)?;
        d.set_item("devices_with_defaults", s.with_defaults)?;
        d.set_item("unseen_devices", s.unseen)?;
        d.set_item(
            "rejections",
            crate::filter::rejections_dict(py, &s.rejections)?,
        )?;
        Ok(Some(d))
    }

    fn __repr__(&self) -> String {
        format!(
            "EstimateStream(columns={:?}, read={})",
            self.column_names(),
            !self.estimates.lock().is_ok_and(|e| e.is_some())
        )
    }
}

/// Estimates of the IMU rows of an Arrow stream (a pyarrow `Table` or `RecordBatchReader`,
/// or any object with `__arrow_c_stream__`) or of a Parquet or Arrow IPC file (a path, read
/// in Rust as `rootfuse run` reads it: the fastest way in, nothing materialised first) through the batch engine's fleet runner: the
/// columns and rules of `rootfuse run` on a Parquet or Arrow file (`t` s; `gx..gz` rad/s;
/// `ax..az` m/s²; optional `mx..mz`; optional `device`, integer or string; numbers (floats,
/// integers, decimals; `t` also a timestamp, in s); rows of a device in time order, devices interleaved in any way). Returns an
/// `EstimateStream` with one estimate row per input row, in input order, each device's
/// estimates equal to the CLI's bit for bit.
///
/// `device_params`: per-device parameters, `{device: {name: value}}` (device as its label,
/// an integer device `7` as `7` or `"7"`), over `params`; devices not in it run with
/// `params`. Devices that share the structural parameters share SIMD chunks, and each
/// device equals a scalar run with its own parameters bit for bit. After the stream is
/// read, `EstimateStream.summary()` says how many devices ran with the defaults and which
/// devices of `device_params` never appeared.
#[pyfunction]
#[pyo3(signature = (source, filter, *, precision="f64", dof=None, bias=false, covariance=false, flags=false, device_params=None, **params))]
#[allow(clippy::too_many_arguments)]
pub fn estimate_arrow(
    py: Python<'_>,
    source: &Bound<'_, PyAny>,
    filter: &str,
    precision: &str,
    dof: Option<DofArg>,
    bias: bool,
    covariance: bool,
    flags: bool,
    device_params: Option<&Bound<'_, PyAny>>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<EstimateStream> {
    let prec = self::precision(precision)?;
    let spec = spec_from(filter, dof, params)?;
    let (labels, device_specs) = match device_params {
        Some(table) if !table.is_none() => {
            let table = table.cast::<PyDict>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "device_params: expected a dict {{device: {{name: value}}}} (rootfuse.arrow's functions also take a table with a `device` column), got {}",
                    type_name(table)
                ))
            })?;
            per_device_specs(py, table, filter, dof, params)?
        }
        _ => (Vec::new(), Vec::new()),
    };
    let devices = Devices::planned(&labels).map_err(|i| {
        PyValueError::new_err(format!(
            "device_params: device {:?} is given twice",
            labels[i]
        ))
    })?;
    let runner = FleetRunner::with_device_specs(
        &spec,
        &device_specs,
        prec,
        columns_of(bias, covariance, flags),
    )
    .map_err(|e| {
        PyValueError::new_err(format!(
            "device_params[{:?}]: not the same filter",
            labels[e.channel]
        ))
    })?;
    let reader = fleet_reader(py, source)?;
    // As the CLI: 9D asked for explicitly needs a magnetometer; a filter that is 9D by
    // default runs without one, its magnetometer corrections skipped and counted.
    if dof == Some(DofArg(9)) && !reader.has_mag() {
        return Err(PyValueError::new_err(format!(
            "{}: no magnetometer columns (mx, my, mz) for 9D operation: give dof=6",
            reader.path().display()
        )));
    }
    let columns = columns_of(bias, covariance, flags);
    let has_cov = spec.build::<f64>().attitude_covariance().is_some();
    let names = estimate_names(columns, has_cov);
    let writer = EstimateWriter::in_memory(reader.device_type(), &names);
    let schema = writer.schema();
    let summary = Arc::new(Mutex::new(None));
    Ok(EstimateStream {
        summary: summary.clone(),
        estimates: Mutex::new(Some(Estimates {
            reader,
            planned: labels.len(),
            devices,
            runner,
            summary,
            blocks: FleetBlocks::new(),
            writer,
            ready: VecDeque::new(),
            done: false,
        })),
        schema,
    })
}

/// The fleet reader of `source`: a path (`str` or `os.PathLike`) is opened and read in Rust,
/// exactly as `rootfuse run` reads it (Parquet or Arrow IPC, memory-mapped, decoded a row
/// group at a time, nothing materialised in Python); anything else is imported as an Arrow
/// stream.
fn fleet_reader(py: Python<'_>, source: &Bound<'_, PyAny>) -> PyResult<FleetReader> {
    let refuse = |e: ColumnarError| match e {
        ColumnarError::ColumnType { .. } => PyTypeError::new_err(e.to_string()),
        ColumnarError::Io { ref source, .. } if source.kind() == std::io::ErrorKind::NotFound => {
            pyo3::exceptions::PyFileNotFoundError::new_err(e.to_string())
        }
        ColumnarError::Io { .. } => pyo3::exceptions::PyOSError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    };
    if source.is_instance_of::<pyo3::types::PyString>() || source.hasattr("__fspath__")? {
        let path: std::path::PathBuf = source.extract()?;
        if rootfuse_columnar::Format::of_path(&path) == Some(rootfuse_columnar::Format::Csv) {
            return Err(PyValueError::new_err(format!(
                "{}: a CSV file: this reads fleets from Parquet and Arrow; a CSV recording is read by rootfuse.read_csv and run by Filter.update_batch (or `rootfuse run` on the file)",
                path.display()
            )));
        }
        // Opening reads the footer and the schema: file work, without the GIL.
        return py
            .detach(|| FleetReader::open(&path, ImuGaps::Keep))
            .map_err(refuse);
    }
    let stream = import_stream(source)?;
    FleetReader::from_batches(SOURCE, Box::new(stream), ImuGaps::Keep).map_err(refuse)
}

fn columns_of(bias: bool, covariance: bool, flags: bool) -> Columns {
    Columns {
        bias,
        covariance,
        flags,
    }
}

/// `{device: {name: value}}` as device labels and their specs (`params` under each).
fn per_device_specs(
    py: Python<'_>,
    table: &Bound<'_, PyDict>,
    filter: &str,
    dof: Option<DofArg>,
    params: Option<&Bound<'_, PyDict>>,
) -> PyResult<(Vec<String>, Vec<rootfuse_attitude::registry::FilterSpec>)> {
    let mut labels = Vec::with_capacity(table.len());
    let mut specs = Vec::with_capacity(table.len());
    for (device, values) in table.iter() {
        let label = device.str()?.to_string();
        let values = values.cast_into::<PyDict>().map_err(|_| {
            PyTypeError::new_err(format!(
                "device_params[{label:?}]: expected a dict of parameter values"
            ))
        })?;
        let merged = PyDict::new(py);
        if let Some(p) = params {
            merged.update(p.as_mapping())?;
        }
        merged.update(values.as_mapping())?;
        let spec = spec_from(filter, dof, Some(&merged)).map_err(|e| {
            let inner = e.value(py).to_string();
            if e.is_instance_of::<PyTypeError>(py) {
                PyTypeError::new_err(format!("device_params[{label:?}]: {inner}"))
            } else {
                PyValueError::new_err(format!("device_params[{label:?}]: {inner}"))
            }
        })?;
        labels.push(label);
        specs.push(spec);
    }
    Ok((labels, specs))
}
