//! Building blocks: orientation from gravity and the magnetic field, gyro integration, the
//! first-order low-pass gain.
//!
//! All functions return a per-lane validity mask instead of failing: a zero, NaN or infinite
//! vector, or a degenerate geometry, gives a finite fallback value and a false mask bit.

use crate::quat::Quat;
use crate::vec3::Vec3;
use rootfuse_lane::{Lane, Mask, Mat};

mod lowpass;
pub use lowpass::{
    LowPassGain, lowpass_gain, lowpass_gain_at_rate, lowpass_gains, lowpass_gains_at_rates,
};

/// Standard gravity, m/s² (the `g` of `acc=g`).
pub const STANDARD_GRAVITY: f64 = 9.80665;

/// Below this `a² = |ω·dt/2|²` (rad², i.e. `a < 0.1`, 1150 °/s at 100 Hz) [`integrate_gyro`]
/// takes `cos a` and `sin a / a` from their Taylor series in `a²`. Through the `a⁸` terms the
/// truncation error is below `a¹⁰/10! < 3e-17` (under one ulp of f64), so the series is as
/// accurate as the trigonometric path, and it needs no square root, range reduction or
/// division.
pub const GYRO_SERIES_A2: f64 = 0.01;

/// Integrates body rates over `dt` by the exact exponential map:
/// `q ⊗ exp(ω·dt/2)`, renormalised. `omega` in rad/s (sensor frame), `dt` in s; `q` a unit
/// quaternion (to rounding: a filter's own state).
///
/// The rule, per lane: where `a² = |ω·dt/2|² < `[`GYRO_SERIES_A2`] the exponential's
/// `cos a` and `sin a / a` come from their series in `a²`, elsewhere from [`Quat::exp`]. When
/// every lane is below the limit (the usual case) only the series is computed; otherwise both
/// are and each lane selects by its own `a²`, so a lane's result does not depend on its
/// neighbours and equals the scalar result bit for bit.
///
/// The product is formed as `q·cos a + (q ⊗ [0, v])·(sin a / a)` and renormalised with the
/// norm of the *input* (`q·(3 − |q|²)/2`, one Newton step toward `|q| = 1`): the exponential is
/// unit to rounding, so `|q ⊗ e| = |q|`, and the factor is computed beside the series instead
/// of after the product. Every update thus starts from the norm the last one left, within a
/// few ulp of 1, and only four multiply-adds follow the series on the filter's dependency
/// chain (a filter update's speed is that chain's length).
///
/// ```
/// use rootfuse_attitude::{Quat, Vec3, blocks::integrate_gyro};
/// let q = integrate_gyro(Quat::<f64>::identity(), Vec3::new(0.0, 0.0, 1.0), 0.01);
/// let exact = Quat::from_axis_angle(Vec3::new(0.0, 0.0, 1.0), 0.01);
/// assert!((q.w - exact.w).abs() < 1e-16 && (q.z - exact.z).abs() < 1e-16);
/// ```
#[inline]
pub fn integrate_gyro<T: Lane>(q: Quat<T>, omega: Vec3<T>, dt: T) -> Quat<T> {
    // `dt/2` first: halving is exact, so this is `ω·dt·½` bit for bit with one multiply
    // fewer on the dependency chain through `ω` (`dt` does not depend on the state).
    times_exp(q, omega * (dt * T::from_f64(0.5)), false)
}

/// Turns `q` by the earth-frame rotation vector `phi` (axis·angle, rad): `exp(phi/2) ⊗ q`,
/// renormalised; `q` a unit quaternion (to rounding). A correction applied in the earth frame
/// (toward up, about earth-z), computed as [`integrate_gyro`] computes its step, by the same
/// rule (series below [`GYRO_SERIES_A2`] in `|phi/2|²`) and with the same renormalisation by
/// the input's own norm.
///
/// ```
/// use rootfuse_attitude::{Quat, Vec3, blocks::turn_in_earth};
/// let q = Quat::<f64>::from_euler_zyx(0.3, 0.1, -0.2);
/// let phi = Vec3::new(0.01, -0.02, 0.005);
/// let exact = Quat::from_rotation_vector(phi) * q;
/// let t = turn_in_earth(q, phi);
/// assert!((t.w - exact.w).abs() < 1e-15 && (t.x - exact.x).abs() < 1e-15);
/// ```
#[inline]
pub fn turn_in_earth<T: Lane>(q: Quat<T>, phi: Vec3<T>) -> Quat<T> {
    times_exp(q, phi * T::from_f64(0.5), true)
}

