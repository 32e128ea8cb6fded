//! Recordings and estimates as files.
//!
//! Depends on `rootfuse-attitude` (for [`Recording`], `Quat`, `Vec3`), `csv` and `thiserror`;
//! nothing numeric lives here. The filters never see a file: this crate turns files into
//! [`Recording`]s and estimates back into files.
//!
//! # CSV
//! Reading and writing recordings as CSV (the BROAD-as-CSV format of `docs/conventions.md` in the repository).
//!
//! # Format read
//! One header line, comma separated, `.` decimal point, no quoting needed. Columns are found by
//! name, so their order is free:
//! - required: `t` (s, strictly increasing), `gx,gy,gz` (rad/s, sensor frame),
//!   `ax,ay,az` (m/s², specific force, sensor frame);
//! - optional: `mx,my,mz` (magnetometer, sensor frame; absent = a 6D recording),
//!   `qw,qx,qy,qz` (ground truth, sensor to earth, ENU; `NaN` where unknown),
//!   `use` (`0`/`1`, samples that count for error evaluation);
//! - any other column is ignored.
//!
//! An IMU value that is `NaN` or infinite (a dropped packet) is an error by default
//! ([`read_csv`]); [`read_csv_with`] and [`ImuGaps::Keep`] keep it, for the filters to skip and
//! count (see `rootfuse_attitude::filters::Screened`).
//!
//! A group (`mx,my,mz` or `qw,qx,qy,qz`) is all or nothing: a partial group is an error, since
//! a half-present magnetometer is a broken file rather than a 6D one.
//!
//! # Errors
//! Every problem is a [`ReadError`] whose message names the file, the 1-based line and, where
//! one cell is at fault, the column by name and 1-based index, so a user can go straight to it.
//! Nothing in here panics on data.
//!
//! # Writing
//! [`write_estimates`] and [`write_recording`] write to a temporary file beside the target and
//! rename it into place, so a reader never sees a half-written file (rename is atomic within a
//! file system).

#![warn(missing_docs)]

mod atomic;
mod csv_format;

pub use atomic::{AtomicFile, CsvEstimateWriter, Staged};
pub use csv_format::*;
pub use rootfuse_attitude::Recording;
