//! `rootfuse calibrate mag|acc|gyro FILE…`: sensor calibration from recordings, printed with
//! its quality and written as JSON that `rootfuse run --calibration FILE` applies.
//!
//! The file holds one section per sensor (`mag`, `acc`, `gyro`), each the model
//! `y_cal = S·(y_raw − h)` as `matrix` (S, row-major), `offset` (h, raw units) and `norm`,
//! plus the fitted model and quality for the record. Calibrating another sensor into an
//! existing file replaces that sensor's section and keeps the others.
//!
//! Readings are converted by `--units` first, as `rootfuse run` converts them before it
//! applies a calibration: the calibration is in the filters' units (µT, m/s², rad/s), and
//! each section records the unit its readings were written in (`units`), which `run` checks
//! against its own `--units`.
use crate::checks::{InputChecks, parse_units};
use clap::{Args, ValueEnum};
use rootfuse_attitude::units::{Sensor as UnitSensor, Unit, Units};
use rootfuse_attitude::{Mat, Recording, SensorCalibration, Vec3};
use rootfuse_batch::RejectionTotals;
use rootfuse_calibration::{
    EllipsoidFit, FitOptions, RestOptions, RestPhase, accelerometer, fit_ellipsoid, gyro_bias,
    rest_phases, rest_search,
};
use rootfuse_io::{ImuGaps, read_csv_in, temporary_path};
use serde_json::{Map, Value, json};
use std::path::{Path, PathBuf};

/// Which sensor to calibrate.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Sensor {
    /// Magnetometer hard and soft iron (turn the sensor through as many orientations as
    /// possible).
    Mag,
    /// Accelerometer offset and scale (rest in six or more orientations: each axis up and down).
    Acc,
    /// Gyroscope bias (rest phases).
    Gyro,
}

impl Sensor {
    fn key(self) -> &'static str {
        self.unit_sensor().key()
    }

    /// The sensor as `--units` names it.
    fn unit_sensor(self) -> UnitSensor {
        match self {
            Sensor::Mag => UnitSensor::Magnetometer,
            Sensor::Acc => UnitSensor::Accelerometer,
            Sensor::Gyro => UnitSensor::Gyroscope,
        }
    }

    const ALL: [Sensor; 3] = [Sensor::Mag, Sensor::Acc, Sensor::Gyro];
}

/// Options of `rootfuse calibrate`.
#[derive(Args)]
pub struct CalibrateArgs {
    /// The sensor.
    #[arg(value_enum)]
    sensor: Sensor,
    /// IMU CSV files (all are used together).
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// The calibration file to write (its other sensors' sections are kept).
    #[arg(long, default_value = "calibration.json")]
    out: PathBuf,
    /// Magnetometer: the field norm the calibrated readings should have (the local field
    /// strength, µT: after `--units`); default: scale S to det S = 1.
    #[arg(long)]
    norm: Option<f64>,
    /// Magnetometer: the smallest share of the sphere of directions the readings must cover
    /// for a three-dimensional fit (a fit to a cap of it extrapolates the rest: on BROAD
    /// trials, fits at 4–33 % made the 9D error 3–165°).
    #[arg(long, value_name = "FRACTION", default_value_t = 0.4)]
    min_coverage: f64,
    /// The units the files are written in, as given to `rootfuse run --units` (readings are
    /// converted first; the calibration file records them and `run` checks its own against
    /// them).
    #[arg(long, value_name = "LIST", value_parser = parse_units, default_value = "")]
    units: Units,
    /// Accelerometer: gravity, m/s².
    #[arg(long, default_value_t = 9.81)]
    gravity: f64,
}

