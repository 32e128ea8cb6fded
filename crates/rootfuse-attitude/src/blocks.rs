//! Building blocks: orientation from gravity and the magnetic field, gyro integration, the
//! first-order low-pass gain.
//!
//! All functions return a per-lane validity mask instead of failing: a zero, NaN or infinite
//! vector, or a degenerate geometry, gives a finite fallback value and a false mask bit.

use crate::quat::Quat;
use crate::vec3::Vec3;
use rootfuse_lane::{Lane, Mask, Mat};

/// Below this `a² = |ω·dt/2|²` (rad², i.e. `a < 0.1`, 1150 °/s at 100 Hz) [`integrate_gyro`]
/// takes `cos a` and `sin a / a` from their Taylor series in `a²`. Through the `a⁸` terms the
/// truncation error is below `a¹⁰/10! < 3e-17` (under one ulp of f64), so the series is as
/// accurate as the trigonometric path, and it needs no square root, range reduction or
/// division.
pub const GYRO_SERIES_A2: f64 = 0.01;

/// Integrates body rates over `dt` by the exact exponential map:
/// `q ⊗ exp(ω·dt/2)`, renormalised. `omega` in rad/s (sensor frame), `dt` in s.
///
/// The rule, per lane: where `a² = |ω·dt/2|² < `[`GYRO_SERIES_A2`] the exponential's
/// `cos a` and `sin a / a` come from their series in `a²`, elsewhere from [`Quat::exp`]. When
/// every lane is below the limit (the usual case) only the series is computed; otherwise both
/// are and each lane selects by its own `a²`, so a lane's result does not depend on its
/// neighbours and equals the scalar result bit for bit.
#[inline]
pub fn integrate_gyro<T: Lane>(q: Quat<T>, omega: Vec3<T>, dt: T) -> Quat<T> {
    // `dt/2` first: halving is exact, so this is `ω·dt·½` bit for bit with one multiply
    // fewer on the dependency chain through `ω` (`dt` does not depend on the state).
    let v = omega * (dt * T::from_f64(0.5));
    let a2 = v.norm_squared();
    let small = a2.simd_lt(T::from_f64(GYRO_SERIES_A2));
    let c = |x: f64| T::from_f64(x);
    // Horner in a²: cos a = 1 − a²/2! + a⁴/4! − a⁶/6! + a⁸/8!,
    // sin a / a = 1 − a²/3! + a⁴/5! − a⁶/7! + a⁸/9!.
    let cos = T::one()
        + a2 * (c(-1.0 / 2.0)
            + a2 * (c(1.0 / 24.0) + a2 * (c(-1.0 / 720.0) + a2 * c(1.0 / 40320.0))));
    let sinc = T::one()
        + a2 * (c(-1.0 / 6.0)
            + a2 * (c(1.0 / 120.0) + a2 * (c(-1.0 / 5040.0) + a2 * c(1.0 / 362880.0))));
    let series = Quat::from_parts(cos, v * sinc);
    let e = if small.all() {
        series
    } else {
        Quat::select(small, series, Quat::exp(v))
    };
    (q * e).renormalize()
}

/// The exact discrete gain `k = 1 − exp(−dt/τ)` of a first-order low-pass
/// `y ← y + k·(x − y)` with time constant `tau` (s) over a step `dt` (s): the one low-pass
/// discretisation of every filter in this crate.
///
/// It is exact for every `dt/τ` from 0 to ∞: `k = −expm1(−x)`, `x = dt/τ`, computed in `f64`
/// and rounded once to the lane's precision, so a small `x` keeps its digits (`1 − exp` would
/// cancel) and a large one gives 1 rather than diverging. For `x ≤ 1/8` (every filter's usual
/// case: `dt` of milliseconds against `τ` of tenths of a second and more) it is the Taylor
/// series through `x¹²` by Horner (the first dropped term is below 3·10⁻¹⁹ of the result),
/// and `f64` lanes evaluate it in SIMD: a sample rate with jitter, which changes `dt` at
/// every sample, costs a dozen multiply-adds per gain instead of a libm call per lane.
/// Larger `x` calls libm's `expm1`. Against `−expm1(−x)` the result is within one rounding
/// in `f32` and a few ulp in `f64` (the tests bound 4). Each lane is computed on its own, so
/// a lane equals the scalar result bit for bit.
///
/// Special values, per lane:
/// - `tau = 0` means **no low-pass**: `k = 1` (the output is the input) for any `dt > 0`;
///   a negative or NaN `tau` is treated the same way (parameters never give one);
/// - `dt ≤ 0` or NaN (no time passed, a skipped sample): `k = 0`, nothing is taken in, also
///   for `tau = 0`;
/// - `tau = ∞`: `k = 0` (the output holds); `dt = ∞` with a finite `tau`: `k = 1`.
///
/// ```
/// use rootfuse_attitude::blocks::lowpass_gain;
/// assert_eq!(lowpass_gain(0.01_f64, 0.0), 1.0);
/// assert_eq!(lowpass_gain(0.0_f64, 0.0), 0.0);
/// // 1 − exp(−1e-9) = 1e-9 − 5e-19 + …: every digit kept (`1.0 - (-1e-9).exp()` keeps 7).
/// assert!((lowpass_gain(1e-9_f64, 1.0) - (1e-9 - 5e-19)).abs() < 1e-24);
/// ```
#[inline]
pub fn lowpass_gain<T: Lane>(dt: T, tau: T) -> T {
    // f64 lanes: the series in SIMD when every lane is in its range. The per-lane path below
    // gives each lane the same operations in the same order, so the bits agree either way.
    if core::mem::size_of::<T::Scalar>() == core::mem::size_of::<f64>() {
        let x = dt / tau;
        let series = dt.simd_gt(T::zero())
            & tau.simd_gt(T::zero())
            & x.simd_le(T::from_f64(GAIN_SERIES_LIMIT));
        if series.all() {
            return gain_series(x);
        }
    } else if T::LANES > 1 && T::LANES <= MAX_SERIES_LANES {
        // f32 lanes: the same f64 series as the scalar path, over an array of the lanes'
        // `dt/τ` that the compiler vectorises (a jittered `dt` changes every lane's gain at
        // every sample, and lane-by-lane calls cost more than the filter's arithmetic).
        let mut x = [0.0f64; MAX_SERIES_LANES];
        let mut series = true;
        for (i, x) in x.iter_mut().enumerate().take(T::LANES) {
            let (d, t): (f64, f64) = (dt.extract(i).into(), tau.extract(i).into());
            *x = d / t;
            series &= d > 0.0 && t > 0.0 && *x <= GAIN_SERIES_LIMIT;
        }
        if series {
            for x in &mut x {
                *x = gain_series(*x);
            }
            return T::from_fn(|i| <T::Scalar as Lane>::from_f64(x[i]));
        }
    }
    T::from_fn(|i| {
        <T::Scalar as Lane>::from_f64(scalar_gain(dt.extract(i).into(), tau.extract(i).into()))
    })
}

