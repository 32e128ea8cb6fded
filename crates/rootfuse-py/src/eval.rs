//! Metrics (`rootfuse_eval::metrics`), the simulator (`rootfuse_eval::sim`) and recordings on
//! disk (`rootfuse_io`).

use crate::arrays::{
    DofArg, SeedArg, Steps, dtype_name, matrix, real, same_length, shape_text, type_name, vector,
};
use crate::filter::imu_arrays;
use crate::inputs::Inputs;
use crate::inputs::recording;
use numpy::{PyArray1, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyIOError, PyTypeError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use rootfuse_attitude::units::{UnitCheck, Units, UnitsError};
use rootfuse_attitude::{Quat, Recording};
use rootfuse_eval::metrics::{self, Alignment};

fn quats(obj: &Bound<'_, PyAny>, name: &str) -> PyResult<Vec<Quat<f64>>> {
    let (a, _) = matrix(obj, name, 4)?;
    Ok(a.as_slice()
        .chunks_exact(4)
        .map(|c| Quat::new(c[0], c[1], c[2], c[3]))
        .collect())
}

/// What `use` may be, for messages.
const USE_EXPECTED: &str =
    "expected a 1-D array or list of N booleans (or 0/1 values), one per sample";

/// The `use` argument: booleans (or 0/1 numbers) for the `n` samples of argument `of`
/// (`est`, `gyr`).
fn use_mask(obj: Option<&Bound<'_, PyAny>>, n: usize, of: &str) -> PyResult<Option<Vec<bool>>> {
    let o = match obj {
        None => return Ok(None),
        Some(o) if o.is_none() => return Ok(None),
        Some(o) => o,
    };
    match o.cast::<numpy::PyUntypedArray>() {
        Ok(a) if a.ndim() != 1 => {
            return Err(PyValueError::new_err(format!(
                "use: {USE_EXPECTED}, got shape {}",
                shape_text(a.shape())
            )));
        }
        Ok(_) => {}
        Err(_) if o.is_instance_of::<PyList>() || o.is_instance_of::<PyTuple>() => {}
        Err(_) => {
            return Err(PyTypeError::new_err(format!(
                "use: {USE_EXPECTED}, got {}",
                type_name(o)
            )));
        }
    }
    let v: Vec<bool> = match o.extract::<Vec<bool>>() {
        Ok(v) => v,
        Err(_) => {
            // Float arrays directly; integer arrays and lists of numbers element-wise.
            let values: Vec<f64> = match vector(o, "use") {
                Ok(v) => v,
                Err(_) => o.extract::<Vec<f64>>().map_err(|_| {
                    let got = if o.cast::<numpy::PyUntypedArray>().is_ok() {
                        format!("an array of dtype {}", dtype_name(o))
                    } else {
                        format!("a {} holding other values", type_name(o))
                    };
                    PyTypeError::new_err(format!("use: {USE_EXPECTED}, got {got}"))
                })?,
            };
            // 0 or 1 only: a NaN (`x != 0.0` is true for it) would count its row.
            if let Some((row, x)) = values
                .iter()
                .enumerate()
                .find(|(_, x)| **x != 0.0 && **x != 1.0)
            {
                return Err(PyValueError::new_err(format!(
                    "use: row {row} is {x}: expected 0 or 1 (or booleans)"
                )));
            }
            values.iter().map(|&x| x != 0.0).collect()
        }
    };
    if v.len() != n {
        return Err(PyValueError::new_err(format!(
            "use: has {} samples but {of} has {n}; use marks each sample of {of}",
            v.len()
        )));
    }
    Ok(Some(v))
}

/// Estimates, truth (both `(N, 4)`, same N) and the optional use mask.
pub(crate) type Compared = (Vec<Quat<f64>>, Vec<Quat<f64>>, Option<Vec<bool>>);

/// `truth` is an `(N, 4)` array, or a recording dict (`read_csv`, `simulate`) whose `truth`
/// and `use` are taken, as `rootfuse eval` takes them (an explicit `use` wins).
pub(crate) fn compared(
    est: &Bound<'_, PyAny>,
    truth: &Bound<'_, PyAny>,
    r#use: Option<&Bound<'_, PyAny>>,
) -> PyResult<Compared> {
    let e = quats(est, "est")?;
    let (truth, recording_use) = match truth.cast::<PyDict>() {
        Ok(rec) => {
            let t = rec
                .get_item("truth")?
                .filter(|t| !t.is_none())
                .ok_or_else(|| {
                    PyValueError::new_err(
                        "truth: the recording has no ground truth (`truth` is None)",
                    )
                })?;
            (t, rec.get_item("use")?)
        }
        Err(_) => (truth.clone(), None),
    };
    let r#use = match r#use {
        Some(u) if !u.is_none() => Some(u.clone()),
        _ => recording_use,
    };
    let r#use = r#use.as_ref();
    let t = quats(&truth, "truth")?;
    if t.len() != e.len() {
        return Err(PyValueError::new_err(format!(
            "truth: has {} samples but est has {}",
            t.len(),
            e.len()
        )));
    }
    let mask = use_mask(r#use, e.len(), "est")?;
    Ok((e, t, mask))
}

pub(crate) fn alignment(dof: u8) -> PyResult<Alignment> {
    match dof {
        9 => Ok(Alignment::NineD),
        6 => Ok(Alignment::SixD),
        _ => Err(PyValueError::new_err(format!(
            "dof: expected 6 or 9, got {dof}"
        ))),
    }
}

pub(crate) fn metric_err(e: metrics::MetricsError) -> PyErr {
    PyValueError::new_err(format!("est, truth: {e}"))
}

/// The BROAD RMSE, degrees, of estimates `est` `(N, 4)` against `truth` `(N, 4)` (both
/// `[w, x, y, z]`, sensor to earth) over the samples with `use` (bool `(N,)`, all when None)
/// and finite truth. `truth` may be a recording dict: its `truth` and `use` are taken, which
/// is what `rootfuse eval` scores (BROAD's `use` marks the samples to count). ValueError for
/// an estimate that counts and is no unit quaternion (norm off 1 by more than 0.01, or NaN),
/// naming the row, as `eval` refuses it. `dof=6` first removes the constant heading offset (circular mean), as
/// BROAD does for 6D estimates. Returns `{"total", "heading", "inclination", "n_used",
/// "heading_offset"}` (degrees; the offset removed, 0 for 9D).
#[pyfunction]
#[pyo3(
    signature = (est, truth, *, r#use=None, dof=DofArg(9)),
    text_signature = "(est, truth, *, use=None, dof=9)"
)]
pub fn rmse<'py>(
    py: Python<'py>,
    est: &Bound<'py, PyAny>,
    truth: &Bound<'py, PyAny>,
    r#use: Option<&Bound<'py, PyAny>>,
    dof: DofArg,
) -> PyResult<Bound<'py, PyDict>> {
    let (e, t, mask) = compared(est, truth, r#use)?;
    let r = metrics::rmse(&e, &t, mask.as_deref(), alignment(dof.0)?).map_err(metric_err)?;
    let d = PyDict::new(py);
    d.set_item("total", r.total)?;
    d.set_item("heading", r.heading)?;
    d.set_item("inclination", r.inclination)?;
    d.set_item("n_used", r.n_used)?;
    d.set_item("heading_offset", r.heading_offset)?;
    Ok(d)
}