/// Runs the command.
pub fn run(args: &CalibrateArgs) -> Result<(), String> {
    let recs = args
        .files
        .iter()
        .map(|f| read_csv_in(f, ImuGaps::Keep, args.units).map_err(|e| e.to_string()))
        .collect::<Result<Vec<_>, _>>()?;
    check_units(args, &recs)?;
    let section = match args.sensor {
        Sensor::Mag => {
            let mut mag = Vec::new();
            for (rec, file) in recs.iter().zip(&args.files) {
                let m = rec
                    .mag
                    .as_ref()
                    .ok_or_else(|| format!("{}: no magnetometer columns", file.display()))?;
                mag.extend_from_slice(m);
            }
            let options = FitOptions {
                norm: args.norm,
                min_coverage: args.min_coverage,
                ..FitOptions::default()
            };
            let fit = fit_ellipsoid(&mag, &options).map_err(|e| format!("mag: {e}"))?;
            print_fit("magnetometer", &fit);
            print_outliers(&fit.outliers, &recs, &args.files);
            fit_json(&fit)
        }
        Sensor::Acc | Sensor::Gyro => {
            let (mut gyr, mut acc, mut phases) = (Vec::new(), Vec::new(), Vec::new());
            for rec in &recs {
                let offset = acc.len();
                phases.extend(
                    rest_phases(
                        &rec.t,
                        &rec.gyr,
                        &rec.acc,
                        rec.mag.as_deref(),
                        &RestOptions::default(),
                    )
                    .into_iter()
                    .map(|p| RestPhase {
                        start: p.start + offset,
                        end: p.end + offset,
                        ..p
                    }),
                );
                gyr.extend_from_slice(&rec.gyr);
                acc.extend_from_slice(&rec.acc);
            }
            out!("rest phases: {}", phases.len());
            if phases.is_empty() {
                // Say why, file by file: which test the blocks failed.
                let why: Vec<String> = recs
                    .iter()
                    .zip(&args.files)
                    .map(|(rec, file)| {
                        let search =
                            rest_search(&rec.t, &rec.gyr, &rec.acc, &RestOptions::default());
                        format!("{}: {search}", file.display())
                    })
                    .collect();
                return Err(format!("no rest phase found: {}", why.join("; ")));
            }
            if args.sensor == Sensor::Acc {
                let fit = accelerometer(&acc, &phases, args.gravity, &FitOptions::default())
                    .map_err(|e| format!("acc: {e}"))?;
                print_fit("accelerometer", &fit.fit);
                fit_json(&fit.fit)
            } else {
                let fit = gyro_bias(&gyr, &phases).map_err(|e| format!("gyro: {e}"))?;
                let b = fit.calibration.offset;
                let se = fit.std_error;
                out!(
                    "gyroscope bias (rad/s): [{:.6}, {:.6}, {:.6}] ± [{:.1e}, {:.1e}, {:.1e}]",
                    b.x,
                    b.y,
                    b.z,
                    se.x,
                    se.y,
                    se.z
                );
                out!(
                    "from {} samples in {} rest phases; largest phase deviation {:.2e} rad/s",
                    fit.samples,
                    fit.phases,
                    fit.phase_spread
                );
                let mut v = calibration_json(&fit.calibration);
                v["std_error"] = json!(se.to_array());
                v["phase_spread"] = json!(fit.phase_spread);
                v
            }
        }
    };
    let mut root = match std::fs::read_to_string(&args.out) {
        Ok(text) => serde_json::from_str::<Value>(&text)
            .ok()
            .and_then(|v| v.as_object().cloned())
            .ok_or_else(|| {
                format!(
                    "{}: exists and is not a calibration file; not overwritten",
                    args.out.display()
                )
            })?,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Map::new(),
        Err(e) => return Err(format!("{}: {e}", args.out.display())),
    };
    root.insert("format".into(), json!("rootfuse-calibration"));
    root.insert("version".into(), json!(1));
    let mut section = section;
    section["units"] = json!(args.units.get(args.sensor.unit_sensor()).to_string());
    root.insert(args.sensor.key().into(), section);
    write_json_atomic(&args.out, &Value::Object(root))?;
    out!("written: {}", args.out.display());
    Ok(())
}

/// The files' readings checked against `--units` as `rootfuse run` checks them (warnings
/// printed; a gyroscope that fails against the motion an error): time in ms found thousands
/// of "rest phases" without a word.
fn check_units(args: &CalibrateArgs, recs: &[Recording]) -> Result<(), String> {
    let mut checks = InputChecks::new(args.units, false);
    for (d, (rec, file)) in recs.iter().zip(&args.files).enumerate() {
        checks.observe_recording(d as u32, rec);
        let what = file.display().to_string();
        // The magnetometer's magnitude says nothing before it is calibrated (a hard iron of
        // 200 µT looked like mG): its findings are left out.
        let verdict = checks.judge(&what, d as u32, RejectionTotals::default(), false);
        for w in &verdict.warnings {
            eprintln!("warning: {w}");
        }
        if let Some(e) = verdict.error {
            return Err(e);
        }
    }
    Ok(())
}

