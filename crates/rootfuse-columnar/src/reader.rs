//! [`FleetReader`]: a Parquet or Arrow IPC file read a block of rows at a time.

use crate::DEVICE;
use crate::error::{ColumnarError, Part};
use crate::kind::{self, Kind};
use crate::mapped::{Footer, IpcFile, IpcStream, Mapped, StreamEnd};
use crate::schema::{
    MAG, REQUIRED, check_schema, column_list, float_values, time_like, type_error,
};
use arrow::array::{Array, ArrayRef, AsArray, RecordBatch, RecordBatchReader};
use arrow::datatypes::{DataType, Int64Type};
use parquet::arrow::ProjectionMask;
use parquet::arrow::arrow_reader::{
    ArrowReaderMetadata, ArrowReaderOptions, ParquetRecordBatchReader,
    ParquetRecordBatchReaderBuilder,
};
use rootfuse_attitude::Vec3;
use rootfuse_attitude::units::{Sensor, Unit, Units};
use rootfuse_batch::FleetBlock;
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Rows per block read (and per record batch written): a few MB per block whatever the
/// length of the file.
pub const BLOCK_ROWS: usize = 65_536;

/// A device as written in the file: an integer or a string.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
enum DeviceKey {
    Int(i64),
    Text(String),
}

/// The devices of a fleet, numbered `0..` in order of first appearance across all files
/// read with it (so a device keeps its filter from one file to the next).
#[derive(Clone, Debug, Default)]
pub struct Devices {
    index: HashMap<DeviceKey, u32>,
    labels: Vec<String>,
    /// Devices named before any row ([`Devices::planned`]) and not yet seen, by label.
    planned: HashMap<String, u32>,
    /// Device number of the integer keys `0..SMALL_KEYS` seen (`u32::MAX`: not seen): rows
    /// of many devices interleave, so the key changes from row to row and a hash lookup per
    /// row showed in profiles.
    small: Vec<u32>,
}

/// Integer device keys below this are looked up in a table rather than hashed.
const SMALL_KEYS: i64 = 1 << 16;

impl Devices {
    /// Number of devices seen.
    pub fn len(&self) -> usize {
        self.labels.len()
    }

    /// True before any device was seen.
    pub fn is_empty(&self) -> bool {
        self.labels.is_empty()
    }

    /// Devices known before any row is read, numbered `0..labels.len()` in the order given
    /// (a per-device parameter table's devices: the fleet runner plans their lanes before
    /// their rows come). A row's device matches a label by its text, an integer `7` the label
    /// `"7"`; devices not listed are numbered from `labels.len()` on, in order of first
    /// appearance. `None` when a label is given twice (its index is returned in `Err`).
    ///
    /// ```
    /// use rootfuse_columnar::Devices;
    /// let devices = Devices::planned(&["b".to_string(), "7".to_string()]).unwrap();
    /// assert_eq!(devices.len(), 2);
    /// assert_eq!(devices.unseen().collect::<Vec<_>>(), ["b", "7"]);
    /// assert_eq!(Devices::planned(&["a".into(), "a".into()]).unwrap_err(), 1);
    /// ```
    pub fn planned(labels: &[String]) -> Result<Self, usize> {
        let mut devices = Self::default();
        for (i, label) in labels.iter().enumerate() {
            if devices.planned.insert(label.clone(), i as u32).is_some() {
                return Err(i);
            }
            devices.labels.push(label.clone());
        }
        Ok(devices)
    }

    /// Labels of the [`planned`](Self::planned) devices that no row has named so far, in
    /// plan order.
    pub fn unseen(&self) -> impl Iterator<Item = &str> {
        let mut unseen: Vec<(u32, &str)> = self
            .planned
            .iter()
            .map(|(label, &d)| (d, label.as_str()))
            .collect();
        unseen.sort_unstable();
        unseen.into_iter().map(|(_, label)| label)
    }

    /// Device `d` as written in its file (the file stem for a file without a device column).
    pub fn label(&self, d: u32) -> &str {
        self.labels.get(d as usize).map_or("", String::as_str)
    }

    /// The device number of the integer key `v` when it is below [`SMALL_KEYS`] and seen.
    #[inline]
    fn small_id(&self, v: i64) -> Option<u32> {
        let d = *self.small.get(usize::try_from(v).ok()?)?;
        (d != u32::MAX).then_some(d)
    }

