//! The CSV recording reader on arbitrary bytes.

use rootfuse_io::{ReadError, read_csv_from};

/// Fuzz target `csv_reader`: [`read_csv_from`] on arbitrary bytes.
///
/// Invariants: no panic; either a recording whose columns all have one length, whose time
/// stamps are finite and strictly increasing, whose IMU values are finite and whose truth has
/// no infinity, or a typed error whose message names the file and, for errors about one line,
/// a line `≥ 1` (≥ 2 for data rows).
pub fn csv_reader(data: &[u8]) {
    match read_csv_from(data, "fuzz.csv", "fuzz") {
        Ok(rec) => {
            let n = rec.t.len();
            assert!(rec.gyr.len() == n && rec.acc.len() == n, "column lengths");
            assert!(rec.mag.as_ref().is_none_or(|m| m.len() == n), "mag length");
            assert!(
                rec.truth.as_ref().is_none_or(|q| q.len() == n),
                "truth length"
            );
            assert!(
                rec.use_mask.as_ref().is_none_or(|u| u.len() == n),
                "use length"
            );
            assert!(rec.t.iter().all(|t| t.is_finite()), "time not finite");
            assert!(rec.t.windows(2).all(|w| w[0] < w[1]), "time not increasing");
            let finite =
                |v: &rootfuse_attitude::Vec3<f64>| v.to_array().iter().all(|c| c.is_finite());
            assert!(
                rec.gyr.iter().all(finite) && rec.acc.iter().all(finite),
                "IMU not finite"
            );
            assert!(
                rec.mag.as_ref().is_none_or(|m| m.iter().all(finite)),
                "mag not finite"
            );
            assert!(
                rec.truth.as_ref().is_none_or(|q| q
                    .iter()
                    .all(|q| q.to_array().iter().all(|c| !c.is_infinite()))),
                "truth infinite"
            );
            assert_eq!(rec.name, "fuzz");
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(
                msg.starts_with("fuzz.csv: "),
                "message without the file: {msg}"
            );
            let data_line = match &e {
                ReadError::FieldCount { place, .. }
                | ReadError::NotNumeric { place, .. }
                | ReadError::NonFiniteTime { place, .. }
                | ReadError::NonMonotonicTime { place, .. }
                | ReadError::NonFiniteImu { place, .. }
                | ReadError::InfiniteTruth { place, .. }
                | ReadError::BadUse { place, .. } => Some(place.line),
                _ => None,
            };
            if let Some(line) = data_line {
                assert!(line >= 2, "data error on line {line}: {msg}");
            }
        }
    }
}
