//! The sensor calibration model, written once: `y_cal = S·(y_raw − h)`.
//!
//! - `y_raw`: the sensor's reading (sensor frame, its own unit);
//! - `h`: the **offset**, in raw units — the magnetometer's hard iron, the accelerometer's
//!   zero-g offset, the gyroscope's bias. It is subtracted *before* `S` is applied;
//! - `S`: the **correction matrix**, symmetric positive definite — the inverse of the
//!   magnetometer's soft-iron distortion (scaled, see below), the inverse of the
//!   accelerometer's scale-factor and cross-axis errors, the identity for a gyroscope bias;
//! - `y_cal`: the calibrated reading, sensor frame.
//!
//! The other order, `S·y_raw − h`, is a different model (its offset is in calibrated units);
//! mixing the two is the classic calibration mistake, so the library only ever stores and
//! applies this one.
//!
//! For a magnetometer the calibrated field has a constant norm, the **field norm** `F`
//! ([`SensorCalibration::norm`]): `|S·(m_raw − h)| = F` for every orientation of an
//! undisturbed sensor. Magnetometer data alone fix `S` only up to a scalar; a batch fit
//! either scales `S` to a known field norm or to `det S = 1` (the correction preserves
//! volume) and reports the resulting `F`. For an accelerometer the norm is gravity.

use crate::vec3::Vec3;
use rootfuse_lane::{Lane, Mat};

/// The affine calibration `y_cal = S·(y_raw − h)` of a three-axis sensor (see the
/// [module documentation](self) for the model and its conventions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorCalibration<T: Lane> {
    /// `S`, symmetric positive definite (dimensionless for a pure correction; calibrated unit
    /// per raw unit).
    pub matrix: Mat<T, 3, 3>,
    /// `h`, the offset in raw units (hard iron, zero-g offset, gyro bias).
    pub offset: Vec3<T>,
    /// The norm `|y_cal|` of an undisturbed reading (field norm, gravity), calibrated units;
    /// NaN when the sensor has none (a gyroscope).
    pub norm: T,
}

impl<T: Lane> SensorCalibration<T> {
    /// The identity calibration (`S = I`, `h = 0`) with the given norm.
    pub fn identity(norm: T) -> Self {
        Self {
            matrix: Mat::identity(),
            offset: Vec3::zero(),
            norm,
        }
    }

    /// An offset-only calibration (`S = I`): hard iron, gyro bias.
    pub fn offset_only(offset: Vec3<T>, norm: T) -> Self {
        Self {
            matrix: Mat::identity(),
            offset,
            norm,
        }
    }

    /// `S·(raw − h)`.
    #[inline]
    pub fn apply(&self, raw: Vec3<T>) -> Vec3<T> {
        let d = raw - self.offset;
        let s = &self.matrix;
        Vec3::new(
            s.m[0][0] * d.x + s.m[0][1] * d.y + s.m[0][2] * d.z,
            s.m[1][0] * d.x + s.m[1][1] * d.y + s.m[1][2] * d.z,
            s.m[2][0] * d.x + s.m[2][1] * d.y + s.m[2][2] * d.z,
        )
    }

    /// Every entry finite (the norm may be NaN: a gyroscope has none), per lane.
    pub fn is_finite(&self) -> T::Mask {
        self.matrix.is_finite() & self.offset.is_finite()
    }
}

pub mod online;
mod wrapper;

pub use online::{OnlineHardIron, OnlineHardIronParams};
pub use wrapper::MagCalibrated;