    fn id(&mut self, key: DeviceKey) -> u32 {
        let small = match key {
            DeviceKey::Int(v) if (0..SMALL_KEYS).contains(&v) => Some(v as usize),
            _ => None,
        };
        if let DeviceKey::Int(v) = key
            && let Some(d) = self.small_id(v)
        {
            return d;
        }
        if let Some(&d) = self.index.get(&key) {
            return d;
        }
        let label = match &key {
            DeviceKey::Int(v) => v.to_string(),
            DeviceKey::Text(s) => s.clone(),
        };
        let d = match self.planned.remove(&label) {
            Some(d) => d,
            None => {
                self.labels.push(label);
                (self.labels.len() - 1) as u32
            }
        };
        if let Some(i) = small {
            if self.small.len() <= i {
                self.small.resize(i + 1, u32::MAX);
            }
            self.small[i] = d;
        }
        self.index.insert(key, d);
        d
    }

    /// The device named `label` (a file without a device column is one device, named after
    /// its stem).
    pub fn named(&mut self, label: &str) -> u32 {
        self.id(DeviceKey::Text(label.to_string()))
    }
}

/// One block of a file: the rows for the fleet runner and where they came from.
#[derive(Clone, Debug)]
pub struct FleetChunk {
    /// The rows, device numbers from [`Devices`].
    pub block: FleetBlock,
    /// The file's device column for these rows, as read (written back unchanged); `None`
    /// when the file has none.
    pub device_column: Option<ArrayRef>,
    /// Row group or record batch of these rows.
    pub part: Part,
    /// File row (0-based) of the block's first row.
    pub first_row: u64,
    /// Rows with a NaN, null or infinite IMU value (kept for the filter to skip and count).
    pub missing_imu: usize,
}

/// What a reader does with a NaN, null or infinite IMU value.
pub use rootfuse_io::ImuGaps;

enum Source {
    Parquet {
        file: std::fs::File,
        meta: ArrowReaderMetadata,
        projection: Vec<usize>,
        current: Option<ParquetRecordBatchReader>,
    },
    IpcFile {
        map: Mapped,
        file: IpcFile,
    },
    IpcStream {
        map: Mapped,
        stream: IpcStream,
    },
    /// Record batches from memory or another library (an Arrow C stream from Python).
    Batches {
        reader: Box<dyn RecordBatchReader + Send>,
    },
}

/// A Parquet or Arrow IPC (file or stream format) fleet read block by block.
///
/// The format is told by the file's first bytes (`PAR1`: Parquet; `ARROW1`: Arrow IPC
/// file); a file with neither magic is read as an Arrow IPC stream when its name is an Arrow
/// one ([`Format::of_path`](crate::Format::of_path): `.arrow`, `.arrows`, ...), else as
/// Parquet. A stream must end with its end-of-stream marker: one that stops after a whole
/// message is refused as truncated rather than read as complete.
///
/// Columns are found by name, as in the CSV format: `t` (s), `gx,gy,gz` (rad/s), `ax,ay,az`
/// (m/s²), optionally `mx,my,mz` (all three or none) and `device` (an integer or string
/// column; without it the file is one device named after its stem); numbers (float,
/// integer, decimal, or a dictionary of them; `t` also a timestamp, in s), read as `f64`
/// and converted by [`with_units`](Self::with_units) (raw counts); other columns are ignored and not read. A null IMU value is read as NaN (a dropped
/// packet). Row groups (record batches) without rows are skipped, not an error, and listed
/// ([`empty_parts`](Self::empty_parts)) for the caller to report; a file whose parts are
/// all empty has no rows ([`ColumnarError::Empty`] is the caller's to raise).
pub struct FleetReader {
    file: PathBuf,
    source: Source,
    format: &'static str,
    stem: String,
    gaps: ImuGaps,
    units: Units,
    parts: usize,
    part: usize,
    rows_read: u64,
    has_mag: bool,
    device_type: Option<DataType>,
    empty_parts: Vec<usize>,
    /// The rest of a record batch longer than [`BLOCK_ROWS`] (sliced without copying).
    pending: Option<(RecordBatch, Part)>,
}

