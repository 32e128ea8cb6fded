//! Sensor calibration from recordings, on the least-squares toolkit.
//!
//! The model is [`SensorCalibration`] of `rootfuse-attitude`: `y_cal = S·(y_raw − h)` with
//! `S` symmetric positive definite and the offset `h` in raw units (written once there; read
//! its documentation before anything else). This crate estimates it in batch:
//!
//! - [`fit_ellipsoid`]: magnetometer hard and soft iron from readings over many orientations
//!   (algebraic ellipsoid fit, observability ladder, geometric refinement), with the quality
//!   figures of [`FitQuality`] and, when the motion does not determine the full `S`, an
//!   honest fallback ([`FittedModel`]) that says which parameters were left out and why
//!   ([`RefusedModel`]);
//! - [`gyro_bias`] and [`accelerometer`]: gyroscope bias and accelerometer offset and scale
//!   from rest phases (the six-position method), found by [`rest_phases`].
//!
//! The online counterpart (hard iron learned while a filter runs) is in
//! `rootfuse_attitude::calibration`, because it runs in `no_std` lanes.
//!
//! ```
//! use rootfuse_attitude::Vec3;
//! use rootfuse_calibration::{fit_ellipsoid, FitOptions, FittedModel};
//!
//! // Readings of a 50 µT field over 800 directions spread evenly (a Fibonacci spiral),
//! // through hard iron (3, −2, 5) µT and a soft-iron stretch of the x axis by 10 %.
//! let raw: Vec<Vec3<f64>> = (0..800)
//!     .map(|k| {
//!         let z = 1.0 - 2.0 * (k as f64 + 0.5) / 800.0;
//!         let (r, phi) = ((1.0 - z * z).sqrt(), 2.399963 * k as f64);
//!         Vec3::new(55.0 * r * phi.cos() + 3.0, 50.0 * r * phi.sin() - 2.0, 50.0 * z + 5.0)
//!     })
//!     .collect();
//! let fit = fit_ellipsoid(&raw, &FitOptions { norm: Some(50.0), ..FitOptions::default() })?;
//! assert_eq!(fit.model, FittedModel::Full);
//! assert!((fit.calibration.offset - Vec3::new(3.0, -2.0, 5.0)).norm() < 1e-9);
//! assert!((fit.calibration.matrix.m[0][0] - 50.0 / 55.0).abs() < 1e-12);
//! assert!(fit.quality.residual_rms_relative < 1e-12 && fit.quality.coverage == 1.0);
//! # Ok::<(), rootfuse_calibration::CalibrationError>(())
//! ```

mod ellipsoid;
mod error;
mod inertial;
mod mat3;
mod quality;

pub use ellipsoid::{
    EllipsoidFit, FitOptions, GROSS_OUTLIER_FACTOR, MAX_OUTLIER_FRACTION, MIN_OUTLIER_RESIDUAL,
    MIN_RELATIVE_SPREAD, RESIDUAL_OUTLIER_SIGMAS, SATURATION_MIN_COUNT, fit_ellipsoid,
};
pub use error::CalibrationError;
pub use inertial::{
    AccelerometerFit, GyroBiasFit, RestOptions, RestPhase, RestSearch, accelerometer, gyro_bias,
    rest_phases, rest_search,
};
pub use quality::{DIRECTION_CELLS, FitQuality};
pub use rootfuse_attitude::SensorCalibration;

/// Which parameters of `y_cal = S·(y_raw − h)` a batch fit determined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FittedModel {
    /// `h` and the full symmetric `S` (9 parameters).
    Full,
    /// `h` and a diagonal `S` (per-axis scale; 6 parameters): the cross terms were not
    /// determined.
    DiagonalScale,
    /// `h` only, `S` a multiple of the identity (4 parameters).
    OffsetOnly,
    /// The motion stayed in one plane (a turn about one axis): only the offset's two
    /// components within that plane are determined; the component along the plane's normal
    /// is left at 0 (no correction) and `S = I`.
    InPlaneOffset,
}

impl FittedModel {
    /// Short name (`full`, `diagonal-scale`, `offset-only`, `in-plane-offset`).
    pub fn name(self) -> &'static str {
        match self {
            FittedModel::Full => "full",
            FittedModel::DiagonalScale => "diagonal-scale",
            FittedModel::OffsetOnly => "offset-only",
            FittedModel::InPlaneOffset => "in-plane-offset",
        }
    }
}

impl core::fmt::Display for FittedModel {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.name())
    }
}

/// A richer model the data did not determine: its design's condition number exceeded
/// [`FitOptions::max_condition`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefusedModel {
    /// The model.
    pub model: FittedModel,
    /// Its condition number (`σ_max/σ_min` of the normalised design; infinite if singular).
    pub condition: f64,
}
