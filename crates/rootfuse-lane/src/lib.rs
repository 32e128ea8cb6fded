//! One scalar abstraction over `f32`, `f64` and the `wide` SIMD vectors.
//!
//! Every estimator in rootfuse is written once against the [`Lane`] trait. A scalar build
//! (`f32`, `f64`) runs one channel; a SIMD build ([`wide::f32x8`], [`wide::f64x4`], …) runs
//! one channel per lane with the *same* code, and — because every operation here is
//! deterministic IEEE arithmetic or shares one implementation across widths — each lane's
//! result equals the scalar result bit for bit (NaN payloads aside).
//!
//! Branches in lane-generic code become "compute both sides, [`Lane::select`] by mask".
//! Write guards so that NaN lands on the reject side:
//!
//! ```
//! use rootfuse_lane::{Lane, Mask};
//! use wide::f32x4;
//!
//! let n2 = f32x4::new([4.0, 0.0, f32::NAN, f32::INFINITY]);
//! // accept = n2 > eps && finite; never `!(n2 <= eps)`, which accepts NaN.
//! let accept = n2.simd_gt(f32x4::splat(1e-12)) & n2.is_finite();
//! let inv = Lane::select(accept, f32x4::ONE / n2.sqrt(), f32x4::ZERO);
//! assert_eq!(inv.to_array(), [0.5, 0.0, 0.0, 0.0]);
//! assert_eq!(accept.bitmask(), 0b0001);
//! ```
//!
//! Small const-generic matrices with the kernels a 7-state EKF and a square-root filter need
//! live in [`mat`].
#![no_std]
#![warn(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

mod impls;
mod lane;
pub mod mat;
mod x2;

pub use lane::{Counts, Lane, Mask, Select};
pub use mat::{Mat, Vector};
pub use wide;
pub use x2::X2;