impl FleetReader {
    /// Opens `path` (Parquet, Arrow IPC file or stream: see the type's documentation) and
    /// checks its schema.
    pub fn open(path: impl AsRef<Path>, gaps: ImuGaps) -> Result<Self, ColumnarError> {
        let path = path.as_ref();
        let io = |source| ColumnarError::Io {
            file: path.to_owned(),
            source,
        };
        let mut file = std::fs::File::open(path).map_err(io)?;
        let kind = kind::detect(path, &mut file).map_err(io)?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let map = |file: &std::fs::File, format: &'static str| {
            Mapped::open(file).map_err(|e| format_error(path, format, None, e))
        };
        let (source, parts, name, (_, has_mag, device_type)) = match kind {
            Kind::IpcFile => {
                let map = map(&file, "Arrow IPC")?;
                let buffer = map.buffer();
                let footer =
                    Footer::read(&buffer).map_err(|e| format_error(path, "Arrow IPC", None, e))?;
                let checked = check_schema(path, &footer.schema)?;
                let file = IpcFile::new(buffer, footer, checked.0.clone())
                    .map_err(|e| format_error(path, "Arrow IPC", None, e))?;
                let parts = file.len();
                (Source::IpcFile { map, file }, parts, "Arrow IPC", checked)
            }
            Kind::IpcStream => {
                let map = map(&file, "Arrow IPC stream")?;
                let (stream, schema) = IpcStream::open(map.buffer())
                    .map_err(|e| format_error(path, "Arrow IPC stream", None, e))?;
                let checked = check_schema(path, &schema)?;
                // The count is known only at the end.
                (
                    Source::IpcStream { map, stream },
                    usize::MAX,
                    "Arrow IPC stream",
                    checked,
                )
            }
            Kind::Parquet => {
                let meta = ArrowReaderMetadata::load(&file, ArrowReaderOptions::new())
                    .map_err(|e| format_error(path, "Parquet", None, e))?;
                let checked = check_schema(path, meta.schema())?;
                let parts = meta.metadata().num_row_groups();
                let source = Source::Parquet {
                    file,
                    meta,
                    projection: checked.0.clone(),
                    current: None,
                };
                (source, parts, "Parquet", checked)
            }
        };
        Ok(Self::reading(
            path.to_owned(),
            stem,
            source,
            name,
            parts,
            gaps,
            (has_mag, device_type),
        ))
    }

    /// A reader at the start of `source` (`parts` row groups or record batches; `usize::MAX`
    /// when a stream does not say), with the schema's findings `(has_mag, device_type)`.
    fn reading(
        file: PathBuf,
        stem: String,
        source: Source,
        format: &'static str,
        parts: usize,
        gaps: ImuGaps,
        (has_mag, device_type): (bool, Option<DataType>),
    ) -> Self {
        Self {
            file,
            source,
            format,
            stem,
            gaps,
            units: Units::default(),
            parts,
            part: 0,
            rows_read: 0,
            has_mag,
            device_type,
            empty_parts: Vec::new(),
            pending: None,
        }
    }

    /// Reads the record batches of `reader` (any [`RecordBatchReader`]: batches in memory, an
    /// Arrow C stream imported from another library) as a fleet, exactly as a file of those
    /// batches would be read. `name` stands for the file in messages (and names the one
    /// device of batches without a device column).
    ///
    /// ```
    /// use arrow::array::{Float64Array, RecordBatch, RecordBatchIterator, UInt32Array};
    /// use arrow::datatypes::{DataType, Field, Schema};
    /// use rootfuse_columnar::{Devices, FleetReader, ImuGaps};
    /// use std::sync::Arc;
    ///
    /// let mut fields = vec![Field::new("device", DataType::UInt32, false)];
    /// for name in ["t", "gx", "gy", "gz", "ax", "ay", "az"] {
    ///     fields.push(Field::new(name, DataType::Float64, false));
    /// }
    /// let schema = Arc::new(Schema::new(fields));
    /// let column = |v: f64| Arc::new(Float64Array::from(vec![v; 4])) as _;
    /// let mut columns = vec![Arc::new(UInt32Array::from(vec![7, 9, 7, 9])) as _];
    /// columns.push(Arc::new(Float64Array::from(vec![0.0, 0.0, 0.01, 0.01])) as _);
    /// columns.extend([0.0, 0.0, 0.0, 0.0, 0.0, 9.81].map(column));
    /// let batch = RecordBatch::try_new(schema.clone(), columns).unwrap();
    /// let batches = RecordBatchIterator::new([Ok(batch)], schema);
    /// let mut reader = FleetReader::from_batches("<memory>", Box::new(batches), ImuGaps::Keep).unwrap();
    /// let mut devices = Devices::default();
    /// let chunk = reader.next_chunk(&mut devices).unwrap().unwrap();
    /// assert_eq!(chunk.block.device, [0, 1, 0, 1]);
    /// assert_eq!(devices.label(1), "9");
    /// ```
    pub fn from_batches(
        name: &str,
        reader: Box<dyn RecordBatchReader + Send>,
        gaps: ImuGaps,
    ) -> Result<Self, ColumnarError> {
        let path = PathBuf::from(name);
        let (_, has_mag, device_type) = check_schema(&path, &reader.schema())?;
        Ok(Self::reading(
            path,
            name.to_string(),
            Source::Batches { reader },
            "Arrow",
            usize::MAX,
            gaps,
            (has_mag, device_type),
        ))
    }

    /// The file read (the name given to [`from_batches`](Self::from_batches)).
    pub fn path(&self) -> &Path {
        &self.file
    }

    /// True when the file has magnetometer columns.
    pub fn has_mag(&self) -> bool {
        self.has_mag
    }

    /// The type of the file's device column, `None` without one.
    pub fn device_type(&self) -> Option<&DataType> {
        self.device_type.as_ref()
    }

    /// Row groups (record batches) that had no rows, skipped.
    pub fn empty_parts(&self) -> &[usize] {
        &self.empty_parts
    }

    /// Rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.rows_read
    }

    /// Reads the fleet as written in `units`: every block is converted to the filters' units
    /// (s, rad/s, m/s², µT) as it is read. A timestamp or duration `t` says its own unit and
    /// is read in seconds whatever `units` says of time (one `--units time=ms` may serve a
    /// fleet of files whose `t` is int64 ms in some and a timestamp in others).
    pub fn with_units(mut self, units: Units) -> Self {
        self.units = units;
        self
    }

    /// The next block (at most [`BLOCK_ROWS`] rows, never empty), `None` at the end.
    pub fn next_chunk(
        &mut self,
        devices: &mut Devices,
    ) -> Result<Option<FleetChunk>, ColumnarError> {
        loop {
            let next = match self.pending.take() {
                Some(p) => Some(p),
                None => self.next_batch()?,
            };
            let Some((mut batch, part)) = next else {
                return Ok(None);
            };
            if batch.num_rows() == 0 {
                continue;
            }
            if batch.num_rows() > BLOCK_ROWS {
                let rest = batch.slice(BLOCK_ROWS, batch.num_rows() - BLOCK_ROWS);
                self.pending = Some((rest, part));
                batch = batch.slice(0, BLOCK_ROWS);
            }
            let first_row = self.rows_read;
            self.rows_read += batch.num_rows() as u64;
            let mut units = self.units;
            if batch
                .column_by_name("t")
                .is_some_and(|t| time_like(t.data_type()))
                && let Some(seconds) = Unit::parse(Sensor::Time, "s")
            {
                units.set(seconds);
            }
            let chunk = self.convert(&batch, part, first_row, devices).map(|mut c| {
                let b = &mut c.block;
                units.convert(&mut b.t, &mut b.gyr, &mut b.acc, b.mag.as_deref_mut());
                c
            });
            if let Source::IpcFile { map, .. } | Source::IpcStream { map, .. } = &self.source {
                // The block's values are copied out: let its pages go.
                map.release();
            }
            return chunk.map(Some);
        }
    }

    fn next_batch(&mut self) -> Result<Option<(RecordBatch, Part)>, ColumnarError> {
        let path = self.file.as_path();
        match &mut self.source {
            Source::IpcFile { file, .. } => loop {
                if self.part >= self.parts {
                    return Ok(None);
                }
                let part = Part::RecordBatch(self.part);
                self.part += 1;
                match file.batch(self.part - 1) {
                    Ok(None) => return Ok(None),
                    Err(e) => return Err(format_error(path, "Arrow IPC", Some(part), e)),
                    Ok(Some(b)) if b.num_rows() == 0 => {
                        self.empty_parts.push(self.part - 1);
                    }
                    Ok(Some(b)) => return Ok(Some((b, part))),
                }
            },
            Source::IpcStream { stream, .. } => loop {
                let part = Part::RecordBatch(self.part);
                let error = |e| format_error(path, "Arrow IPC stream", Some(part), e);
                match stream.next() {
                    Ok(None) => return Ok(None),
                    Err(Ok(StreamEnd::NoMarker)) => {
                        return Err(error(
                            "the file ends without the end-of-stream marker (truncated)".into(),
                        ));
                    }
                    Err(Ok(StreamEnd::InsideMessage)) => {
                        return Err(error("the file ends inside a message (truncated)".into()));
                    }
                    Err(Err(e)) => return Err(error(e)),
                    Ok(Some(b)) => {
                        self.part += 1;
                        if b.num_rows() > 0 {
                            return Ok(Some((b, part)));
                        }
                        self.empty_parts.push(self.part - 1);
                    }
                }
            },
            Source::Batches { reader } => loop {
                let part = Part::RecordBatch(self.part);
                match reader.next() {
                    None => return Ok(None),
                    Some(Err(e)) => return Err(format_error(path, "Arrow", Some(part), e)),
                    Some(Ok(b)) => {
                        self.part += 1;
                        if b.num_rows() > 0 {
                            return Ok(Some((b, part)));
                        }
                        self.empty_parts.push(self.part - 1);
                    }
                }
            },
            Source::Parquet {
                file,
                meta,
                projection,
                current,
            } => loop {
                if let Some(reader) = current {
                    // `self.part` is one past the row group being read.
                    let part = Part::RowGroup(self.part - 1);
                    match reader.next() {
                        Some(Ok(b)) => return Ok(Some((b, part))),
                        Some(Err(e)) => return Err(format_error(path, "Parquet", Some(part), e)),
                        None => *current = None,
                    }
                }
                if self.part >= self.parts {
                    return Ok(None);
                }
                let g = self.part;
                self.part += 1;
                if meta.metadata().row_group(g).num_rows() == 0 {
                    self.empty_parts.push(g);
                    continue;
                }
                let io = |source| ColumnarError::Io {
                    file: path.to_owned(),
                    source,
                };
                let mask = ProjectionMask::roots(meta.parquet_schema(), projection.iter().copied());
                let reader = ParquetRecordBatchReaderBuilder::new_with_metadata(
                    file.try_clone().map_err(io)?,
                    meta.clone(),
                )
                .with_row_groups(vec![g])
                .with_projection(mask)
                .with_batch_size(BLOCK_ROWS)
                .build()
                .map_err(|e| format_error(path, "Parquet", Some(Part::RowGroup(g)), e))?;
                *current = Some(reader);
            },
        }
    }

    fn convert(
        &self,
        batch: &RecordBatch,
        part: Part,
        first_row: u64,
        devices: &mut Devices,
    ) -> Result<FleetChunk, ColumnarError> {
        let n = batch.num_rows();
        let bad = |row: usize, column: &str, problem: String| ColumnarError::BadValue {
            file: self.file.clone(),
            part,
            row: first_row + row as u64,
            column: column.to_string(),
            problem,
        };
        let column = |name: &str| -> Result<Cow<'_, [f64]>, ColumnarError> {
            let col = batch
                .column_by_name(name)
                .ok_or_else(|| ColumnarError::MissingColumn {
                    file: self.file.clone(),
                    column: REQUIRED
                        .iter()
                        .chain(&MAG)
                        .find(|&&c| c == name)
                        .copied()
                        .unwrap_or("t"),
                    found: column_list(batch.schema().fields().iter().map(|f| f.name())),
                })?;
            float_values(col).ok_or_else(|| type_error(&self.file, name, col.data_type()))
        };
        let t = column("t")?.into_owned();
        if let Some(r) = t.iter().position(|v| v.is_nan()) {
            let null = batch.column_by_name("t").is_some_and(|c| c.is_null(r));
            let what = if null { "null" } else { "NaN" };
            return Err(bad(r, "t", format!("time is {what}")));
        }
        let mut imu = Vec::with_capacity(9);
        let names: Vec<&str> = REQUIRED[1..]
            .iter()
            .chain(if self.has_mag { &MAG[..] } else { &[] })
            .copied()
            .collect();
        for name in &names {
            let values = column(name)?;
            if self.gaps == ImuGaps::Refuse
                && let Some(r) = values.iter().position(|v| !v.is_finite())
            {
                return Err(bad(
                    r,
                    name,
                    format!(
                        "IMU value {} is not finite (null or NaN: a dropped packet)",
                        values[r]
                    ),
                ));
            }
            imu.push(values);
        }
        // Zipped, not indexed: no bounds check per value (each column has `n` values).
        let vec3 = |k: usize| -> Vec<Vec3<f64>> {
            imu[k]
                .iter()
                .zip(imu[k + 1].iter())
                .zip(imu[k + 2].iter())
                .map(|((&x, &y), &z)| Vec3::new(x, y, z))
                .collect()
        };
        let block_mag = self.has_mag.then(|| vec3(6));
        let device_column = batch.column_by_name(DEVICE).cloned();
        let device = match &device_column {
            None => vec![devices.named(&self.stem); n],
            Some(col) => device_ids(col, devices).map_err(|r| match r {
                Some(r) => bad(r, DEVICE, "device is null".into()),
                None => type_error(&self.file, DEVICE, col.data_type()),
            })?,
        };
        let block = FleetBlock {
            device,
            t,
            gyr: vec3(0),
            acc: vec3(3),
            mag: block_mag,
        };
        let missing_imu = block.rows_with_missing_imu(0..n);
        Ok(FleetChunk {
            block,
            device_column,
            part,
            first_row,
            missing_imu,
        })
    }

    /// The file's format name for messages (`Parquet`, `Arrow IPC`, `Arrow IPC stream`).
    pub fn format_name(&self) -> &'static str {
        self.format
    }
}

