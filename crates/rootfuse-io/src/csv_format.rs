//! The CSV format of recordings and estimates: reader, writers, index, folder listing.

use rootfuse_attitude::Quat;
use rootfuse_attitude::Recording;
use rootfuse_attitude::Vec3;
use std::borrow::ToOwned;
use std::fmt::Write as _;
use std::format;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::string::{String, ToString};
use std::vec;
use std::vec::Vec;

/// Why a CSV file could not be read. Lines and column indices are 1-based; the header is
/// line 1.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be opened or read (missing file, permissions, I/O failure).
    #[error("{file}: cannot read: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The CSV layer failed (for example invalid UTF-8 in the header).
    #[error("{file}: line {line}: malformed CSV: {message}")]
    Csv {
        /// The file.
        file: PathBuf,
        /// Line where it happened (0 when unknown).
        line: u64,
        /// The CSV layer's description.
        message: String,
    },
    /// The file has no header line.
    #[error("{file}: line 1: empty file (no header)")]
    Empty {
        /// The file.
        file: PathBuf,
    },
    /// A required column (or one of a column group that is partly present) is missing.
    #[error("{file}: line 1: missing required column `{column}`")]
    MissingColumn {
        /// The file.
        file: PathBuf,
        /// The missing column's name.
        column: &'static str,
    },
    /// A column name appears twice, so which one to use is ambiguous.
    #[error("{file}: line 1, column `{column}` (#{index}): duplicate column name")]
    DuplicateColumn {
        /// The file.
        file: PathBuf,
        /// The repeated name.
        column: String,
        /// 1-based index of the second occurrence.
        index: usize,
    },
    /// A data row has a different number of fields than the header.
    #[error("{file}: line {line}: expected {expected} fields (as in the header), found {found}")]
    FieldCount {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Fields in the header.
        expected: usize,
        /// Fields in this row.
        found: usize,
    },
    /// A cell is not a number.
    #[error("{file}: line {line}, column `{column}` (#{index}): `{text}` is not a number")]
    NotNumeric {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Column name.
        column: String,
        /// 1-based column index.
        index: usize,
        /// The cell as written (lossy UTF-8).
        text: String,
    },
    /// A time stamp is NaN or infinite.
    #[error("{file}: line {line}, column `{column}` (#{index}): time {value} is not finite")]
    NonFiniteTime {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Column name (`t`).
        column: String,
        /// 1-based column index.
        index: usize,
        /// The value read.
        value: f64,
    },
    /// A time stamp does not exceed the previous one.
    #[error(
        "{file}: line {line}, column `{column}` (#{index}): time {value} does not increase (previous {previous})"
    )]
    NonMonotonicTime {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Column name (`t`).
        column: String,
        /// 1-based column index.
        index: usize,
        /// This sample's time, s.
        value: f64,
        /// The previous sample's time, s.
        previous: f64,
    },
    /// An IMU reading (gyroscope, accelerometer, magnetometer) is NaN or infinite.
    ///
    /// Missing IMU values are not part of the format (only the ground truth may be unknown);
    /// a filter must not be fed a silently repaired value.
    #[error("{file}: line {line}, column `{column}` (#{index}): IMU value {value} is not finite")]
    NonFiniteImu {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Column name.
        column: String,
        /// 1-based column index.
        index: usize,
        /// The value read.
        value: f64,
    },
    /// A ground-truth component is infinite (NaN is allowed and means "unknown").
    #[error(
        "{file}: line {line}, column `{column}` (#{index}): truth value {value} is infinite (use NaN for unknown)"
    )]
    InfiniteTruth {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Column name.
        column: String,
        /// 1-based column index.
        index: usize,
        /// The value read.
        value: f64,
    },
    /// An estimate value (`t`, `qw..qz` of an estimate file) is NaN or infinite.
    #[error(
        "{file}: line {line}, column `{column}` (#{index}): estimate value {value} is not finite"
    )]
    NonFiniteEstimate {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Column name.
        column: String,
        /// 1-based column index.
        index: usize,
        /// The value read.
        value: f64,
    },
    /// A quaternion (estimate or known truth) is far from unit norm, so it is no orientation:
    /// scoring it would be meaningless (an all-zero quaternion would score as perfect).
    #[error(
        "{file}: line {line}: quaternion `{columns}` has norm {norm}, not 1 (within {UNIT_NORM_TOLERANCE})"
    )]
    NotUnitQuaternion {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// The quaternion's columns, `qw,qx,qy,qz`.
        columns: &'static str,
        /// Its norm.
        norm: f64,
    },
    /// The `use` cell is neither `0` nor `1`.
    #[error("{file}: line {line}, column `{column}` (#{index}): `{text}` is not 0 or 1")]
    BadUse {
        /// The file.
        file: PathBuf,
        /// The line.
        line: u64,
        /// Column name (`use`).
        column: String,
        /// 1-based column index.
        index: usize,
        /// The cell as written (lossy UTF-8).
        text: String,
    },
}