/// The widest lane type (`f32x8` doubled) whose gains [`lowpass_gain`] evaluates as one array.
const MAX_SERIES_LANES: usize = 16;

/// The largest `x = dt/τ` [`lowpass_gain`] takes from its series.
const GAIN_SERIES_LIMIT: f64 = 0.125;

/// `−expm1(−x) = Σ (−1)ⁿ⁺¹ xⁿ/n!`: the coefficients of `x¹ … x¹²`.
const GAIN_SERIES: [f64; 12] = [
    1.0,
    -1.0 / 2.0,
    1.0 / 6.0,
    -1.0 / 24.0,
    1.0 / 120.0,
    -1.0 / 720.0,
    1.0 / 5040.0,
    -1.0 / 40320.0,
    1.0 / 362880.0,
    -1.0 / 3628800.0,
    1.0 / 39916800.0,
    -1.0 / 479001600.0,
];

/// The series of [`GAIN_SERIES`] at `x` (Horner), in the arithmetic of `L`.
#[inline]
fn gain_series<L: Lane>(x: L) -> L {
    let mut p = L::from_f64(GAIN_SERIES[11]);
    for &c in GAIN_SERIES[..11].iter().rev() {
        p = p * x + L::from_f64(c);
    }
    p * x
}

/// One lane of [`lowpass_gain`], in `f64`.
#[inline]
fn scalar_gain(dt: f64, tau: f64) -> f64 {
    // NaN lands on the documented side: a NaN `dt` takes nothing in, a NaN `tau` is no
    // low-pass.
    if dt > 0.0 {
        if tau > 0.0 {
            let x = dt / tau;
            if x <= GAIN_SERIES_LIMIT {
                gain_series(x)
            } else {
                -libm::expm1(-x)
            }
        } else {
            1.0
        }
    } else {
        0.0
    }
}

/// A [`lowpass_gain`] for one time constant, per lane, cached for the `dt` it was last
/// computed for: with a constant sample rate (the usual case) the exponential is evaluated
/// once instead of every sample. The cache is exact (the same bits as a fresh computation),
/// so it changes no result.
#[derive(Clone, Copy, Debug)]
pub struct LowPassGain<T: Lane> {
    tau: T,
    dt: T,
    gain: T,
}

impl<T: Lane> LowPassGain<T> {
    /// The gain of time constant `tau` (s, per lane; 0 = no low-pass, see [`lowpass_gain`]).
    pub fn new(tau: T) -> Self {
        Self {
            tau,
            dt: T::zero(),
            gain: lowpass_gain(T::zero(), tau),
        }
    }
    /// The time constant, s.
    pub fn tau(&self) -> T {
        self.tau
    }
    /// `1 − exp(−dt/τ)` per lane for a step `dt` (s); recomputed only when a lane's `dt`
    /// differs from the last one's.
    #[inline]
    pub fn gain(&mut self, dt: T) -> T {
        if dt.simd_ne(self.dt).any() {
            self.dt = dt;
            self.gain = lowpass_gain(dt, self.tau);
        }
        self.gain
    }
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
    let hxy2 = h.x * h.x + h.y * h.y;
    let ok = hxy2.simd_gt(T::from_f64(0.0025) * h.norm_squared())
        & hxy2.is_finite()
        & hxy2.simd_gt(T::zero());
    (T::select(ok, h.x.atan2(h.y), T::zero()), ok)
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