/// `q ⊗ exp(v)` (`earth` false) or `exp(v) ⊗ q` (`earth` true) for a pure `v`, as
/// `q·cos a + (q ⊗ [0, v])·(sin a / a)` (or `[0, v] ⊗ q`), `q` renormalised by its own norm
/// first (see [`integrate_gyro`]).
#[inline(always)]
fn times_exp<T: Lane>(q: Quat<T>, v: Vec3<T>, earth: bool) -> Quat<T> {
    let (cos, sinc) = exp_cos_sinc(v.norm_squared());
    let unit = q.scale(T::from_f64(1.5) - T::from_f64(0.5) * q.norm_squared());
    let turned = if earth {
        unit.pure_times(v)
    } else {
        unit.times_pure(v)
    };
    Quat::new(
        turned.w.mul_add(sinc, unit.w * cos),
        turned.x.mul_add(sinc, unit.x * cos),
        turned.y.mul_add(sinc, unit.y * cos),
        turned.z.mul_add(sinc, unit.z * cos),
    )
}

/// `exp(ω·dt/2)`: the rotation [`integrate_gyro`] multiplies by, from the same series by the
/// same rule (`integrate_gyro(q, ω, dt)` is `q ⊗ gyro_increment(ω, dt)` to rounding). `omega`
/// in rad/s (sensor frame), `dt` in s.
///
/// A filter that measures a vector `v` in the earth frame of the propagated orientation can
/// turn it by the increment first, `R(q ⊗ e)·v = R(q)·(R(e)·v)`: `R(e)·v` depends on the
/// sample only, so one rotation by `q` is left where a propagation and a rotation were.
///
/// ```
/// use rootfuse_attitude::{Quat, Vec3, blocks::{gyro_increment, integrate_gyro}};
/// let q = Quat::<f64>::from_euler_zyx(0.3, 0.1, -0.2);
/// let (omega, v) = (Vec3::new(0.5, -1.0, 2.0), Vec3::new(0.0, 0.6, 0.8));
/// let e = gyro_increment(omega, 0.01);
/// let a = integrate_gyro(q, omega, 0.01).rotate(v);
/// let b = q.rotate(e.rotate(v));
/// assert!((a - b).norm() < 1e-15);
/// ```
#[inline]
pub fn gyro_increment<T: Lane>(omega: Vec3<T>, dt: T) -> Quat<T> {
    series_exp(omega * (dt * T::from_f64(0.5)))
}

/// `exp(φ/2)`: the rotation [`turn_in_earth`] applies, by the same rule
/// (`turn_in_earth(q, phi)` is `earth_turn(phi) ⊗ q` to rounding). `phi` the earth-frame
/// rotation vector (axis·angle, rad).
///
/// ```
/// use rootfuse_attitude::{Quat, Vec3, blocks::earth_turn};
/// let phi = Vec3::<f64>::new(0.01, -0.02, 0.005);
/// let exact = Quat::from_rotation_vector(phi);
/// let t = earth_turn(phi);
/// assert!((t.w - exact.w).abs() < 1e-16 && (t.y - exact.y).abs() < 1e-16);
/// ```
#[inline]
pub fn earth_turn<T: Lane>(phi: Vec3<T>) -> Quat<T> {
    series_exp(phi * T::from_f64(0.5))
}

/// `exp([0, v])` by the rule of [`times_exp`].
#[inline(always)]
fn series_exp<T: Lane>(v: Vec3<T>) -> Quat<T> {
    let (cos, sinc) = exp_cos_sinc(v.norm_squared());
    Quat::from_parts(cos, v * sinc)
}

