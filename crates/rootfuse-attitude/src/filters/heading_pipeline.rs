//! A patent's MEMS heading pipeline (S1–S3) as a full-attitude filter [`heading-pipeline`].

use super::LaneParams;
use super::complementary::tilt_correction;
use super::{Dof, OrientationFilter, Rejections, ScreenBounds, Screened, initialise, params};
use super::{StateError, quat_without_covariance};
use crate::blocks::{LowPassGain, integrate_gyro, true_heading_error};
use crate::preprocess::{LowPass, MovingMean, MovingMedian, low_pass_factor};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask};

params! {
    /// Parameters of [`HeadingPipeline`].
    pub struct HeadingPipelineParams {
        /// Time constant of the inclination correction toward the smoothed gravity direction.
        tau_acc: f64 = 3.0, "s", [1e-3, 1e6];
        /// Low-pass factor `a` of the pre-processing chain, `Y(n) = a·X(n) + (1 − a)·Y(n−1)`
        /// (1 = pass-through).
        lp_alpha: f64 = 0.5, "1", [1e-3, 1.0];
        /// Heading random-walk intensity of the 2-state Kalman filter.
        q_heading: f64 = 1e-4, "rad²/s", [0.0, 10.0];
        /// Heading-rate bias random-walk intensity of the 2-state Kalman filter.
        q_bias: f64 = 1e-8, "rad²/s³", [0.0, 1.0];
        /// Variance of one tilt-compensated magnetic heading measurement.
        r_mag: f64 = 0.01, "rad²", [1e-8, 100.0];
        /// Initial standard deviation of the heading-rate bias.
        bias_std0: f64 = 0.01, "rad/s", [0.0, 10.0];
        /// The bias learns only while the inclination disagrees with the smoothed gravity by
        /// less than this (about 6° by default): a tilt transient makes the magnetic heading
        /// wrong in a way that looks like drift, not bias.
        bias_gate: f64 = 0.1, "rad", [0.0, 10.0];
        /// Weight of the gyro-integrated heading in `ψ_MEMS = Coeff·ψ_gyro + (1 − Coeff)·ψ_filtered`.
        coeff: f64 = 0.96, "1", [0.0, 1.0];
        /// Magnetic declination (east positive): true north is this far west of magnetic north.
        declination: f64 = 0.0, "rad", [-3.15, 3.15];
        /// 9: magnetic heading; 6: no heading reference (the heading is the gyro heading).
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// Pre-processing chain S1 on one channel: low-pass, moving mean (5), moving median (5).
#[derive(Clone, Debug)]
struct Chain<T: Lane> {
    low_pass: LowPass<T>,
    mean: MovingMean<T, 5>,
    median: MovingMedian<T, 5>,
}

impl<T: Lane> Chain<T> {
    fn new(a: T) -> Self {
        Self {
            low_pass: LowPass::with_factor(a),
            mean: MovingMean::new(),
            median: MovingMedian::new(),
        }
    }
    fn update(&mut self, x: T, active: T::Mask) -> T {
        let y = self.low_pass.update_where(x, active);
        let y = self.mean.update_where(y, active);
        self.median.update_where(y, active)
    }
}

/// The chain on the three components of a vector; `ok` false feeds NaN, which the chain holds
/// (its last accepted value) instead of letting it in; lanes outside `active` (a skipped
/// sample) do not move at all.
#[derive(Clone, Debug)]
struct VecChain<T: Lane>([Chain<T>; 3]);

impl<T: Lane> VecChain<T> {
    fn new(a: T) -> Self {
        Self([Chain::new(a), Chain::new(a), Chain::new(a)])
    }
    fn update(&mut self, v: Vec3<T>, ok: T::Mask, active: T::Mask) -> Vec3<T> {
        let nan = T::from_f64(f64::NAN);
        let [x, y, z] = v.to_array().map(|c| T::select(ok, c, nan));
        Vec3::new(
            self.0[0].update(x, active),
            self.0[1].update(y, active),
            self.0[2].update(z, active),
        )
    }
}

/// The MEMS heading of Ye et al. (S1–S3), completed to a full quaternion:
/// `q = qz(ψ_MEMS) ⊗ q_incl`.
///
/// - **Inclination** (the accelerometer path): gyro propagation, then a first-order
///   correction toward the smoothed gravity direction (time constant `tau_acc`), as in
///   [`Complementary`](super::Complementary); `q_incl` is its inclination part.
/// - **Magnetic heading** (S2): `ψ_mag` = tilt-compensated true heading (declination applied,
///   [`true_heading_error`]).
/// - **2-state Kalman filter** (S3) on `x = [ψ, b]`: `x_k = [[1, −T], [0, 1]]·x_{k−1} +
///   [T, 0]ᵀ·ψ̇_gyro`, `z = ψ_mag`, with the innovation wrapped to `[-π, π]`; `ψ̇_gyro·T` is
///   the heading increment of the gyro propagation, `b` the heading-rate bias (rad/s).
/// - **Fusion** (S3): `ψ_gyro = ψ_MEMS,k−1 + ψ̇_gyro·T − b·T`, then
///   `ψ_MEMS = ψ_gyro + (1 − Coeff)·wrap(ψ_filtered − ψ_gyro)`, the blend taken on the circle.
///
/// In **6D** there is no heading reference: the Kalman filter only predicts (its `b` stays at
/// 0), so `ψ_filtered` and `ψ_gyro` are the same gyro integration and the heading is the gyro
/// heading from the initial one (0 from the accelerometer-only start), drifting with the gyro
/// bias; the inclination is corrected as in 9D.
///
/// Reading of the source:
/// - S1 does not say which signals are smoothed; here the chain (low-pass `lp_alpha`, moving
///   mean of 5, moving median of 5) runs on the unit gravity and field directions expressed in
///   the earth frame of the gyro-propagated estimate, where both are constant, so smoothing
///   removes vibration and spikes without the rotation lag a sensor-frame smoother adds. The
///   gyroscope is not smoothed (it is integrated). A rejected sample feeds NaN, which the chain
///   holds out. The spectrum (S14) is an analysis tool (`rootfuse_eval::spectrum`).
/// - S31's complementary filter is read as the inclination path above (the source's formulas
///   are images, not in the text).
/// - S33/S34: the integration interval `[T_k, T_{k+1}]` is one sample and it starts from the
///   previous `ψ_MEMS` (the first from the filtered heading), with the Kalman bias removed.
///   That makes `Coeff = 0.96` a first-order complementary blend with time constant
///   `24·dt` (0.24 s at 100 Hz). Restarting every interval from `ψ_filtered` would make
///   `ψ_MEMS ≈ ψ_filtered`; never restarting would keep 96 % of the gyro drift forever.
/// - The bias is learned only while the inclination agrees with the smoothed gravity to
///   within `bias_gate` (the heading is still corrected): during a tilt transient the
///   tilt-compensated heading is wrong in a way that looks like drift.
/// - Kalman noise values, the initial covariance (`π²` on heading, `bias_std0²` on bias) and
///   the measurement variance `r_mag` are ours; the source gives none.
#[derive(Clone, Debug)]
pub struct HeadingPipeline<T: Lane> {
    q: Quat<T>,
    incl: Quat<T>,
    psi_kf: T,
    bias: T,
    p: [T; 3],
    psi_mems: T,
    initialized: T::Mask,
    acc_chain: VecChain<T>,
    mag_chain: VecChain<T>,
    /// Inclination-correction gain `1 − exp(−dt/tau_acc)`.
    k_acc: LowPassGain<T>,
    q_heading: T,
    q_bias: T,
    r_mag: T,
    bias_gate: T,
    p0: [T; 3],
    coeff: T,
    declination: T,
    nine_d: bool,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    /// The low-pass factor of both pre-processing chains, for `reset`.
    lp_factor: T,
    params: HeadingPipelineParams,
}

impl<T: Lane> HeadingPipeline<T> {
    crate::filters::uniform_constructors!(HeadingPipelineParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(p: &LaneParams<'_, HeadingPipelineParams, T>) -> Self {
        let p0 = [
            T::from_f64(core::f64::consts::PI * core::f64::consts::PI),
            T::zero(),
            p.coef(|p| p.bias_std0 * p.bias_std0),
        ];
        let lp_factor = p.coef(|p| low_pass_factor(p.lp_alpha));
        Self {
            q: Quat::identity(),
            incl: Quat::identity(),
            psi_kf: T::zero(),
            bias: T::zero(),
            p: p0,
            psi_mems: T::zero(),
            initialized: <T::Mask as Mask>::splat(false),
            acc_chain: VecChain::new(lp_factor),
            mag_chain: VecChain::new(lp_factor),
            k_acc: LowPassGain::new(p.coef(|p| p.tau_acc)),
            q_heading: p.coef(|p| p.q_heading),
            q_bias: p.coef(|p| p.q_bias),
            r_mag: p.coef(|p| p.r_mag),
            bias_gate: p.coef(|p| p.bias_gate),
            p0,
            coeff: p.coef(|p| p.coeff),
            declination: p.coef(|p| p.declination),
            nine_d: p.first().dof.uses_magnetometer(),
            bounds: p.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            lp_factor,
            params: p.first().clone(),
        }
    }
    /// `ψ_MEMS`, rad, counter-clockwise about earth-up from true north (`[-π, π]`).
    pub fn heading(&self) -> T {
        self.psi_mems
    }
    /// The Kalman heading `ψ_filtered`, rad.
    pub fn heading_filtered(&self) -> T {
        self.psi_kf
    }
    /// The Kalman heading-rate bias `b`, rad/s (about earth-up).
    pub fn heading_bias(&self) -> T {
        self.bias
    }
}

impl<T: Lane> OrientationFilter<T> for HeadingPipeline<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let was = self.initialized;
        let mut q0 = initialise(self.q, &mut self.initialized, &s, self.nine_d);
        let fresh = self.initialized & !was;
        if self.nine_d {
            // `initialise` points the field at +y; true north is `declination` west of it.
            let turned = Quat::from_heading(-self.declination) * q0;
            q0 = Quat::select(fresh, turned, q0);
        }
        let (psi0, _) = q0.heading_inclination();
        let psi_kf = T::select(fresh, psi0, self.psi_kf);
        let psi_mems = T::select(fresh, psi0, self.psi_mems);
        let bias = T::select(fresh, T::zero(), self.bias);
        let p = [0, 1, 2].map(|i| T::select(fresh, self.p0[i], self.p[i]));

        // Inclination path.
        let q_prop = integrate_gyro(q0, s.gyr, s.dt);
        let a_earth = self
            .acc_chain
            .update(q_prop.rotate(s.acc), s.acc_ok, s.step);
        let (a_earth, a_ok) = a_earth.try_normalize();
        let k_acc = self.k_acc.gain(s.dt);
        let tilt_full = tilt_correction(a_earth);
        let settled = tilt_full.norm().simd_lt(self.bias_gate) & a_ok & s.acc_ok;
        let tilt = tilt_full * k_acc;
        let q_acc = (Quat::from_rotation_vector(tilt) * q_prop).normalize();
        let q_tilted = Quat::select(s.acc_ok & a_ok, q_acc, q_prop);
        let (psi_prop, incl) = q_tilted.heading_inclination();
        let dpsi_gyro = (psi_prop - psi0).wrap_pi();

        // 2-state Kalman prediction.
        let t = s.dt;
        let mut psi = (psi_kf + dpsi_gyro - bias * t).wrap_pi();
        let mut b = bias;
        let p00 = p[0] - t * (p[1] + p[1]) + t * t * p[2] + self.q_heading * t;
        let p01 = p[1] - t * p[2];
        let p11 = p[2] + self.q_bias * t;
        let mut pn = [p00, p01, p11];

        // 6D is the same for every lane and has no measurement: skipping changes no bits.
        if self.nine_d {
            let h = self
                .mag_chain
                .update(q_tilted.rotate(s.mag), s.mag_ok, s.step);
            let (err, h_ok) = true_heading_error(Quat::identity(), h, self.declination);
            let ok = s.mag_ok & h_ok;
            let psi_mag = (psi_prop + err).wrap_pi();
            let nu = (psi_mag - psi).wrap_pi();
            let sinv = (p00 + self.r_mag).recip();
            let (k0, k1) = (p00 * sinv, p01 * sinv);
            let upd = [p00 - k0 * p00, p01 - k0 * p01, p11 - k1 * p01];
            psi = T::select(ok, (psi + k0 * nu).wrap_pi(), psi);
            b = T::select(ok & settled, b + k1 * nu, b);
            pn = [0, 1, 2].map(|i| T::select(ok, upd[i], pn[i]));
            self.rejections.reject_field(s.mag_ok & !h_ok);
        }

        let psi_gyro = (psi_mems + dpsi_gyro - b * t).wrap_pi();
        let one = T::one();
        let mems = (psi_gyro + (one - self.coeff) * (psi - psi_gyro).wrap_pi()).wrap_pi();
        let q_new = (Quat::from_heading(mems) * incl).normalize();

        let step = s.step;
        self.q = Quat::select(step, q_new, q0);
        self.incl = Quat::select(step, incl, self.incl);
        self.psi_kf = T::select(step, psi, psi_kf);
        self.bias = T::select(step, b, bias);
        self.p = [0, 1, 2].map(|i| T::select(step, pn[i], p[i]));
        self.psi_mems = T::select(step, mems, psi_mems);
    }
    fn reset(&mut self) {
        self.q = Quat::identity();
        self.incl = Quat::identity();
        self.psi_kf = T::zero();
        self.bias = T::zero();
        self.p = self.p0;
        self.psi_mems = T::zero();
        self.initialized = <T::Mask as Mask>::splat(false);
        self.acc_chain = VecChain::new(self.lp_factor);
        self.mag_chain = VecChain::new(self.lp_factor);
        self.rejections = Rejections::default();
    }
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
        let q = quat_without_covariance(q, sigma)?;
        let (heading, incl) = q.heading_inclination();
        self.q = q;
        self.incl = incl;
        self.psi_kf = heading;
        self.psi_mems = heading;
        self.initialized = <T::Mask as Mask>::splat(true);
        Ok(())
    }
    fn quat(&self) -> Quat<T> {
        self.q
    }
    /// The heading-rate bias about earth-up, expressed in the sensor frame (rad/s); the other
    /// two axes are not estimated.
    fn bias(&self) -> Vec3<T> {
        self.q
            .rotate_inverse(Vec3::new(T::zero(), T::zero(), self.bias))
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
}
