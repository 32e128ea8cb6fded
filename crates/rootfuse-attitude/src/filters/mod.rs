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
        $vis:vis struct $name:ident<T: Lane> {
            $( $(#[$fmeta:meta])* $fvis:vis $field:ident: $ty:ty, )*
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug)]
        $vis struct $name<T: Lane> {
            $( $(#[$fmeta])* $fvis $field: $ty, )*
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

/// A filter's `try_new` (validated), `new` (one parameter set in every lane, over its
/// `with_lane_params`) and `params()` (its `params` field): written once for every filter.
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

        /// The parameters the filter was built with: those of every lane after `new` or
        /// `try_new`, those of the first lane after `with_lane_params`.
        pub fn params(&self) -> &$params {
            &self.params
        }
    };
}
pub(crate) use uniform_constructors;

/// `reset`, `set_quat` and `set_bias` of a filter whose state is `q`, `bias`, `initialized`
/// and `rejections` alone (no covariance): written once for Mahony and Madgwick.
macro_rules! quat_bias_state {
    ($($field:ident: $value:expr),* $(,)?) => {
        fn reset(&mut self) {
            self.q = Quat::identity();
            self.bias = Vec3::zero();
            self.initialized = <T::Mask as Mask>::splat(false);
            self.rejections = Rejections::default();
            $(self.$field = $value;)*
        }
        fn set_quat(
            &mut self,
            q: Quat<T>,
            sigma: Option<T>,
        ) -> Result<(), crate::filters::StateError> {
            self.q = crate::filters::quat_without_covariance(q, sigma)?;
            self.initialized = <T::Mask as Mask>::splat(true);
            Ok(())
        }
        fn set_bias(
            &mut self,
            bias: Vec3<T>,
            sigma: Option<T>,
        ) -> Result<(), crate::filters::StateError> {
            self.bias = crate::filters::bias_without_covariance(bias, sigma)?;
            Ok(())
        }
    };
}
pub(crate) use quat_bias_state;

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
pub use screen::{Rejections, SampleFlags, ScreenBounds, ScreenLimits, Screened};
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
    /// Current estimate of the gyroscope's scale error per sensor axis, a fraction `s` in
    /// `ω_measured = (1 + s)·ω`, for filters that estimate it (the flagship with
    /// `gyr_scale_window > 0`); zero otherwise.
    fn gyro_scale(&self) -> Vec3<T> {
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
    /// Time constant, s, with which the offline smoother
    /// (`smooth::forward_backward`, with `std`) refines its fused estimate by
    /// the gyroscope, bias removed: above `1/(2π·τ)` the result follows the integrated rate,
    /// below it the fused estimate (zero-phase). 0, the default, keeps the fused estimate.
    /// The first lane's value.
    fn smoothing_gyro_tau(&self) -> f64 {
        0.0
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
    /// From the next sample on, the magnetometer's readings in the lanes of `lanes` change
    /// for a reason that is not the field's (a calibration is now applied to them, as
    /// [`MagCalibrated`](crate::calibration::MagCalibrated) does): a filter that learns a
    /// reference of the field forgets it there and takes the next usable reading as its
    /// reference, pointing north, instead of rejecting the new readings as a disturbance.
    /// Nothing else changes. The default, for filters without a field reference, does
    /// nothing.
    fn forget_field_reference(&mut self, lanes: T::Mask) {
        let _ = lanes;
    }
    /// Back to the state of a new filter with the same parameters: the samples that follow
    /// give the same bits as they would in a filter just built (orientation, bias,
    /// covariance, pre-processing windows, counters).
    fn reset(&mut self);
    /// Sets the orientation `q` (sensor to earth, ENU; normalised here) in every lane and
    /// marks the filter initialised, so the next samples correct from there instead of
    /// starting over from the accelerometer.
    ///
    /// `sigma` (rad, per earth axis, per lane) sets the attitude uncertainty with it, for
    /// filters that carry one ([`attitude_covariance`](Self::attitude_covariance) then reads
    /// `sigma`² back on its diagonal); `None` keeps the covariance learned so far.
    ///
    /// Refused, with nothing changed in any lane: a non-finite `q`, one whose norm is
    /// outside [0.5, 2] (not an orientation that was meant), a `sigma` that is NaN, negative
    /// or above π ([`StateError::Invalid`], naming the first lane's value), and a `sigma` for
    /// a filter without an attitude covariance ([`StateError::Unsupported`]).
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError>;
    /// Sets the gyro-bias estimate `bias` (rad/s, sensor frame) and, with `sigma` (rad/s,
    /// per axis, per lane), its uncertainty, for filters that carry one (`None` keeps it).
    ///
    /// Refused, with nothing changed: a non-finite bias or one above 1 rad/s in a component
    /// (no gyroscope bias is that large: it is a unit error), a `sigma` that is NaN,
    /// negative or above 1 rad/s ([`StateError::Invalid`]); and by filters without a
    /// three-axis bias estimate ([`StateError::Unsupported`]): those without one, and
    /// `heading-pipeline`, whose estimate is one component (the heading rate about
    /// earth-up); `complementary-reconstruction` refuses it during its still period (the
    /// mean is being taken), and a `sigma` because it carries no bias covariance.
    fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
        let _ = (bias, sigma);
        Err(StateError::Unsupported("gyro-bias estimate"))
    }
    /// Turns the orientation about earth-up so that its heading (yaw, rad, counter-clockwise
    /// from north, see [`Quat::heading_inclination`]) becomes `heading`; the inclination and
    /// the covariance are kept. Refused like [`set_quat`](Self::set_quat) for a non-finite
    /// heading.
    fn set_heading(&mut self, heading: T) -> Result<(), StateError> {
        let q = self.quat();
        let (current, _) = q.heading_inclination();
        self.set_quat(Quat::from_heading(heading - current) * q, None)
    }
}

/// Why a filter refused a state set from outside ([`OrientationFilter::set_quat`],
/// [`OrientationFilter::set_bias`], [`OrientationFilter::set_heading`]); nothing was changed.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum StateError {
    /// A value out of its range, or NaN (the first lane that fails).
    Invalid(InvalidParam),
    /// The filter carries no such state: the text names what it lacks.
    Unsupported(&'static str),
}

impl core::fmt::Display for StateError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Invalid(e) => {
                let InvalidParam {
                    name,
                    value,
                    min,
                    max,
                    ..
                } = e;
                write!(
                    f,
                    "`{name}` = {value} is outside [{min}, {max}]; nothing was set"
                )
            }
            Self::Unsupported(what) => write!(
                f,
                "this filter carries no {what}; nothing was set (the flagship carries all)"
            ),
        }
    }
}