/// Per-sample BROAD errors, degrees (NaN where the truth is unknown), after the alignment of
/// `dof` (see `rmse`). Returns `{"total", "heading", "inclination"}` float64 `(N,)`, `"used"`
/// bool `(N,)` and `"heading_offset"` (degrees).
#[pyfunction]
#[pyo3(
    signature = (est, truth, *, r#use=None, dof=DofArg(9)),
    text_signature = "(est, truth, *, use=None, dof=9)"
)]
pub fn error_series<'py>(
    py: Python<'py>,
    est: &Bound<'py, PyAny>,
    truth: &Bound<'py, PyAny>,
    r#use: Option<&Bound<'py, PyAny>>,
    dof: DofArg,
) -> PyResult<Bound<'py, PyDict>> {
    let (e, t, mask) = compared(est, truth, r#use)?;
    let s =
        metrics::error_series(&e, &t, mask.as_deref(), alignment(dof.0)?).map_err(metric_err)?;
    let d = PyDict::new(py);
    d.set_item("total", PyArray1::from_vec(py, s.total))?;
    d.set_item("heading", PyArray1::from_vec(py, s.heading))?;
    d.set_item("inclination", PyArray1::from_vec(py, s.inclination))?;
    d.set_item("used", PyArray1::from_vec(py, s.used))?;
    d.set_item("heading_offset", s.heading_offset)?;
    Ok(d)
}

