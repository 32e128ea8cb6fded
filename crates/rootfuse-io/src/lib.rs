//! Recordings and estimates as files.
//!
//! Depends on `rootfuse-attitude` (for [`Recording`], `Quat`, `Vec3`), `csv` and `thiserror`;
//! nothing numeric lives here. The filters never see a file: this crate turns files into
//! [`Recording`]s and estimates back into files.
//!
//! # Format read
//! One header line, then one row per sample. The delimiter is found from the header: comma,
//! semicolon or tab (where it is not a comma, a decimal comma `0,25` is read too). UTF-8, with
//! or without a byte-order mark; UTF-16 and UTF-32 are refused by name, as are Parquet, Arrow and
//! compressed or zipped files (by their first bytes). Columns are found by
//! name, so their order is free:
//! - required: `t` (strictly increasing), `gx,gy,gz` (angular rate, sensor frame),
//!   `ax,ay,az` (specific force, sensor frame);
//! - optional: `mx,my,mz` (magnetometer, sensor frame; absent = a 6D recording),
//!   `qw,qx,qy,qz` (ground truth, sensor to earth, ENU; `NaN` or empty where unknown),
//!   `use` (`0`/`1`, also `true`/`false`; empty = not counted: samples that count for error
//!   evaluation);
//! - any other column is ignored.
//!
//! The reader keeps the file's units; the filters take s, rad/s, m/s² and µT. A file in other
//! units is converted with [`Units`](rootfuse_attitude::units::Units), and
//! [`UnitCheck`](rootfuse_attitude::units::UnitCheck) names the units its data look like.
//!
//! An IMU value that is empty, `NaN` or infinite (a dropped packet) is an error by default
//! ([`read_csv`]); [`read_csv_with`] and [`ImuGaps::Keep`] keep it (an empty cell as NaN), for
//! the filters to skip and count (see `rootfuse_attitude::filters::Screened`).
//!
//! A group (`mx,my,mz` or `qw,qx,qy,qz`) is all or nothing: a partial group is an error, since
//! a half-present magnetometer is a broken file rather than a 6D one.
//!
//! # Errors
//! Every problem is a [`ReadError`] carrying its [`Place`]: the file, the 1-based line and,
//! where one cell is at fault, the column by name and 1-based index, so a user can go straight
//! to it. Nothing in here panics on data.
//!
//! # Writing
//! [`write_estimates`] and [`write_recording`] write to a temporary file beside the target and
//! rename it into place, so a reader never sees a half-written file (rename is atomic within a
//! file system); they refuse what their readers would refuse, so what they write reads back.

#![warn(missing_docs)]

mod atomic;
mod error;
mod estimates;
mod folder;
mod format;
mod recording;
mod table;
mod write;

pub use atomic::{AtomicFile, CsvEstimateWriter, Staged, stale_temporaries, temporary_path};
pub use error::{Place, ReadError, WriteError};
pub use estimates::{Estimates, Truth, read_estimates, read_truth};
pub use folder::{
    FolderKind, FolderListing, IndexEntry, is_fleet_file, list_dir, read_dir, read_index, scan_dir,
};
pub use recording::{
    CsvBlocks, ImuGaps, UNIT_NORM_TOLERANCE, read_csv, read_csv_from, read_csv_in, read_csv_with,
};
pub use rootfuse_attitude::Recording;
pub use table::{Dialect, column_list};
pub use write::{write_estimates, write_recording, write_recording_with};
