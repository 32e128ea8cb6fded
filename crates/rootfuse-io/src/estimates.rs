//! Estimate files read back: `t,qw,qx,qy,qz` and whatever columns the run added.

use crate::error::{Place, ReadError};
use crate::recording::{not_unit, truth, use_cell};
use crate::table::Table;
use rootfuse_attitude::Quat;
use std::path::Path;
use std::string::String;
use std::vec::Vec;

/// Orientation estimates read back from a `t,qw,qx,qy,qz` file (what [`write_estimates`](crate::write_estimates)
/// and `rootfuse run` write), with the other columns (`bx,by,bz`, `p_xx…`, `flags`, …) by name.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimates {
    /// Sample times, s, strictly increasing.
    pub t: Vec<f64>,
    /// Orientation, sensor to earth (ENU).
    pub quat: Vec<Quat<f64>>,
    /// Every other column, in file order: its name and values (an empty cell is NaN).
    pub extra: Vec<(String, Vec<f64>)>,
}

impl Estimates {
    /// The values of column `name` among the [`extra`](Self::extra) columns.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.extra
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }
}

/// Reads an estimate file (`t,qw,qx,qy,qz` in any column order, other columns kept in
/// [`Estimates::extra`]).
///
/// Errors name file, line and column like [`read_csv`](crate::read_csv); time and quaternion
/// must be finite, time must increase, quaternions must have unit norm; other columns must be
/// numbers (or empty).
pub fn read_estimates(path: impl AsRef<Path>) -> Result<Estimates, ReadError> {
    let mut table = Table::open(path.as_ref())?;
    let mut cols = [0usize; 5];
    for (slot, name) in cols.iter_mut().zip(["t", "qw", "qx", "qy", "qz"]) {
        *slot = table.find(name).ok_or_else(|| table.missing(name))?;
    }
    let others: Vec<usize> = (0..table.header.len())
        .filter(|c| !cols.contains(c))
        .collect();
    let mut est = Estimates {
        extra: others
            .iter()
            .map(|&c| (table.header[c].clone(), Vec::new()))
            .collect(),
        ..Estimates::default()
    };
    while let Some(line) = table.next_row()? {
        let mut v = [0.0; 5];
        for (k, &c) in cols.iter().enumerate() {
            let x = table.value(line, c)?;
            if !x.is_finite() {
                return Err(ReadError::NonFiniteEstimate {
                    place: table.place(line, c),
                    value: x,
                });
            }
            v[k] = x;
        }
        if let Some(&previous) = est.t.last()
            && v[0] <= previous
        {
            return Err(ReadError::NonMonotonicTime {
                place: table.place(line, cols[0]),
                value: v[0],
                previous,
                hint: "",
            });
        }
        if let Some(norm) = not_unit(&[v[1], v[2], v[3], v[4]]) {
            return Err(ReadError::NotUnitQuaternion {
                place: Place::line(&table.file, line),
                columns: "qw,qx,qy,qz",
                norm,
            });
        }
        for (&c, (_, values)) in others.iter().zip(&mut est.extra) {
            values.push(table.value(line, c)?);
        }
        est.t.push(v[0]);
        est.quat.push(Quat::new(v[1], v[2], v[3], v[4]));
    }
    Ok(est)
}

/// Ground truth read on its own: `t,qw,qx,qy,qz` and optionally `use`, from a recording
/// (its IMU columns are not read) or from a motion-capture export that has no IMU columns.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Truth {
    /// Sample times as written (the file's time unit), strictly increasing.
    pub t: Vec<f64>,
    /// Orientation, sensor to earth; all four components NaN where unknown.
    pub quat: Vec<Quat<f64>>,
    /// The samples that count for error evaluation (the `use` column), if the file has one.
    pub use_mask: Option<Vec<bool>>,
}

/// Reads the ground truth of a file: `t` and `qw,qx,qy,qz` (any column order; NaN or empty
/// where unknown, as [`read_csv`](crate::read_csv) reads them), and `use` if present. Other
/// columns, the IMU's too, are not read: a motion-capture file `t,qw,qx,qy,qz,use` is truth
/// enough to score estimates against (`rootfuse eval`).
///
/// ```
/// let text = "t,qw,qx,qy,qz,use\n0,1,0,0,0,1\n0.01,,,,,0\n";
/// let path = std::env::temp_dir().join("rootfuse_read_truth_doc.csv");
/// std::fs::write(&path, text).unwrap();
/// let truth = rootfuse_io::read_truth(&path).unwrap();
/// assert_eq!(truth.t, [0.0, 0.01]);
/// assert!(truth.quat[1].w.is_nan());
/// assert_eq!(truth.use_mask, Some(vec![true, false]));
/// ```
///
/// # Errors
/// As [`read_csv`](crate::read_csv) for these columns: a missing one (the columns found are
/// listed), a time not finite or not increasing, an infinite component, a known quaternion
/// off unit norm, a `use` cell that is not 0/1.
pub fn read_truth(path: impl AsRef<Path>) -> Result<Truth, ReadError> {
    let mut table = Table::open(path.as_ref())?;
    let tc = table.find("t").ok_or_else(|| table.missing("t"))?;
    let mut cols = [0usize; 4];
    for (slot, name) in cols.iter_mut().zip(["qw", "qx", "qy", "qz"]) {
        *slot = table.find(name).ok_or_else(|| table.missing(name))?;
    }
    let use_col = table.find("use");
    let mut out = Truth {
        use_mask: use_col.map(|_| Vec::new()),
        ..Truth::default()
    };
    while let Some(line) = table.next_row()? {
        let t = table.value(line, tc)?;
        if !t.is_finite() {
            return Err(ReadError::NonFiniteTime {
                place: table.place(line, tc),
                value: t,
            });
        }
        if let Some(&previous) = out.t.last()
            && t <= previous
        {
            return Err(ReadError::NonMonotonicTime {
                place: table.place(line, tc),
                value: t,
                previous,
                hint: "",
            });
        }
        out.quat.push(truth(&table, line, cols)?);
        if let (Some(c), Some(mask)) = (use_col, &mut out.use_mask) {
            mask.push(use_cell(&table, line, c)?);
        }
        out.t.push(t);
    }
    Ok(out)
}
