//! The one integration-test binary of the workspace (docs/architecture.md: one binary links
//! once), grouped by subject.
// Lane-by-lane loops index several arrays with the same lane number; that reads best as `i`.
#![allow(clippy::needless_range_loop)]
mod attitude;
mod batch;
mod calibration;
mod common;
mod eval;
mod fuzz_corpus;
mod io;
mod kernels;
mod lsq;
