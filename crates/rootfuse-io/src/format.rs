//! How numbers and column names are written: shared by the whole-file writers and the
//! streaming estimate writer.

use crate::error::WriteError;
use std::borrow::ToOwned;
use std::fmt::Write as _;
use std::path::Path;
use std::string::{String, ToString};

/// Refuses a column name that is empty, repeats one of `taken`, has white space at its ends or
/// contains a comma, quote or line break (it would not read back as one name).
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
