//! Python bindings of rootfuse (PyO3 + rust-numpy), built by maturin into the package
//! `rootfuse` (abi3, CPython ≥ 3.9): every registered filter by name, whole arrays with the GIL
//! released, many channels through the SIMD batch engine, the smoother, the recursive and
//! dense least-squares solvers with the stress scenarios, the BROAD metrics, the simulator and
//! recordings on disk. Nothing is reimplemented here: every function calls the library.
//!
//! Bad arguments (shape, dtype, lengths that disagree) raise `TypeError`/`ValueError` naming
//! the argument; bad samples inside valid arrays are the library's documented per-sample
//! skips, visible in the returned flags.

mod arrays;
mod calibration;
mod consistency;
mod eval;
mod filter;
mod fleet;
mod inputs;
mod lsq;
mod many;
mod registry;
mod series_arrays;
mod smooth;
mod unit_warnings;

use pyo3::prelude::*;

/// The x86-64 extensions this build's code may use (fixed at compile time: the workspace
/// builds with `-C target-cpu=native`, a portable wheel with `-C target-cpu=x86-64`), each with
/// whether the running CPU has it.
macro_rules! features {
    ($($f:tt),*) => {
        [$(($f, cfg!(target_feature = $f), cpu_has($f))),*]
    };
}

#[cfg(target_arch = "x86_64")]
fn cpu_has(feature: &str) -> bool {
    match feature {
        "sse3" => std::arch::is_x86_feature_detected!("sse3"),
        "ssse3" => std::arch::is_x86_feature_detected!("ssse3"),
        "sse4.1" => std::arch::is_x86_feature_detected!("sse4.1"),
        "sse4.2" => std::arch::is_x86_feature_detected!("sse4.2"),
        "popcnt" => std::arch::is_x86_feature_detected!("popcnt"),
        "avx" => std::arch::is_x86_feature_detected!("avx"),
        "avx2" => std::arch::is_x86_feature_detected!("avx2"),
        "fma" => std::arch::is_x86_feature_detected!("fma"),
        "bmi1" => std::arch::is_x86_feature_detected!("bmi1"),
        "bmi2" => std::arch::is_x86_feature_detected!("bmi2"),
        "lzcnt" => std::arch::is_x86_feature_detected!("lzcnt"),
        "f16c" => std::arch::is_x86_feature_detected!("f16c"),
        "avx512f" => std::arch::is_x86_feature_detected!("avx512f"),
        "avx512bw" => std::arch::is_x86_feature_detected!("avx512bw"),
        "avx512dq" => std::arch::is_x86_feature_detected!("avx512dq"),
        "avx512vl" => std::arch::is_x86_feature_detected!("avx512vl"),
        _ => false,
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn cpu_has(_: &str) -> bool {
    false
}

fn features() -> [(&'static str, bool, bool); 16] {
    features!(
        "sse3", "ssse3", "sse4.1", "sse4.2", "popcnt", "avx", "avx2", "fma", "bmi1", "bmi2",
        "lzcnt", "f16c", "avx512f", "avx512bw", "avx512dq", "avx512vl"
    )
}

/// The extensions this build was compiled to use and whether this CPU has each:
/// `{"compiled": [names], "missing": [names the CPU lacks]}`. Importing the package fails
/// with ImportError where `missing` is not empty, instead of crashing on an illegal
/// instruction later.
#[pyfunction]
fn build_info(py: Python<'_>) -> PyResult<Bound<'_, pyo3::types::PyDict>> {
    let d = pyo3::types::PyDict::new(py);
    let f = features();
    let compiled: Vec<&str> = f.iter().filter(|x| x.1).map(|x| x.0).collect();
    let missing: Vec<&str> = f.iter().filter(|x| x.1 && !x.2).map(|x| x.0).collect();
    d.set_item("compiled", compiled)?;
    d.set_item("missing", missing)?;
    Ok(d)
}

#[pymodule]
fn _rootfuse(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // Checked before any other code of this build runs (the checks themselves use no
    // extension beyond the x86-64 baseline).
    let missing: Vec<&str> = features()
        .iter()
        .filter(|x| x.1 && !x.2)
        .map(|x| x.0)
        .collect();
    if !missing.is_empty() {
        return Err(pyo3::exceptions::PyImportError::new_err(format!(
            "rootfuse: this build was compiled for a CPU with {} (-C target-cpu=native), which this CPU lacks; build it here (pip install ./crates/rootfuse-py) or install a portable wheel (scripts/build-wheel.sh)",
            missing.join(", ")
        )));
    }
    // The crate's version is the package's (maturin takes it from Cargo.toml).
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<filter::Filter>()?;
    m.add_function(wrap_pyfunction!(registry::filters, m)?)?;
    m.add_function(wrap_pyfunction!(smooth::smooth, m)?)?;
    m.add_function(wrap_pyfunction!(many::run_many, m)?)?;
    m.add_function(wrap_pyfunction!(fleet::estimate_arrow, m)?)?;
    m.add_class::<fleet::EstimateStream>()?;
    m.add_class::<lsq::Rls>()?;
    m.add_function(wrap_pyfunction!(lsq::lstsq, m)?)?;
    m.add_function(wrap_pyfunction!(lsq::stress, m)?)?;
    m.add_function(wrap_pyfunction!(lsq::stress_scenarios, m)?)?;
    m.add_function(wrap_pyfunction!(lsq::rls_forms, m)?)?;
    m.add_function(wrap_pyfunction!(eval::rmse, m)?)?;
    m.add_function(wrap_pyfunction!(eval::error_series, m)?)?;
    m.add_function(wrap_pyfunction!(eval::heading_offset, m)?)?;
    m.add_function(wrap_pyfunction!(consistency::consistency, m)?)?;
    m.add_function(wrap_pyfunction!(eval::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(eval::scenario_names, m)?)?;
    m.add_function(wrap_pyfunction!(eval::read_csv, m)?)?;
    m.add_function(wrap_pyfunction!(eval::write_recording, m)?)?;
    m.add_function(wrap_pyfunction!(eval::write_estimates, m)?)?;
    m.add_function(wrap_pyfunction!(eval::read_estimates, m)?)?;
    m.add_function(wrap_pyfunction!(calibration::fit_ellipsoid_calibration, m)?)?;
    m.add_function(wrap_pyfunction!(build_info, m)?)?;
    Ok(())
}
