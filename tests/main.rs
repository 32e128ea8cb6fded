//! The one integration-test binary of the workspace (docs/architecture.md: one binary links once).
// Lane-by-lane loops index several arrays with the same lane number; that reads best as `i`.
#![allow(clippy::needless_range_loop)]
mod batch;
mod batch_lsq;
mod broad;
mod common;
mod data_io;
mod filters;
mod flagship;
mod frames;
mod fuzz_corpus;
mod lane;
mod mat;
mod preprocess;
mod quat;
mod rls;
mod seed_000;
mod seed_001_004;
mod seed_003;
mod sim;
