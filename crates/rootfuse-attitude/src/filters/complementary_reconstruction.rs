//! Complementary reconstruction (patent CN104101345B) [`complementary-reconstruction`].

use super::LaneParams;
use super::complementary::tilt_correction;
use super::{Dof, OrientationFilter, Rejections, ScreenBounds, Screened, initialise, params};
use super::{StateError, bias_without_covariance, quat_without_covariance};
use crate::blocks::{acc_mag_quat, coning_rotation_vector};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask};

params! {
    /// Parameters of [`ComplementaryReconstruction`].
    pub struct ComplementaryReconstructionParams {
        /// Length of the initial still period (usable time from the first sample) over which
        /// the gyro bias, the accelerometer statistics and the static maxima are taken.
        still_s: f64 = 1.0, "s", [0.0, 10000.0];
        /// 1: two-sample coning correction of the rotation vector; 0: `Φ = ω·T`.
        coning: bool = 1.0, "1", [0.0, 1.0];
        /// Motion parameter rule: 0 = the source's literal `|ωx|, |ωy|, |ωz|, |ax|, |ay|` (a
        /// level carrier); 1 = gravity removed: `|ω|` axes, `|‖a‖ − g|` and the horizontal
        /// specific force.
        alpha_rule: u32 = 1.0, "1", [0.0, 1.0];
        /// A fixed blend weight α of the gyro quaternion in `[0, 1]`; negative: adaptive α.
        alpha_fixed: f64 = -1.0, "1", [-1.0, 1.0], shared;
        /// 1: subtract the still-period mean of ax and ay from the accelerometer (the source's
        /// offset correction, valid only if the carrier is level then); 0: do not.
        acc_offsets: bool = 0.0, "1", [0.0, 1.0];
        /// Floor of the static gyro maximum `ω_static_max` (an ideal sensor reads 0 at rest).
        min_static_rate: f64 = 0.01, "rad/s", [1e-9, 100.0];
        /// Floor of the static accelerometer maximum `a_static_max`.
        min_static_acc: f64 = 0.05, "m/s²", [1e-9, 1000.0];
        /// 9: heading from the magnetometer; 6: gravity only (heading from the gyroscope).
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// Complementary reconstruction (CN104101345B). Gyro propagation by the rotation vector,
/// `Q(t_k) = Q'(t_{k−1}) ⊗ q(h)`, `q(h) = [cos(|Φ|/2), sin(|Φ|/2)·Φ/|Φ|]`; an observed
/// quaternion `Q̂` from the accelerometer (pitch, roll) and the tilt-compensated magnetometer
/// (heading) through the direction-cosine matrix; the reconstruction
/// `Q'(t_k) = normalise(α·Q(t_k) + (1 − α)·Q̂(t_k))` with the motion parameter
/// `α = m/(m + 1)`, `m = max(Kω·|ωx|, Kω·|ωy|, Kω·|ωz|, Ka·|ax|, Ka·|ay|)`,
/// `Kω = 1/ω_static_max`, `Ka = 1/a_static_max`.
///
/// Reading of the source:
/// - "initial still period": the first `still_s` seconds of usable samples are taken as still
///   (the source samples "several times" before starting); during them the gyro bias, the
///   accelerometer means and the largest static deviations are accumulated online while the
///   method has not started (the source samples them "in advance"): the first sample's
///   attitude is propagated by the uncorrected gyro alone (α = 1); after them the estimates
///   are frozen and applied and the blend starts;
/// - `ω_static_max` / `a_static_max` are the largest absolute deviations from the still-period
///   means (the readings after the offset correction), floored by `min_static_rate` /
///   `min_static_acc` so an ideal sensor does not give an infinite `K`;
/// - the accelerometer x/y offset correction (z keeps gravity) only holds for a level carrier;
///   it is the `acc_offsets` option, off by default; the literal α rule always uses the
///   deviations of ax, ay from their still-period means;
/// - the α variant (`alpha_rule = 1`) replaces `|ax|, |ay|` by `|‖a‖ − g|` (`g` = the
///   still-period mean norm) and the horizontal part of the specific force seen through the
///   gyro quaternion `Q(t_k)`, with `a_static_max` the largest still-period deviation of the
///   accelerometer vector from its mean;
/// - the rate samples are point values at the interval ends: with coning correction the two
///   half-interval increments of the linear (trapezoid) rate model give
///   `Φ = Δθ1 + Δθ2 + ⅔·Δθ1 × Δθ2 = T·(ω_{k−1} + ω_k)/2 + (T²/12)·ω_{k−1} × ω_k`; without, `Φ = ω_k·T`;
/// - the patent's matrix `M'[q(h)]` is the update written for its product convention; in the
///   project's convention (sensor to earth, body rates right-multiplied) it is `Q' ⊗ q(h)`;
/// - the observation's DCM → quaternion step is the largest-pivot (Shepperd) form of the
///   patent's `|q_i| = ½·√(1 ± T11 ± T22 ± T33)` ([`acc_mag_quat`]); the "filtering" of the
///   accelerometer angles is not specified and none is added (the α blend is the low-pass);
/// - the source leaves the sign of `Q̂` free: it is aligned to `Q`'s hemisphere before the
///   blend (averaging antipodal quaternions would cancel them);
/// - in 6D, and in 9D where the field is unusable, `Q̂` is `Q(t_k)` turned about a horizontal
///   earth axis until its predicted gravity matches the measured one: the gyro heading is
///   kept (a swing-twist split of `Q` into heading and tilt would be ill-defined near upside
///   down).
#[derive(Clone, Debug)]
pub struct ComplementaryReconstruction<T: Lane> {
    q: Quat<T>,
    initialized: T::Mask,
    prev_gyr: Vec3<T>,
    has_prev: T::Mask,
    alpha: T,
    still: Still<T>,
    still_s: T,
    coning: bool,
    literal: bool,
    alpha_fixed: Option<T>,
    acc_offsets: bool,
    min_rate: T,
    min_acc: T,
    nine_d: bool,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    params: ComplementaryReconstructionParams,
}

/// Online statistics of the still period and the estimates frozen at its end.
#[derive(Clone, Copy, Debug)]
struct Still<T: Lane> {
    elapsed: T,
    n_gyr: T,
    n_acc: T,
    gyr_sum: Vec3<T>,
    gyr_max: Vec3<T>,
    gyr_min: Vec3<T>,
    acc_sum: Vec3<T>,
    acc_max: Vec3<T>,
    acc_min: Vec3<T>,
    norm_sum: T,
    norm_max: T,
    norm_min: T,
    /// Gyro bias, rad/s (applied after the still period).
    bias: Vec3<T>,
    /// Mean accelerometer over the still period, m/s².
    acc_mean: Vec3<T>,
    /// Mean accelerometer norm over the still period, m/s².
    gravity: T,
    /// Largest static gyro deviation, rad/s.
    rate_max: T,
    /// Largest static ax/ay deviation, m/s² (literal rule).
    acc_xy_max: T,
    /// Largest static accelerometer vector or norm deviation, m/s² (variant).
    acc_vec_max: T,
}

impl<T: Lane> Still<T> {
    fn new() -> Self {
        let (inf, zero) = (T::from_f64(f64::INFINITY), T::zero());
        let v = |x: T| Vec3::new(x, x, x);
        Self {
            elapsed: zero,
            n_gyr: zero,
            n_acc: zero,
            gyr_sum: Vec3::zero(),
            gyr_max: v(-inf),
            gyr_min: v(inf),
            acc_sum: Vec3::zero(),
            acc_max: v(-inf),
            acc_min: v(inf),
            norm_sum: zero,
            norm_max: -inf,
            norm_min: inf,
            bias: Vec3::zero(),
            acc_mean: Vec3::zero(),
            gravity: T::from_f64(9.81),
            rate_max: zero,
            acc_xy_max: zero,
            acc_vec_max: zero,
        }
    }

    /// Adds a sample where `active` (gyro) and `active & acc_ok` (accelerometer, `acc` the
    /// raw specific force) and refreshes the estimates there.
    fn accumulate(&mut self, active: T::Mask, s: &Screened<T>, acc: Vec3<T>) -> Self {
        let mut n = *self;
        let one = T::one();
        let acc_in = active & s.acc_ok;
        n.elapsed += s.dt;
        n.n_gyr += one;
        n.gyr_sum += s.gyr;
        n.gyr_max = vmax(n.gyr_max, s.gyr);
        n.gyr_min = vmin(n.gyr_min, s.gyr);
        n.n_acc += one;
        n.acc_sum += acc;
        n.acc_max = vmax(n.acc_max, acc);
        n.acc_min = vmin(n.acc_min, acc);
        n.norm_sum += s.acc_norm;
        n.norm_max = n.norm_max.max(s.acc_norm);
        n.norm_min = n.norm_min.min(s.acc_norm);

        n.bias = n.gyr_sum * (one / n.n_gyr);
        let spread = |max: Vec3<T>, min: Vec3<T>, mean: Vec3<T>| vmax(max - mean, mean - min);
        let dg = spread(n.gyr_max, n.gyr_min, n.bias);
        n.rate_max = dg.x.max(dg.y).max(dg.z);
        n.acc_mean = n.acc_sum * (one / n.n_acc);
        n.gravity = n.norm_sum / n.n_acc;
        let da = spread(n.acc_max, n.acc_min, n.acc_mean);
        n.acc_xy_max = da.x.max(da.y);
        let dn = (n.norm_max - n.gravity).max(n.gravity - n.norm_min);
        n.acc_vec_max = da.norm().max(dn);

        // The gyro statistics move wherever active; the accelerometer ones only with a usable
        // accelerometer.
        let mut out = *self;
        out.elapsed = T::select(active, n.elapsed, out.elapsed);
        out.n_gyr = T::select(active, n.n_gyr, out.n_gyr);
        out.gyr_sum = Vec3::select(active, n.gyr_sum, out.gyr_sum);
        out.gyr_max = Vec3::select(active, n.gyr_max, out.gyr_max);
        out.gyr_min = Vec3::select(active, n.gyr_min, out.gyr_min);
        out.bias = Vec3::select(active, n.bias, out.bias);
        out.rate_max = T::select(active, n.rate_max, out.rate_max);
        out.n_acc = T::select(acc_in, n.n_acc, out.n_acc);
        out.acc_sum = Vec3::select(acc_in, n.acc_sum, out.acc_sum);
        out.acc_max = Vec3::select(acc_in, n.acc_max, out.acc_max);
        out.acc_min = Vec3::select(acc_in, n.acc_min, out.acc_min);
        out.norm_sum = T::select(acc_in, n.norm_sum, out.norm_sum);
        out.norm_max = T::select(acc_in, n.norm_max, out.norm_max);
        out.norm_min = T::select(acc_in, n.norm_min, out.norm_min);
        out.acc_mean = Vec3::select(acc_in, n.acc_mean, out.acc_mean);
        out.gravity = T::select(acc_in, n.gravity, out.gravity);
        out.acc_xy_max = T::select(acc_in, n.acc_xy_max, out.acc_xy_max);
        out.acc_vec_max = T::select(acc_in, n.acc_vec_max, out.acc_vec_max);
        out
    }
}

#[inline]
fn vmax<T: Lane>(a: Vec3<T>, b: Vec3<T>) -> Vec3<T> {
    Vec3::new(a.x.max(b.x), a.y.max(b.y), a.z.max(b.z))
}
#[inline]
fn vmin<T: Lane>(a: Vec3<T>, b: Vec3<T>) -> Vec3<T> {
    Vec3::new(a.x.min(b.x), a.y.min(b.y), a.z.min(b.z))
}

impl<T: Lane> ComplementaryReconstruction<T> {
    crate::filters::uniform_constructors!(ComplementaryReconstructionParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(p: &LaneParams<'_, ComplementaryReconstructionParams, T>) -> Self {
        Self {
            q: Quat::identity(),
            initialized: <T::Mask as Mask>::splat(false),
            prev_gyr: Vec3::zero(),
            has_prev: <T::Mask as Mask>::splat(false),
            alpha: T::zero(),
            still: Still::new(),
            still_s: p.coef(|p| p.still_s),
            coning: p.first().coning,
            literal: p.first().alpha_rule == 0,
            alpha_fixed: (p.first().alpha_fixed >= 0.0).then(|| p.coef(|p| p.alpha_fixed)),
            acc_offsets: p.first().acc_offsets,
            min_rate: p.coef(|p| p.min_static_rate),
            min_acc: p.coef(|p| p.min_static_acc),
            nine_d: p.first().dof.uses_magnetometer(),
            bounds: p.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            params: p.first().clone(),
        }
    }
    /// The blend weight α of the gyro quaternion used by the last update (0: observation only,
    /// 1: gyro only).
    pub fn alpha(&self) -> T {
        self.alpha
    }

    /// The rotation vector over one interval from the bias-corrected rates at its ends.
    fn rotation_vector(&self, w_prev: Vec3<T>, w: Vec3<T>, dt: T) -> Vec3<T> {
        if self.coning {
            // Linear rate over the interval: the increments of its two halves.
            let k = dt * T::from_f64(0.125);
            let d1 = (w_prev * T::from_f64(3.0) + w) * k;
            let d2 = (w_prev + w * T::from_f64(3.0)) * k;
            coning_rotation_vector(d1, d2)
        } else {
            w * dt
        }
    }

    /// The motion parameter `m` of the rule in use.
    fn motion(&self, w: Vec3<T>, acc: Vec3<T>, q: Quat<T>) -> T {
        let st = &self.still;
        let k_w = T::one() / st.rate_max.max(self.min_rate);
        let m_w = w.x.abs().max(w.y.abs()).max(w.z.abs()) * k_w;
        let m_a = if self.literal {
            let d = acc - st.acc_mean;
            d.x.abs().max(d.y.abs()) / st.acc_xy_max.max(self.min_acc)
        } else {
            let a = q.rotate(acc);
            let horizontal = (a.x * a.x + a.y * a.y).sqrt();
            let norm = (acc.norm() - st.gravity).abs();
            horizontal.max(norm) / st.acc_vec_max.max(self.min_acc)
        };
        m_w.max(m_a)
    }
}

impl<T: Lane> OrientationFilter<T> for ComplementaryReconstruction<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let acc_raw = s.acc * s.acc_norm;
        let still = self.still.elapsed.simd_lt(self.still_s) & s.step;
        // Uniform across lanes, so results are unchanged: after the still period skip the work.
        if still.any() {
            self.still = self.still.accumulate(still, &s, acc_raw);
        }
        let q0 = initialise(self.q, &mut self.initialized, &s, self.nine_d);

        let bias = Vec3::select(still, Vec3::zero(), self.still.bias);
        let w = s.gyr - bias;
        let w_prev = Vec3::select(self.has_prev, self.prev_gyr - bias, w);
        let q =
            (q0 * Quat::from_rotation_vector(self.rotation_vector(w_prev, w, s.dt))).normalize();

        let offset = Vec3::new(self.still.acc_mean.x, self.still.acc_mean.y, T::zero());
        let acc = if self.acc_offsets {
            acc_raw - Vec3::select(still, Vec3::zero(), offset)
        } else {
            acc_raw
        };
        // Gravity alone: `Q` turned about a horizontal axis until its predicted gravity matches
        // the measured one, so the heading of `Q` is kept (no swing-twist split, which is
        // ill-defined near upside down).
        let (a_unit, tilt_ok) = acc.try_normalize();
        let tilt = tilt_correction(q.rotate(a_unit));
        let mut q_obs = (Quat::from_rotation_vector(tilt) * q).normalize();
        if self.nine_d {
            let (am, am_ok) = acc_mag_quat(acc, s.mag, T::from_f64(0.1));
            q_obs = Quat::select(am_ok & s.mag_ok, am, q_obs);
        }
        let obs_ok = s.acc_ok & tilt_ok;

        let alpha = match self.alpha_fixed {
            Some(a) => a,
            None => {
                let m = self.motion(w, acc, q);
                let a = T::one() - T::one() / (m + T::one());
                T::select(a.is_finite(), a, T::one())
            }
        };
        // The method starts after the still period: until then the gyro alone propagates.
        let alpha = T::select(still, T::one(), alpha);
        // nlerp weights `self` by 1 − t and the hemisphere-aligned `other` by t.
        let blended = q.nlerp(q_obs, T::one() - alpha);
        let q_new = Quat::select(obs_ok, blended, q);

        self.q = Quat::select(s.step, q_new, self.q);
        self.alpha = T::select(s.step, T::select(obs_ok, alpha, T::one()), self.alpha);
        self.prev_gyr = Vec3::select(s.step, s.gyr, self.prev_gyr);
        self.has_prev |= s.step;
    }
    fn reset(&mut self) {
        self.q = Quat::identity();
        self.initialized = <T::Mask as Mask>::splat(false);
        self.prev_gyr = Vec3::zero();
        self.has_prev = <T::Mask as Mask>::splat(false);
        self.alpha = T::zero();
        self.still = Still::new();
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
    fn bias(&self) -> Vec3<T> {
        self.still.bias
    }
    /// Replaces the still-period mean once the still period is over (in every lane); refused
    /// (and nothing changed) during it, while the mean is being taken.
    fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
        let bias = bias_without_covariance(bias, sigma)?;
        if self.still.elapsed.simd_lt(self.still_s).any() {
            return Err(StateError::Unsupported(
                "gyro-bias estimate yet (its still period is taking the mean)",
            ));
        }
        self.still.bias = bias;
        Ok(())
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
}
