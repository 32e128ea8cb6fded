//! Orientation filters, all generic over [`Lane`].
//!
//! Every filter is a plain struct of parameters and state with
//! [`OrientationFilter::update`]; nothing is allocated per update. Input screening is shared
//! ([`Screened`]): a sample whose gyroscope or `dt` is unusable is skipped entirely for that
//! lane, an unusable accelerometer or magnetometer only skips that correction; each skip is
//! counted per reason in [`Rejections`].

mod complementary;
mod complementary_reconstruction;
mod ecf_ekf;
mod ekf;
mod gyro;
mod heading_pipeline;
mod lsq_fusion;
mod madgwick;
mod mahony;
mod params;
mod screen;
mod sqrt_eskf;
mod upper_factor;

/// Declares a struct of per-lane filter state with its [`Select`](rootfuse_lane::Select)
/// implementation generated field by field: a skipped sample keeps a lane's state with one
/// `select`, and a field added later cannot be left out of it.
macro_rules! lane_state {
    (
        $(#[$meta:meta])*
        struct $name:ident<T: Lane> {
            $( $(#[$fmeta:meta])* $field:ident: $ty:ty, )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug)]
        struct $name<T: Lane> {
            $( $(#[$fmeta])* $field: $ty, )*
        }
        impl<T: Lane> rootfuse_lane::Select<T::Mask> for $name<T> {
            #[inline]
            fn select(mask: T::Mask, a: &Self, b: &Self) -> Self {
                Self { $( $field: rootfuse_lane::Select::select(mask, &a.$field, &b.$field), )* }
            }
        }
    };
}
pub(crate) use lane_state;

/// A filter's `try_new` (validated) and `new` (one parameter set in every lane) over its
/// `with_lane_params`: the constructor pair every filter has, written once.
macro_rules! uniform_constructors {
    ($params:ident) => {
        #[doc = concat!("A filter with the given parameters once they pass [`validate`](", stringify!($params), "::validate): an invalid set (a struct literal with a value out of range, or NaN) is refused instead of run.")]
        pub fn try_new(p: &$params) -> Result<Self, crate::filters::InvalidParam> {
            p.validate()?;
            Ok(Self::new(p))
        }

        /// A filter with the given parameters in every lane (not validated: see `try_new`).
        pub fn new(p: &$params) -> Self {
            Self::with_lane_params(&crate::filters::LaneParams::uniform(p))
        }
    };
}
pub(crate) use uniform_constructors;

pub use complementary::{Complementary, ComplementaryParams};
pub use complementary_reconstruction::{
    ComplementaryReconstruction, ComplementaryReconstructionParams,
};
pub use ecf_ekf::{EcfEkf, EcfEkfParams};
pub use ekf::{Ekf, EkfParams};
pub use gyro::{GyroIntegration, GyroParams};
pub use heading_pipeline::{HeadingPipeline, HeadingPipelineParams};
pub use lsq_fusion::{
    DriftConfig, DriftEstimator, DriftSample, LsqFusion, LsqFusionParams, PolyDenoiser,
};
pub use madgwick::{Madgwick, MadgwickParams};
pub use mahony::{Mahony, MahonyParams};
pub use params::{
    Dof, InvalidParam, LaneParams, LaneParamsError, ParamInfo, ParamKind, ParamSet, ParamValue,
};
#[cfg(feature = "std")]
pub use params::{ParamError, Params};
pub(crate) use params::{params, params_with_screening};
pub use screen::{Rejections, SampleFlags, ScreenLimits, Screened};
pub use sqrt_eskf::{SqrtEskf, SqrtEskfParams};

use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat};

/// A causal orientation filter over lanes of type `T`.
pub trait OrientationFilter<T: Lane> {
    /// Processes one sample taken `dt` seconds after the previous one.
    fn update(&mut self, sample: &ImuSample<T>, dt: T);
    /// Current orientation, sensor to earth (ENU), unit norm.
    fn quat(&self) -> Quat<T>;
    /// Current gyroscope-bias estimate, rad/s (zero for filters without one).
    fn bias(&self) -> Vec3<T> {
        Vec3::zero()
    }
    /// Per-lane counts of skipped samples and corrections, by reason.
    fn rejections(&self) -> &Rejections<T>;
    /// Covariance of the attitude error of [`quat`](Self::quat), rad², for filters that carry
    /// one (`None` otherwise; the answer is the same for every lane).
    ///
    /// Convention: the global (earth-frame) error `δθ` with `q_true = Exp(δθ) ⊗ q`, where
    /// `Exp(v) = [cos(|v|/2), sin(|v|/2)·v/|v|]`; axes ENU, so `[2][2]` is the heading
    /// variance and the upper-left 2×2 block is the inclination.
    fn attitude_covariance(&self) -> Option<Mat<T, 3, 3>> {
        None
    }
    /// Per lane: the sensor is detected at rest now, for filters with rest detection (`None`
    /// otherwise; the answer is the same for every lane).
    fn rest_detected(&self) -> Option<T::Mask> {
        None
    }
    /// Per lane: the last magnetometer sample was rejected as a disturbed field, for filters
    /// with magnetic-disturbance detection (`None` otherwise).
    fn magnetic_disturbance(&self) -> Option<T::Mask> {
        None
    }
    /// What happened to the last sample, per lane ([`SampleFlags::bits`] gives the `flags`
    /// column): skips by reason, gating, magnetic disturbance, rest.
    fn flags(&self) -> SampleFlags<T> {
        let mut f = self.rejections().last;
        if let Some(rest) = self.rest_detected() {
            f.at_rest = rest;
        }
        f
    }
    /// Sets the orientation (sensor to earth, ENU; normalised here) in every lane and marks
    /// the filter initialised, so the next samples correct from there instead of starting
    /// over from the accelerometer. Filters that learn more state (bias, covariance) keep it.
    fn set_quat(&mut self, q: Quat<T>);
    /// Sets the gyro-bias estimate, rad/s (sensor frame); `false` (and nothing changed) for
    /// filters without one, for `heading-pipeline`, whose estimate is one component (the
    /// heading rate about earth-up) and cannot hold a three-axis bias, and for
    /// `complementary-reconstruction` during its still period (the mean is being taken).
    fn set_bias(&mut self, bias: Vec3<T>) -> bool {
        let _ = bias;
        false
    }
    /// Turns the orientation about earth-up so that its heading (yaw, rad, counter-clockwise
    /// from north, see [`Quat::heading_inclination`]) becomes `heading`; the inclination is
    /// kept.
    fn set_heading(&mut self, heading: T) {
        let q = self.quat();
        let (current, _) = q.heading_inclination();
        self.set_quat(Quat::from_heading(heading - current) * q);
    }
}

/// Shared initialisation: where a lane is not yet initialised and this sample has a usable
/// accelerometer, the orientation is taken from the sample (gravity, and the magnetometer
/// when `nine_d` and usable); elsewhere `q` is returned unchanged.
#[inline]
pub(crate) fn initialise<T: Lane>(
    q: Quat<T>,
    initialized: &mut T::Mask,
    s: &Screened<T>,
    nine_d: bool,
) -> Quat<T> {
    // Uniform across lanes, so results are unchanged: once no lane can start, skip the work.
    if (!*initialized & s.acc_ok).none() {
        return q;
    }
    let (tilt, _) = crate::blocks::tilt_from_acc(s.acc);
    let q_meas = if nine_d {
        let (am, am_ok) = crate::blocks::acc_mag_quat(s.acc, s.mag, T::from_f64(0.1));
        Quat::select(am_ok & s.mag_ok, am, tilt)
    } else {
        tilt
    };
    let fresh = !*initialized & s.acc_ok;
    *initialized |= fresh;
    Quat::select(fresh, q_meas, q)
}

/// Earth-up in ENU.
#[inline]
pub(crate) fn up<T: Lane>() -> Vec3<T> {
    Vec3::new(T::zero(), T::zero(), T::one())
}

/// The field direction reference `[0, |h_xy|, h_z]` (unit, ENU) for a unit sensor-frame field
/// `mag` seen through `q`: north-pointing horizontal part, the measured dip kept.
#[inline]
pub(crate) fn mag_reference<T: Lane>(q: Quat<T>, mag: Vec3<T>) -> Vec3<T> {
    let h = q.rotate(mag);
    Vec3::new(T::zero(), (h.x * h.x + h.y * h.y).sqrt(), h.z)
}
