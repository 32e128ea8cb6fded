//! Magnetometer pre-processing for any 9D filter: one wrapper, no copy per filter.

use super::online::{OnlineHardIron, OnlineHardIronParams};
use crate::blocks::magnetic_heading_error;
use crate::filters::{OrientationFilter, Rejections, SampleFlags, StateError};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat};
use rootfuse_lsq::rls::RlsError;

/// Any orientation filter `F` whose magnetometer readings are first corrected by an
/// [`OnlineHardIron`] estimator (learned and gated as documented there); everything else is
/// the inner filter's.
///
/// When a lane's correction is applied for the first time, the inner filter's heading in that
/// lane is re-aligned to the corrected field ([`OrientationFilter::set_heading`] with the
/// tilt-compensated heading of the corrected reading): the heading it had was built from the
/// uncorrected field, and a filter that trusts its gyroscope would otherwise take minutes to
/// walk it over; and the inner filter forgets the field reference it learned from the
/// uncorrected readings ([`OrientationFilter::forget_field_reference`]).
#[derive(Clone, Debug)]
pub struct MagCalibrated<T: Lane, F> {
    inner: F,
    calibration: OnlineHardIron<T>,
    was_active: T::Mask,
}

impl<T: Lane, F: OrientationFilter<T>> MagCalibrated<T, F> {
    /// Wraps `inner`. Fails only for invalid `params` (see [`OnlineHardIron::new`]).
    pub fn new(inner: F, params: OnlineHardIronParams) -> Result<Self, RlsError> {
        Ok(Self {
            inner,
            calibration: OnlineHardIron::new(params)?,
            was_active: T::Mask::splat(false),
        })
    }
    /// The wrapped filter.
    pub fn inner(&self) -> &F {
        &self.inner
    }
    /// The online calibration.
    pub fn calibration(&self) -> &OnlineHardIron<T> {
        &self.calibration
    }
}

impl<T: Lane, F: OrientationFilter<T>> OrientationFilter<T> for MagCalibrated<T, F> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let mag = self.calibration.update(sample.mag);
        let active = self.calibration.active();
        let fresh = active & !self.was_active;
        self.was_active = active;
        // Uniform across lanes: lanes that did not just switch keep their heading exactly.
        if fresh.any() {
            let q = self.inner.quat();
            let (err, ok) = magnetic_heading_error(q, mag);
            let (current, _) = q.heading_inclination();
            // Refused only for a non-finite heading, which `ok` and a finite `q` exclude;
            // then every lane keeps its heading, as the lanes that did not switch do.
            let _ = self
                .inner
                .set_heading(T::select(fresh & ok, current + err, current));
            // The corrected readings are a new field only to the filter: not a disturbance.
            self.inner.forget_field_reference(fresh);
        }
        self.inner.update(&ImuSample { mag, ..*sample }, dt);
    }
    fn quat(&self) -> Quat<T> {
        self.inner.quat()
    }
    fn bias(&self) -> Vec3<T> {
        self.inner.bias()
    }
    fn gyro_scale(&self) -> Vec3<T> {
        self.inner.gyro_scale()
    }
    fn smoothing_gyro_tau(&self) -> f64 {
        self.inner.smoothing_gyro_tau()
    }
    fn rejections(&self) -> &Rejections<T> {
        self.inner.rejections()
    }
    fn attitude_covariance(&self) -> Option<Mat<T, 3, 3>> {
        self.inner.attitude_covariance()
    }
    fn rest_detected(&self) -> Option<T::Mask> {
        self.inner.rest_detected()
    }
    fn magnetic_disturbance(&self) -> Option<T::Mask> {
        self.inner.magnetic_disturbance()
    }
    fn flags(&self) -> SampleFlags<T> {
        self.inner.flags()
    }
    /// The inner filter and the calibration both start over.
    fn reset(&mut self) {
        self.inner.reset();
        self.calibration.reset();
        self.was_active = T::Mask::splat(false);
    }
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
        self.inner.set_quat(q, sigma)
    }
    fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
        self.inner.set_bias(bias, sigma)
    }
    fn set_heading(&mut self, heading: T) -> Result<(), StateError> {
        self.inner.set_heading(heading)
    }
    fn forget_field_reference(&mut self, lanes: T::Mask) {
        self.inner.forget_field_reference(lanes);
    }
}