/// The 6D heading offset, degrees in (−180, 180]: the circular mean heading of `est` relative
/// to `truth` over the counted samples; None when undefined.
#[pyfunction]
#[pyo3(signature = (est, truth, *, r#use=None), text_signature = "(est, truth, *, use=None)")]
pub fn heading_offset(
    est: &Bound<'_, PyAny>,
    truth: &Bound<'_, PyAny>,
    r#use: Option<&Bound<'_, PyAny>>,
) -> PyResult<Option<f64>> {
    let (e, t, mask) = compared(est, truth, r#use)?;
    Ok(metrics::heading_offset(&e, &t, mask.as_deref())
        .map_err(metric_err)?
        .map(f64::to_degrees))
}

/// A recording as a dict of float64 arrays: `t` `(N,)` s, `gyr` `(N, 3)` rad/s, `acc` `(N, 3)`
/// m/s², `mag` `(N, 3)` or None, `truth` `(N, 4)` `[w, x, y, z]` or None (NaN where unknown),
/// `use` bool `(N,)` or None, `name`.
fn recording_dict<'py>(py: Python<'py>, rec: Recording) -> PyResult<Bound<'py, PyDict>> {
    let n = rec.len();
    let v3 = |v: &[rootfuse_attitude::Vec3<f64>]| -> Vec<f64> {
        v.iter().flat_map(|x| [x.x, x.y, x.z]).collect()
    };
    let d = PyDict::new(py);
    d.set_item("name", &rec.name)?;
    d.set_item("gyr", PyArray1::from_vec(py, v3(&rec.gyr)).reshape([n, 3])?)?;
    d.set_item("acc", PyArray1::from_vec(py, v3(&rec.acc)).reshape([n, 3])?)?;
    match &rec.mag {
        Some(m) => d.set_item("mag", PyArray1::from_vec(py, v3(m)).reshape([n, 3])?)?,
        None => d.set_item("mag", py.None())?,
    }
    match &rec.truth {
        Some(q) => {
            let q: Vec<f64> = q.iter().flat_map(|q| [q.w, q.x, q.y, q.z]).collect();
            d.set_item("truth", PyArray1::from_vec(py, q).reshape([n, 4])?)?;
        }
        None => d.set_item("truth", py.None())?,
    }
    match rec.use_mask {
        Some(u) => d.set_item("use", PyArray1::from_vec(py, u))?,
        None => d.set_item("use", py.None())?,
    }
    d.set_item("t", PyArray1::from_vec(py, rec.t))?;
    Ok(d)
}

/// Simulates an IMU with the named preset (`scenario_names()`), seeded: returns a recording
/// dict (see `read_csv`) with the true orientation in `truth`. `duration_s` s, `rate_hz` Hz.
#[pyfunction]
#[pyo3(
    signature = (scenario, *, seed=SeedArg(0), duration_s=10.0, rate_hz=100.0),
    text_signature = "(scenario, *, seed=0, duration_s=10.0, rate_hz=100.0)"
)]
pub fn simulate<'py>(
    py: Python<'py>,
    scenario: &str,
    seed: SeedArg,
    #[pyo3(from_py_with = real)] duration_s: f64,
    #[pyo3(from_py_with = real)] rate_hz: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let rec = py
        .detach(|| rootfuse_eval::sim::scenario(scenario, seed.0, duration_s, rate_hz))
        .map_err(|e| PyValueError::new_err(format!("scenario: {e}")))?;
    recording_dict(py, rec)
}

/// The simulator's preset names.
#[pyfunction]
pub fn scenario_names() -> Vec<&'static str> {
    rootfuse_eval::sim::scenario_names().collect()
}

