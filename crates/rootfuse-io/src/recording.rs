//! CSV recordings: the header-driven reader, whole or a block of rows at a time.

use crate::error::{Place, ReadError};
use crate::table::{Cell, Dialect, Table, stem};
use rootfuse_attitude::units::Units;
use rootfuse_attitude::{Quat, Recording, Vec3};
use std::path::Path;
use std::string::{String, ToString};
use std::vec::Vec;

/// How far from 1 the norm of a quaternion read may be: a quaternion written with three
/// decimals is within 2·10⁻³ of unit norm; a zero or unnormalised one is far outside.
pub const UNIT_NORM_TOLERANCE: f64 = 0.01;

/// The quaternion is far from unit norm (NaN, i.e. unknown, is not).
pub(crate) fn not_unit(q: &[f64; 4]) -> Option<f64> {
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    ((norm - 1.0).abs() > UNIT_NORM_TOLERANCE).then_some(norm)
}

/// What the reader does with an IMU value (gyroscope, accelerometer, magnetometer) that is
/// empty, `NaN` or infinite, as wireless IMU logs write for a dropped packet.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ImuGaps {
    /// Refuse the file ([`ReadError::NonFiniteImu`]): a filter must not be fed a silently
    /// repaired value.
    #[default]
    Refuse,
    /// Keep the value as read (an empty cell as NaN). Every filter screens it
    /// ([`Screened`](rootfuse_attitude::filters::Screened)): a non-finite gyroscope skips the
    /// whole sample, a non-finite accelerometer or magnetometer skips that correction, and each
    /// skip is counted in [`Rejections`](rootfuse_attitude::filters::Rejections).
    Keep,
}

// Column groups, in the order their values are stored.
pub(crate) const REQUIRED: [&str; 7] = ["t", "gx", "gy", "gz", "ax", "ay", "az"];
pub(crate) const MAG: [&str; 3] = ["mx", "my", "mz"];
pub(crate) const QUAT: [&str; 4] = ["qw", "qx", "qy", "qz"];

/// Reads one CSV recording from a file; the recording is named after the file stem.
///
/// See the [crate documentation](crate) for the format and the errors.
pub fn read_csv(path: impl AsRef<Path>) -> Result<Recording, ReadError> {
    read_csv_with(path, ImuGaps::Refuse)
}

/// [`read_csv`] with a choice of what a missing or non-finite IMU value does.
pub fn read_csv_with(path: impl AsRef<Path>, gaps: ImuGaps) -> Result<Recording, ReadError> {
    CsvBlocks::open(path, gaps)?.read_all()
}

/// [`read_csv_with`] for a file written in `units` (converted to the filters' units as read,
/// see [`CsvBlocks::with_units`]).
pub fn read_csv_in(
    path: impl AsRef<Path>,
    gaps: ImuGaps,
    units: Units,
) -> Result<Recording, ReadError> {
    CsvBlocks::open(path, gaps)?.with_units(units).read_all()
}

/// Reads one CSV recording from any reader; `file` is only used in error messages and `name`
/// becomes [`Recording::name`].
pub fn read_csv_from<R: std::io::Read>(
    reader: R,
    file: impl AsRef<Path>,
    name: &str,
) -> Result<Recording, ReadError> {
    CsvBlocks::new(reader, file, name, ImuGaps::Refuse)?.read_all()
}

/// A CSV recording read a block of rows at a time, so that a long recording can be processed
/// in bounded memory; the same format, checks and errors as [`read_csv_with`] (which reads
/// the whole file through it).
///
/// ```
/// use rootfuse_io::{CsvBlocks, ImuGaps};
///
/// let text = "t,gx,gy,gz,ax,ay,az\n0,0,0,0,0,0,9.8\n0.01,0,0,0,0,0,9.8\n0.02,0,0,0,0,0,9.8\n";
/// let mut blocks = CsvBlocks::new(text.as_bytes(), "mem.csv", "mem", ImuGaps::Refuse).unwrap();
/// let mut rec = blocks.empty_recording();
/// assert_eq!(blocks.read_into(&mut rec, 2).unwrap(), 2);
/// rec.t.clear();
/// assert_eq!(blocks.read_into(&mut rec, 2).unwrap(), 1);
/// assert_eq!(rec.t, [0.02]);
///
/// // Semicolons and decimal commas, as spreadsheets write in many locales:
/// let text = "t;gx;gy;gz;ax;ay;az\n0;0;0;0;0;0;9,8\n";
/// let rec = rootfuse_io::read_csv_from(text.as_bytes(), "mem.csv", "mem").unwrap();
/// assert_eq!(rec.acc[0].z, 9.8);
/// ```
pub struct CsvBlocks<R: std::io::Read> {
    table: Table<R>,
    name: String,
    layout: Layout,
    gaps: ImuGaps,
    units: Units,
    previous_t: f64,
}

