//! Quaternion complementary filter with decoupled inclination and heading corrections
//! [`complementary`].

use super::LaneParams;
use super::{Dof, OrientationFilter, Rejections, ScreenBounds, Screened, initialise, params};
use super::{StateError, quat_without_covariance};
use crate::blocks::{
    LowPassGain, exp_cos_sinc, field_heading_error, gyro_increment, heading_field_ok,
    small_turn_cos_sinc,
};
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
///
/// Within about 5.7° the correction angles come from series (`asin(s)/s` of the tilt,
/// `atan(t)/t` of the heading, `t = h_x/h_y`), beyond from `atan2`. Both corrections are
/// measured in the frame the gyro step leaves and applied one after the other (the heading's
/// field is not turned by the tilt correction first: the two differ by the tilt correction's
/// angle, a fraction `dt/τ` of the tilt, times the heading's own gain); the tilt is turned in
/// the sensor frame (the same rotation: docs/methods.md).
#[derive(Clone, Debug)]
pub struct Complementary<T: Lane> {
    q: Quat<T>,
    initialized: T::Mask,
    /// Correction gains `1 − exp(−dt/τ)` of `tau_acc` and `tau_mag`.
    k_acc: LowPassGain<T>,
    k_mag: LowPassGain<T>,
    nine_d: bool,
    bounds: ScreenBounds<T>,
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
            bounds: p.first().screen_limits().bounds(),
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
    // `a × up`, written out: the products with up's zeros change no value but the sign of a
    // zero, and would sit on the dependency chain.
    let axis = Vec3::new(a_earth.y, -a_earth.x, T::zero());
    let s2 = a_earth.x * a_earth.x + a_earth.y * a_earth.y;
    axis * tilt_ratio(s2, a_earth.z, T::one())
}

/// `k·angle/sin` of the angle between two unit vectors given the squared norm `s2` of their
/// cross product and their dot product `cos`: from the series of `asin(s)/s` where
/// `s2 < TILT_SERIES_S2` and `cos > 0` (in every lane: only the series), from `atan2`
/// elsewhere (each lane by its own angle).
#[inline(always)]
fn tilt_ratio<T: Lane>(s2: T, cos: T, k: T) -> T {
    let near = s2.simd_lt(T::from_f64(TILT_SERIES_S2)) & cos.simd_gt(T::zero());
    if near.all() {
        return asin_ratio_series(s2, k);
    }
    let s = s2.sqrt();
    let angle = s.atan2(cos);
    let small = s.simd_lt(T::from_f64(1e-4)) & cos.simd_gt(T::zero());
    let exact = T::select(small, T::one(), angle / s);
    T::select(near, asin_ratio_series(s2, k), k * exact)
}

/// Below this `|a × up|²` (a tilt of about 5.7°) [`tilt_correction`] takes angle/sin from its
/// series.
const TILT_SERIES_S2: f64 = 0.01;

/// `k·asin(s)/s = k·Σ C(2n, n)·s²ⁿ/(4ⁿ·(2n + 1))` at `s² < TILT_SERIES_S2`.
#[inline(always)]
fn asin_ratio_series<T: Lane>(s2: T, k: T) -> T {
    ratio_series(
        s2,
        &[
            1.0,
            1.0 / 6.0,
            3.0 / 40.0,
            5.0 / 112.0,
            35.0 / 1152.0,
            63.0 / 2816.0,
            231.0 / 13312.0,
            143.0 / 10240.0,
        ],
        k,
    )
}

/// `k·atan(t)/t = k·Σ (−1)ⁿ·t²ⁿ/(2n + 1)` at `t² < TILT_SERIES_S2` (the first dropped term
/// below `6·10⁻¹⁸` in `f64`, `1.2·10⁻⁹` in `f32`).
#[inline(always)]
fn atan_ratio_series<T: Lane>(t2: T, k: T) -> T {
    ratio_series(
        t2,
        &[
            1.0,
            -1.0 / 3.0,
            1.0 / 5.0,
            -1.0 / 7.0,
            1.0 / 9.0,
            -1.0 / 11.0,
            1.0 / 13.0,
            -1.0 / 15.0,
        ],
        k,
    )
}

/// `k·Σ cₙ·x²ⁿ`: all eight coefficients in `f64`, the first four in `f32`, each times `k`
/// (known before `x2`), by powers side by side (Estrin's scheme: the depth after `x2` grows
/// with the logarithm of the term count, where Horner's nested chain grows with the count).
#[inline(always)]
fn ratio_series<T: Lane>(x2: T, coefficients: &[f64; 8], k: T) -> T {
    let c = |n: usize| k * T::from_f64(coefficients[n]);
    let x4 = x2 * x2;
    let low = (c(0) + c(1) * x2) + x4 * (c(2) + c(3) * x2);
    if core::mem::size_of::<T::Scalar>() == 8 {
        let high = (c(4) + c(5) * x2) + x4 * (c(6) + c(7) * x2);
        low + (x4 * x4) * high
    } else {
        low
    }
}

