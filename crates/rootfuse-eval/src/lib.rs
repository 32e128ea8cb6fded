//! Evaluation of orientation estimates: the BROAD error metrics ([`metrics`]), the frame
//! alignment of motion-capture references ([`alignment`]), a seeded IMU simulator with named
//! scenarios ([`sim`]) and offline spectra ([`spectrum`]).
//!
//! Depends on `rootfuse-attitude` (quaternions and [`Recording`](rootfuse_attitude::Recording)),
//! `rootfuse-lsq` and `nalgebra` (the alignment's least squares and its closed-form start),
//! `rand`/`rand_chacha`/`rand_distr` (the simulator's seeded noise) and `realfft` (spectra).
//! Everything here is `std` and `f64`: it measures filters, it is not part of one.

#![warn(missing_docs)]

pub mod alignment;
pub mod consistency;
pub mod metrics;
pub mod sim;
mod spectrum;

pub use spectrum::spectrum;
