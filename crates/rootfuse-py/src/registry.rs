//! The registry listing: every filter with its parameters, units and ranges.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use rootfuse_attitude::registry::FilterKind;

/// Every registered filter: a list of dicts `{"name", "description", "params": [{"name",
/// "kind", "default", "unit", "min", "max", "doc"}]}`.
#[pyfunction]
pub fn filters(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let out = PyList::empty(py);
    for kind in FilterKind::ALL {
        let d = PyDict::new(py);
        d.set_item("name", kind.name())?;
        d.set_item("description", kind.description())?;
        let params = PyList::empty(py);
        for p in kind.params() {
            let pd = PyDict::new(py);
            pd.set_item("name", p.name)?;
            pd.set_item("kind", p.kind.describe())?;
            pd.set_item("default", p.default)?;
            pd.set_item("unit", p.unit)?;
            pd.set_item("min", p.min)?;
            pd.set_item("max", p.max)?;
            pd.set_item("doc", p.doc)?;
            params.append(pd)?;
        }
        d.set_item("params", params)?;
        out.append(d)?;
    }
    Ok(out)
}
