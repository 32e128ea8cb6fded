//! LS quaternion fusion (a patent method) [`lsq-fusion`]: gyro pre-processing, forgetting-factor
//! least-squares denoising, square-root RLS drift estimation, and the compensated quaternion
//! fused with the accelerometer quaternion by least squares.

mod denoise;
mod drift;

pub use denoise::PolyDenoiser;
pub use drift::{DriftConfig, DriftEstimator, DriftSample};

use super::complementary::tilt_correction;
use super::{Dof, LaneParams, OrientationFilter, Rejections, ScreenBounds, Screened, params};
use super::{StateError, bias_without_covariance, quat_without_covariance};
use crate::blocks::{LowPassGain, acc_mag_quat};
use crate::preprocess::{Hampel, LowPass, hampel_threshold, low_pass_factor};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat, Vector};
use rootfuse_lsq::rls::{Potter, RecursiveLeastSquares, RlsConfig};

params! {
    /// Parameters of [`LsqFusion`].
    pub struct LsqFusionParams {
        /// Hampel outlier threshold on the raw gyroscope, in robust standard deviations
        /// (`1.4826·MAD` over the last 5 samples).
        hampel_k: f64 = 3.0, "1", [0.5, 1000.0];
        /// Smoothing factor `a` of the first-order low-pass after the Hampel stage
        /// (`y = a·x + (1 − a)·y₋₁`; 1 = no smoothing).
        smooth: f64 = 1.0, "1", [0.01, 1.0];
        /// Memory of the local quadratic least-squares denoiser (forgetting `τ/(τ + dt)` per
        /// sample).
        denoise_tau: f64 = 0.01, "s", [1e-4, 10.0], shared;
        /// Gyroscope white-noise standard deviation per sample (the denoiser's weight
        /// `1/σ²`; it scales its covariance only).
        gyr_noise: f64 = 0.01, "rad/s", [1e-6, 10.0], shared;
        /// Memory of the quaternion least-squares fusion (forgetting `τ/(τ + dt)` per sample;
        /// the steady-state gain is `dt/(τ + dt)`).
        fusion_tau: f64 = 5.0, "s", [1e-3, 1e4];
        /// Standard deviation of the accelerometer quaternion's angle at rest (weight
        /// `1/σ²`).
        acc_noise: f64 = 0.02, "rad", [1e-6, 10.0];
        /// Deviation of the specific-force norm from 9.81 m/s² at which the accelerometer
        /// quaternion's variance is doubled (`σ²·(1 + (Δ/acc_dev)²)`).
        acc_dev: f64 = 0.5, "m/s²", [1e-3, 1e3];
        /// Length of one averaging block of the drift estimator (one drift measurement per
        /// two blocks).
        drift_block: f64 = 0.5, "s", [0.01, 1000.0], shared;
        /// Memory of the drift estimator.
        drift_memory: f64 = 60.0, "s", [0.1, 1e7], shared;
        /// Standard deviation of a block mean of the accelerometer quaternion's angle at rest
        /// (the drift measurement's noise).
        drift_noise: f64 = 0.005, "rad", [1e-6, 1.0], shared;
        /// Standard deviation of a block mean of the magnetometer heading at rest (the
        /// vertical row of the 9D drift measurement; larger than `drift_noise` because indoor
        /// fields are disturbed).
        drift_mag_noise: f64 = 0.2, "rad", [1e-6, 100.0];
        /// Relative gyro scale/alignment error: the drift measurement of a window that turned
        /// by `φ` gets the extra variance `(gyr_scale·φ)²`.
        gyr_scale: f64 = 0.2, "1", [0.0, 1.0], shared;
        /// Prior standard deviation and largest drift estimate (covariance bound).
        drift_max: f64 = 0.05, "rad/s", [1e-5, 5.0], shared;
        /// 9: heading of the accelerometer quaternion from the magnetometer; 6: from the gyro
        /// quaternion.
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// The LS quaternion fusion of Chen et al. (patent, 2019); see `docs/methods.md` in the repository.
///
/// Per sample:
/// 1. **Pre-processing** of each gyro axis: causal [`Hampel`] outlier replacement (window 5,
///    threshold `hampel_k`), then a first-order [`LowPass`] (`smooth`).
/// 2. **Denoising** of each axis by the forgetting-factor weighted least-squares local
///    quadratic fit [`PolyDenoiser`] (memory `denoise_tau`), the fitted value at the current
///    sample.
/// 3. **Drift** `ω₀` by the square-root RLS [`DriftEstimator`] on the growth of the
///    difference between the gyro quaternion and the accelerometer quaternion (bounded, so the
///    unobservable vertical drift of 6D does not wind up).
/// 4. **Compensated quaternion, fused**: the state of a 4-dimensional [`Potter`] RLS is the
///    quaternion; the time update turns it by `exp((ω − ω̂₀)·dt/2)` (right multiplication, an
///    exact orthogonal transition) with forgetting `τ/(τ + dt)`; the measurement is the
///    accelerometer quaternion `q_a` (`H = I₄`, weights `W = R⁻¹`); the output is the
///    normalised state.
///
/// The accelerometer quaternion is the tilt from gravity with the heading of the predicted
/// quaternion (6D) or of the magnetometer ([`acc_mag_quat`], 9D; the 6D form where the field
/// is unusable).
///
/// Reading of the source (the patent's equations are not in the text we have; these are our
/// choices):
/// - Pre-processing is "general data smoothing" that removes "obviously abnormal values": a
///   Hampel filter (outliers) and a low-pass, both causal; the low-pass is off by default
///   (`smooth = 1`): the denoiser smooths already, without a low-pass's lag.
/// - The weighted LS with forgetting is a local polynomial about the current sample (the
///   source's `y = f(x, tᵢ)`, `S = Σ λ^{k−i} wᵢ rᵢ²`, `W = R⁻¹`), quadratic, evaluated at
///   the current sample; the forgetting factor is per sample `τ/(τ + dt)` so that the memory
///   is in seconds whatever the rate.
/// - "Improved LS recursion" is the square-root (Potter) RLS with `P = ΔΔᵀ`. The drift
///   regression uses the growth of the quaternion difference, as earth-frame rotation vector,
///   between block means within a window anchored on the fused orientation (see
///   [`DriftEstimator`]), which cancels the unknown error of the anchor. Its measurement
///   noise is modelled (block-mean noise `drift_noise`, a rotation-proportional term
///   `gyr_scale`, a larger `drift_mag_noise` for the 9D vertical row) and gated at 3σ of the
///   predicted innovation: without that, correlated accelerometer errors (translation,
///   centripetal acceleration, magnetic disturbances) drove the weakly observable
///   components to the bound on BROAD and on the `translation` simulation.
/// - "Compensated quaternion, fused with the accelerometer quaternion by the LS model" is a
///   square-root RLS on the quaternion itself with the gyro rotation as its state transition;
///   its gain starts near 1 (the first accelerometer quaternion is taken as it is: the
///   initial attitude) and settles at `1 − exp(−dt/fusion_tau)`. The weight of `q_a` falls as the
///   specific force departs from gravity (`acc_dev`), our addition within `W = R⁻¹`.
/// - The quaternion's covariance is forgotten only while it is below its steady state at
///   full weight: after a stretch of down-weighted samples the gain never exceeds the nominal
///   one (plain forgetting let it grow and then snap to the next accelerometer sample, and
///   tripled the BROAD errors), and a long absence of the accelerometer cannot overflow it.
/// - In 9D the accelerometer quaternion is the TRIAD [`acc_mag_quat`]: its heading comes from
///   the field levelled with the accelerometer's tilt, and so the tilt and heading rows have
///   the same gain (`fusion_tau`).
/// - Defaults were chosen on the simulated presets and the four BROAD trials (see the
///   measured tables in docs/accuracy.md); they are not the source's (it gives none).
#[derive(Clone, Debug)]
pub struct LsqFusion<T: Lane> {
    stages: Stages<T>,
    q: Quat<T>,
    /// Forgetting gain `1 − exp(−dt/fusion_tau)` of the quaternion RLS.
    fusion_gain: LowPassGain<T>,
    acc_weight: T,
    inv_acc_dev: T,
    nine_d: bool,
    mag_drift_weight: T,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    /// Per-lane Hampel threshold and low-pass factor of the pre-processing, for `reset`.
    hampel_threshold: T,
    smooth_factor: T,
    params: LsqFusionParams,
}

/// The stages of [`LsqFusion`] that carry state: pre-processing per gyro axis, the drift
/// estimator and the quaternion fusion.
#[derive(Clone, Debug)]
struct Stages<T: Lane> {
    hampel: [Hampel<T, 5>; 3],
    smooth: [LowPass<T>; 3],
    denoise: [PolyDenoiser<T, 3>; 3],
    drift: DriftEstimator<T>,
    fusion: Potter<T, 4>,
}

impl<T: Lane> Stages<T> {
    /// The stages as a new filter has them: per-lane pre-processing coefficients, the
    /// denoiser and drift estimator from the first lane's (shared) parameters.
    fn new(hampel_threshold: T, smooth_factor: T, p: &LsqFusionParams) -> Self {
        let fusion = Potter::with_isotropic_prior(
            &Vector::from_column([T::one(), T::zero(), T::zero(), T::zero()]),
            T::from_f64(FUSION_PRIOR),
            RlsConfig::new(1.0),
        );
        Self {
            hampel: core::array::from_fn(|_| Hampel::with_threshold(hampel_threshold)),
            smooth: core::array::from_fn(|_| LowPass::with_factor(smooth_factor)),
            denoise: core::array::from_fn(|_| PolyDenoiser::new(p.denoise_tau, p.gyr_noise)),
            drift: DriftEstimator::new(&DriftConfig {
                block: p.drift_block,
                memory: p.drift_memory,
                max: p.drift_max,
                nine_d: p.dof.uses_magnetometer(),
                gate: 0.1,
                noise: p.drift_noise,
                scale: p.gyr_scale,
            }),
            // Unreachable: construction fails only for λ ∉ (0, 1], invalid bounds, a
            // non-finite x₀ or P₀ not PD; here λ = 1, no bounds, x₀ = [1, 0, 0, 0],
            // P₀ = FUSION_PRIOR·I = I.
            fusion: fusion.expect("unreachable: constant, valid prior"),
        }
    }
}

/// Gravity the accelerometer weight compares the specific-force norm with, m/s².
const GRAVITY: f64 = 9.81;

/// Prior variance of each quaternion component of the fusion.
const FUSION_PRIOR: f64 = 1.0;

impl<T: Lane> LsqFusion<T> {
    crate::filters::uniform_constructors!(LsqFusionParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, the denoiser's and the drift estimator's, marked `shared`, and the
    /// screening limits) come from the first set.
    pub fn with_lane_params(lanes: &LaneParams<'_, LsqFusionParams, T>) -> Self {
        let p = lanes.first();
        let nine = p.dof.uses_magnetometer();
        let positive = |v: f64, default: f64| if v > 0.0 && v.is_finite() { v } else { default };
        let hampel_threshold = lanes.coef(|p| hampel_threshold(p.hampel_k));
        let smooth_factor = lanes.coef(|p| low_pass_factor(p.smooth));
        Self {
            stages: Stages::new(hampel_threshold, smooth_factor, p),
            q: Quat::identity(),
            fusion_gain: LowPassGain::new(lanes.coef(|p| positive(p.fusion_tau, 3.0))),
            acc_weight: lanes.coef(|p| {
                let acc_noise = positive(p.acc_noise, 0.02);
                1.0 / (acc_noise * acc_noise)
            }),
            inv_acc_dev: lanes.coef(|p| 1.0 / positive(p.acc_dev, 1.0)),
            nine_d: nine,
            mag_drift_weight: lanes.coef(|p| {
                let mag_ratio = positive(p.drift_noise, 0.005) / positive(p.drift_mag_noise, 0.2);
                mag_ratio * mag_ratio
            }),
            bounds: p.screen_limits().bounds(),
            rejections: Rejections::default(),
            hampel_threshold,
            smooth_factor,
            params: p.clone(),
        }
    }

    /// The drift estimator (its covariance and unclamped estimate).
    pub fn drift(&self) -> &DriftEstimator<T> {
        &self.stages.drift
    }
}

/// The 4×4 matrix of right multiplication by `p`: `q ⊗ p = M(p)·q` (`q = [w, x, y, z]`).
fn right_mul_matrix<T: Lane>(p: Quat<T>) -> Mat<T, 4, 4> {
    let (w, x, y, z) = (p.w, p.x, p.y, p.z);
    Mat::from_rows([[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]])
}

impl<T: Lane> OrientationFilter<T> for LsqFusion<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let zero = T::zero();
        let one = T::one();

        // 1–2: pre-processing and denoising, per axis, only in lanes whose sample is usable.
        let g = s.gyr.to_array();
        let mut denoised = [zero; 3];
        for i in 0..3 {
            let h = self.stages.hampel[i].update_where(g[i], s.step);
            let l = self.stages.smooth[i].update_where(h, s.step);
            denoised[i] = self.stages.denoise[i].update(l, s.dt, s.step);
        }
        let gyr = Vec3::select(s.step, Vec3::from_array(denoised), Vec3::zero());

        // 4: the compensated quaternion as the fusion's time update. Where `!step`, `dt = 0`
        // makes the transition the identity and λ = 1: the state keeps its values.
        let turn = Quat::from_rotation_vector((gyr - self.stages.drift.bias()) * s.dt);
        let f = right_mul_matrix(turn);
        let mut trace = zero;
        for row in &self.stages.fusion.factor().m {
            for &v in row {
                trace = v.mul_add(v, trace);
            }
        }
        // Forget only while the covariance is below its steady state at full weight,
        // `trace P = 4·(1 − λ)/w` (gain `1 − λ`): after a stretch of down-weighted samples the
        // gain then stays at most the nominal one instead of snapping to the next sample.
        // Forgetting by λ = exp(−dt/τ) settles the gain at 1 − λ, the exact first-order
        // low-pass gain (λ = 1/(1 + dt/τ) settled at dt/(τ + dt), first order only).
        let k = self.fusion_gain.gain(s.dt);
        let ceiling = T::from_f64(4.0) * k / (self.acc_weight * T::from_f64(4.0));
        let lambda = T::select(trace.simd_ge(ceiling), one, one - k);
        // No bounds are configured, so the transition is always accepted as a call.
        let _ = self.stages.fusion.predict(&f, lambda);
        let x = self.stages.fusion.estimate();
        let predicted = Quat::new(x[0], x[1], x[2], x[3]).normalize();

        // The accelerometer quaternion: `source` turned about a horizontal axis until gravity
        // is up (its heading kept, 6D), or gravity and the field (TRIAD, 9D, where usable).
        let acc = s.acc;
        let (am, am_ok) = if self.nine_d {
            acc_mag_quat(acc, s.mag, T::from_f64(0.1))
        } else {
            (Quat::identity(), <T::Mask as Mask>::splat(false))
        };
        let mag_ok = am_ok & s.mag_ok;
        let q_a = move |source: Quat<T>| {
            let tilt = tilt_correction(source.rotate(acc));
            let tilted = (Quat::from_rotation_vector(tilt) * source).normalize();
            Quat::select(mag_ok, am, tilted)
        };

        let dev = (s.acc_norm - T::from_f64(GRAVITY)) * self.inv_acc_dev;
        let rel = T::select(s.acc_ok, one / dev.mul_add(dev, one), zero);
        let w = rel * self.acc_weight;
        let z = q_a(predicted).align_to(predicted).to_array();
        // Quaternion components carry half angles: their variance is a quarter of the angle's.
        let wq = w * T::from_f64(4.0);
        let h = Mat::<T, 4, 4>::identity();
        let zv = Vector::from_column(z);
        self.stages
            .fusion
            .update_vector(&h, &zv, &Vector::from_column([wq; 4]));
        let x = self.stages.fusion.estimate();
        let fused = Quat::new(x[0], x[1], x[2], x[3]).normalize();
        self.q = Quat::select(s.step, fused, self.q);

        // 3: the drift, for the next samples.
        let w_z = T::select(mag_ok, rel * self.mag_drift_weight, zero);
        let sample = DriftSample {
            gyr,
            dt: s.dt,
            step: s.step,
            fused: self.q,
            w: rel,
            w_z,
        };
        self.stages.drift.update(&sample, q_a);
    }
    fn reset(&mut self) {
        self.stages = Stages::new(self.hampel_threshold, self.smooth_factor, &self.params);
        self.q = Quat::identity();
        self.rejections = Rejections::default();
    }
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
        let q = quat_without_covariance(q, sigma)?;
        // The fusion's estimate is the quaternion: restart it there with its prior spread.
        // Fails only for a non-finite state, which `quat_without_covariance` refused.
        let fusion = Potter::with_isotropic_prior(
            &Vector::from_column(q.to_array()),
            T::from_f64(FUSION_PRIOR),
            RlsConfig::new(1.0),
        )
        .map_err(|_| StateError::Unsupported("finite quaternion state"))?;
        self.stages.fusion = fusion;
        self.q = q;
        Ok(())
    }
    fn quat(&self) -> Quat<T> {
        self.q
    }
    fn bias(&self) -> Vec3<T> {
        self.stages.drift.bias()
    }
    /// Sets the drift estimate (clamped to `drift_max`, as every estimate is; its covariance
    /// kept).
    fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
        let bias = bias_without_covariance(bias, sigma)?;
        if self.stages.drift.set_bias(bias) {
            Ok(())
        } else {
            Err(StateError::Unsupported("finite drift state"))
        }
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
}