fn print_fit(what: &str, fit: &EllipsoidFit) {
    let c = &fit.calibration;
    let q = &fit.quality;
    out!("{what}: model {} (y_cal = S·(y_raw − h))", fit.model);
    for r in &fit.refused {
        out!(
            "  not determined by the motion: {} (condition {:.3e})",
            r.model,
            r.condition
        );
    }
    out!(
        "  h = [{:.6}, {:.6}, {:.6}]",
        c.offset.x,
        c.offset.y,
        c.offset.z
    );
    for (i, row) in c.matrix.m.iter().enumerate() {
        out!(
            "  {} [{:.6}, {:.6}, {:.6}]",
            if i == 0 { "S =" } else { "   " },
            row[0],
            row[1],
            row[2]
        );
    }
    out!("  norm = {:.6}", c.norm);
    out!(
        "  residual RMS {:.3} % of the norm (max {:.3} %), coverage {:.0} % of directions, spread {:.2}, condition {:.1}, {} samples ({} non-finite skipped)",
        100.0 * q.residual_rms_relative,
        100.0 * q.residual_max_relative,
        100.0 * q.coverage,
        q.direction_spread,
        q.condition,
        q.samples,
        fit.skipped_non_finite
    );
}

/// Names the rows the fit left out as outliers: file and 0-based data row (the first few).
fn print_outliers(rows: &[usize], recs: &[Recording], files: &[PathBuf]) {
    if rows.is_empty() {
        return;
    }
    let named: Vec<String> = rows
        .iter()
        .take(5)
        .map(|&row| {
            // `row` indexes the files' readings laid end to end.
            let mut rest = row;
            for (rec, file) in recs.iter().zip(files) {
                if rest < rec.len() {
                    return format!("{} row {rest}", file.display());
                }
                rest -= rec.len();
            }
            format!("row {row}")
        })
        .collect();
    let more = rows.len().saturating_sub(named.len());
    eprintln!(
        "note: {} outlier reading(s) left out of the fit (far from every other, or off the fitted ellipsoid): {}{}",
        rows.len(),
        named.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        }
    );
}

fn calibration_json(c: &SensorCalibration<f64>) -> Value {
    json!({
        "matrix": c.matrix.m,
        "offset": c.offset.to_array(),
        // JSON has no NaN: a sensor without a norm (gyroscope) writes null.
        "norm": if c.norm.is_finite() { json!(c.norm) } else { Value::Null },
    })
}

fn fit_json(fit: &EllipsoidFit) -> Value {
    let mut v = calibration_json(&fit.calibration);
    let q = &fit.quality;
    v["model"] = json!(fit.model.name());
    v["not_determined"] = json!(
        fit.refused
            .iter()
            .map(|r| json!({"model": r.model.name(), "condition": r.condition}))
            .collect::<Vec<_>>()
    );
    v["quality"] = json!({
        "residual_rms_relative": q.residual_rms_relative,
        "residual_max_relative": q.residual_max_relative,
        "coverage": q.coverage,
        "direction_spread": q.direction_spread,
        "condition": q.condition,
        "samples": q.samples,
        "skipped_non_finite": fit.skipped_non_finite,
        "outliers": fit.outliers.len(),
    });
    v
}

fn write_json_atomic(path: &Path, value: &Value) -> Result<(), String> {
    let tmp = temporary_path(path, std::process::id());
    let text = serde_json::to_string_pretty(value).map_err(|e| e.to_string())?;
    let result = std::fs::write(&tmp, text + "\n").and_then(|()| std::fs::rename(&tmp, path));
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(format!("{}: cannot write: {e}", path.display()));
    }
    Ok(())
}

/// The calibrations of a file written by `rootfuse calibrate` (absent sensors: `None`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CalibrationSet {
    /// The file, for messages.
    pub file: PathBuf,
    /// Per section present (`mag`, `acc`, `gyro`), the unit its readings were written in as
    /// the file records it (`None`: a file written before units were recorded, fitted on the
    /// readings as written).
    pub units: Vec<(Sensor, Option<String>)>,
    /// Magnetometer.
    pub mag: Option<SensorCalibration<f64>>,
    /// Accelerometer.
    pub acc: Option<SensorCalibration<f64>>,
    /// Gyroscope.
    pub gyro: Option<SensorCalibration<f64>>,
}