/// `cos a` and `sin a / a` of `a = √a2` by the rule of [`integrate_gyro`]: the series below
/// [`GYRO_SERIES_A2`] (only the series where every lane is below it), [`Quat::exp`]'s
/// coefficients elsewhere, each lane selecting by its own `a2`.
#[inline(always)]
pub(crate) fn exp_cos_sinc<T: Lane>(a2: T) -> (T, T) {
    let small = a2.simd_lt(T::from_f64(GYRO_SERIES_A2));
    if small.all() {
        gyro_series(a2)
    } else {
        let (cos, sinc) = gyro_series(a2);
        let (c, s) = Quat::exp_cos_sinc(a2);
        (T::select(small, cos, c), T::select(small, sinc, s))
    }
}

/// [`exp_cos_sinc`] of a turn so small that both values round to one: where every lane's
/// `a²` is at most [`ROUNDS_TO_ONE_A2`] (`2⁻²⁴` in `f32`, `2⁻⁵³` in `f64`), `(1, 1)` without
/// the series, the same bits (`each_value_rounds_to_one_below_the_limit`); elsewhere
/// [`exp_cos_sinc`]. For a correction that turns by a fraction `dt/τ` of an error angle (the
/// complementary filter's heading): in `f32` below the limit while the error is below tens
/// of degrees. The test is a predicted branch, so the series leaves the dependency chain
/// from the correction's angle to the corrected orientation.
#[inline(always)]
pub(crate) fn small_turn_cos_sinc<T: Lane>(a2: T) -> (T, T) {
    let limit = ROUNDS_TO_ONE_A2[usize::from(is_f64::<T>())];
    if a2.simd_le(T::from_f64(limit)).all() {
        (T::one(), T::one())
    } else {
        exp_cos_sinc(a2)
    }
}

/// The largest `a²` at which [`gyro_series`]' `cos a` and `sin a / a` both round to one, in
/// `f32` and in `f64`: `a²/2` and `a²/6` at most half an ulp below one, `2⁻²⁵` and `2⁻⁵⁴`
/// (round to nearest, ties to even: one), the higher terms far below.
const ROUNDS_TO_ONE_A2: [f64; 2] = [1.0 / 16_777_216.0, 1.0 / 9_007_199_254_740_992.0];

/// `cos a` and `sin a / a` from their Taylor series in `a² < `[`GYRO_SERIES_A2`]: through
/// `a⁸` in `f64` (the first dropped term below `a¹⁰/10! < 3·10⁻¹⁷`), through `a⁴` in `f32`
/// (below `a⁶/6! < 1.4·10⁻⁹`, a hundredth of an f32 ulp of 1). Evaluated by powers of `a²`
/// side by side (Estrin's scheme), not Horner's nested chain: the series sits on Mahony's
/// dependency chain, and Estrin's depth grows with the logarithm of the term count.
#[inline(always)]
fn gyro_series<T: Lane>(a2: T) -> (T, T) {
    let c = |x: f64| T::from_f64(x);
    let a4 = a2 * a2;
    if is_f64::<T>() {
        // cos a = 1 − a²/2! + a⁴/4! − a⁶/6! + a⁸/8!, sin a / a = 1 − a²/3! + … + a⁸/9!.
        let a8 = a4 * a4;
        let cos = a2.mul_add(c(-1.0 / 2.0), T::one())
            + a4 * a2.mul_add(c(-1.0 / 720.0), c(1.0 / 24.0))
            + a8 * c(1.0 / 40320.0);
        let sinc = a2.mul_add(c(-1.0 / 6.0), T::one())
            + a4 * a2.mul_add(c(-1.0 / 5040.0), c(1.0 / 120.0))
            + a8 * c(1.0 / 362880.0);
        (cos, sinc)
    } else {
        let cos = a2.mul_add(c(-1.0 / 2.0), T::one()) + a4 * c(1.0 / 24.0);
        let sinc = a2.mul_add(c(-1.0 / 6.0), T::one()) + a4 * c(1.0 / 120.0);
        (cos, sinc)
    }
}

/// Whether `L`'s scalar is `f64` (a series then takes more terms).
fn is_f64<L: Lane>() -> bool {
    core::mem::size_of::<L::Scalar>() == core::mem::size_of::<f64>()
}