/// Device numbers of a device column: `Err(Some(row))` for a null, `Err(None)` for a type
/// that is neither integer nor string.
fn device_ids(col: &ArrayRef, devices: &mut Devices) -> Result<Vec<u32>, Option<usize>> {
    if col.null_count() > 0
        && let Some(r) = (0..col.len()).find(|&r| col.is_null(r))
    {
        return Err(Some(r));
    }
    let mut ids = Vec::with_capacity(col.len());
    let ty = col.data_type();
    if ty.is_integer() && *ty != DataType::UInt64 {
        let ints = arrow::compute::cast(col, &DataType::Int64).map_err(|_| None)?;
        // Rows of one device usually come in runs: look up only when the key changes; a
        // small key seen before is one table read (rows of interleaved devices change key
        // at every row).
        let mut last: Option<(i64, u32)> = None;
        for &v in ints.as_primitive::<Int64Type>().values() {
            let d = match (last, devices.small_id(v)) {
                (Some((k, d)), _) if k == v => d,
                (_, Some(d)) => d,
                _ => devices.id(DeviceKey::Int(v)),
            };
            last = Some((v, d));
            ids.push(d);
        }
    } else if ty.is_integer()
        || matches!(
            ty,
            DataType::Utf8 | DataType::LargeUtf8 | DataType::Utf8View | DataType::Dictionary(..)
        )
    {
        let text = arrow::compute::cast(col, &DataType::Utf8).map_err(|_| None)?;
        if let Some(r) = (0..text.len()).find(|&r| text.is_null(r)) {
            return Err(Some(r));
        }
        // Rows of one device usually come in runs: look up only when the key changes.
        let mut last: Option<(&str, u32)> = None;
        for v in text.as_string::<i32>().iter() {
            let v = v.unwrap_or_default();
            let d = match last {
                Some((k, d)) if k == v => d,
                _ => devices.id(DeviceKey::Text(v.to_string())),
            };
            last = Some((v, d));
            ids.push(d);
        }
    } else {
        return Err(None);
    }
    Ok(ids)
}

fn format_error(
    file: &Path,
    format: &'static str,
    part: Option<Part>,
    e: impl std::fmt::Display,
) -> ColumnarError {
    ColumnarError::Format {
        file: file.to_owned(),
        format,
        part: part.map_or_else(String::new, |p| format!("{p}: ")),
        message: e.to_string(),
    }
}
