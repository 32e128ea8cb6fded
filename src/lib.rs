//! rootfuse: numerically robust estimation in Rust.
//!
//! This facade re-exports the workspace crates:
//! - [`lane`]: the [`Lane`] trait (one scalar abstraction over `f32`, `f64` and SIMD vectors)
//!   and small fixed-size matrix kernels;
//! - [`attitude`]: quaternions ([`Quat`]), vectors ([`Vec3`]) and, as they land, orientation
//!   filters.
//!
//! ```
//! use rootfuse::{Quat, Vec3};
//! // Integrate 1 rad/s about z for 1 s in 100 steps: a 1 rad heading change.
//! let w = Vec3::new(0.0, 0.0, 1.0f64);
//! let mut q = Quat::identity();
//! for _ in 0..100 {
//!     q = (q * Quat::from_rotation_vector(w * 0.01)).normalize();
//! }
//! let (yaw, _pitch, _roll) = q.to_euler_zyx();
//! assert!((yaw - 1.0).abs() < 1e-12);
//! ```
pub use rootfuse_attitude as attitude;
pub use rootfuse_attitude::{Quat, Vec3};
pub use rootfuse_batch as batch;
pub use rootfuse_beacon as beacon;
pub use rootfuse_calibration as calibration;
pub use rootfuse_eval as eval;
pub use rootfuse_io as io;
pub use rootfuse_lane as lane;
pub use rootfuse_lane::{Lane, Mask, Mat};
pub use rootfuse_lsq as lsq;
