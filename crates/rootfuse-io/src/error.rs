//! Why a file could not be read or written, and where: every read error carries one [`Place`].

use std::borrow::ToOwned;
use std::fmt;
use std::path::{Path, PathBuf};
use std::string::String;

/// Where in a file a problem is: the file, the 1-based line (the header is line 1; 0 when
/// unknown) and, where one cell is at fault, its column by name and 1-based index.
///
/// Shown as `file: line 7, column `gx` (#2)`, `file: line 7` or `file`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Place {
    /// The file.
    pub file: PathBuf,
    /// The 1-based line; 0 when the problem is with the file as a whole.
    pub line: u64,
    /// The column at fault, if one is: its name and 1-based index.
    pub column: Option<(String, usize)>,
}

impl Place {
    /// The file as a whole.
    pub fn file(file: &Path) -> Self {
        Self {
            file: file.to_owned(),
            line: 0,
            column: None,
        }
    }

    /// A line of the file.
    pub fn line(file: &Path, line: u64) -> Self {
        Self {
            file: file.to_owned(),
            line,
            column: None,
        }
    }

    /// One cell: the column `name` at 0-based field index `field`.
    pub fn cell(file: &Path, line: u64, name: &str, field: usize) -> Self {
        Self {
            file: file.to_owned(),
            line,
            column: Some((name.to_owned(), field + 1)),
        }
    }
}

impl fmt::Display for Place {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file.display())?;
        if self.line > 0 {
            write!(f, ": line {}", self.line)?;
        }
        if let Some((name, index)) = &self.column {
            write!(f, ", column `{name}` (#{index})")?;
        }
        Ok(())
    }
}

/// Why a CSV file could not be read. Every variant names its [`Place`]; the message says what
/// is wrong there and, where there is one, what to do.
#[derive(Debug, thiserror::Error)]
pub enum ReadError {
    /// The file could not be opened or read (missing file, permissions, I/O failure).
    #[error("{place}: cannot read: {source}")]
    Io {
        /// The file.
        place: Place,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The CSV layer failed (an unterminated quote, invalid UTF-8).
    #[error("{place}: malformed CSV: {message}")]
    Csv {
        /// Where it happened.
        place: Place,
        /// The CSV layer's description.
        message: String,
    },
    /// The file is in a text encoding other than UTF-8 (or ASCII).
    #[error("{place}: the file is {encoding}, not UTF-8: save it as UTF-8 (or plain ASCII)")]
    Encoding {
        /// The file.
        place: Place,
        /// The encoding recognised (`UTF-16 little-endian`, …).
        encoding: &'static str,
    },
    /// The file is a binary format its first bytes name (Parquet, Arrow, a compressed or
    /// zipped file), not CSV text.
    #[error("{place}: this is {format}, not CSV text: {what_to_do}")]
    NotText {
        /// The file.
        place: Place,
        /// What its first bytes say it is (`a Parquet file`, …).
        format: &'static str,
        /// What to do instead.
        what_to_do: &'static str,
    },
    /// The file's lines end in a carriage return alone (classic Mac OS), which the reader
    /// would take as one long first line.
    #[error(
        "{place}: lines end in a carriage return alone (classic Mac OS line endings): convert them to LF or CRLF, e.g. `tr '\\r' '\\n' < in.csv > out.csv`"
    )]
    CarriageReturns {
        /// Line 1 of the file.
        place: Place,
    },
    /// The file has no header line.
    #[error("{place}: empty file (no header)")]
    Empty {
        /// Line 1 of the file.
        place: Place,
    },
    /// A required column (or one of a column group that is partly present) is missing.
    #[error("{place}: missing required column `{column}` (the header has {found})")]
    MissingColumn {
        /// Line 1 of the file.
        place: Place,
        /// The missing column's name.
        column: &'static str,
        /// The header's columns, for the message.
        found: String,
    },
    /// A column name appears twice, so which one to use is ambiguous.
    #[error("{place}: duplicate column name")]
    DuplicateColumn {
        /// The second occurrence.
        place: Place,
    },
    /// A data row has a different number of fields than the header.
    #[error("{place}: expected {expected} fields (as in the header), found {found}")]
    FieldCount {
        /// The line.
        place: Place,
        /// Fields in the header.
        expected: usize,
        /// Fields in this row.
        found: usize,
    },
    /// A cell is not a number.
    #[error("{place}: `{text}` is not a number")]
    NotNumeric {
        /// The cell.
        place: Place,
        /// The cell as written (lossy UTF-8).
        text: String,
    },
    /// A time stamp is empty, NaN or infinite.
    #[error("{place}: time {value} is not finite")]
    NonFiniteTime {
        /// The cell.
        place: Place,
        /// The value read (NaN for an empty cell).
        value: f64,
    },
    /// A time stamp does not exceed the previous one.
    #[error("{place}: time {value} does not increase (previous {previous}){hint}")]
    NonMonotonicTime {
        /// The cell.
        place: Place,
        /// This sample's time.
        value: f64,
        /// The previous sample's time.
        previous: f64,
        /// What the file suggests, appended to the message (empty, or `; …`): a CSV with a
        /// `device` column holds a fleet, which CSV cannot.
        hint: &'static str,
    },
    /// An IMU reading (gyroscope, accelerometer, magnetometer) is empty, NaN or infinite.
    ///
    /// Missing IMU values are refused unless the reader keeps them ([`ImuGaps::Keep`](crate::ImuGaps)),
    /// for the filters to skip and count: a filter must not be fed a silently repaired value.
    #[error("{place}: IMU value {} is {}", if *empty { "(empty cell)".into() } else { value.to_string() }, if *empty { "missing" } else { "not finite" })]
    NonFiniteImu {
        /// The cell.
        place: Place,
        /// The value read (NaN for an empty cell).
        value: f64,
        /// The cell was empty.
        empty: bool,
    },
    /// A ground-truth component is infinite (NaN and an empty cell mean "unknown").
    #[error(
        "{place}: truth value {value} is infinite (use NaN, or leave the cell empty, for unknown)"
    )]
    InfiniteTruth {
        /// The cell.
        place: Place,
        /// The value read.
        value: f64,
    },
    /// An estimate value (`t`, `qw..qz` of an estimate file) is NaN, infinite or empty.
    #[error("{place}: estimate value {value} is not finite")]
    NonFiniteEstimate {
        /// The cell.
        place: Place,
        /// The value read (NaN for an empty cell).
        value: f64,
    },
    /// A quaternion (estimate or known truth) is far from unit norm, so it is no orientation:
    /// scoring it would be meaningless (an all-zero quaternion would score as perfect).
    #[error(
        "{place}: quaternion `{columns}` has norm {norm}, not 1 (within {tolerance})",
        tolerance = crate::UNIT_NORM_TOLERANCE
    )]
    NotUnitQuaternion {
        /// The line.
        place: Place,
        /// The quaternion's columns, `qw,qx,qy,qz`.
        columns: &'static str,
        /// Its norm.
        norm: f64,
    },
    /// The `use` cell is none of `0`, `1`, `true`, `false` (in any case) or empty.
    #[error("{place}: `{text}` is not 0 or 1")]
    BadUse {
        /// The cell.
        place: Place,
        /// The cell as written (lossy UTF-8).
        text: String,
    },
}

