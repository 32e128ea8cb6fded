"""rootfuse: numerically robust attitude filters, a SIMD batch engine over many IMU channels,
recursive and dense least squares, from NumPy. Every function calls the Rust library
(``crates/rootfuse-py``); nothing is reimplemented in Python.

Conventions: quaternions ``[w, x, y, z]``, sensor to earth, earth frame ENU; gyroscope rad/s,
accelerometer m/s² (+g up at rest), magnetometer in µT, time in seconds
(arrays that look like °/s, g, ms or nT are named in a ``UserWarning``).
Flags per sample (uint8): 1 dt, 2 gyroscope (whole sample skipped), 4 accelerometer,
8 magnetometer (correction skipped), 16 gated by the filter, 32 at rest, 64 magnetic
disturbance.
"""

from ._rootfuse import (
    __version__,
    Filter,
    Rls,
    build_info,
    consistency,
    error_series,
    filters,
    fit_ellipsoid_calibration,
    heading_offset,
    lstsq,
    read_csv,
    read_estimates,
    rls_forms,
    rmse,
    run_many,
    scenario_names,
    simulate,
    smooth,
    stress,
    stress_scenarios,
    write_estimates,
    write_recording,
)

FLAG_DT = 1
FLAG_GYR = 2
FLAG_ACC = 4
FLAG_MAG = 8
FLAG_GATED = 16
FLAG_REST = 32
FLAG_MAG_DISTURBED = 64

__all__ = [
    "__version__",
    "Filter",
    "Rls",
    "build_info",
    "consistency",
    "error_series",
    "filters",
    "fit_ellipsoid_calibration",
    "heading_offset",
    "lstsq",
    "read_csv",
    "read_estimates",
    "rls_forms",
    "rmse",
    "run_many",
    "scenario_names",
    "simulate",
    "smooth",
    "stress",
    "stress_scenarios",
    "write_estimates",
    "write_recording",
    "FLAG_DT",
    "FLAG_GYR",
    "FLAG_ACC",
    "FLAG_MAG",
    "FLAG_GATED",
    "FLAG_REST",
    "FLAG_MAG_DISTURBED",
]
