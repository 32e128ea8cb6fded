//! Is a filter's reported covariance honest? `rootfuse_eval::consistency` for NumPy arrays.

use crate::arrays::{DofArg, float_array, real};
use crate::eval::{alignment, compared, metric_err};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rootfuse_eval::consistency::{UpperTriangle, consistency as nees};

/// NEES and 95 % coverage of estimates `est` `(N, 4)` `[w, x, y, z]` with their attitude
/// covariances `cov` against `truth` (as in `rmse`: an `(N, 4)` array or a recording dict).
///
/// `cov` is what `Filter.update_batch` returns under `"covariance"` (`(N, 3, 3)`, rad², earth
/// frame ENU) or the upper triangle `(N, 6)` `[p_xx, p_xy, p_xz, p_yy, p_yz, p_zz]` that
/// `rootfuse run --covariance` writes. `floor_deg` is a floor for the reference's own error
/// per axis, degrees (optical truth is off by a fraction of a degree); `skip` the leading
/// share of samples left out (the start-up transient; 0.1 as `rootfuse eval --consistency`).
/// `dof=6` removes the estimate's constant heading offset first, the covariance turned with
/// it. Returns `{"nees_total", "coverage_total", "nees_inclination", "coverage_inclination",
/// "n_used", "n_invalid"}`: NEES/3 and NEES/2 are 1 and the coverages 0.95 for an honest
/// covariance; NEES above 1 and coverage below 0.95 mean overconfident.
#[pyfunction]
#[pyo3(
    signature = (est, cov, truth, *, r#use=None, dof=DofArg(9), floor_deg=0.0, skip=0.1),
    text_signature = "(est, cov, truth, *, use=None, dof=9, floor_deg=0.0, skip=0.1)"
)]
#[allow(clippy::too_many_arguments)]
pub fn consistency<'py>(
    py: Python<'py>,
    est: &Bound<'py, PyAny>,
    cov: &Bound<'py, PyAny>,
    truth: &Bound<'py, PyAny>,
    r#use: Option<&Bound<'py, PyAny>>,
    dof: DofArg,
    #[pyo3(from_py_with = real)] floor_deg: f64,
    #[pyo3(from_py_with = real)] skip: f64,
) -> PyResult<Bound<'py, PyDict>> {
    if !(floor_deg.is_finite() && floor_deg >= 0.0) {
        return Err(PyValueError::new_err(format!(
            "floor_deg: expected a finite number ≥ 0 (degrees), got {floor_deg}"
        )));
    }
    if !(0.0..1.0).contains(&skip) {
        return Err(PyValueError::new_err(format!(
            "skip: expected a share in [0, 1), got {skip}"
        )));
    }
    let (e, t, mask) = compared(est, truth, r#use)?;
    let c = covariances(cov, e.len())?;
    let mode = alignment(dof.0)?;
    let r = py
        .detach(|| {
            nees(
                &e,
                &c,
                &t,
                mask.as_deref(),
                mode,
                floor_deg.to_radians(),
                skip,
            )
        })
        .map_err(metric_err)?;
    let d = PyDict::new(py);
    d.set_item("nees_total", r.nees_total)?;
    d.set_item("coverage_total", r.coverage_total)?;
    d.set_item("nees_inclination", r.nees_inclination)?;
    d.set_item("coverage_inclination", r.coverage_inclination)?;
    d.set_item("n_used", r.n_used)?;
    d.set_item("n_invalid", r.n_invalid)?;
    Ok(d)
}

/// `cov` `(N, 3, 3)` or `(N, 6)` as upper triangles, `N` equal to the estimates'.
fn covariances(cov: &Bound<'_, PyAny>, n: usize) -> PyResult<Vec<UpperTriangle>> {
    let a = float_array(cov, "cov")?;
    let shape = a.shape.clone();
    let v = a.as_slice();
    let rows: Vec<UpperTriangle> = match shape.as_slice() {
        [_, 3, 3] => v
            .chunks_exact(9)
            .map(|m| [m[0], m[1], m[2], m[4], m[5], m[8]])
            .collect(),
        [_, 6] => v
            .chunks_exact(6)
            .map(|m| [m[0], m[1], m[2], m[3], m[4], m[5]])
            .collect(),
        _ => {
            return Err(PyValueError::new_err(format!(
                "cov: expected shape (N, 3, 3) or (N, 6), got {shape:?}"
            )));
        }
    };
    if rows.len() != n {
        return Err(PyValueError::new_err(format!(
            "cov: has {} samples but est has {n}",
            rows.len()
        )));
    }
    Ok(rows)
}