/// Why a CSV file could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// Creating, writing or renaming failed.
    #[error("{file}: cannot write: {source}")]
    Io {
        /// The target file.
        file: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A column has a different length than the time column.
    #[error("{file}: column `{column}` has {found} values, the time column has {expected}")]
    Length {
        /// The target file.
        file: PathBuf,
        /// The column.
        column: String,
        /// Number of time stamps.
        expected: usize,
        /// Values in this column.
        found: usize,
    },
    /// An extra column name is empty, repeats a name or contains a comma, quote or line break.
    #[error("{file}: bad column name `{column}`")]
    BadColumnName {
        /// The target file.
        file: PathBuf,
        /// The name.
        column: String,
    },
}

/// One row of a dataset's `index.csv` (`trial,group,fs_hz,n_samples,n_use,duration_s`).
///
/// Only `trial` is required; the other columns are `None` when absent.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexEntry {
    /// Trial name = file stem of `<trial>.csv`.
    pub trial: String,
    /// Group label (`undisturbed`, `disturbed`).
    pub group: Option<String>,
    /// Sampling rate, Hz.
    pub fs_hz: Option<f64>,
    /// Number of samples (data rows).
    pub n_samples: Option<usize>,
    /// Number of rows with `use = 1`.
    pub n_use: Option<usize>,
    /// Duration, s.
    pub duration_s: Option<f64>,
}

/// How far from 1 the norm of a quaternion read may be: a quaternion written with three
/// decimals is within 2·10⁻³ of unit norm; a zero or unnormalised one is far outside.
pub const UNIT_NORM_TOLERANCE: f64 = 0.01;

/// The quaternion is far from unit norm (NaN, i.e. unknown, is not).
fn not_unit(q: &[f64; 4]) -> Option<f64> {
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    ((norm - 1.0).abs() > UNIT_NORM_TOLERANCE).then_some(norm)
}

/// A cell as written, for a message: lossy UTF-8 with control characters (a NUL byte, a
/// carriage return) escaped, so the message shows what is in the file.
fn shown(cell: &[u8]) -> String {
    let mut out = String::new();
    for c in String::from_utf8_lossy(cell).chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// What the reader does with an IMU value (gyroscope, accelerometer, magnetometer) that is
/// `NaN` or infinite, as wireless IMU logs write for a dropped packet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImuGaps {
    /// Refuse the file ([`ReadError::NonFiniteImu`]): a filter must not be fed a silently
    /// repaired value.
    #[default]
    Refuse,
    /// Keep the value as read. Every filter screens it ([`Screened`](rootfuse_attitude::filters::Screened)): a
    /// non-finite gyroscope skips the whole sample, a non-finite accelerometer or magnetometer
    /// skips that correction, and each skip is counted in [`Rejections`](rootfuse_attitude::filters::Rejections).
    Keep,
}

// Column groups, in the order their values are stored.
const REQUIRED: [&str; 7] = ["t", "gx", "gy", "gz", "ax", "ay", "az"];
const MAG: [&str; 3] = ["mx", "my", "mz"];
const QUAT: [&str; 4] = ["qw", "qx", "qy", "qz"];

/// Reads one CSV recording from a file; the recording is named after the file stem.
///
/// See the [crate documentation](crate) for the format and the errors.
pub fn read_csv(path: impl AsRef<Path>) -> Result<Recording, ReadError> {
    read_csv_with(path, ImuGaps::Refuse)
}

