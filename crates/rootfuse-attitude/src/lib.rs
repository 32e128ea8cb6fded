//! Quaternions, conventions, building blocks and orientation filters over [`Lane`].
//!
//! # Conventions (the whole project; see `METHODS.md`)
//! - A quaternion is `q = [w, x, y, z]`, scalar first, Hamilton product (`i·j = k`), unit norm.
//! - `q` rotates **sensor to earth**: `v_earth = q ⊗ v_sensor ⊗ q*`
//!   ([`Quat::rotate`]); [`Quat::rotate_inverse`] goes earth to sensor.
//! - Gyro integration is `q_{k+1} = q_k ⊗ exp(ω·dt/2)` (body rates in rad/s, right-multiplied).
//! - The earth frame is ENU (x east, y north, z up) unless a type says otherwise; an
//!   accelerometer at rest reads `+g` along earth-up.
//! - Euler angles are ZYX (yaw ψ about z, then pitch θ about the new y, then roll φ about the
//!   newest x): `q = qz(ψ) ⊗ qy(θ) ⊗ qx(φ)`, in radians.
//!
//! Everything is generic over `T: Lane`: `Quat<f32>` is one orientation, `Quat<wide::f32x8>`
//! is eight, computed by the same code with the same bits per lane.
//!
//! [`Lane`]: rootfuse_lane::Lane
#![no_std]
#![warn(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

#[cfg(feature = "std")]
pub mod alignment;
#[cfg(feature = "std")]
pub mod beacon;
pub mod blocks;
pub mod filters;
pub mod frames;
mod interop;
#[cfg(feature = "std")]
pub mod io;
#[cfg(feature = "std")]
pub mod metrics;
pub mod preprocess;
pub mod quat;
#[cfg(feature = "std")]
pub mod recording;
#[cfg(feature = "std")]
pub mod registry;
pub mod sample;
#[cfg(feature = "std")]
pub mod sim;
#[cfg(feature = "std")]
pub mod smooth;
pub mod vec3;

pub use filters::OrientationFilter;
pub use quat::Quat;
#[cfg(feature = "std")]
pub use recording::Recording;
pub use rootfuse_lane::{Lane, Mask, Mat};
pub use sample::ImuSample;
pub use vec3::Vec3;
