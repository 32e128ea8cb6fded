//! [`ColumnarError`]: what can go wrong reading or writing a columnar file.

use std::path::PathBuf;

/// Where in a columnar file: the row group (Parquet) or record batch (Arrow IPC), both
/// 0-based as Arrow and Parquet tools count them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Part {
    /// A Parquet row group.
    RowGroup(usize),
    /// An Arrow IPC record batch.
    RecordBatch(usize),
    /// A block of a CSV file (its rows are named by line instead).
    Block,
}

impl core::fmt::Display for Part {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::RowGroup(g) => write!(f, "row group {g}"),
            Self::RecordBatch(b) => write!(f, "record batch {b}"),
            Self::Block => write!(f, "block"),
        }
    }
}

/// Why a columnar file could not be read or written. Rows are 0-based indices into the whole
/// file (as `pyarrow.Table.slice` counts them).
#[derive(Debug, thiserror::Error)]
pub enum ColumnarError {
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// The file.
        file: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The Parquet or Arrow layer refused the file (truncated, corrupt, unsupported).
    #[error("{file}: {part}not a readable {format} file: {message}")]
    Format {
        /// The file.
        file: PathBuf,
        /// `Parquet`, `Arrow IPC` or `Arrow IPC stream`.
        format: &'static str,
        /// Where, when known (`"row group 3: "`), else empty.
        part: String,
        /// The decoder's message.
        message: String,
    },
    /// A required column (or one of a group that is partly present) is missing.
    #[error("{file}: missing required column `{column}` (the file has {found})")]
    MissingColumn {
        /// The file.
        file: PathBuf,
        /// The column.
        column: &'static str,
        /// The columns the file has, by name (the first 12, then how many in all).
        found: String,
    },
    /// A column has a type the format does not allow.
    #[error("{file}: column `{column}` has type {found}, expected {expected}")]
    ColumnType {
        /// The file.
        file: PathBuf,
        /// The column.
        column: String,
        /// Its type in the file.
        found: String,
        /// What is accepted.
        expected: &'static str,
    },
    /// A column name appears twice.
    #[error("{file}: column `{column}` appears twice")]
    DuplicateColumn {
        /// The file.
        file: PathBuf,
        /// The column.
        column: String,
    },
    /// A cell is null (or not finite) where a value is required.
    #[error("{file}: {part}, row {row}, column `{column}`: {problem}")]
    BadValue {
        /// The file.
        file: PathBuf,
        /// Row group or record batch.
        part: Part,
        /// Row in the file (0-based).
        row: u64,
        /// The column.
        column: String,
        /// What is wrong.
        problem: String,
    },
    /// A device's time stamp is not finite or does not increase.
    #[error("{file}: {part}, row {row}, column `t` (device {device}): {source}{hint}")]
    Time {
        /// The file.
        file: PathBuf,
        /// Row group or record batch.
        part: Part,
        /// Row in the file (0-based).
        row: u64,
        /// The device, as written in the file.
        device: String,
        /// What is wrong.
        #[source]
        source: rootfuse_batch::FleetError,
        /// What may be the cause, with a leading `; ` (empty when nothing is known).
        hint: &'static str,
    },
    /// A per-device parameter table has a bad cell ([`DeviceParams`](crate::DeviceParams)).
    #[error("{file}: {place}column `{column}`: {problem}")]
    Param {
        /// The file.
        file: PathBuf,
        /// `line N, ` (CSV) or `row N, ` (0-based), empty for the whole file.
        place: String,
        /// The column (empty for the whole row or file).
        column: String,
        /// What is wrong.
        problem: String,
    },
    /// The file has no data rows.
    #[error("{file}: no data rows")]
    Empty {
        /// The file.
        file: PathBuf,
    },
    /// Writing failed.
    #[error("{file}: cannot write: {message}")]
    Write {
        /// The file.
        file: PathBuf,
        /// What failed.
        message: String,
    },
}

impl From<rootfuse_io::WriteError> for ColumnarError {
    fn from(e: rootfuse_io::WriteError) -> Self {
        let file = match &e {
            rootfuse_io::WriteError::Io { file, .. }
            | rootfuse_io::WriteError::Length { file, .. }
            | rootfuse_io::WriteError::BadColumnName { file, .. }
            | rootfuse_io::WriteError::Unreadable { file, .. } => file.clone(),
        };
        let message = e.to_string();
        let message = message
            .strip_prefix(&format!("{}: cannot write: ", file.display()))
            .unwrap_or(&message)
            .to_string();
        Self::Write { file, message }
    }
}