/// Rotation vector over one interval with the two-sample coning correction
/// `Φ = Δθ1 + Δθ2 + ⅔·Δθ1 × Δθ2` (Bortz; Savage 1998), from two consecutive angle increments
/// (rad) that together span the interval.
#[inline]
pub fn coning_rotation_vector<T: Lane>(dtheta1: Vec3<T>, dtheta2: Vec3<T>) -> Vec3<T> {
    dtheta1 + dtheta2 + dtheta1.cross(dtheta2) * T::from_f64(2.0 / 3.0)
}

/// The inclination-only orientation (zero heading) that maps the measured specific force to
/// earth-up: `q.rotate(acc/|acc|) = [0, 0, 1]`.
///
/// Returns the identity and a false mask where `acc` is zero, tiny or not finite. Works for
/// any tilt including upside down (the shortest arc is taken from the nearer of ±z).
pub fn tilt_from_acc<T: Lane>(acc: Vec3<T>) -> (Quat<T>, T::Mask) {
    let (a, ok) = acc.try_normalize();
    let one = T::one();
    // Shortest arc a → +z, well defined unless a ≈ −z.
    let up = Quat::new(one + a.z, a.y, -a.x, T::zero());
    // a → −z, then 180° about x (which maps −z to +z); well defined unless a ≈ +z.
    let down = Quat::new(T::zero(), one, T::zero(), T::zero())
        * Quat::new(one - a.z, -a.y, a.x, T::zero());
    let q = Quat::select(a.z.simd_ge(T::zero()), up, down).normalize();
    // Both branches carry some rotation about earth-z; inclination alone is what is wanted.
    let (_, incl) = q.heading_inclination();
    (Quat::select(ok, incl.normalize(), Quat::identity()), ok)
}

/// Orientation from gravity and the magnetic field (TRIAD with gravity as the exact vector):
/// earth-up from `acc`, east along `mag × up`, north = up × east (ENU).
///
/// `min_sin_dip` is the smallest accepted sine of the angle between the two vectors: below it
/// (field near vertical or parallel to gravity) the heading is ill-defined and the mask bit
/// is false. The fallback value is [`tilt_from_acc`]'s.
pub fn acc_mag_quat<T: Lane>(acc: Vec3<T>, mag: Vec3<T>, min_sin_dip: T) -> (Quat<T>, T::Mask) {
    let (up, acc_ok) = acc.try_normalize();
    let (m, mag_ok) = mag.try_normalize();
    let east_raw = m.cross(up);
    let (east, _) = east_raw.try_normalize();
    let geometry_ok = east_raw.norm().simd_gt(min_sin_dip);
    let north = up.cross(east);
    // Rows are the earth axes in sensor coordinates: R maps sensor to earth.
    let r = Mat::from_rows([east.to_array(), north.to_array(), up.to_array()]);
    let q = Quat::from_rotation_matrix(&r);
    let ok = acc_ok & mag_ok & geometry_ok;
    let (tilt, _) = tilt_from_acc(acc);
    (Quat::select(ok, q, tilt), ok)
}

/// Tilt-compensated magnetic heading: the rotation about earth-z (rad, counter-clockwise
/// seen from above, `[-π, π]`) that turns the horizontal field of `q.rotate(mag)` onto north
/// (+y in ENU), i.e. `atan2(h_x, h_y)` of the field in the earth frame of `q`.
///
/// Positive means `q` must turn left (counter-clockwise) by that much to point its field
/// north. Returns a false mask where the horizontal field is too weak relative to the total
/// (`|h_xy| < 0.05·|h|`) or the input is not finite.
pub fn magnetic_heading_error<T: Lane>(q: Quat<T>, mag: Vec3<T>) -> (T, T::Mask) {
    field_heading_error(q.rotate(mag))
}

/// [`magnetic_heading_error`] of a field `h` already in the earth frame: `atan2(h_x, h_y)`
/// (rad, `[-π, π]`), with the same mask. Rotating `h` about earth-z by `δ` lowers the result
/// by `δ` (modulo 2π), so a filter that knows `h` in one frame need not rotate it again.
pub fn field_heading_error<T: Lane>(h: Vec3<T>) -> (T, T::Mask) {
    let (_, ok) = horizontal_field(h);
    (T::select(ok, h.x.atan2(h.y), T::zero()), ok)
}