/// [`field_heading_error`] of an earth-frame field `h`, `atan2(h_x, h_y)`, times `k`, with
/// the same mask; within about 5.7° of north (`h_y > 0`, `(h_x/h_y)² < 0.01`: every
/// correction of a converged filter) from the series of `atan(t)/t`, `t = h_x/h_y`, with no
/// `atan2` (a division and a longer polynomial); where every lane is there only the series is
/// computed, otherwise each lane selects by its own `t`.
#[inline]
fn heading_error<T: Lane>(h: Vec3<T>, k: T) -> (T, T::Mask) {
    let t = h.x / h.y;
    let t2 = t * t;
    let near = t2.simd_lt(T::from_f64(TILT_SERIES_S2)) & h.y.simd_gt(T::zero());
    if near.all() {
        let ok = heading_field_ok(h);
        return (T::select(ok, t * atan_ratio_series(t2, k), T::zero()), ok);
    }
    let (exact, ok) = field_heading_error(h);
    (
        T::select(near & ok, t * atan_ratio_series(t2, k), k * exact),
        ok,
    )
}

/// `q0 ⊗ e`, each component's four products summed as a tree. Its norm is `|q0|`, within a few
/// ulp of one (the last update's result); the caller renormalises the corrected result by
/// `(3 − |q0|²)/2` (one Newton step of `1/|q0|`), off the path to the rotations.
#[inline]
fn propagate<T: Lane>(q0: Quat<T>, e: Quat<T>) -> Quat<T> {
    let (a, b) = (q0, e);
    Quat::new(
        (a.w * b.w - a.x * b.x) - (a.y * b.y + a.z * b.z),
        (a.w * b.x + a.x * b.w) + (a.y * b.z - a.z * b.y),
        (a.w * b.y - a.x * b.z) + (a.y * b.w + a.z * b.x),
        (a.w * b.z + a.x * b.y) + (a.z * b.w - a.y * b.x),
    )
}