impl CsvBlocks<std::fs::File> {
    /// Opens a CSV recording and reads its header; the recording is named after the file stem.
    pub fn open(path: impl AsRef<Path>, gaps: ImuGaps) -> Result<Self, ReadError> {
        let path = path.as_ref();
        let file = std::fs::File::open(path).map_err(|e| ReadError::io(path, e))?;
        Self::new(file, path, &stem(path), gaps)
    }
}

impl<R: std::io::Read> CsvBlocks<R> {
    /// Reads the header from `reader`; `file` is only used in error messages and `name`
    /// becomes [`Recording::name`].
    pub fn new(
        reader: R,
        file: impl AsRef<Path>,
        name: &str,
        gaps: ImuGaps,
    ) -> Result<Self, ReadError> {
        let table = Table::new(reader, file.as_ref())?;
        let layout = Layout::from_header(&table)?;
        Ok(Self {
            table,
            name: name.to_string(),
            layout,
            gaps,
            units: Units::default(),
            previous_t: f64::NEG_INFINITY,
        })
    }

    /// Reads the file as written in `units`: every block is converted to the filters' units
    /// (s, rad/s, m/s², µT) as it is read. Time is checked (finite, increasing) as written.
    ///
    /// ```
    /// use rootfuse_io::{CsvBlocks, ImuGaps};
    ///
    /// let text = "t,gx,gy,gz,ax,ay,az\n0,90,0,0,0,0,1\n10,90,0,0,0,0,1\n";
    /// let units = "time=ms,gyro=deg/s,acc=g".parse().unwrap();
    /// let rec = CsvBlocks::new(text.as_bytes(), "mem.csv", "mem", ImuGaps::Refuse)
    ///     .unwrap()
    ///     .with_units(units)
    ///     .read_all()
    ///     .unwrap();
    /// assert_eq!(rec.t, [0.0, 0.01]);
    /// assert!((rec.gyr[0].x - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
    /// assert_eq!(rec.acc[0].z, 9.80665);
    /// ```
    pub fn with_units(mut self, units: Units) -> Self {
        self.units = units;
        self
    }

    /// The units the file is read as.
    pub fn units(&self) -> Units {
        self.units
    }

    /// True when the file has magnetometer columns.
    pub fn has_mag(&self) -> bool {
        self.layout.mag.is_some()
    }

    /// How the file is written (delimiter, decimal comma).
    pub fn dialect(&self) -> Dialect {
        self.table.dialect
    }

    /// A recording with no rows and the file's column groups (`mag`, `truth`, `use_mask`
    /// present or not), to read blocks into.
    pub fn empty_recording(&self) -> Recording {
        Recording {
            name: self.name.clone(),
            mag: self.layout.mag.map(|_| Vec::new()),
            truth: self.layout.quat.map(|_| Vec::new()),
            use_mask: self.layout.use_col.map(|_| Vec::new()),
            ..Recording::default()
        }
    }

    /// Reads every remaining row into a recording.
    pub fn read_all(mut self) -> Result<Recording, ReadError> {
        let mut rec = self.empty_recording();
        self.read_into(&mut rec, usize::MAX)?;
        Ok(rec)
    }

    /// Reads up to `max_rows` more rows and appends them to `rec` (made by
    /// [`empty_recording`](Self::empty_recording)); returns how many were read, 0 at the end
    /// of the file. Time must increase across blocks too.
    pub fn read_into(&mut self, rec: &mut Recording, max_rows: usize) -> Result<usize, ReadError> {
        let start = rec.len();
        let mut read = 0;
        while read < max_rows {
            let Some(line) = self.table.next_row()? else {
                break;
            };
            read += 1;
            self.read_row(line, rec)?;
        }
        if !self.units.is_si() {
            self.units.convert(
                &mut rec.t[start..],
                &mut rec.gyr[start..],
                &mut rec.acc[start..],
                rec.mag.as_mut().map(|m| &mut m[start..]),
            );
        }
        Ok(read)
    }

