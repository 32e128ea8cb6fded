//! Estimate files read back: `t,qw,qx,qy,qz` and whatever columns the run added.

use crate::error::{Place, ReadError};
use crate::recording::not_unit;
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