/// Reads a calibration file; every error names the file and the offending key.
pub fn read_calibration(path: &Path) -> Result<CalibrationSet, String> {
    let err = |what: String| format!("{}: {what}", path.display());
    let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
    let root: Value = serde_json::from_str(&text).map_err(|e| err(e.to_string()))?;
    if root.get("format") != Some(&json!("rootfuse-calibration")) {
        return Err(err(
            "not a rootfuse calibration file (no \"format\": \"rootfuse-calibration\")".into(),
        ));
    }
    let section = |key: &str| -> Result<Option<SensorCalibration<f64>>, String> {
        let Some(s) = root.get(key) else {
            return Ok(None);
        };
        let num = |v: &Value, what: &str| {
            v.as_f64()
                .filter(|x| x.is_finite())
                .ok_or_else(|| err(format!("{key}.{what}: not a finite number")))
        };
        let offset = s
            .get("offset")
            .and_then(Value::as_array)
            .filter(|a| a.len() == 3)
            .ok_or_else(|| err(format!("{key}.offset: not an array of 3 numbers")))?;
        let rows = s
            .get("matrix")
            .and_then(Value::as_array)
            .filter(|a| a.len() == 3)
            .ok_or_else(|| err(format!("{key}.matrix: not 3 rows")))?;
        let mut m = [[0.0; 3]; 3];
        for (i, row) in rows.iter().enumerate() {
            let row = row
                .as_array()
                .filter(|r| r.len() == 3)
                .ok_or_else(|| err(format!("{key}.matrix[{i}]: not 3 numbers")))?;
            for (j, v) in row.iter().enumerate() {
                m[i][j] = num(v, &format!("matrix[{i}][{j}]"))?;
            }
        }
        let h = [
            num(&offset[0], "offset[0]")?,
            num(&offset[1], "offset[1]")?,
            num(&offset[2], "offset[2]")?,
        ];
        let norm = match s.get("norm") {
            None | Some(Value::Null) => f64::NAN,
            Some(v) => num(v, "norm")?,
        };
        Ok(Some(SensorCalibration {
            matrix: Mat::from_rows(m),
            offset: Vec3::from_array(h),
            norm,
        }))
    };
    let units = Sensor::ALL
        .into_iter()
        .filter_map(|s| {
            let section = root.get(s.key())?;
            let unit = section.get("units").and_then(Value::as_str);
            Some((s, unit.map(str::to_string)))
        })
        .collect();
    Ok(CalibrationSet {
        file: path.to_path_buf(),
        units,
        mag: section("mag")?,
        acc: section("acc")?,
        gyro: section("gyro")?,
    })
}

/// Applies the calibrations to a recording's raw readings, in place (the one place where
/// `rootfuse run --calibration` corrects data).
pub fn apply_calibration(rec: &mut Recording, set: &CalibrationSet) {
    set.apply(&mut rec.gyr, &mut rec.acc, rec.mag.as_deref_mut());
}

impl CalibrationSet {
    /// Refuses a run whose `--units` read a sensor in another unit than its calibration was
    /// fitted on: the calibration applies to converted readings, in the filters' units.
    pub fn check_units(&self, units: &Units) -> Result<(), String> {
        for (sensor, recorded) in &self.units {
            let (key, which) = (sensor.key(), sensor.unit_sensor());
            let read = units.get(which);
            // A file without units was fitted on the readings as written: the filters' units.
            let fitted = match recorded {
                Some(text) => Unit::parse(which, text).ok_or_else(|| {
                    format!(
                        "{}: {key}.units: {text:?} is no unit of the {} ({})",
                        self.file.display(),
                        which.name(),
                        Unit::names(which)
                    )
                })?,
                None => Units::default().get(which),
            };
            if fitted.factor() != read.factor() {
                let said = match recorded {
                    Some(_) => format!("was fitted on readings in {fitted}"),
                    None => format!(
                        "records no unit (written before units were recorded: taken as {fitted})"
                    ),
                };
                return Err(format!(
                    "{}: the {key} calibration {said}, and this run reads them in {read}: run with --units {key}={fitted}, or calibrate again with this run's --units",
                    self.file.display()
                ));
            }
        }
        Ok(())
    }

    /// Applies each sensor's calibration (`y_cal = S·(y_raw − h)`) to its readings in place;
    /// sensors without a calibration are left as they are. Used on whole recordings
    /// (`--offline`) and on the blocks `run` streams.
    pub fn apply(
        &self,
        gyr: &mut [Vec3<f64>],
        acc: &mut [Vec3<f64>],
        mag: Option<&mut [Vec3<f64>]>,
    ) {
        let apply = |cal: &Option<SensorCalibration<f64>>, v: &mut [Vec3<f64>]| {
            if let Some(c) = cal {
                for y in v {
                    *y = c.apply(*y);
                }
            }
        };
        apply(&self.gyro, gyr);
        apply(&self.acc, acc);
        if let Some(mag) = mag {
            apply(&self.mag, mag);
        }
    }
}