/// Whether an earth-frame field gives a heading: the mask of [`field_heading_error`].
#[inline]
pub(crate) fn heading_field_ok<T: Lane>(h: Vec3<T>) -> T::Mask {
    horizontal_field(h).1
}

/// `|h_xy|²` of an earth-frame field and whether it gives a heading: finite, and at least
/// `0.05·|h|` horizontal (the mask of [`field_heading_error`]).
fn horizontal_field<T: Lane>(h: Vec3<T>) -> (T, T::Mask) {
    let hxy2 = h.x * h.x + h.y * h.y;
    let ok = hxy2.simd_gt(T::from_f64(0.0025) * h.norm_squared())
        & hxy2.is_finite()
        & hxy2.simd_gt(T::zero());
    (hxy2, ok)
}

/// The heading error of an earth-frame field `h` for a feedback loop, in a form whose
/// normalisation the loop can take off its dependency chain: `h_x` clamped to `±hxy_prev`,
/// and `±hxy_prev` (the sign of `h_x`) once the error passes 90° (`h_y < 0`), where
/// `hxy_prev` is `|h_xy|` of an earlier field (0 before the first: no correction). Divided by
/// `hxy_prev` it is the sine of [`field_heading_error`] clamped to `[-1, 1]` (to the factor
/// `|h_xy|/hxy_prev`, about 1 from one sample to the next). Returns it, the `|h_xy|` to pass
/// next time (this field's, or `hxy_prev` where the mask is false) and the mask of
/// [`field_heading_error`] (the value is 0 where it is false).
///
/// A loop that corrects by `sin ψ` gets the angle's gain for small errors without a square
/// root, a division or an `atan2` between the orientation and its correction: it multiplies
/// whatever scales the error by `1/hxy_prev`, known before the sample arrives.
///
/// ```
/// use rootfuse_attitude::Vec3;
/// use rootfuse_attitude::blocks::heading_sine_times_previous;
/// let h = Vec3::new(0.1_f64, 20.0, -40.0); // the field about 0.29° east of north
/// let (first, hxy, ok) = heading_sine_times_previous(h, 0.0);
/// assert!(ok && first == 0.0 && (hxy - h.x.hypot(h.y)).abs() < 1e-12);
/// let (next, _, _) = heading_sine_times_previous(h, hxy);
/// assert!((next / hxy - h.x.atan2(h.y)).abs() < 1e-6);
/// // Past 90° the whole previous |h_xy|, with the error's sign.
/// let (behind, _, _) = heading_sine_times_previous(Vec3::new(-1.0, -20.0, -40.0), hxy);
/// assert_eq!(behind, -hxy);
/// ```
pub fn heading_sine_times_previous<T: Lane>(h: Vec3<T>, hxy_prev: T) -> (T, T, T::Mask) {
    let (hxy2, ok) = horizontal_field(h);
    let sine = h.x.clamp(-hxy_prev, hxy_prev);
    let beyond = T::select(h.x.simd_lt(T::zero()), -hxy_prev, hxy_prev);
    let e = T::select(h.y.simd_lt(T::zero()), beyond, sine);
    (
        T::select(ok, e, T::zero()),
        T::select(ok, hxy2.sqrt(), hxy_prev),
        ok,
    )
}

/// [`magnetic_heading_error`] toward **true** north: the rotation about earth-z (rad,
/// counter-clockwise seen from above, `[-π, π]`) that turns `q` so its horizontal field points
/// at magnetic north, which lies `declination` (rad, **east positive**, the usual sign) east of
/// true north (+y in ENU). `wrap(atan2(h_x, h_y) − declination)` with `h = q.rotate(mag)`.
///
/// With `declination = 0` this equals [`magnetic_heading_error`] bit for bit. Same mask.
pub fn true_heading_error<T: Lane>(q: Quat<T>, mag: Vec3<T>, declination: T) -> (T, T::Mask) {
    let (dpsi, ok) = magnetic_heading_error(q, mag);
    (T::select(ok, (dpsi - declination).wrap_pi(), T::zero()), ok)
}

