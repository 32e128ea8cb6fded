//! Evaluation of orientation estimates: the BROAD error metrics ([`metrics`]), a seeded IMU
//! simulator with named scenarios ([`sim`]) and offline spectra ([`spectrum`]).
//!
//! Depends on `rootfuse-attitude` (quaternions and [`Recording`](rootfuse_attitude::Recording)),
//! `rand`/`rand_chacha`/`rand_distr` (the simulator's seeded noise) and `realfft` (spectra).
//! Everything here is `std` and `f64`: it measures filters, it is not part of one.

#![warn(missing_docs)]

pub mod metrics;
pub mod sim;
mod spectrum;

pub use spectrum::spectrum;
