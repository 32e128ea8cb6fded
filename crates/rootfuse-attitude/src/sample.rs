//! IMU samples and recordings.

use crate::vec3::Vec3;
use rootfuse_lane::Lane;

/// One synchronous IMU sample in the sensor frame.
///
/// Units: gyroscope rad/s, accelerometer m/s² (specific force: `+g` along sensor-up at rest),
/// magnetometer µT (filters use its direction, some its norm relative to a learned reference;
/// the screening limit `max_mag`, 1000 by default, is in µT, so a field in nT needs it set). A 6D sample has no magnetometer: put NaN in `mag` (a 9D filter
/// then skips its magnetometer correction for that sample and counts it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImuSample<T> {
    /// Angular rate, rad/s, sensor frame.
    pub gyr: Vec3<T>,
    /// Specific force, m/s², sensor frame.
    pub acc: Vec3<T>,
    /// Magnetic field, sensor frame (NaN when absent).
    pub mag: Vec3<T>,
}

impl<T: Lane> ImuSample<T> {
    /// A sample from gyroscope, accelerometer and magnetometer readings.
    #[inline]
    pub fn new(gyr: Vec3<T>, acc: Vec3<T>, mag: Vec3<T>) -> Self {
        Self { gyr, acc, mag }
    }
    /// A 6D sample (no magnetometer: `mag` is NaN).
    #[inline]
    pub fn six_d(gyr: Vec3<T>, acc: Vec3<T>) -> Self {
        let nan = T::from_f64(f64::NAN);
        Self {
            gyr,
            acc,
            mag: Vec3::new(nan, nan, nan),
        }
    }
}