/// [`read_csv`] with a choice of what a non-finite IMU value does.
pub fn read_csv_with(path: impl AsRef<Path>, gaps: ImuGaps) -> Result<Recording, ReadError> {
    CsvBlocks::open(path, gaps)?.read_all()
}

/// Reads one CSV recording from any reader; `file` is only used in error messages and `name`
/// becomes [`Recording::name`].
pub fn read_csv_from<R: std::io::Read>(
    reader: R,
    file: impl AsRef<Path>,
    name: &str,
) -> Result<Recording, ReadError> {
    CsvBlocks::new(reader, file, name, ImuGaps::Refuse)?.read_all()
}

/// A CSV recording read a block of rows at a time, so that a long recording can be processed
/// in bounded memory; the same format, checks and errors as [`read_csv_with`] (which reads
/// the whole file through it).
///
/// ```
/// use rootfuse_io::{CsvBlocks, ImuGaps};
///
/// let text = "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.8\n0.02,0,0,0,0,0,9.8\n";
/// let mut blocks = CsvBlocks::new(text.as_bytes(), "mem.csv", "mem", ImuGaps::Refuse).unwrap();
/// let mut rec = blocks.empty_recording();
/// assert_eq!(blocks.read_into(&mut rec, 2).unwrap(), 2);
/// rec.t.clear();
/// assert_eq!(blocks.read_into(&mut rec, 2).unwrap(), 1);
/// assert_eq!(rec.t, [0.02]);
/// ```
pub struct CsvBlocks<R: std::io::Read> {
    rdr: csv::Reader<R>,
    record: csv::ByteRecord,
    file: PathBuf,
    name: String,
    header: Vec<String>,
    layout: Layout,
    gaps: ImuGaps,
    previous_t: f64,
}

impl CsvBlocks<std::io::BufReader<std::fs::File>> {
    /// Opens a CSV recording and reads its header; the recording is named after the file stem.
    pub fn open(path: impl AsRef<Path>, gaps: ImuGaps) -> Result<Self, ReadError> {
        let path = path.as_ref();
        let file = std::fs::File::open(path).map_err(|source| ReadError::Io {
            file: path.to_owned(),
            source,
        })?;
        // The csv reader buffers internally; a large buffer keeps a 9 MB file to a few reads.
        let reader = std::io::BufReader::with_capacity(1 << 16, file);
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Self::new(reader, path, &name, gaps)
    }
}

impl<R: std::io::Read> CsvBlocks<R> {
    /// Reads the header from `reader`; `file` is only used in error messages and `name`
    /// becomes [`Recording::name`].
    pub fn new(
        reader: R,
        file: impl AsRef<Path>,
        name: &str,
        gaps: ImuGaps,
    ) -> Result<Self, ReadError> {
        let file = file.as_ref();
        let mut rdr = csv::ReaderBuilder::new()
            .has_headers(false)
            // Field counts are checked here so that the error can name the line.
            .flexible(true)
            .buffer_capacity(1 << 16)
            .from_reader(reader);
        let mut record = csv::ByteRecord::new();
        let got = rdr
            .read_byte_record(&mut record)
            .map_err(|e| csv_error(file, e))?;
        if !got {
            return Err(ReadError::Empty {
                file: file.to_owned(),
            });
        }
        let mut header: Vec<String> = record
            .iter()
            .map(|f| String::from_utf8_lossy(trim(f)).into_owned())
            .collect();
        // Spreadsheet programs like to start UTF-8 files with a byte-order mark.
        if let Some(first) = header.first_mut()
            && let Some(rest) = first.strip_prefix('\u{feff}')
        {
            *first = rest.to_string();
        }
        let layout = Layout::from_header(file, &header)?;
        Ok(Self {
            rdr,
            record,
            file: file.to_owned(),
            name: name.to_string(),
            header,
            layout,
            gaps,
            previous_t: f64::NEG_INFINITY,
        })
    }

    /// True when the file has magnetometer columns.
    pub fn has_mag(&self) -> bool {
        self.layout.mag.is_some()
    }

