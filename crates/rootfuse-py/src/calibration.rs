//! Sensor calibration from data (`rootfuse_calibration`): the batch ellipsoid fit of the
//! model `y_cal = S·(y_raw − h)`, with its quality and what the motion left undetermined.

use crate::arrays::{float_array, real_or_none};
use numpy::{PyArray1, PyArrayMethods};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rootfuse_attitude::Vec3;
use rootfuse_calibration::{FitOptions, fit_ellipsoid};

/// Fits `y_cal = S·(y_raw − h)` with `|y_cal|` constant to raw three-axis readings `(N, 3)`
/// (a magnetometer turned through many orientations, or an accelerometer at rest in several
/// positions): an algebraic ellipsoid fit, then a geometric (Levenberg–Marquardt) refinement.
///
/// `norm`: the calibrated norm to scale to (field norm, gravity); by default `det S = 1`.
/// Returns a dict: `matrix` `S` (3, 3), `offset` `h` (3,) in raw units, `norm`, `model`
/// (`"full"`, `"diagonal-scale"`, `"offset-only"` or `"in-plane-offset"`: what the data
/// determined), `refused` (list of `(model, condition number)` the data could not determine),
/// `residual_rms_relative`, `residual_max_relative`, `coverage` (share of direction cells with
/// data), `direction_spread`, `condition`, `samples`, `skipped_non_finite`, `outliers` (the input rows left out as outliers). ValueError for
/// too few samples, a constant reading, a saturated axis, a quadric that is no ellipsoid, a
/// residual above 5 % or a three-dimensional fit to readings covering less than
/// `min_coverage` of the sphere of directions (default 0.4; an accelerometer's six rest
/// positions need 0) — a refusal, never a wrong calibration.
#[pyfunction]
#[pyo3(signature = (samples, *, norm=None, min_coverage=0.4))]
pub fn fit_ellipsoid_calibration<'py>(
    py: Python<'py>,
    samples: &Bound<'py, PyAny>,
    #[pyo3(from_py_with = real_or_none)] norm: Option<f64>,
    min_coverage: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let a = float_array(samples, "samples")?;
    if !matches!(a.shape.as_slice(), [_, 3]) {
        return Err(PyValueError::new_err(format!(
            "samples: expected shape (N, 3), got {:?}",
            a.shape
        )));
    }
    let v: Vec<Vec3<f64>> = a
        .as_slice()
        .chunks_exact(3)
        .map(|r| Vec3::new(r[0], r[1], r[2]))
        .collect();
    let options = FitOptions {
        norm,
        min_coverage,
        ..FitOptions::default()
    };
    let fit = py
        .detach(|| fit_ellipsoid(&v, &options))
        .map_err(|e| PyValueError::new_err(format!("fit_ellipsoid_calibration: {e}")))?;
    let c = &fit.calibration;
    let d = PyDict::new(py);
    let s: Vec<f64> = c.matrix.m.iter().flatten().copied().collect();
    d.set_item("matrix", PyArray1::from_vec(py, s).reshape([3, 3])?)?;
    d.set_item(
        "offset",
        PyArray1::from_vec(py, c.offset.to_array().to_vec()),
    )?;
    d.set_item("norm", c.norm)?;
    d.set_item("model", fit.model.name())?;
    let refused = PyList::empty(py);
    for r in &fit.refused {
        refused.append((r.model.name(), r.condition))?;
    }
    d.set_item("refused", refused)?;
    let q = &fit.quality;
    d.set_item("residual_rms_relative", q.residual_rms_relative)?;
    d.set_item("residual_max_relative", q.residual_max_relative)?;
    d.set_item("coverage", q.coverage)?;
    d.set_item("direction_spread", q.direction_spread)?;
    d.set_item("condition", q.condition)?;
    d.set_item("samples", q.samples)?;
    d.set_item("skipped_non_finite", fit.skipped_non_finite)?;
    d.set_item("outliers", fit.outliers.clone())?;
    Ok(d)
}
