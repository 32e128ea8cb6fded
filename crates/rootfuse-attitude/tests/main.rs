//! The attitude crate's integration tests (one binary): quaternions, frames, pre-processing,
//! the filters and their configuration, against closed forms, independent implementations
//! (nalgebra), simulated motion and the BROAD recordings. Filters run through the batch
//! engine are tested at the workspace root (`tests/attitude/bad_samples.rs`), the heading
//! pipeline with beacons in `rootfuse-beacon`.
// Lane-by-lane loops index several arrays with the same lane number; that reads best as `i`.
#![allow(clippy::needless_range_loop)]
// The workspace's shared test helpers (special floats, bit equality, the BROAD folder).
#[path = "../../../tests/common.rs"]
mod common;
mod configuration;
mod filters;
mod flagship;
mod flagship_accuracy;
mod frames;
mod lsq_fusion;
mod preprocess;
mod quat;
mod reconstruction_and_ecf_ekf;
mod units;