    fn read_row(&mut self, line: u64, rec: &mut Recording) -> Result<(), ReadError> {
        let (table, layout) = (&self.table, &self.layout);
        let imu = |field: usize| -> Result<f64, ReadError> {
            let (value, empty) = match table.cell(field) {
                Cell::Number(v) => (v, false),
                Cell::Empty => (f64::NAN, true),
                Cell::Text => return table.number(line, field),
            };
            if value.is_finite() || self.gaps == ImuGaps::Keep {
                Ok(value)
            } else {
                Err(ReadError::NonFiniteImu {
                    place: table.place(line, field),
                    value,
                    empty,
                })
            }
        };
        let tc = layout.required[0];
        let t = table.value(line, tc)?;
        if !t.is_finite() {
            return Err(ReadError::NonFiniteTime {
                place: table.place(line, tc),
                value: t,
            });
        }
        if t <= self.previous_t {
            return Err(ReadError::NonMonotonicTime {
                place: table.place(line, tc),
                value: t,
                previous: self.previous_t,
                hint: if table.find("device").is_some() {
                    "; the file has a `device` column, but a CSV file is one recording: write a fleet as Parquet or Arrow (read by device), or one CSV file per device"
                } else {
                    ""
                },
            });
        }
        let r = &layout.required;
        let gyr = Vec3::new(imu(r[1])?, imu(r[2])?, imu(r[3])?);
        let acc = Vec3::new(imu(r[4])?, imu(r[5])?, imu(r[6])?);
        let mag = match layout.mag {
            Some(c) => Some(Vec3::new(imu(c[0])?, imu(c[1])?, imu(c[2])?)),
            None => None,
        };
        let truth = layout.quat.map(|c| truth(table, line, c)).transpose()?;
        let use_row = layout
            .use_col
            .map(|c| use_cell(table, line, c))
            .transpose()?;
        self.previous_t = t;
        rec.t.push(t);
        rec.gyr.push(gyr);
        rec.acc.push(acc);
        if let (Some(m), Some(out)) = (mag, &mut rec.mag) {
            out.push(m);
        }
        if let (Some(q), Some(out)) = (truth, &mut rec.truth) {
            out.push(q);
        }
        if let (Some(u), Some(out)) = (use_row, &mut rec.use_mask) {
            out.push(u);
        }
        Ok(())
    }
}

/// The truth quaternion of a row: NaN (unknown) when any component is NaN or empty, an error
/// when one is infinite or the whole is far from unit norm.
pub(crate) fn truth<R: std::io::Read>(
    table: &Table<R>,
    line: u64,
    cols: [usize; 4],
) -> Result<Quat<f64>, ReadError> {
    let mut q = [0.0; 4];
    for (k, &c) in cols.iter().enumerate() {
        let v = table.value(line, c)?;
        if v.is_infinite() {
            return Err(ReadError::InfiniteTruth {
                place: table.place(line, c),
                value: v,
            });
        }
        q[k] = v;
    }
    // A partly known quaternion is no orientation: unknown as a whole.
    if q.iter().any(|v| v.is_nan()) {
        q = [f64::NAN; 4];
    } else if let Some(norm) = not_unit(&q) {
        return Err(ReadError::NotUnitQuaternion {
            place: Place::line(&table.file, line),
            columns: "qw,qx,qy,qz",
            norm,
        });
    }
    Ok(Quat::new(q[0], q[1], q[2], q[3]))
}

/// A `use` cell: `1`/`0` (also `1.0`, `true`, `false` in any case, as pandas writes a bool or
/// a float column); empty means unknown, which does not count.
pub(crate) fn use_cell<R: std::io::Read>(
    table: &Table<R>,
    line: u64,
    c: usize,
) -> Result<bool, ReadError> {
    let text = table.text(c);
    match table.cell(c) {
        Cell::Number(1.0) => Ok(true),
        Cell::Number(0.0) => Ok(false),
        Cell::Empty => Ok(false),
        _ if text.eq_ignore_ascii_case("true") => Ok(true),
        _ if text.eq_ignore_ascii_case("false") => Ok(false),
        _ => Err(ReadError::BadUse {
            place: table.place(line, c),
            text: table.shown(c),
        }),
    }
}

/// Where each known column is (0-based field indices).
struct Layout {
    required: [usize; 7],
    mag: Option<[usize; 3]>,
    quat: Option<[usize; 4]>,
    use_col: Option<usize>,
}

impl Layout {
    fn from_header<R: std::io::Read>(table: &Table<R>) -> Result<Self, ReadError> {
        let header = &table.header;
        // Duplicate names would make "the" column ambiguous; extra columns may repeat freely
        // only if we never look at them, but a clear rule is simpler: no duplicates at all.
        for (i, h) in header.iter().enumerate() {
            if header[..i].contains(h) {
                return Err(ReadError::DuplicateColumn {
                    place: Place::cell(&table.file, 1, h, i),
                });
            }
        }
        let all = |names: &[&'static str]| -> Result<Option<Vec<usize>>, ReadError> {
            let found: Vec<Option<usize>> = names.iter().map(|n| table.find(n)).collect();
            if found.iter().all(Option::is_none) {
                return Ok(None);
            }
            match found.iter().position(Option::is_none) {
                Some(k) => Err(table.missing(names[k])),
                None => Ok(Some(found.into_iter().flatten().collect())),
            }
        };
        let mut required = [0; 7];
        for (slot, name) in required.iter_mut().zip(REQUIRED) {
            *slot = table.find(name).ok_or_else(|| table.missing(name))?;
        }
        let mag = all(&MAG)?.map(|v| [v[0], v[1], v[2]]);
        let quat = all(&QUAT)?.map(|v| [v[0], v[1], v[2], v[3]]);
        Ok(Self {
            required,
            mag,
            quat,
            use_col: table.find("use"),
        })
    }
}
