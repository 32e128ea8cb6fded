//! The column types a fleet file may have, read as `f64`, and the check of its schema.

use crate::DEVICE;
use crate::error::ColumnarError;
use arrow::array::{Array, ArrayRef, AsArray};
use arrow::datatypes::{DataType, Float32Type, Float64Type, Int64Type, Schema};
use std::borrow::Cow;
use std::path::Path;

pub(crate) use rootfuse_io::column_list;

/// The columns every fleet file has.
pub(crate) const REQUIRED: [&str; 7] = ["t", "gx", "gy", "gz", "ax", "ay", "az"];
/// The magnetometer's columns: all three or none.
pub(crate) const MAG: [&str; 3] = ["mx", "my", "mz"];

/// Values of a numeric column as `f64`, nulls as NaN; `None` for a type [`numeric`] does not
/// accept. Floats are read as they are, integers (raw counts, a time in ms) and decimals
/// converted (exact up to 2⁵³), a dictionary by its values, and a timestamp or duration
/// (accepted for `t`) in seconds. A float64 column without nulls is borrowed, not copied (the
/// IMU columns are read once, into the block's vectors).
pub(crate) fn float_values(col: &ArrayRef) -> Option<Cow<'_, [f64]>> {
    use arrow::datatypes::TimeUnit;
    let ty = col.data_type();
    if *ty == DataType::Float64 && col.null_count() == 0 {
        return Some(Cow::Borrowed(col.as_primitive::<Float64Type>().values()));
    }
    let mut values: Vec<f64> = match ty {
        DataType::Float64 => col.as_primitive::<Float64Type>().values().to_vec(),
        DataType::Float32 => col
            .as_primitive::<Float32Type>()
            .values()
            .iter()
            .map(|&v| f64::from(v))
            .collect(),
        DataType::Timestamp(unit, _) | DataType::Duration(unit) => {
            let seconds = match unit {
                TimeUnit::Second => 1.0,
                TimeUnit::Millisecond => 1e-3,
                TimeUnit::Microsecond => 1e-6,
                TimeUnit::Nanosecond => 1e-9,
            };
            let ticks = arrow::compute::cast(col, &DataType::Int64).ok()?;
            let ticks = ticks.as_primitive::<Int64Type>().values();
            ticks.iter().map(|&v| v as f64 * seconds).collect()
        }
        _ if numeric(ty) => {
            let cast = arrow::compute::cast(col, &DataType::Float64).ok()?;
            cast.as_primitive::<Float64Type>().values().to_vec()
        }
        _ => return None,
    };
    if let Some(nulls) = col.logical_nulls() {
        for r in (0..values.len()).filter(|&r| nulls.is_null(r)) {
            values[r] = f64::NAN;
        }
    }
    Some(Cow::Owned(values))
}

/// A type whose values read as numbers: floats, integers, decimals, and a dictionary of them.
fn numeric(ty: &DataType) -> bool {
    match ty {
        DataType::Dictionary(_, values) => numeric(values),
        _ => ty.is_numeric(),
    }
}

/// A type `t` may have beside a number: a timestamp or duration (read in seconds).
pub(crate) fn time_like(ty: &DataType) -> bool {
    matches!(ty, DataType::Timestamp(..) | DataType::Duration(_))
}

pub(crate) fn type_error(file: &Path, column: &str, found: &DataType) -> ColumnarError {
    ColumnarError::ColumnType {
        file: file.to_owned(),
        column: column.to_string(),
        found: found.to_string(),
        expected: match column {
            DEVICE => "an integer or string",
            "t" => "a number (float, integer) or a timestamp",
            _ => "a number (float, integer, decimal)",
        },
    }
}

/// Checks names and types; returns the indices of the columns to read, whether there is a
/// magnetometer and the device column's type.
pub(crate) fn check_schema(
    file: &Path,
    schema: &Schema,
) -> Result<(Vec<usize>, bool, Option<DataType>), ColumnarError> {
    let fields = schema.fields();
    for (i, f) in fields.iter().enumerate() {
        if fields[..i].iter().any(|g| g.name() == f.name()) {
            return Err(ColumnarError::DuplicateColumn {
                file: file.to_owned(),
                column: f.name().clone(),
            });
        }
    }
    let find = |name: &str| fields.iter().position(|f| f.name() == name);
    let mut projection = Vec::new();
    let mut float = |name: &'static str, i: usize| -> Result<(), ColumnarError> {
        let ty = fields[i].data_type();
        if !(numeric(ty) || name == "t" && time_like(ty)) {
            return Err(type_error(file, name, ty));
        }
        projection.push(i);
        Ok(())
    };
    let missing = |column: &'static str| ColumnarError::MissingColumn {
        file: file.to_owned(),
        column,
        found: column_list(fields.iter().map(|f| f.name())),
    };
    for name in REQUIRED {
        let i = find(name).ok_or_else(|| missing(name))?;
        float(name, i)?;
    }
    let mag: Vec<Option<usize>> = MAG.iter().map(|n| find(n)).collect();
    let has_mag = mag.iter().any(Option::is_some);
    if has_mag {
        for (name, i) in MAG.into_iter().zip(&mag) {
            let i = i.ok_or_else(|| missing(name))?;
            float(name, i)?;
        }
    }
    let device_type = match find(DEVICE) {
        Some(i) => {
            let ty = fields[i].data_type().clone();
            let text = matches!(
                ty,
                DataType::Utf8
                    | DataType::LargeUtf8
                    | DataType::Utf8View
                    | DataType::Dictionary(..)
            );
            if !ty.is_integer() && !text {
                return Err(type_error(file, DEVICE, &ty));
            }
            projection.push(i);
            Some(ty)
        }
        None => None,
    };
    projection.sort_unstable();
    Ok((projection, has_mag, device_type))
}
