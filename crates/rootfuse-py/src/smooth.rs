//! The offline smoother (`rootfuse_attitude::smooth`) on NumPy arrays.

use crate::arrays::{DofArg, Steps};
use crate::filter::{imu_arrays, spec_from};
use crate::inputs::Inputs;
use crate::inputs::recording;
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rootfuse_attitude::units::{UnitCheck, Units};

/// Offline forward-backward smoothing of one recording (f64), for filters with an attitude
/// covariance (`sqrt-eskf`/`flagship`, `ekf`).
///
/// gyr, acc, mag (or None): `(N, 3)`; `t` sample times, s `(N,)` (or `dt`, a fixed step:
/// times `k·dt`; the smoother reads steps as differences of times, like `rootfuse run
/// --offline`). Returns `{"quat": (N, 4), "forward_only": int}`: `forward_only` counts the
/// samples where fusion was impossible and the forward estimate was kept; for the flagship
/// (`smoothing_gyro_scale=1`, the default) also `"gyro_scale"` `(3,)`, the scale error per
/// axis (a fraction) an online run at half the rate estimated and both passes' readings were
/// divided by (`smoothing_gyro_scale=0` skips that run).
///
/// The arrays are checked against the filters' units as `read_csv` checks a file: a sensor
/// whose readings look like another unit (a gyroscope in °/s, time in ms) raises a
/// `UserWarning` naming it; convert it before the call (`read_csv(path, units=...)` converts
/// files).
#[pyfunction]
#[pyo3(signature = (name, gyr, acc, mag=None, *, t=None, dt=None, dof=None, **params))]
#[allow(clippy::too_many_arguments)]
pub fn smooth<'py>(
    py: Python<'py>,
    name: &str,
    gyr: &Bound<'py, PyAny>,
    acc: &Bound<'py, PyAny>,
    mag: Option<&Bound<'py, PyAny>>,
    t: Option<&Bound<'py, PyAny>>,
    dt: Option<&Bound<'py, PyAny>>,
    dof: Option<DofArg>,
    params: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyDict>> {
    let spec = spec_from(name, dof, params)?;
    let (gyr, acc, mag, n) = imu_arrays(gyr, acc, mag)?;
    let steps = Steps::parse(dt, t, n)?;
    if let Steps::PerSample(_) = steps {
        return Err(PyValueError::new_err(
            "dt: the smoother takes sample times t (s, shape (N,)) or a fixed step dt (a number), not per-sample steps",
        ));
    }
    let input = Inputs::new(&gyr, &acc, mag.as_ref(), &steps, n);
    let rec = recording(&input, steps.times(n), None, None);
    let nine_d = spec.uses_magnetometer();
    let findings = py.detach(|| UnitCheck::of_recording(&rec, &Units::default()));
    let judged = crate::unit_warnings::Judged::of(&spec, true);
    let findings = findings.iter().filter(|f| judged.keeps(f));
    crate::unit_warnings::warn_findings(py, "smooth", findings)?;
    let result = py.detach(|| rootfuse_attitude::smooth::smooth_spec(&rec, &spec, nine_d));
    let smoothed = result.map_err(|e| PyValueError::new_err(format!("name: {e}")))?;
    let q: Vec<f64> = smoothed
        .quat
        .iter()
        .flat_map(|q| [q.w, q.x, q.y, q.z])
        .collect();
    let out = PyDict::new(py);
    out.set_item("quat", PyArray1::from_vec(py, q).reshape([n, 4])?)?;
    out.set_item("forward_only", smoothed.forward_only)?;
    if let Some(s) = smoothed.gyro_scale {
        out.set_item("gyro_scale", PyArray1::from_slice(py, &[s.x, s.y, s.z]))?;
    }
    Ok(out)
}
