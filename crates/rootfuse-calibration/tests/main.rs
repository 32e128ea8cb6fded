//! The calibration crate's integration tests (one binary): the batch ellipsoid fit against the
//! simulator's known hard and soft iron and on the BROAD recordings, rest phases, the
//! gyroscope bias and the six-position accelerometer calibration. The online hard-iron
//! estimator (in `rootfuse-attitude`) is tested at the workspace root
//! (`tests/calibration/online.rs`).
// Axis-by-axis loops index several arrays with the same axis number; that reads best as `k`.
#![allow(clippy::needless_range_loop)]
// The workspace's shared test helpers (the BROAD folder).
mod batch;
#[path = "../../../tests/common.rs"]
mod common;
mod inertial;