    /// A recording with no rows and the file's column groups (`mag`, `truth`, `use_mask`
    /// present or not), to read blocks into.
    pub fn empty_recording(&self) -> Recording {
        Recording {
            name: self.name.clone(),
            mag: self.layout.mag.map(|_| Vec::new()),
            truth: self.layout.quat.map(|_| Vec::new()),
            use_mask: self.layout.use_col.map(|_| Vec::new()),
            ..Recording::default()
        }
    }

    /// Reads every remaining row into a recording.
    pub fn read_all(mut self) -> Result<Recording, ReadError> {
        let mut rec = self.empty_recording();
        self.read_into(&mut rec, usize::MAX)?;
        Ok(rec)
    }

    /// Reads up to `max_rows` more rows and appends them to `rec` (made by
    /// [`empty_recording`](Self::empty_recording)); returns how many were read, 0 at the end
    /// of the file. Time must increase across blocks too.
    pub fn read_into(&mut self, rec: &mut Recording, max_rows: usize) -> Result<usize, ReadError> {
        let Self {
            rdr,
            record,
            file,
            header,
            layout,
            gaps,
            previous_t,
            ..
        } = self;
        let (file, header, gaps) = (file.as_path(), header.as_slice(), *gaps);
        let mut read = 0;
        while read < max_rows {
            let Some(line) = next_row(rdr, record, file, header.len())? else {
                break;
            };
            read += 1;
            let record = &*record;
            let cell = |col: usize| -> Result<f64, ReadError> {
                parse_f64(&record[col]).ok_or_else(|| ReadError::NotNumeric {
                    file: file.to_owned(),
                    line,
                    column: header[col].clone(),
                    index: col + 1,
                    text: shown(&record[col]),
                })
            };
            let imu = |col: usize| -> Result<f64, ReadError> {
                let v = cell(col)?;
                if v.is_finite() || gaps == ImuGaps::Keep {
                    Ok(v)
                } else {
                    Err(ReadError::NonFiniteImu {
                        file: file.to_owned(),
                        line,
                        column: header[col].clone(),
                        index: col + 1,
                        value: v,
                    })
                }
            };

            let tc = layout.required[0];
            let t = cell(tc)?;
            if !t.is_finite() {
                return Err(ReadError::NonFiniteTime {
                    file: file.to_owned(),
                    line,
                    column: header[tc].clone(),
                    index: tc + 1,
                    value: t,
                });
            }
            if t <= *previous_t {
                return Err(ReadError::NonMonotonicTime {
                    file: file.to_owned(),
                    line,
                    column: header[tc].clone(),
                    index: tc + 1,
                    value: t,
                    previous: *previous_t,
                });
            }
            *previous_t = t;
            let r = &layout.required;
            rec.t.push(t);
            rec.gyr.push(Vec3::new(imu(r[1])?, imu(r[2])?, imu(r[3])?));
            rec.acc.push(Vec3::new(imu(r[4])?, imu(r[5])?, imu(r[6])?));
            if let (Some(cols), Some(out)) = (&layout.mag, &mut rec.mag) {
                out.push(Vec3::new(imu(cols[0])?, imu(cols[1])?, imu(cols[2])?));
            }
            if let (Some(cols), Some(out)) = (&layout.quat, &mut rec.truth) {
                let mut q = [0.0; 4];
                for (k, &c) in cols.iter().enumerate() {
                    let v = cell(c)?;
                    if v.is_infinite() {
                        return Err(ReadError::InfiniteTruth {
                            file: file.to_owned(),
                            line,
                            column: header[c].clone(),
                            index: c + 1,
                            value: v,
                        });
                    }
                    q[k] = v;
                }
                // A partly known quaternion is no orientation: unknown as a whole.
                if q.iter().any(|v| v.is_nan()) {
                    q = [f64::NAN; 4];
                } else if let Some(norm) = not_unit(&q) {
                    return Err(ReadError::NotUnitQuaternion {
                        file: file.to_owned(),
                        line,
                        columns: "qw,qx,qy,qz",
                        norm,
                    });
                }
                out.push(Quat::new(q[0], q[1], q[2], q[3]));
            }
            if let (Some(c), Some(out)) = (layout.use_col, &mut rec.use_mask) {
                let f = trim(&record[c]);
                let u = match f {
                    b"1" => true,
                    b"0" => false,
                    _ => {
                        return Err(ReadError::BadUse {
                            file: file.to_owned(),
                            line,
                            column: header[c].clone(),
                            index: c + 1,
                            text: shown(&record[c]),
                        });
                    }
                };
                out.push(u);
            }
        }
        Ok(read)
    }
}

