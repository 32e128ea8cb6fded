//! Gyro-only integration [`gyro`].

use super::LaneParams;
use super::{OrientationFilter, Rejections, ScreenBounds, Screened, initialise, params};
use super::{StateError, quat_without_covariance};
use crate::{ImuSample, Quat, blocks::integrate_gyro};
use rootfuse_lane::{Lane, Mask};

params! {
    /// Parameters of [`GyroIntegration`].
    pub struct GyroParams {
        /// 1: take the initial inclination from the first usable accelerometer sample (heading
        /// 0); 0: start at the identity.
        init_from_acc: bool = 1.0, "1", [0.0, 1.0];
    }
}

/// Integrates the gyroscope by the exact exponential map, nothing else: the drift reference.
#[derive(Clone, Debug)]
pub struct GyroIntegration<T: Lane> {
    q: Quat<T>,
    initialized: T::Mask,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    params: GyroParams,
}

impl<T: Lane> GyroIntegration<T> {
    crate::filters::uniform_constructors!(GyroParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(params: &LaneParams<'_, GyroParams, T>) -> Self {
        Self {
            q: Quat::identity(),
            initialized: <T::Mask as Mask>::splat(!params.first().init_from_acc),
            bounds: params.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            params: params.first().clone(),
        }
    }
}

impl<T: Lane> OrientationFilter<T> for GyroIntegration<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::new(sample, dt, &self.bounds, &mut self.rejections);
        let q = initialise(self.q, &mut self.initialized, &s, false);
        self.q = Quat::select(s.step, integrate_gyro(q, s.gyr, s.dt), self.q);
    }
    fn reset(&mut self) {
        self.q = Quat::identity();
        self.initialized = <T::Mask as Mask>::splat(!self.params.init_from_acc);
        self.rejections = Rejections::default();
    }
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
        self.q = quat_without_covariance(q, sigma)?;
        self.initialized = <T::Mask as Mask>::splat(true);
        Ok(())
    }
    fn quat(&self) -> Quat<T> {
        self.q
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
}