impl ReadError {
    /// Where the problem is.
    pub fn place(&self) -> &Place {
        match self {
            ReadError::Io { place, .. }
            | ReadError::Csv { place, .. }
            | ReadError::Encoding { place, .. }
            | ReadError::NotText { place, .. }
            | ReadError::CarriageReturns { place }
            | ReadError::Empty { place }
            | ReadError::MissingColumn { place, .. }
            | ReadError::DuplicateColumn { place }
            | ReadError::FieldCount { place, .. }
            | ReadError::NotNumeric { place, .. }
            | ReadError::NonFiniteTime { place, .. }
            | ReadError::NonMonotonicTime { place, .. }
            | ReadError::NonFiniteImu { place, .. }
            | ReadError::InfiniteTruth { place, .. }
            | ReadError::NonFiniteEstimate { place, .. }
            | ReadError::NotUnitQuaternion { place, .. }
            | ReadError::BadUse { place, .. } => place,
        }
    }

    pub(crate) fn io(file: &Path, source: std::io::Error) -> Self {
        ReadError::Io {
            place: Place::file(file),
            source,
        }
    }
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
    /// A recording or estimate that its reader would refuse: a time that is not finite or does
    /// not increase, a sample that is not finite (the file would not read back). Shown with
    /// the line and column the reader would name (the header is line 1, data row 0 line 2).
    #[error(
        "{file}: row {row} (line {line}), column `{column}`: {what}; the file would not read back",
        line = *row + 2
    )]
    Unreadable {
        /// The target file.
        file: PathBuf,
        /// 0-based row of the data.
        row: usize,
        /// The column at fault (`qw,qx,qy,qz` for a quaternion as a whole).
        column: String,
        /// What is wrong with it.
        what: String,
    },
}
