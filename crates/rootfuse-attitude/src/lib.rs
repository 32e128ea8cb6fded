//! Quaternions, conventions, building blocks and orientation filters over [`Lane`]: the
//! numeric core that an embedded user links.
//!
//! Depends on `rootfuse-lane` (the [`Lane`] trait, small matrices), `rootfuse-lsq` (the
//! recursive least-squares forms behind `lsq-fusion`, `no_std`) and `libm`. Without default
//! features it is `no_std` and allocation-free: quaternions, vectors, frames, building blocks,
//! pre-processing and every filter. The `std` feature adds the filter registry (names and
//! `key=value` parameters), [`Recording`] (a whole recording in memory) and the offline
//! forward–backward smoother ([`smooth`]); `nalgebra` adds conversions to and from nalgebra's
//! types. Files live in `rootfuse-io`, metrics and the simulator in `rootfuse-eval`.
//!
//! # Conventions (the whole project; see `docs/conventions.md` in the repository)
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

pub mod blocks;
pub mod calibration;
pub mod filters;
pub mod frames;
#[cfg(feature = "nalgebra")]
mod interop;
pub mod preprocess;
pub mod quat;
#[cfg(feature = "std")]
pub mod recording;
#[cfg(feature = "std")]
pub mod registry;
pub mod sample;
#[cfg(feature = "std")]
pub mod smooth;
#[cfg(feature = "std")]
pub mod units;
pub mod vec3;

pub use calibration::SensorCalibration;
pub use filters::{Dof, OrientationFilter};
pub use quat::Quat;
#[cfg(feature = "std")]
pub use recording::Recording;
pub use rootfuse_lane::{Lane, Mask, Mat};
pub use sample::ImuSample;
pub use vec3::Vec3;
