//! Quaternion complementary filter with decoupled inclination and heading corrections
//! [`complementary`].

use super::LaneParams;
use super::{Dof, OrientationFilter, Rejections, ScreenLimits, Screened, initialise, params, up};
use super::{StateError, quat_without_covariance};
use crate::blocks::{LowPassGain, integrate_gyro, magnetic_heading_error, turn_in_earth};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask};

params! {
    /// Parameters of [`Complementary`].
    pub struct ComplementaryParams {
        /// Time constant of the inclination correction toward gravity.
        tau_acc: f64 = 3.0, "s", [1e-3, 1e6];
        /// Time constant of the heading correction toward magnetic north.
        tau_mag: f64 = 5.0, "s", [1e-3, 1e6];
        /// 9: use the magnetometer for heading; 6: gravity only.
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// Gyro propagation, then two first-order corrections in the earth frame: a rotation about a
/// horizontal axis that turns the measured gravity toward up by the fraction
/// `1 − exp(−dt/tau_acc)` of the angle, and a rotation about earth-z that turns the horizontal
/// field toward north by `1 − exp(−dt/tau_mag)` ([`lowpass_gain`](crate::blocks::lowpass_gain):
/// exact for any `dt`, where `dt/τ` clipped at 1 is first order only).
///
/// Because the heading correction is a rotation about earth-z, a magnetic disturbance can
/// never tilt the inclination (unlike filters that feed the magnetometer into all axes).
#[derive(Clone, Debug)]
pub struct Complementary<T: Lane> {
    q: Quat<T>,
    initialized: T::Mask,
    /// Correction gains `1 − exp(−dt/τ)` of `tau_acc` and `tau_mag`.
    k_acc: LowPassGain<T>,
    k_mag: LowPassGain<T>,
    nine_d: bool,
    limits: ScreenLimits,
    rejections: Rejections<T>,
    params: ComplementaryParams,
}

impl<T: Lane> Complementary<T> {
    crate::filters::uniform_constructors!(ComplementaryParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(p: &LaneParams<'_, ComplementaryParams, T>) -> Self {
        Self {
            q: Quat::identity(),
            initialized: <T::Mask as Mask>::splat(false),
            k_acc: LowPassGain::new(p.coef(|p| p.tau_acc)),
            k_mag: LowPassGain::new(p.coef(|p| p.tau_mag)),
            nine_d: p.first().dof.uses_magnetometer(),
            limits: p.first().screen_limits(),
            rejections: Rejections::default(),
            params: p.first().clone(),
        }
    }
}

/// The earth-frame rotation vector that turns unit `a_earth` toward `up`, of angle
/// `atan2(|a × up|, a·up)`: `a × up` scaled by angle/sin.
///
/// Where the tilt is below about 5.7° (`|a × up|² < 0.01`, `a` above the horizon: every
/// correction of a converged filter without strong acceleration) angle/sin is `asin(s)/s`, from
/// its series in `s²` (through `s¹⁴` in `f64`, `s⁶` in `f32`; the first dropped term below
/// `1.2·10⁻¹⁸` and `3·10⁻¹⁰`), with no square root, `atan2` or division; where every lane is
/// there only the series is computed, otherwise each lane selects by its own tilt.
#[inline]
pub(crate) fn tilt_correction<T: Lane>(a_earth: Vec3<T>) -> Vec3<T> {
    let axis = a_earth.cross(up());
    let s2 = axis.norm_squared();
    let near = s2.simd_lt(T::from_f64(TILT_SERIES_S2)) & a_earth.z.simd_gt(T::zero());
    if near.all() {
        return axis * asin_ratio_series(s2);
    }
    let s = s2.sqrt();
    let angle = s.atan2(a_earth.z);
    let small = s.simd_lt(T::from_f64(1e-4)) & a_earth.z.simd_gt(T::zero());
    let exact = T::select(small, T::one(), angle / s);
    axis * T::select(near, asin_ratio_series(s2), exact)
}

/// Below this `|a × up|²` (a tilt of about 5.7°) [`tilt_correction`] takes angle/sin from its
/// series.
const TILT_SERIES_S2: f64 = 0.01;

/// `asin(s)/s = Σ C(2n, n)·s²ⁿ/(4ⁿ·(2n + 1))` at `s² < TILT_SERIES_S2`, by Horner in `s²`.
#[inline(always)]
fn asin_ratio_series<T: Lane>(s2: T) -> T {
    const COEFFICIENTS: [f64; 8] = [
        1.0,
        1.0 / 6.0,
        3.0 / 40.0,
        5.0 / 112.0,
        35.0 / 1152.0,
        63.0 / 2816.0,
        231.0 / 13312.0,
        143.0 / 10240.0,
    ];
    let terms = if core::mem::size_of::<T::Scalar>() == 8 {
        8
    } else {
        4
    };
    let mut p = T::from_f64(COEFFICIENTS[terms - 1]);
    for &c in COEFFICIENTS[..terms - 1].iter().rev() {
        p = s2.mul_add(p, T::from_f64(c));
    }
    p
}

impl<T: Lane> OrientationFilter<T> for Complementary<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.limits, &mut self.rejections, self.nine_d);
        let q0 = initialise(self.q, &mut self.initialized, &s, self.nine_d);
        let mut q = integrate_gyro(q0, s.gyr, s.dt);

        let k_acc = self.k_acc.gain(s.dt);
        let tilt = tilt_correction(q.rotate(s.acc)) * k_acc;
        let q_acc = turn_in_earth(q, tilt);
        q = Quat::select(s.acc_ok, q_acc, q);

        // 6D is the same for every lane and discards this correction: skipping it changes no bits.
        if self.nine_d {
            let (dpsi, heading_ok) = magnetic_heading_error(q, s.mag);
            let k_mag = self.k_mag.gain(s.dt);
            let q_mag = turn_in_earth(q, Vec3::new(T::zero(), T::zero(), dpsi * k_mag));
            q = Quat::select(s.mag_ok & heading_ok, q_mag, q);
        }

        self.q = Quat::select(s.step, q, self.q);
    }
    fn reset(&mut self) {
        self.q = Quat::identity();
        self.initialized = <T::Mask as Mask>::splat(false);
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
