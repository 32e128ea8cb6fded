//! Whole recordings in `f64`: what the CSV reader and the simulator produce and the metrics
//! and the CLI consume.

use crate::quat::Quat;
use crate::sample::ImuSample;
use crate::vec3::Vec3;
use std::string::String;
use std::vec::Vec;

/// A recording of one IMU, column-wise, in `f64`, in the conventions of this crate.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recording {
    /// A name for reports (file stem or scenario name).
    pub name: String,
    /// Sample times, s, strictly increasing.
    pub t: Vec<f64>,
    /// Angular rate, rad/s, sensor frame.
    pub gyr: Vec<Vec3<f64>>,
    /// Specific force, m/s², sensor frame.
    pub acc: Vec<Vec3<f64>>,
    /// Magnetic field, sensor frame; `None` for a 6D recording.
    pub mag: Option<Vec<Vec3<f64>>>,
    /// Ground-truth orientation (sensor to earth, ENU); NaN where unknown.
    pub truth: Option<Vec<Quat<f64>>>,
    /// Which samples count for error evaluation (BROAD's `use` column); all when `None`.
    pub use_mask: Option<Vec<bool>>,
}

impl Recording {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }
    /// True when there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }
    /// Sample `i` (NaN magnetometer for a 6D recording).
    pub fn sample(&self, i: usize) -> ImuSample<f64> {
        match &self.mag {
            Some(mag) => ImuSample::new(self.gyr[i], self.acc[i], mag[i]),
            None => ImuSample::six_d(self.gyr[i], self.acc[i]),
        }
    }
    /// Time step before sample `i`, s (the first sample uses the second interval).
    pub fn dt(&self, i: usize) -> f64 {
        match i {
            _ if self.t.len() < 2 => 0.0,
            0 => self.t[1] - self.t[0],
            _ => self.t[i] - self.t[i - 1],
        }
    }
}