impl core::error::Error for StateError {}

impl From<InvalidParam> for StateError {
    fn from(e: InvalidParam) -> Self {
        Self::Invalid(e)
    }
}

/// `Ok` if `ok` holds in every lane; else the value of the first lane where it fails,
/// refused as `name` outside `[min, max]`.
fn within<T: Lane>(
    name: &'static str,
    value: T,
    ok: T::Mask,
    min: f64,
    max: f64,
) -> Result<(), StateError> {
    match (0..T::LANES).find(|&i| !ok.test(i)) {
        Some(i) => Err(StateError::Invalid(InvalidParam {
            name,
            value: value.extract(i).into(),
            min,
            max,
            unit: "",
        })),
        None => Ok(()),
    }
}

/// `q` normalised, if every lane's norm is in [0.5, 2] (NaN fails).
pub(crate) fn checked_quat<T: Lane>(q: Quat<T>) -> Result<Quat<T>, StateError> {
    let norm = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
    let ok = norm.simd_ge(T::from_f64(0.5)) & norm.simd_le(T::from_f64(2.0));
    within("|q|", norm, ok, 0.5, 2.0)?;
    Ok(q.normalize())
}

/// `sigma` if every lane is in [0, max] (NaN fails).
pub(crate) fn checked_sigma<T: Lane>(sigma: T, max: f64) -> Result<T, StateError> {
    let ok = sigma.simd_ge(T::zero()) & sigma.simd_le(T::from_f64(max));
    within("sigma", sigma, ok, 0.0, max)?;
    Ok(sigma)
}

/// `bias` if every component of every lane is finite and at most 1 rad/s in magnitude.
pub(crate) fn checked_bias<T: Lane>(bias: Vec3<T>) -> Result<Vec3<T>, StateError> {
    let largest = bias.x.abs().max(bias.y.abs()).max(bias.z.abs());
    let nan = bias.x.is_nan() | bias.y.is_nan() | bias.z.is_nan();
    let shown = T::select(nan, T::from_f64(f64::NAN), largest);
    within("bias", shown, largest.simd_le(T::one()) & !nan, -1.0, 1.0)?;
    Ok(bias)
}

/// A `sigma` given to a filter that carries no covariance for it (`what`) is refused.
fn no_covariance<T>(sigma: Option<T>, what: &'static str) -> Result<(), StateError> {
    match sigma {
        Some(_) => Err(StateError::Unsupported(what)),
        None => Ok(()),
    }
}

/// `set_quat` for filters without an attitude covariance: `q` checked and normalised, a
/// `sigma` refused.
pub(crate) fn quat_without_covariance<T: Lane>(
    q: Quat<T>,
    sigma: Option<T>,
) -> Result<Quat<T>, StateError> {
    let q = checked_quat(q)?;
    no_covariance(sigma, "attitude covariance")?;
    Ok(q)
}

/// `set_bias` for filters without a bias covariance: `bias` checked, a `sigma` refused.
pub(crate) fn bias_without_covariance<T: Lane>(
    bias: Vec3<T>,
    sigma: Option<T>,
) -> Result<Vec3<T>, StateError> {
    let bias = checked_bias(bias)?;
    no_covariance(sigma, "gyro-bias covariance")?;
    Ok(bias)
}

/// Shared initialisation: where a lane is not yet initialised and this sample has a usable
/// accelerometer, the orientation is taken from the sample (gravity, and the magnetometer
/// when `nine_d` and usable); elsewhere `q` is returned unchanged. Always inlined: left to
/// itself the compiler called it out of line from some updates, which cost scalar `f32`
/// Mahony 53 → 47 ns per update and the complementary filter 66 → 62 (`rootfuse throughput`).
#[inline(always)]
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