/// Tilt-compensated true heading from one accelerometer and magnetometer sample: the yaw
/// `ψ` (rad, `[-π, π]`, counter-clockwise about earth-up, 0 when the sensor's +y axis points
/// to true north) such that `qz(ψ) ⊗ q_tilt` is the sensor orientation, where `q_tilt` is the
/// inclination from `acc` ([`tilt_from_acc`]). `declination` is in rad, east positive.
///
/// Closed form for a level sensor at yaw `ψ0` in a field whose horizontal part points
/// `declination` east of true north: returns `ψ0` (see the tests).
///
/// Reading of the source (heading pipeline, S2): its sensor frame (X right, Y forward, Z up) is our
/// sensor frame with ENU, so its "nose left positive" yaw is our counter-clockwise `ψ`. The
/// source levels the magnetometer with the pitch and roll rotations from the accelerometer;
/// here that levelling is the inclination quaternion of [`tilt_from_acc`] (the same angles
/// when the tilt is small, and well defined at any tilt). The source writes
/// `ψ_north = ψ_m + Δψ`, which is the rule for a clockwise bearing `β = −ψ` with an
/// east-positive declination; in the counter-clockwise yaw used here it reads
/// `ψ_true = ψ_mag − Δψ` (the same physical correction, `β_true = β_mag + Δψ`).
///
/// The mask is false where `acc` or the horizontal field is unusable (as in
/// [`tilt_from_acc`] and [`magnetic_heading_error`]); the value is then 0.
pub fn tilt_compensated_heading<T: Lane>(
    acc: Vec3<T>,
    mag: Vec3<T>,
    declination: T,
) -> (T, T::Mask) {
    let (tilt, acc_ok) = tilt_from_acc(acc);
    // Turning the zero-heading tilt left by the error brings the field to magnetic north: that
    // turn is the sensor's own yaw.
    let (psi, mag_ok) = true_heading_error(tilt, mag, declination);
    let ok = acc_ok & mag_ok;
    (T::select(ok, psi, T::zero()), ok)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Below [`ROUNDS_TO_ONE_A2`] the series gives exactly `(1, 1)`, in `f32` and in `f64`,
    /// so [`small_turn_cos_sinc`]'s shortcut changes no bit; just above, it does not (the
    /// limit is not looser than it needs to be by more than a factor of two).
    #[test]
    fn each_value_rounds_to_one_below_the_limit() {
        fn check<T: Lane>(limit: f64, one_ulp_below: f64) {
            let mut a2 = limit;
            while a2 > 1e-300 {
                for x in [a2, a2 * 0.999_999, a2 * 0.7] {
                    let (cos, sinc) = gyro_series(T::from_f64(x));
                    assert!(
                        cos.simd_eq(T::one()).all() && sinc.simd_eq(T::one()).all(),
                        "{x:e}"
                    );
                }
                a2 *= 0.5;
            }
            for x in [0.0, f64::MIN_POSITIVE] {
                let (cos, sinc) = gyro_series(T::from_f64(x));
                assert!(cos.simd_eq(T::one()).all() && sinc.simd_eq(T::one()).all());
            }
            let (cos, _) = gyro_series(T::from_f64(4.0 * limit));
            assert!(cos.simd_le(T::from_f64(one_ulp_below)).all());
        }
        check::<f32>(ROUNDS_TO_ONE_A2[0], 1.0 - f64::from(f32::EPSILON) / 2.0);
        check::<f64>(ROUNDS_TO_ONE_A2[1], 1.0 - f64::EPSILON / 2.0);
        check::<rootfuse_lane::wide::f32x8>(
            ROUNDS_TO_ONE_A2[0],
            1.0 - f64::from(f32::EPSILON) / 2.0,
        );
        // The shortcut and the series agree on both sides of the limit.
        for x in [
            0.0,
            1e-9,
            ROUNDS_TO_ONE_A2[0],
            2.0 * ROUNDS_TO_ONE_A2[0],
            1e-3,
            0.5,
        ] {
            assert_eq!(
                small_turn_cos_sinc(x as f32),
                exp_cos_sinc(x as f32),
                "{x:e}"
            );
            assert_eq!(small_turn_cos_sinc(x), exp_cos_sinc(x), "{x:e}");
        }
    }
}
