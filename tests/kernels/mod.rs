//! The `Lane` trait and the small matrix kernels.
mod lane;
mod mat;