/// Orientation estimates read back from a `t,qw,qx,qy,qz` file (what [`write_estimates`] and
/// `rootfuse run` write; extra columns are ignored).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimates {
    /// Sample times, s, strictly increasing.
    pub t: Vec<f64>,
    /// Orientation, sensor to earth (ENU).
    pub quat: Vec<Quat<f64>>,
}

/// Reads an estimate file (`t,qw,qx,qy,qz`, any column order, extra columns ignored).
///
/// Errors name file, line and column like [`read_csv`]; every value must be finite and time
/// must increase.
pub fn read_estimates(path: impl AsRef<Path>) -> Result<Estimates, ReadError> {
    let file = path.as_ref();
    let io = |source| ReadError::Io {
        file: file.to_owned(),
        source,
    };
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(std::io::BufReader::new(
            std::fs::File::open(file).map_err(io)?,
        ));
    let mut record = csv::ByteRecord::new();
    if !rdr
        .read_byte_record(&mut record)
        .map_err(|e| csv_error(file, e))?
    {
        return Err(ReadError::Empty {
            file: file.to_owned(),
        });
    }
    let header: Vec<String> = record
        .iter()
        .map(|f| {
            String::from_utf8_lossy(trim(f))
                .trim_start_matches('\u{feff}')
                .to_string()
        })
        .collect();
    let mut cols = [0usize; 5];
    for (slot, name) in cols.iter_mut().zip(["t", "qw", "qx", "qy", "qz"]) {
        *slot = header
            .iter()
            .position(|h| h == name)
            .ok_or_else(|| ReadError::MissingColumn {
                file: file.to_owned(),
                column: name,
            })?;
    }
    let mut est = Estimates::default();
    while let Some(line) = next_row(&mut rdr, &mut record, file, header.len())? {
        let mut v = [0.0; 5];
        for (k, &c) in cols.iter().enumerate() {
            let x = parse_f64(&record[c]).ok_or_else(|| ReadError::NotNumeric {
                file: file.to_owned(),
                line,
                column: header[c].clone(),
                index: c + 1,
                text: shown(&record[c]),
            })?;
            if !x.is_finite() {
                return Err(ReadError::NonFiniteEstimate {
                    file: file.to_owned(),
                    line,
                    column: header[c].clone(),
                    index: c + 1,
                    value: x,
                });
            }
            v[k] = x;
        }
        if let Some(&previous) = est.t.last()
            && v[0] <= previous
        {
            return Err(ReadError::NonMonotonicTime {
                file: file.to_owned(),
                line,
                column: header[cols[0]].clone(),
                index: cols[0] + 1,
                value: v[0],
                previous,
            });
        }
        if let Some(norm) = not_unit(&[v[1], v[2], v[3], v[4]]) {
            return Err(ReadError::NotUnitQuaternion {
                file: file.to_owned(),
                line,
                columns: "qw,qx,qy,qz",
                norm,
            });
        }
        est.t.push(v[0]);
        est.quat.push(Quat::new(v[1], v[2], v[3], v[4]));
    }
    Ok(est)
}

/// Where each known column is (0-based field indices).
struct Layout {
    required: [usize; 7],
    mag: Option<[usize; 3]>,
    quat: Option<[usize; 4]>,
    use_col: Option<usize>,
}

