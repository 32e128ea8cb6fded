//! Quaternions, conventions, building blocks and orientation filters over [`Lane`]: the
//! numeric core that an embedded user links.
//!
//! # Using rootfuse-attitude
//!
//! ```toml
//! [dependencies]
//! # no_std and allocation-free without default features (every filter, no registry):
//! rootfuse-attitude = { version = "0.1", default-features = false }
//! ```
//!
//! The flagship filter ([`SqrtEskf`], registry name `flagship`): one sample at a time, gyroscope
//! in rad/s, accelerometer in m/s² (its corrections use the direction, its rest and spike
//! thresholds m/s²), magnetometer in µT (its direction; the screening limit `max_mag` is in
//! µT), all in the sensor frame; `dt` in seconds since the previous sample.
//!
//! ```
//! use rootfuse_attitude::prelude::*;
//!
//! let mut filter = SqrtEskf::<f32>::try_new(&SqrtEskfParams::default()).expect("valid defaults");
//! for _ in 0..500 {
//!     // At rest, level, facing north: gravity up, the field north and down.
//!     let sample = ImuSample::new(
//!         Vec3::new(0.0, 0.0, 0.0),      // gyroscope, rad/s
//!         Vec3::new(0.0, 0.0, 9.81),     // accelerometer, m/s²
//!         Vec3::new(0.0, 20.0, -45.0),   // magnetometer, µT
//!     );
//!     filter.update(&sample, 0.01);
//! }
//! let q: Quat<f32> = filter.quat(); // sensor to earth (ENU), [w, x, y, z]
//! let bias: Vec3<f32> = filter.bias(); // gyroscope bias, rad/s
//! // rad², earth axes: [2][2] is the heading variance (`None` for filters without one)
//! let p = filter.attitude_covariance().expect("the flagship carries one");
//! assert!(q.angle_to(Quat::identity()) < 0.01);
//! assert!(bias.norm() < 1e-3 && p.m[0][0] > 0.0);
//! ```
//!
//! State control, the same on every filter ([`OrientationFilter`]): `reset()` starts over
//! with the same parameters (`params()` returns them), `set_quat(q, sigma)` and
//! `set_bias(b, sigma)` set the state with its uncertainty (`None` keeps the covariance), and
//! refuse NaN or absurd values with a [`StateError`], changing nothing:
//!
//! ```
//! use rootfuse_attitude::prelude::*;
//!
//! let mut filter = SqrtEskf::<f64>::try_new(&SqrtEskfParams::default()).expect("valid defaults");
//! // A known start: heading 0.5 rad, level, to within 0.02 rad per axis.
//! filter.set_quat(Quat::from_euler_zyx(0.5, 0.0, 0.0), Some(0.02))?;
//! let p = filter.attitude_covariance().expect("the flagship carries one");
//! assert!((p.m[2][2] - 0.02 * 0.02).abs() < 1e-12);
//! // A bias measured beforehand, rad/s, to within 1 mrad/s.
//! filter.set_bias(Vec3::new(0.01, -0.002, 0.0), Some(1e-3))?;
//! assert!(filter.set_bias(Vec3::new(f64::NAN, 0.0, 0.0), None).is_err());
//! assert_eq!(filter.params().tau_acc, SqrtEskfParams::default().tau_acc);
//! filter.reset(); // as new: identity, zero bias, the initial covariance
//! assert_eq!(filter.bias(), Vec3::zero());
//! # Ok::<(), StateError>(())
//! ```
//!
//! `SqrtEskf::<wide::f32x8>` runs eight independent channels in one register with the same
//! bits per lane; `rootfuse-batch` feeds thousands of channels that way. 6D data (no
//! magnetometer): [`ImuSample::six_d`] and `SqrtEskfParams { dof: Dof::Six, ..Default::default() }`.
//! The other filters are in [`filters`], each with its parameters struct; the [`prelude`]
//! imports the flagship, the trait and the types.
//!
//! Depends on `rootfuse-lane` (the [`Lane`] trait, small matrices), `rootfuse-lsq` (the
//! recursive least-squares forms behind `lsq-fusion`, `no_std`) and `libm`. Without default
//! features it is `no_std` and allocation-free: quaternions, vectors, frames, building blocks,
//! pre-processing and every filter. The `std` feature adds the filter registry (names and
//! `key=value` parameters), `Recording` (a whole recording in memory) and the offline
//! forward–backward smoother (module `smooth`); `nalgebra` adds conversions to and from nalgebra's
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

/// The flagship, the filter trait and the types a filter loop needs:
/// `use rootfuse_attitude::prelude::*;`.
pub mod prelude {
    pub use crate::filters::{
        Dof, Madgwick, MadgwickParams, Mahony, MahonyParams, OrientationFilter, SqrtEskf,
        SqrtEskfParams, StateError,
    };
    pub use crate::{ImuSample, Quat, Vec3};
    pub use rootfuse_lane::Lane;
}

pub use calibration::SensorCalibration;
pub use filters::{Dof, OrientationFilter, StateError};
pub use filters::{SqrtEskf, SqrtEskfParams};
pub use quat::Quat;
#[cfg(feature = "std")]
pub use recording::Recording;
pub use rootfuse_lane::{Lane, Mask, Mat};
pub use sample::ImuSample;
pub use vec3::Vec3;

/// The README's Rust blocks, compiled and run as doctests.
#[cfg(doctest)]
#[doc = include_str!("../../../README.md")]
pub struct ReadmeDoctests;
