//! Whole recordings and estimates written as CSV, atomically, in the format the readers read:
//! what a writer accepts, its reader reads back.

use crate::atomic::AtomicFile;
use crate::error::WriteError;
use crate::format::{check_name, push_all};
use crate::recording::{ImuGaps, MAG, QUAT, not_unit};
use rootfuse_attitude::{Quat, Recording, Vec3};
use std::borrow::ToOwned;
use std::format;
use std::io::Write as _;
use std::path::Path;
use std::string::{String, ToString};
use std::vec;
use std::vec::Vec;

/// Writes estimates as CSV: `t,qw,qx,qy,qz` followed by the `extra` columns (name, values),
/// atomically (temporary file, then rename).
///
/// Numbers are written in Rust's shortest round-trip form, so reading them back gives the same
/// `f64` bits. `q` must have one quaternion per time stamp. What [`read_estimates`](crate::read_estimates)
/// would refuse is refused here ([`WriteError::Unreadable`], naming the row, line and column):
/// a time that is not finite or does not increase, a quaternion that is not finite or not of
/// unit norm. The `extra` columns may hold NaN (the reader reads it, or an empty cell, as NaN).
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
    check_times(path, t)?;
    for (row, qi) in q.iter().enumerate() {
        let c = [qi.w, qi.x, qi.y, qi.z];
        if let Some(k) = c.iter().position(|v| !v.is_finite()) {
            return unreadable(
                path,
                row,
                QUAT[k],
                format!("estimate value {} is not finite", c[k]),
            );
        }
        if let Some(norm) = not_unit(&c) {
            return unreadable(
                path,
                row,
                "qw,qx,qy,qz",
                format!("quaternion has norm {norm}, not 1"),
            );
        }
    }
    write_atomic(path, &names, t.len(), |i, row| {
        let qi = q[i];
        push_all(row, &[t[i], qi.w, qi.x, qi.y, qi.z]);
        for (_, values) in extra {
            push_all(row, &[values[i]]);
        }
    })
}

/// Writes a whole recording in the format [`read_csv`](crate::read_csv) reads: `t`, gyroscope,
/// accelerometer, then magnetometer, truth and `use` where present; atomically.
///
/// What `read_csv` would refuse is refused here ([`WriteError::Unreadable`], naming the row,
/// line and column): a time that is not finite or does not increase, an IMU value that is not
/// finite (see [`write_recording_with`] to write dropped samples, read back with
/// [`ImuGaps::Keep`]), an infinite truth component, a known truth quaternion not of unit norm.
pub fn write_recording(path: impl AsRef<Path>, rec: &Recording) -> Result<(), WriteError> {
    write_recording_with(path, rec, ImuGaps::Refuse)
}

/// [`write_recording`] where `gaps` says whether non-finite IMU values (dropped samples) are
/// written (as `NaN`, `inf`: [`ImuGaps::Keep`], read back with `read_csv_with(…, ImuGaps::Keep)`)
/// or refused.
pub fn write_recording_with(
    path: impl AsRef<Path>,
    rec: &Recording,
    gaps: ImuGaps,
) -> Result<(), WriteError> {
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
    check_times(path, &rec.t)?;
    if gaps == ImuGaps::Refuse {
        let sensors = [
            ("gyroscope", ["gx", "gy", "gz"], Some(&rec.gyr)),
            ("accelerometer", ["ax", "ay", "az"], Some(&rec.acc)),
        ];
        for (sensor, columns, values) in
            sensors
                .into_iter()
                .chain([("magnetometer", MAG, rec.mag.as_ref())])
        {
            let Some(values) = values else { continue };
            if let Some((row, k, x)) = first_not_finite(values) {
                return unreadable(
                    path,
                    row,
                    columns[k],
                    format!(
                        "{sensor} value {x} is not finite (write dropped samples with ImuGaps::Keep)"
                    ),
                );
            }
        }
    }
    if let Some(truth) = &rec.truth {
        for (row, q) in truth.iter().enumerate() {
            let c = [q.w, q.x, q.y, q.z];
            if let Some(k) = c.iter().position(|v| v.is_infinite()) {
                return unreadable(
                    path,
                    row,
                    QUAT[k],
                    format!("truth value {} is infinite (NaN means unknown)", c[k]),
                );
            }
            if let Some(norm) = (!c.iter().any(|v| v.is_nan()))
                .then(|| not_unit(&c))
                .flatten()
            {
                return unreadable(
                    path,
                    row,
                    "qw,qx,qy,qz",
                    format!("truth quaternion has norm {norm}, not 1"),
                );
            }
        }
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

/// The first value that is not finite: its row, axis (0..3) and value.
fn first_not_finite(values: &[Vec3<f64>]) -> Option<(usize, usize, f64)> {
    values.iter().enumerate().find_map(|(row, v)| {
        [v.x, v.y, v.z]
            .into_iter()
            .enumerate()
            .find(|(_, x)| !x.is_finite())
            .map(|(k, x)| (row, k, x))
    })
}

fn unreadable(file: &Path, row: usize, column: &str, what: String) -> Result<(), WriteError> {
    Err(WriteError::Unreadable {
        file: file.to_owned(),
        row,
        column: column.to_string(),
        what,
    })
}

/// Times the readers accept: finite and strictly increasing.
fn check_times(file: &Path, t: &[f64]) -> Result<(), WriteError> {
    let mut previous = f64::NEG_INFINITY;
    for (row, &v) in t.iter().enumerate() {
        if !v.is_finite() {
            return unreadable(file, row, "t", format!("time {v} is not finite"));
        }
        if v <= previous {
            return unreadable(
                file,
                row,
                "t",
                format!("time {v} does not increase (previous {previous})"),
            );
        }
        previous = v;
    }
    Ok(())
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

/// Writes header + rows to a temporary file and renames it to `path`.
fn write_atomic(
    path: &Path,
    names: &[&str],
    n: usize,
    mut fill: impl FnMut(usize, &mut String),
) -> Result<(), WriteError> {
    let mut file = AtomicFile::create(path)?;
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