impl Layout {
    fn from_header(file: &Path, header: &[String]) -> Result<Self, ReadError> {
        // Duplicate names would make "the" column ambiguous; extra columns may repeat freely
        // only if we never look at them, but a clear rule is simpler: no duplicates at all.
        for (i, h) in header.iter().enumerate() {
            if header[..i].contains(h) {
                return Err(ReadError::DuplicateColumn {
                    file: file.to_owned(),
                    column: h.clone(),
                    index: i + 1,
                });
            }
        }
        let find = |name: &str| header.iter().position(|h| h == name);
        let all = |names: &[&'static str]| -> Result<Option<Vec<usize>>, ReadError> {
            let found: Vec<Option<usize>> = names.iter().map(|n| find(n)).collect();
            if found.iter().all(Option::is_none) {
                return Ok(None);
            }
            match found.iter().position(Option::is_none) {
                Some(k) => Err(ReadError::MissingColumn {
                    file: file.to_owned(),
                    column: names[k],
                }),
                None => Ok(Some(found.into_iter().flatten().collect())),
            }
        };
        let mut required = [0; 7];
        for (slot, name) in required.iter_mut().zip(REQUIRED) {
            *slot = find(name).ok_or_else(|| ReadError::MissingColumn {
                file: file.to_owned(),
                column: name,
            })?;
        }
        let mag = all(&MAG)?.map(|v| [v[0], v[1], v[2]]);
        let quat = all(&QUAT)?.map(|v| [v[0], v[1], v[2], v[3]]);
        Ok(Self {
            required,
            mag,
            quat,
            use_col: find("use"),
        })
    }
}

/// Reads the next data row into `record` and returns its 1-based line, or `None` at the end.
/// A blank line (an editor's trailing newline) is not a row; a row whose field count differs
/// from the header's is an error naming its line.
fn next_row<R: std::io::Read>(
    rdr: &mut csv::Reader<R>,
    record: &mut csv::ByteRecord,
    file: &Path,
    n_fields: usize,
) -> Result<Option<u64>, ReadError> {
    while rdr
        .read_byte_record(record)
        .map_err(|e| csv_error(file, e))?
    {
        let line = record.position().map_or(0, |p| p.line());
        if record.len() == 1 && trim(&record[0]).is_empty() {
            continue;
        }
        if record.len() != n_fields {
            return Err(ReadError::FieldCount {
                file: file.to_owned(),
                line,
                expected: n_fields,
                found: record.len(),
            });
        }
        return Ok(Some(line));
    }
    Ok(None)
}

fn csv_error(file: &Path, e: csv::Error) -> ReadError {
    let line = e.position().map_or(0, |p| p.line());
    match e.into_kind() {
        csv::ErrorKind::Io(source) => ReadError::Io {
            file: file.to_owned(),
            source,
        },
        kind => ReadError::Csv {
            file: file.to_owned(),
            line,
            message: format!("{kind:?}"),
        },
    }
}

/// ASCII whitespace trimmed from both ends (files written by hand or by `%8.3f`).
fn trim(mut f: &[u8]) -> &[u8] {
    while let [first, rest @ ..] = f {
        if first.is_ascii_whitespace() {
            f = rest;
        } else {
            break;
        }
    }
    while let [rest @ .., last] = f {
        if last.is_ascii_whitespace() {
            f = rest;
        } else {
            break;
        }
    }
    f
}

/// Parses a decimal number; `NaN`, `inf` are accepted in any case (std's grammar).
fn parse_f64(f: &[u8]) -> Option<f64> {
    let s = std::str::from_utf8(trim(f)).ok()?;
    s.parse::<f64>().ok()
}

