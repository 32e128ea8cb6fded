//! Recordings and fleets of IMUs as Parquet and Arrow IPC files, read and written a block of
//! rows at a time.
//!
//! Depends on `rootfuse-attitude`, `rootfuse-io` (atomic files, CSV estimates),
//! `rootfuse-batch` ([`FleetBlock`](rootfuse_batch::FleetBlock), the rows the fleet runner
//! takes), and the Apache Arrow crates `arrow` (IPC) and `parquet` (with Snappy and Zstd).
//!
//! # Format
//! The columns and units of the CSV format (`docs/conventions.md` in the repository), found by
//! name in any order, numbers (floats; integers such as raw counts or a time in ms, and
//! decimals, read as `f64`; a dictionary of them; `t` also a timestamp or duration, read in s):
//! `t` (s, strictly increasing per device),
//! `gx,gy,gz` (rad/s), `ax,ay,az` (m/s²), optionally `mx,my,mz` (µT, all three or
//! none), plus an optional `device` column (integer or string) saying which device a row
//! belongs to: rows of many devices may interleave in any order; without it the file is one
//! device named after its stem. Other columns (truth `qw..qz`, `use`) are ignored by
//! [`FleetReader`]. A null IMU value is read as NaN, a dropped packet (kept for the filter to
//! skip, or refused with [`ImuGaps::Refuse`]). Parquet files are read one row group at a time
//! and Arrow IPC files (the file or the stream format, told apart by their first bytes) one
//! record batch at a time, in blocks of at most [`BLOCK_ROWS`] rows. Arrow IPC files are
//! memory-mapped and decoded in place, so a file written as one record batch of any length
//! is read a block at a time too (an uncompressed one: a compressed batch is decompressed
//! whole); such a file must not be truncated by another program while it is read (the
//! process would end with SIGBUS). Row groups and record
//! batches without rows are skipped and listed ([`FleetReader::empty_parts`]), not refused.
//!
//! Estimates ([`EstimateWriter`]) are `device` (when the input had one, same type), `t`,
//! `qw,qx,qy,qz` (sensor to earth, ENU) and the optional `bx,by,bz`, `p_xx..p_zz`, `flags`
//! of the CSV estimates.
//!
//! # Errors
//! Every problem is a [`ColumnarError`] naming the file and, where it is about a place in the
//! file, the row group (or record batch), the 0-based file row and the column. Nothing here
//! panics on data (the fuzz target `columnar_reader` checks it on arbitrary bytes).
//!
//! # Writing
//! Outputs go to a temporary file renamed into place when complete
//! ([`rootfuse_io::AtomicFile`]): an error or an interruption leaves no partial file.
#![warn(missing_docs)]

mod error;
mod kind;
mod mapped;
mod params;
mod reader;
mod recordings;
mod run;
mod schema;
mod writer;

pub use error::{ColumnarError, Part};
pub use params::{DeviceParamRow, DeviceParams};
pub use reader::{BLOCK_ROWS, Devices, FleetChunk, FleetReader, ImuGaps};
pub use recordings::{FLEET_COLUMNS, FleetFileWriter};
pub use run::FleetBlocks;
pub use writer::{EstimateWriter, ROW_GROUP_ROWS, estimate_names};

/// The name of the device column.
pub const DEVICE: &str = "device";

/// A file format, chosen by `--format` or by the file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// CSV (`.csv`).
    Csv,
    /// Apache Parquet (`.parquet`, `.pq`).
    Parquet,
    /// Arrow IPC (`.arrow`, `.arrows`, `.feather`, `.ipc`): written in the file format, read
    /// in the file or the stream format (told apart by the file's first bytes).
    Arrow,
}

impl Format {
    /// The format of a path by its extension (case-insensitive), `None` for another one.
    pub fn of_path(path: &std::path::Path) -> Option<Self> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "csv" => Some(Self::Csv),
            "parquet" | "pq" => Some(Self::Parquet),
            "arrow" | "arrows" | "feather" | "ipc" => Some(Self::Arrow),
            _ => None,
        }
    }

    /// The usual extension, without the dot.
    pub fn extension(self) -> &'static str {
        match self {
            Self::Csv => "csv",
            Self::Parquet => "parquet",
            Self::Arrow => "arrow",
        }
    }
}