/// Reads a recording CSV (`t,gx,gy,gz,ax,ay,az[,mx,my,mz][,qw,qx,qy,qz][,use]`, the
/// broad_csv format; comma, semicolon or tab, decimal commas with semicolons, empty cells as
/// missing values) into a dict: `t` `(N,)` s, `gyr` `(N, 3)` rad/s, `acc` `(N, 3)` m/s²,
/// `mag` `(N, 3)` µT or None, `truth` `(N, 4)` or None, `use` bool `(N,)` or None, `name`.
///
/// `units` declares the file's units as `rootfuse run --units` does
/// (`"time=ms,gyro=deg/s,acc=g,mag=nT"`, or a factor to SI: `"acc=0.000598"`); the readings
/// are converted as read. The data are then checked against those units: a sensor whose
/// readings look like another unit raises a `UserWarning` naming the likely unit and the
/// `units=` entry that fixes it (an error with `strict=True`); a gyroscope whose readings
/// fail against how the gravity direction turned raises ValueError unless `units` gives its
/// unit (`"gyro=rad/s"` if the readings are rad/s after all), as `rootfuse run` does.
/// A malformed file raises ValueError naming file, line and column; a missing one
/// FileNotFoundError (an OSError).
#[pyfunction]
#[pyo3(signature = (path, *, units=None, strict=false))]
pub fn read_csv<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
    units: Option<&str>,
    strict: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let units: Units = match units {
        Some(text) => text
            .parse()
            .map_err(|e: UnitsError| PyValueError::new_err(e.to_string()))?,
        None => Units::default(),
    };
    let (rec, findings) = py
        .detach(|| {
            let rec = rootfuse_io::read_csv_in(&path, rootfuse_io::ImuGaps::Refuse, units)?;
            let findings = UnitCheck::of_recording(&rec, &units);
            Ok((rec, findings))
        })
        .map_err(read_error)?;
    for f in &findings {
        let advice = if f.dead {
            format!("{}: {f}", path.display())
        } else {
            format!(
                "{}: {f}: pass units=\"{}\"",
                path.display(),
                f.declaration()
            )
        };
        if strict {
            return Err(PyValueError::new_err(format!("{advice} (strict=True)")));
        }
        // As `rootfuse run`: a gyroscope that fails against the motion is an error unless
        // its unit was declared.
        if let Some((why, entry)) = f.refusal(&units) {
            return Err(PyValueError::new_err(format!(
                "{advice} ({why}, pass units=\"{entry}\")"
            )));
        }
        let message = std::ffi::CString::new(advice).unwrap_or_default();
        PyErr::warn(py, &py.get_type::<PyUserWarning>(), &message, 1)?;
    }
    recording_dict(py, rec)
}

