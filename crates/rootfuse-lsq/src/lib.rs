//! Least squares and recursive least squares over [`Lane`](rootfuse_lane::Lane).
//!
//! Depends on `rootfuse-lane` (lanes and small matrices) and, with `std`, on `faer` (the dense
//! solvers). The recursive forms are `no_std` and allocation-free.
//!
//! - [`rls`]: the recursive forms (const-generic size, generic over `T: Lane`, no allocation
//!   per update), all solving the same exponentially weighted problem.
//! - `dense` (with `std`): dense weighted least squares on `faer` (QR, pivoted QR/SVD, normal
//!   equations as a comparison method).
//! - `stress` (feature `stress`): numerical stress scenarios for the recursive forms, against
//!   a double-double reference (a measuring harness, off by default).
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]

#[cfg(feature = "std")]
pub mod dense;
pub mod rls;
#[cfg(feature = "stress")]
pub mod stress;
