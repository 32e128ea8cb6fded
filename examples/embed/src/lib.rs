//! The flagship filter in a `no_std`, allocation-free crate: what firmware links. One call
//! per IMU sample; the orientation, gyro bias and attitude uncertainty read back as plain
//! arrays for a larger estimator.
#![no_std]

use rootfuse_attitude::prelude::*;

/// One IMU channel: the flagship filter in `f32`.
pub struct Attitude {
    filter: SqrtEskf<f32>,
}

impl Attitude {
    /// A 9D filter with the default parameters (the defaults are valid, so `try_new` cannot
    /// fail here; custom parameters go through it and come back as an error).
    pub fn new() -> Self {
        match SqrtEskf::try_new(&SqrtEskfParams::default()) {
            Ok(filter) => Self { filter },
            Err(_) => unreachable!("the default parameters are valid"),
        }
    }

    /// One sample: gyroscope rad/s, accelerometer m/s², magnetometer µT (sensor frame),
    /// `dt` seconds since the previous sample.
    pub fn update(&mut self, gyr: [f32; 3], acc: [f32; 3], mag: [f32; 3], dt: f32) {
        let v = |a: [f32; 3]| Vec3::new(a[0], a[1], a[2]);
        self.filter
            .update(&ImuSample::new(v(gyr), v(acc), v(mag)), dt);
    }

    /// Orientation, sensor to earth (ENU), `[w, x, y, z]`.
    pub fn quat(&self) -> [f32; 4] {
        self.filter.quat().to_array()
    }

    /// Gyroscope-bias estimate, rad/s.
    pub fn bias(&self) -> [f32; 3] {
        self.filter.bias().to_array()
    }

    /// Standard deviation of the attitude error per earth axis (east, north, up), rad.
    pub fn attitude_std(&self) -> [f32; 3] {
        match self.filter.attitude_covariance() {
            Some(p) => [p.m[0][0], p.m[1][1], p.m[2][2]].map(Lane::sqrt),
            None => unreachable!("the flagship carries an attitude covariance"),
        }
    }

    /// Starts from a known orientation (`[w, x, y, z]`, sensor to earth) known to within
    /// `sigma` rad per axis, e.g. from a docking station; refused (nothing changed) for a
    /// non-finite or non-unit quaternion or a `sigma` outside [0, π].
    pub fn set_orientation(&mut self, q: [f32; 4], sigma: f32) -> Result<(), StateError> {
        self.filter
            .set_quat(Quat::new(q[0], q[1], q[2], q[3]), Some(sigma))
    }

    /// Back to a new filter's state, e.g. after the sensor was re-mounted.
    pub fn reset(&mut self) {
        self.filter.reset();
    }
}

impl Default for Attitude {
    fn default() -> Self {
        Self::new()
    }
}