impl<T: Lane> OrientationFilter<T> for Complementary<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let q0 = initialise(self.q, &mut self.initialized, &s, self.nine_d);
        // Both corrections are measured against the propagated `q0 ⊗ e`, with the gains halved
        // (the turns' half angles). Rotating the sample's vectors by `e` and then by `q0` would
        // take the product off the dependency chain at the price of a rotation more per
        // vector, which costs more than it saves (docs/flagship_cost.md).
        let e = gyro_increment(s.gyr, s.dt);
        let k_acc_half = self.k_acc.gain(s.dt) * T::from_f64(0.5);
        let propagated = propagate(q0, e);
        // The tilt correction in the sensor frame: the earth-frame rotation `exp(φ/2) ⊗ q`
        // equals `q ⊗ exp(R(q)ᵀφ/2)`, and `R(q)ᵀ(a × up) = â × R(q)ᵀup` with the angle's sine
        // and cosine unchanged, so up is brought into the sensor frame (the rotation matrix's
        // third row) where the earth-frame form rotated the sample into the earth frame.
        let up = propagated.up_in_sensor();
        let axis = s.acc.cross(up);
        let s2 = axis.norm_squared();
        let ratio = tilt_ratio(s2, s.acc.dot(up), k_acc_half);
        let tilt_half = axis * ratio;
        // q ⊗ exp(φ/2) = q·cos a + (q ⊗ [0, φ/2])·(sin a / a), a = |φ/2|.
        let (cos, sinc) = exp_cos_sinc(s2 * (ratio * ratio));
        let turned = propagated.times_pure(tilt_half);
        // The renormalisation of `q0` (see `propagate`), folded into the turn's parts.
        let f = T::from_f64(1.5) - T::from_f64(0.5) * q0.norm_squared();
        let (cos, sinc) = (cos * f, sinc * f);
        let tilted = Quat::new(
            turned.w.mul_add(sinc, propagated.w * cos),
            turned.x.mul_add(sinc, propagated.x * cos),
            turned.y.mul_add(sinc, propagated.y * cos),
            turned.z.mul_add(sinc, propagated.z * cos),
        );
        let mut q = Quat::select(s.acc_ok, tilted, propagated.scale(f));

        // 6D is the same for every lane and discards this correction: skipping it changes no bits.
        if self.nine_d {
            // The heading error is measured in the frame the gyro step left, before the tilt
            // correction (its effect on the field's azimuth is the tilt correction's angle, a
            // gain of order dt/τ times the tilt, times the gain of this one): the two
            // corrections are measured side by side and applied one after the other.
            let k_mag_half = self.k_mag.gain(s.dt) * T::from_f64(0.5);
            let (psi_half, heading_ok) = heading_error(propagated.rotate(s.mag), k_mag_half);
            // exp(ψ/2·ẑ) ⊗ q, the rotation's vector along earth-z only; the turn is a fraction
            // dt/τ of the heading error, so its cos and sin/x are almost always one (the
            // tilt's turn taken the same way measured slower: docs/flagship_cost.md).
            let (cos, sinc) = small_turn_cos_sinc(psi_half * psi_half);
            let z = psi_half * sinc;
            let q_mag = Quat::new(
                cos * q.w - z * q.z,
                cos * q.x - z * q.y,
                cos * q.y + z * q.x,
                cos * q.z + z * q.w,
            );
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

#[cfg(test)]
mod tests {
    use super::*;
    use rootfuse_lane::wide::f32x8;

    /// Fields at every azimuth (the series within 5.7° of north, `atan2` beyond), with a dip.
    fn field(azimuth: f64) -> Vec3<f64> {
        Vec3::new(20.0 * azimuth.sin(), 20.0 * azimuth.cos(), -40.0)
    }

    #[test]
    fn heading_error_is_atan2_to_rounding() {
        for i in 0..4001 {
            let azimuth = (f64::from(i) / 2000.0 - 1.0) * 0.999 * core::f64::consts::PI;
            let h = field(azimuth);
            let exact = h.x.atan2(h.y);
            let (e, ok) = heading_error(h, 1.0);
            assert!(
                ok && (e - exact).abs() <= 4.0 * f64::EPSILON * exact.abs(),
                "{azimuth}"
            );
            // A gain folded into the series (or applied to atan2) scales the angle.
            let (e, _) = heading_error(h, 0.3);
            assert!(
                (e - 0.3 * exact).abs() <= 8.0 * f64::EPSILON * exact.abs(),
                "{azimuth}"
            );
            let h32 = Vec3::new(h.x as f32, h.y as f32, h.z as f32);
            let exact32 = f64::from(h32.x).atan2(f64::from(h32.y));
            let (e32, ok32) = heading_error(h32, 1.0);
            let tol = 4.0 * f64::from(f32::EPSILON) * exact32.abs();
            assert!(ok32 && (f64::from(e32) - exact32).abs() <= tol, "{azimuth}");
        }
        // A vertical or unusable field gives no heading, in either path: `atan2`'s (h_y 0 or
        // NaN) and the series' (near north, but too vertical or not finite).
        for h in [
            Vec3::new(0.0, 0.0, -40.0),
            Vec3::new(f64::NAN, 1.0, 0.0),
            Vec3::new(0.0, 0.01, -40.0),
            Vec3::new(0.0, f64::INFINITY, 0.0),
        ] {
            assert_eq!(heading_error(h, 1.0), (0.0, false), "{h:?}");
        }
    }

    #[test]
    fn heading_error_lanes_equal_scalars() {
        // Lanes near north and far from it side by side take each its own path.
        let azimuths = [0.01, 2.5, -0.05, -1.0, 0.09, 3.0, 0.0, -0.099];
        let h32: [Vec3<f32>; 8] = core::array::from_fn(|i| {
            let h = field(azimuths[i]);
            Vec3::new(h.x as f32, h.y as f32, h.z as f32)
        });
        let lanes = Vec3::new(
            f32x8::from(core::array::from_fn::<f32, 8, _>(|i| h32[i].x)),
            f32x8::from(core::array::from_fn::<f32, 8, _>(|i| h32[i].y)),
            f32x8::from(core::array::from_fn::<f32, 8, _>(|i| h32[i].z)),
        );
        let (e, _) = heading_error(lanes, f32x8::splat(1.0));
        for (i, h) in h32.iter().enumerate() {
            assert_eq!(
                e.extract(i).to_bits(),
                heading_error(*h, 1.0).0.to_bits(),
                "lane {i}"
            );
        }
    }

    /// The tilt correction in the sensor frame is the earth-frame one: `q ⊗ exp(φ_s/2)` with
    /// `φ_s = k·(â × R(q)ᵀup)·angle/sin` equals `exp(φ/2) ⊗ q` with `φ` from
    /// [`tilt_correction`] of `R(q)·â` times `k`, over tilts on both sides of the series'
    /// limit.
    #[test]
    fn sensor_frame_tilt_is_the_earth_frame_tilt() {
        let q = Quat::<f64>::from_euler_zyx(0.7, -0.4, 0.25);
        for i in 0..200 {
            let angle = f64::from(i) * 0.015;
            let a_earth = Vec3::new(0.3 * angle.sin(), -0.95 * angle.sin(), angle.cos());
            let a_earth = a_earth * (1.0 / a_earth.norm());
            let acc = q.rotate_inverse(a_earth);
            let earth = Quat::from_rotation_vector(tilt_correction(a_earth) * 0.25) * q;
            let up = q.up_in_sensor();
            let axis = acc.cross(up);
            let ratio = tilt_ratio(axis.norm_squared(), acc.dot(up), 0.25);
            let sensor = q * Quat::from_rotation_vector(axis * ratio);
            assert!(
                (earth - sensor).norm() < 1e-14,
                "{angle}: {earth:?} vs {sensor:?}"
            );
        }
    }
}
