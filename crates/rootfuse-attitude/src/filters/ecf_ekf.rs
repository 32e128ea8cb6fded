//! A quaternion EKF observing an explicit complementary filter (a patent) [`ecf-ekf`].

use super::LaneParams;
use super::ekf::{State, set_bias_variance};
use super::{
    Dof, OrientationFilter, Rejections, ScreenBounds, Screened, initialise, mag_reference, params,
    up,
};
use super::{StateError, checked_bias, checked_sigma, quat_without_covariance};
use crate::preprocess::MovingMean;
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat};

/// Capacity of the moving-average windows (the `window` parameter's upper bound).
const MAX_WINDOW: usize = 32;

params! {
    /// Parameters of [`EcfEkf`].
    pub struct EcfEkfParams {
        /// Moving-average window on all nine axes, samples (1 = no pre-processing). The source
        /// uses 10 at 500 Hz (a 20 ms span); the default 2 is that span at 100 Hz.
        window: u32 = 2.0, "samples", [1.0, 32.0];
        /// Proportional gain of the complementary filter.
        kp: f64 = 3.0, "rad/s", [0.0, 100.0];
        /// Integral gain of the complementary filter.
        ki: f64 = 0.01, "rad/s²", [0.0, 100.0];
        /// Largest magnitude of the complementary filter's integral term (anti-windup).
        max_bias: f64 = 0.2, "rad/s", [0.0, 10.0];
        /// Gyroscope white-noise density of the EKF.
        gyr_noise: f64 = 0.005, "rad/s/√Hz", [1e-9, 10.0];
        /// Gyro-bias random-walk density of the EKF.
        bias_walk: f64 = 2e-5, "rad/s²/√Hz", [0.0, 10.0];
        /// Initial standard deviation of each EKF gyro-bias component.
        init_bias_std: f64 = 0.003, "rad/s", [1e-9, 10.0];
        /// Standard deviation of each component of the observed (complementary-filter) quaternion.
        obs_noise: f64 = 0.002, "1", [1e-6, 10.0];
        /// 9: use the magnetometer; 6: gravity only (heading from the gyroscope).
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// After Zheng et al. (patent, 2019): a moving average, an explicit complementary filter (ECF,
/// Mahony) with accelerometer and magnetometer, and a 7-state EKF `x = [q0..q3, bx, by, bz]`
/// that takes the ECF quaternion as its observation (`H = [I4, 0]`); the output is the EKF
/// quaternion.
///
/// - Pre-processing: moving mean over the last `window` samples (step 1) on each of the nine
///   axes ([`MovingMean`]), causal.
/// - ECF: `v̂ = q* ⊗ up ⊗ q`, `h = q ⊗ m̂ ⊗ q*`, `b = [0, √(hx² + hy²), hz]` (ENU, north
///   along y), `ŵ = q* ⊗ b ⊗ q`, `e = â × v̂ + m̂ × ŵ`, `ω_c = ω + Kp·e + Ki·∫e dt`,
///   `q ← normalise(q + (T/2)·q ⊗ [0, ω_c])` (first-order Runge–Kutta).
/// - EKF: prediction and covariance propagation as in [`Ekf`](super::Ekf) (shared code),
///   `F = [[I + (T/2)·Ω(ω − b), −(T/2)·Ξ(q)], [0, I3]]`, `Q = ΓWΓᵀ`; update with
///   `z` = the ECF quaternion, `H = [I4, 0]`, `R = obs_noise²·I4`, Joseph form.
///
/// Reading of the source:
/// - the formula images are lost; the ECF is Mahony, Hamel & Pflimlin (2008) in the paper's
///   own form `e = â × v̂ + m̂ × ŵ` (not our [`Mahony`](super::Mahony)'s heading-error form),
///   with its weak heading gain `cos²(dip)` kept;
/// - the integral term is bounded in magnitude by `max_bias` (anti-windup; the source has
///   none, but without it a large start error winds the integral up);
/// - both the ECF and the EKF run on the pre-processed gyroscope; both start from the first
///   usable sample's gravity (and field) orientation;
/// - the EKF transition is the exact exponential map `q ⊗ exp((ω − b)·T/2)`, whose first-order
///   truncation is the source's `(I + (T/2)·Ω(ω − b))·q`; `F` is the same;
/// - the observed quaternion is sign-aligned to the EKF prediction's hemisphere before the
///   residual `z − q` is formed (the source leaves the sign free: `q` and `−q` are one
///   orientation, and a residual across hemispheres would be near 2);
/// - `R`, `Kp`, `Ki` and the noise densities are not given (images lost): they are parameters
///   with defaults chosen here (on simulated data: the EKF follows the ECF closely, since with
///   a loose `R` its bias state learns the ECF's start-up transient as gyro bias);
/// - the window: the source's 10 samples are at 500 Hz; a causal moving mean of `N` samples
///   delays the attitude by `(N − 1)/2` samples, 45 ms for 10 at 100 Hz (about 2° at
///   0.8 rad/s), so the default keeps the source's 20 ms span at 100 Hz (2 samples);
///   `window=10` is the source's count;
/// - a sample whose gyroscope or `dt` is unusable is skipped, but the moving means are fed the
///   last usable value of that axis (sample-and-hold), so the window stays full;
/// - in 6D the ECF has only the gravity term, the heading comes from the gyroscope.
#[derive(Clone, Debug)]
pub struct EcfEkf<T: Lane> {
    means: [MovingMean<T, MAX_WINDOW>; 9],
    ecf_q: Quat<T>,
    integral: Vec3<T>,
    x: State<T>,
    initialized: T::Mask,
    kp: T,
    ki: T,
    max_bias: T,
    gyr_var: T,
    bias_var: T,
    obs_var: T,
    nine_d: bool,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    /// `init_bias_std²`, rad²/s², for `reset`.
    init_bias_var: T,
    params: EcfEkfParams,
}

impl<T: Lane> EcfEkf<T> {
    crate::filters::uniform_constructors!(EcfEkfParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(p: &LaneParams<'_, EcfEkfParams, T>) -> Self {
        let window = p.first().window as usize;
        let init_bias_var = p.coef(|p| p.init_bias_std * p.init_bias_std);
        Self {
            means: core::array::from_fn(|_| MovingMean::with_len(window)),
            ecf_q: Quat::identity(),
            integral: Vec3::zero(),
            x: State::new(init_bias_var),
            initialized: <T::Mask as Mask>::splat(false),
            kp: p.coef(|p| p.kp),
            ki: p.coef(|p| p.ki),
            max_bias: p.coef(|p| p.max_bias),
            gyr_var: p.coef(|p| p.gyr_noise * p.gyr_noise),
            bias_var: p.coef(|p| p.bias_walk * p.bias_walk),
            obs_var: p.coef(|p| p.obs_noise * p.obs_noise),
            nine_d: p.first().dof.uses_magnetometer(),
            bounds: p.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            init_bias_var,
            params: p.first().clone(),
        }
    }
    /// The complementary filter's own orientation (the EKF's observation), sensor to earth.
    pub fn ecf_quat(&self) -> Quat<T> {
        self.ecf_q
    }
    /// The 7×7 EKF covariance (quaternion components, then bias).
    pub fn covariance(&self) -> &Mat<T, 7, 7> {
        &self.x.p
    }

    /// Moving mean of the usable parts of `sample`; unusable axes feed NaN, which the means
    /// replace by their last finite input.
    fn smooth(&mut self, sample: &ImuSample<T>, s: &Screened<T>) -> ImuSample<T> {
        let nan = T::from_f64(f64::NAN);
        let vectors = [
            (sample.gyr, s.step),
            (sample.acc, s.acc_ok),
            (sample.mag, s.mag_ok),
        ];
        let mut out = [Vec3::zero(); 3];
        for ((v, ok), (dst, means)) in vectors
            .into_iter()
            .zip(out.iter_mut().zip(self.means.chunks_exact_mut(3)))
        {
            let [x, y, z] = v.to_array().map(|c| T::select(ok, c, nan));
            *dst = Vec3::new(means[0].update(x), means[1].update(y), means[2].update(z));
        }
        ImuSample::new(out[0], out[1], out[2])
    }

    /// One ECF step from `q` with the screened, smoothed sample; returns the new orientation
    /// and integral.
    fn ecf(&self, q: Quat<T>, s: &Screened<T>) -> (Quat<T>, Vec3<T>) {
        let v_hat = q.rotate_inverse(up());
        let mut e = Vec3::select(s.acc_ok, s.acc.cross(v_hat), Vec3::zero());
        // 6D is the same for every lane and discards this term: skipping it changes no bits.
        if self.nine_d {
            let w_hat = q.rotate_inverse(mag_reference(q, s.mag));
            e += Vec3::select(s.mag_ok, s.mag.cross(w_hat), Vec3::zero());
        }
        let integral = self.integral + e * s.dt;
        // Anti-windup: the correction Ki·∫e stays on the ball of radius max_bias.
        let correction = integral * self.ki;
        let n = correction.norm();
        let integral = integral * (self.max_bias / n.max(self.max_bias));
        let omega = s.gyr + e * self.kp + integral * self.ki;
        let dq = q * Quat::pure(omega * (s.dt * T::from_f64(0.5)));
        ((q + dq).normalize(), integral)
    }
}

impl<T: Lane> OrientationFilter<T> for EcfEkf<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let raw = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let smoothed = self.smooth(sample, &raw);
        let mut scratch = Rejections::default();
        let mut s = Screened::for_dof(&smoothed, dt, &self.bounds, &mut scratch, self.nine_d);
        s.step = raw.step;
        s.dt = raw.dt;
        s.gyr = Vec3::select(raw.step, s.gyr, Vec3::zero());
        s.acc_ok &= raw.step;
        s.mag_ok &= raw.step;

        let was_initialized = self.initialized;
        let q0 = initialise(self.ecf_q, &mut self.initialized, &s, self.nine_d);
        let fresh = self.initialized & !was_initialized;
        let (ecf_q, integral) = self.ecf(q0, &s);

        let mut x = self.x;
        x.q = Quat::select(fresh, q0, x.q);
        let x = x.predict(s.gyr, s.dt, self.gyr_var, self.bias_var);
        let z = ecf_q.align_to(x.q);
        let y = (z - x.q).to_array();
        let mut h = Mat::<T, 4, 7>::zeros();
        for i in 0..4 {
            h.m[i][i] = T::one();
        }
        let r = Mat::<T, 4, 4>::identity().scale(self.obs_var);
        let (x, accept) = x.update(&h, &Mat::from_column(y), &r, s.step);
        self.rejections.gate(s.step & !accept);

        self.ecf_q = Quat::select(s.step, ecf_q, self.ecf_q);
        self.integral = Vec3::select(s.step, integral, self.integral);
        self.x.q = Quat::select(s.step, x.q, self.x.q);
        self.x.bias = Vec3::select(s.step, x.bias, self.x.bias);
        self.x.p = Mat::select(s.step, &x.p, &self.x.p);
    }
    fn reset(&mut self) {
        let window = self.params.window as usize;
        self.means = core::array::from_fn(|_| MovingMean::with_len(window));
        self.ecf_q = Quat::identity();
        self.integral = Vec3::zero();
        self.x = State::new(self.init_bias_var);
        self.initialized = <T::Mask as Mask>::splat(false);
        self.rejections = Rejections::default();
    }
    /// A `sigma` is refused: the filter reports no attitude covariance (see
    /// `attitude_covariance`).
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
        let q = quat_without_covariance(q, sigma)?;
        self.x.q = q;
        self.ecf_q = q;
        self.initialized = <T::Mask as Mask>::splat(true);
        Ok(())
    }
    fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
        let bias = checked_bias(bias)?;
        if let Some(sigma) = sigma {
            set_bias_variance(&mut self.x.p, checked_sigma(sigma, 1.0)? * sigma);
        }
        self.x.bias = bias;
        Ok(())
    }
    fn quat(&self) -> Quat<T> {
        self.x.q
    }
    fn bias(&self) -> Vec3<T> {
        self.x.bias
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
    /// `None`: the EKF's covariance is conditional on the complementary-filter quaternion
    /// being a measurement of the whole attitude, so in 6D it reports the heading as known to
    /// the observation noise (measured: 2e-4 rad std after 40 s) while nothing observes it.
    /// The 7×7 matrix is still available from [`EcfEkf::covariance`].
    fn attitude_covariance(&self) -> Option<Mat<T, 3, 3>> {
        None
    }
}