/// Writes a recording in the format `read_csv` reads, atomically (temporary file, then
/// rename). `t` `(N,)` s, `gyr`, `acc`, `mag` (or None) `(N, 3)`, `truth` `(N, 4)` or None,
/// `use` bool `(N,)` or None. Numbers are written in shortest round-trip form.
///
/// What `read_csv` would refuse is not written: a time that is not finite or does not
/// increase, a NaN/inf IMU value, an infinite truth value (NaN means unknown), a known truth
/// quaternion off unit norm are a ValueError naming the row, the line the reader would
/// report and the column; nothing is written then. A file that cannot be written is OSError.
#[pyfunction]
#[pyo3(
    signature = (path, t, gyr, acc, mag=None, *, truth=None, r#use=None),
    text_signature = "(path, t, gyr, acc, mag=None, *, truth=None, use=None)"
)]
#[allow(clippy::too_many_arguments)]
pub fn write_recording(
    py: Python<'_>,
    path: std::path::PathBuf,
    t: &Bound<'_, PyAny>,
    gyr: &Bound<'_, PyAny>,
    acc: &Bound<'_, PyAny>,
    mag: Option<&Bound<'_, PyAny>>,
    truth: Option<&Bound<'_, PyAny>>,
    r#use: Option<&Bound<'_, PyAny>>,
) -> PyResult<()> {
    let (gyr, acc, mag, n) = imu_arrays(gyr, acc, mag)?;
    let t = vector(t, "t")?;
    same_length("t", t.len(), n)?;
    let truth = match truth {
        Some(q) if !q.is_none() => {
            let (q, nq) = matrix(q, "truth", 4)?;
            same_length("truth", nq, n)?;
            Some(q.into_vec())
        }
        _ => None,
    };
    let mask = use_mask(r#use, n, "gyr")?;
    let steps = Steps::Times(t.clone());
    let input = Inputs::new(&gyr, &acc, mag.as_ref(), &steps, n);
    let rec = recording(&input, t, truth, mask);
    py.detach(|| rootfuse_io::write_recording(&path, &rec))
        .map_err(write_error)
}

/// OSError for a file that cannot be written; ValueError for data its reader would refuse
/// (naming row, line and column) and for bad column names or lengths.
fn write_error(e: rootfuse_io::WriteError) -> PyErr {
    match e {
        rootfuse_io::WriteError::Io { .. } => PyIOError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}

/// Writes estimates as CSV `t,qw,qx,qy,qz` plus `extra` columns (`{name: (N,) array}`),
/// atomically, in the format `rootfuse run` writes. `t` `(N,)` s, `quat` `(N, 4)`.
///
/// What `read_estimates` would refuse is not written (ValueError naming row, line and
/// column): a time that is not finite or does not increase, a quaternion that is not finite
/// or not of unit norm. `extra` columns may hold NaN (read back as NaN); integer and bool
/// arrays (the `flags` of `update_batch`) are written as their numbers.
#[pyfunction]
#[pyo3(signature = (path, t, quat, extra=None))]
pub fn write_estimates(
    py: Python<'_>,
    path: std::path::PathBuf,
    t: &Bound<'_, PyAny>,
    quat: &Bound<'_, PyAny>,
    extra: Option<&Bound<'_, PyDict>>,
) -> PyResult<()> {
    let t = vector(t, "t")?;
    let q = quats(quat, "quat")?;
    same_length("quat", q.len(), t.len()).map_err(|_| {
        PyValueError::new_err(format!("quat: has {} rows but t has {}", q.len(), t.len()))
    })?;
    let mut columns: Vec<(String, Vec<f64>)> = Vec::new();
    if let Some(extra) = extra {
        for (k, v) in extra.iter() {
            let name: String = k.extract()?;
            // Integer and bool columns (`update_batch`'s uint8 `flags`) are written as numbers
            // too: exact below 2⁵³.
            let v = if v.cast::<numpy::PyUntypedArray>().is_ok()
                && matches!(
                    v.getattr("dtype")?
                        .getattr("kind")?
                        .extract::<String>()?
                        .as_str(),
                    "i" | "u" | "b"
                ) {
                v.call_method1("astype", ("float64",))?
            } else {
                v
            };
            let values = vector(&v, &name)?;
            columns.push((name, values));
        }
    }
    let refs: Vec<(&str, &[f64])> = columns
        .iter()
        .map(|(n, v)| (n.as_str(), v.as_slice()))
        .collect();
    py.detach(|| rootfuse_io::write_estimates(&path, &t, &q, &refs))
        .map_err(write_error)
}

/// Reads an estimates CSV (`t,qw,qx,qy,qz` and any other columns): `{"t": (N,), "quat":
/// (N, 4)}` plus every other column as a float64 `(N,)` array under its name (`bx`, `by`,
/// `bz`, `p_xx`..`p_zz`, `flags`, ...; an empty cell is NaN; a column named `t` or `quat`
/// cannot occur besides those two).
///
/// A malformed file raises ValueError naming file, line and column; a missing one
/// FileNotFoundError (an OSError).
#[pyfunction]
pub fn read_estimates<'py>(
    py: Python<'py>,
    path: std::path::PathBuf,
) -> PyResult<Bound<'py, PyDict>> {
    let est = py
        .detach(|| rootfuse_io::read_estimates(&path))
        .map_err(read_error)?;
    let n = est.t.len();
    let q: Vec<f64> = est.quat.iter().flat_map(|q| [q.w, q.x, q.y, q.z]).collect();
    let d = PyDict::new(py);
    // The named columns first: `t` and `quat` are set last and always are the time and
    // quaternion (a column literally named `quat` would otherwise replace them).
    for (name, values) in est.extra {
        d.set_item(name, PyArray1::from_vec(py, values))?;
    }
    d.set_item("t", PyArray1::from_vec(py, est.t))?;
    d.set_item("quat", PyArray1::from_vec(py, q).reshape([n, 4])?)?;
    Ok(d)
}

/// A reader's error as Python raises it: a missing file `FileNotFoundError` (as
/// `estimate_table` raises it), another I/O failure `OSError`, anything about the content
/// `ValueError`.
fn read_error(e: rootfuse_io::ReadError) -> PyErr {
    match e {
        rootfuse_io::ReadError::Io { ref source, .. }
            if source.kind() == std::io::ErrorKind::NotFound =>
        {
            pyo3::exceptions::PyFileNotFoundError::new_err(e.to_string())
        }
        rootfuse_io::ReadError::Io { .. } => PyIOError::new_err(e.to_string()),
        _ => PyValueError::new_err(e.to_string()),
    }
}