/// Reads a dataset's `index.csv` (header-driven; only `trial` is required).
pub fn read_index(path: impl AsRef<Path>) -> Result<Vec<IndexEntry>, ReadError> {
    let path = path.as_ref();
    let file = std::fs::File::open(path).map_err(|source| ReadError::Io {
        file: path.to_owned(),
        source,
    })?;
    let mut rdr = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(std::io::BufReader::new(file));
    let mut record = csv::ByteRecord::new();
    if !rdr
        .read_byte_record(&mut record)
        .map_err(|e| csv_error(path, e))?
    {
        return Err(ReadError::Empty {
            file: path.to_owned(),
        });
    }
    let header: Vec<String> = record
        .iter()
        .map(|f| String::from_utf8_lossy(trim(f)).into_owned())
        .collect();
    let find = |name: &str| header.iter().position(|h| h == name);
    let trial = find("trial").ok_or_else(|| ReadError::MissingColumn {
        file: path.to_owned(),
        column: "trial",
    })?;
    let (group, fs, ns, nu, dur) = (
        find("group"),
        find("fs_hz"),
        find("n_samples"),
        find("n_use"),
        find("duration_s"),
    );
    let mut out = Vec::new();
    while let Some(line) = next_row(&mut rdr, &mut record, path, header.len())? {
        let text = |c: usize| String::from_utf8_lossy(trim(&record[c])).into_owned();
        let not_numeric = |c: usize| ReadError::NotNumeric {
            file: path.to_owned(),
            line,
            column: header[c].clone(),
            index: c + 1,
            text: shown(trim(&record[c])),
        };
        let float = |c: Option<usize>| -> Result<Option<f64>, ReadError> {
            c.map(|c| parse_f64(&record[c]).ok_or_else(|| not_numeric(c)))
                .transpose()
        };
        let count = |c: Option<usize>| -> Result<Option<usize>, ReadError> {
            c.map(|c| text(c).parse::<usize>().map_err(|_| not_numeric(c)))
                .transpose()
        };
        out.push(IndexEntry {
            trial: text(trial),
            group: group.map(text),
            fs_hz: float(fs)?,
            n_samples: count(ns)?,
            n_use: count(nu)?,
            duration_s: float(dur)?,
        });
    }
    Ok(out)
}

/// The recording files of a folder: the trials listed in its `index.csv` (as
/// `<trial>.csv`, in index order) when there is one, otherwise every `*.csv` except
/// `index.csv`, sorted by name. Other files (README, …) are ignored.
pub fn list_dir(dir: impl AsRef<Path>) -> Result<Vec<PathBuf>, ReadError> {
    let dir = dir.as_ref();
    let index = dir.join("index.csv");
    if index.is_file() {
        return Ok(read_index(&index)?
            .into_iter()
            .map(|e| dir.join(format!("{}.csv", e.trial)))
            .collect());
    }
    let io = |source| ReadError::Io {
        file: dir.to_owned(),
        source,
    };
    let mut files = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        let is_csv = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        let is_index = path.file_name().is_some_and(|n| n == "index.csv");
        if is_csv && !is_index && path.is_file() {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

/// Reads every recording of a folder (see [`list_dir`] for which files), stopping at the
/// first error.
pub fn read_dir(dir: impl AsRef<Path>) -> Result<Vec<Recording>, ReadError> {
    list_dir(dir)?.iter().map(read_csv).collect()
}

/// Writes estimates as CSV: `t,qw,qx,qy,qz` followed by the `extra` columns (name, values),
/// atomically (temporary file, then rename).
///
/// Numbers are written in Rust's shortest round-trip form, so reading them back gives the same
/// `f64` bits. `q` must have one quaternion per time stamp.
pub fn write_estimates(
    path: impl AsRef<Path>,
    t: &[f64],
    q: &[Quat<f64>],
    extra: &[(&str, &[f64])],
) -> Result<(), WriteError> {
    let path = path.as_ref();
    check_len(path, "qw..qz", t.len(), q.len())?;
    let mut names: Vec<&str> = vec!["t", "qw", "qx", "qy", "qz"];
    for (name, values) in extra {
        check_name(path, name, &names)?;
        check_len(path, name, t.len(), values.len())?;
        names.push(name);
    }
    write_atomic(path, &names, t.len(), |i, row| {
        let qi = q[i];
        push_all(row, &[t[i], qi.w, qi.x, qi.y, qi.z]);
        for (_, values) in extra {
            push_all(row, &[values[i]]);
        }
    })
}

/// Writes a whole recording in the format [`read_csv`] reads: `t`, gyroscope, accelerometer,
/// then magnetometer, truth and `use` where present; atomically.
pub fn write_recording(path: impl AsRef<Path>, rec: &Recording) -> Result<(), WriteError> {
    let path = path.as_ref();
    let n = rec.t.len();
    check_len(path, "gx..gz", n, rec.gyr.len())?;
    check_len(path, "ax..az", n, rec.acc.len())?;
    let mut names: Vec<&str> = vec!["t", "gx", "gy", "gz", "ax", "ay", "az"];
    if let Some(m) = &rec.mag {
        check_len(path, "mx..mz", n, m.len())?;
        names.extend(MAG);
    }
    if let Some(q) = &rec.truth {
        check_len(path, "qw..qz", n, q.len())?;
        names.extend(QUAT);
    }
    if let Some(u) = &rec.use_mask {
        check_len(path, "use", n, u.len())?;
        names.push("use");
    }
    write_atomic(path, &names, n, |i, row| {
        let (g, a) = (rec.gyr[i], rec.acc[i]);
        push_all(row, &[rec.t[i], g.x, g.y, g.z, a.x, a.y, a.z]);
        if let Some(m) = &rec.mag {
            push_all(row, &[m[i].x, m[i].y, m[i].z]);
        }
        if let Some(q) = &rec.truth {
            push_all(row, &[q[i].w, q[i].x, q[i].y, q[i].z]);
        }
        if let Some(u) = &rec.use_mask {
            row.push_str(if u[i] { ",1" } else { ",0" });
        }
    })
}

fn check_len(file: &Path, column: &str, expected: usize, found: usize) -> Result<(), WriteError> {
    if expected == found {
        Ok(())
    } else {
        Err(WriteError::Length {
            file: file.to_owned(),
            column: column.to_string(),
            expected,
            found,
        })
    }
}

pub(crate) fn check_name(file: &Path, name: &str, taken: &[&str]) -> Result<(), WriteError> {
    let bad = name.is_empty()
        || taken.contains(&name)
        || name.contains([',', '"', '\n', '\r'])
        || name.trim() != name;
    if bad {
        Err(WriteError::BadColumnName {
            file: file.to_owned(),
            column: name.to_string(),
        })
    } else {
        Ok(())
    }
}

/// Appends `,v` for each value (the leading comma is stripped per row by the caller).
pub(crate) fn push_all(row: &mut String, values: &[f64]) {
    for v in values {
        // Both forms print the shortest string that parses back to the same bits; `{}` never
        // uses an exponent, which would spell 1e-24 with 24 zeros. NaN is "NaN".
        let plain = *v == 0.0 || !v.is_finite() || (1e-5..1e16).contains(&v.abs());
        let _ = if plain {
            write!(row, ",{v}")
        } else {
            write!(row, ",{v:e}")
        };
    }
}

/// The temporary file that process `pid` writes before renaming it to `path`:
/// `<path>.tmp.<pid>`, beside it (a rename is atomic only within one file system).
pub fn temporary_path(path: &Path, pid: u32) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_owned();
    name.push(format!(".tmp.{pid}"));
    path.with_file_name(name)
}

/// Temporary files of writes to `path` by other processes (`<path>.tmp.<pid>`, see
/// [`temporary_path`]) that exist now: what a process killed while writing `path` left
/// behind. The final `path` of such a write is either the previous complete file or absent.
pub fn stale_temporaries(path: &Path) -> Vec<PathBuf> {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return Vec::new();
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let prefix = format!("{}.tmp.", name.to_string_lossy());
    let ours = std::process::id().to_string();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.file_name()
                .and_then(|n| n.to_str())
                .and_then(|n| n.strip_prefix(&prefix))
                .is_some_and(|pid| {
                    !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit()) && pid != ours
                })
        })
        .collect()
}

/// Writes header + rows to [`temporary_path`] and renames it to `path`.
fn write_atomic(
    path: &Path,
    names: &[&str],
    n: usize,
    mut fill: impl FnMut(usize, &mut String),
) -> Result<(), WriteError> {
    let mut file = crate::AtomicFile::create(path)?;
    let result = (|| -> Result<(), std::io::Error> {
        file.write_all(names.join(",").as_bytes())?;
        file.write_all(b"\n")?;
        let mut row = String::with_capacity(256);
        for i in 0..n {
            row.clear();
            fill(i, &mut row);
            // Every field was written with a leading comma.
            file.write_all(&row.as_bytes()[1.min(row.len())..])?;
            file.write_all(b"\n")?;
        }
        Ok(())
    })();
    result.map_err(|source| WriteError::Io {
        file: path.to_owned(),
        source,
    })?;
    file.finish()
}
