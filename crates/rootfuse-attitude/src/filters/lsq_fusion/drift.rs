//! Gyro drift by square-root recursive least squares on the growth of the difference between
//! the gyro quaternion and the accelerometer quaternion.

use crate::{Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat, Vector};
use rootfuse_lsq::rls::{Potter, RecursiveLeastSquares, RlsConfig};

/// Settings of a [`DriftEstimator`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriftConfig {
    /// Length of one averaging block, s; one drift measurement per two blocks.
    pub block: f64,
    /// Memory of the estimator, s (forgetting `λ = memory/(memory + 2·block)` per
    /// measurement).
    pub memory: f64,
    /// Prior standard deviation and largest estimate, rad/s: `p_max = max²` bounds every
    /// eigenvalue of the covariance (no windup), and the applied estimate is clamped to this
    /// norm.
    pub max: f64,
    /// Measurements use the earth-vertical row too (9D: heading from the magnetometer).
    pub nine_d: bool,
    /// Largest mean difference angle of a block, rad, for its window to be used (the
    /// linear model holds for small angles only, e.g. not while the fusion converges).
    pub gate: f64,
    /// Standard deviation of a block mean of the difference angle at rest, rad. Errors of
    /// the accelerometer quaternion are correlated over a block (motion, vibration), so a
    /// block mean is not `√n` times better than one sample.
    pub noise: f64,
    /// Relative gyro scale and alignment error: a window that turned by `φ` rad gets the
    /// extra variance `(scale·φ)²`, because such errors grow with the rotation, not with time.
    pub scale: f64,
}

/// One sample for a [`DriftEstimator`].
#[derive(Clone, Copy, Debug)]
pub struct DriftSample<T: Lane> {
    /// The (denoised) rate with the drift still in it, rad/s, sensor frame.
    pub gyr: Vec3<T>,
    /// Time step, s.
    pub dt: T,
    /// Lanes whose sample is usable.
    pub step: T::Mask,
    /// The fused orientation after this sample (the next window's anchor).
    pub fused: Quat<T>,
    /// Relative weight in `[0, 1]` of the accelerometer quaternion's horizontal rows (1 at
    /// rest, less under acceleration, zero where unusable).
    pub w: T,
    /// Relative weight of its vertical row (9D with a usable magnetometer; zero otherwise).
    pub w_z: T,
}

/// One lane-set of a [`DriftEstimator`]'s running sums.
#[derive(Clone, Copy, Debug)]
struct Block<T: Lane> {
    /// `Σ wᵢ θᵢ` per earth row (the vertical row with the 9D weights).
    theta: Vec3<T>,
    /// `Σ wᵢ Aᵢ`, row by row as `theta`.
    a: Mat<T, 3, 3>,
    /// `Σ wᵢ` of the horizontal rows and of the vertical row.
    w_xy: T,
    w_z: T,
    /// Number of samples with a non-zero weight, horizontal and vertical rows.
    n_xy: T,
    n_z: T,
}

impl<T: Lane> Block<T> {
    fn zero() -> Self {
        Self {
            theta: Vec3::zero(),
            a: Mat::zeros(),
            w_xy: T::zero(),
            w_z: T::zero(),
            n_xy: T::zero(),
            n_z: T::zero(),
        }
    }
    fn select(mask: T::Mask, a: &Self, b: &Self) -> Self {
        Self {
            theta: Vec3::select(mask, a.theta, b.theta),
            a: Mat::select(mask, &a.a, &b.a),
            w_xy: T::select(mask, a.w_xy, b.w_xy),
            w_z: T::select(mask, a.w_z, b.w_z),
            n_xy: T::select(mask, a.n_xy, b.n_xy),
            n_z: T::select(mask, a.n_z, b.n_z),
        }
    }
    /// Weighted mean of row `i` of `θ` and of `A` (zero where the weight is zero) and the
    /// mean relative weight (the block mean's variance is `noise²` over it).
    fn mean_row(&self, i: usize) -> (T, Vector<T, 3>, T) {
        let (w, n) = if i < 2 {
            (self.w_xy, self.n_xy)
        } else {
            (self.w_z, self.n_z)
        };
        let ok = w.simd_gt(T::zero());
        let inv = T::select(ok, T::one() / w, T::zero());
        let theta = self.theta.to_array()[i] * inv;
        let mean_w = T::select(ok, w / n, T::zero());
        (theta, Vector::from_column(self.a.m[i]).scale(inv), mean_w)
    }
}

/// Gyro drift `ω₀` (rad/s, sensor frame) from the growth of the difference between a gyro
/// quaternion and the accelerometer quaternion.
///
/// # Model
/// A gyro quaternion `q_ω` is integrated from an anchor (the fused orientation at the start
/// of a window) with `ω − b`, `b` the drift applied so far. Writing its difference to the
/// accelerometer quaternion `q_a` as the earth-frame rotation vector
/// `θ = 2·log(q_ω ⊗ q_a*)` (to first order the quaternion difference: `q_ω − q_a = ½[0, θ] ⊗ q`),
/// a residual drift `δ = ω₀ − b` makes it grow as
/// `θ_k = θ_anchor + A_k δ + noise`, `A_k = Σ_{j≤k} R(q_ω,j)·dt_j` — the source's
/// `(T/2)·Ξ(q_k)·ω₀` increments, since `Ξ(q)·v = q ⊗ [0, v] = [0, R(q)·v] ⊗ q`. The unknown
/// anchor error is constant over the window, so the difference of the weighted means of two
/// consecutive blocks, `Δθ̄ = ΔĀ·δ + noise`, measures the drift without it:
/// `z = Δθ̄ + ΔĀ·b = ΔĀ·ω₀`, one row per observable earth axis, weight
/// `1/(1/W₁ + 1/W₂)` (`W` the blocks' weight sums, `wᵢ = 1/var(θᵢ)`).
///
/// In 6D the accelerometer quaternion takes its heading from `q_ω` (gravity has none), so its
/// vertical row is zero by construction: it is not a measurement and is not used (regressing
/// it would claim the earth-vertical drift is zero).
///
/// # Estimator
/// [`Potter`] square-root RLS (`P = ΔΔᵀ`, the source's eq. 7–9) with forgetting per
/// measurement and [`CovarianceBounds`](rootfuse_lsq::rls::CovarianceBounds)
/// `eig(P) ≤ max²`: the drift about the axis that stays vertical is unobservable in 6D and,
/// by regularised forgetting, its variance settles at `max²` instead of growing and its
/// estimate is left where it is (no windup).
#[derive(Clone, Debug)]
pub struct DriftEstimator<T: Lane> {
    rls: Potter<T, 3>,
    bias: Vec3<T>,
    q_w: Quat<T>,
    a: Mat<T, 3, 3>,
    first: Block<T>,
    current: Block<T>,
    elapsed: T,
    /// Rotation angle of the window so far, rad.
    turned: T,
    second: T::Mask,
    anchored: T::Mask,
    block: T,
    max: T,
    gate: T,
    inv_noise2: T,
    scale2: T,
    nine_d: bool,
}

/// Squared innovation gate of a drift measurement row, in predicted variances (3σ).
const GATE_SIGMA2: f64 = 9.0;

/// `v` scaled back onto the ball of radius `max`.
fn clamp_norm<T: Lane>(v: Vec3<T>, max: T) -> Vec3<T> {
    v * (max / v.norm().max(max))
}

impl<T: Lane> DriftEstimator<T> {
    /// An estimator at zero drift (out-of-range settings are clamped to sane values).
    pub fn new(config: &DriftConfig) -> Self {
        let pick = |v: f64, lo: f64, hi: f64, default: f64| {
            if v.is_finite() {
                v.clamp(lo, hi)
            } else {
                default
            }
        };
        let block = pick(config.block, 1e-3, 1e4, 1.0);
        let memory = pick(config.memory, 1e-3, 1e9, 60.0);
        let max = pick(config.max, 1e-6, 10.0, 0.05);
        let gate = pick(config.gate, 1e-6, 3.2, 0.3);
        let noise = pick(config.noise, 1e-9, 10.0, 0.005);
        let scale = pick(config.scale, 0.0, 10.0, 0.01);
        let p_max = max * max;
        let lambda = memory / (memory + 2.0 * block);
        let rls = Potter::with_isotropic_prior(
            &Vector::zeros(),
            T::from_f64(p_max),
            RlsConfig::new(lambda).with_bounds(0.0, p_max),
        );
        Self {
            // Unreachable: construction fails only for λ ∉ (0, 1], bounds not 0 ≤ n·p_min <
            // p_max, a non-finite x₀ or P₀ not PD / outside the bounds. Here λ ∈ [5e-8, 1)
            // (memory ≥ 1e-3, block ≤ 1e4), p_min = 0 < p_max ≥ 1e-12 (normal in f32 too),
            // x₀ = 0 and P₀ = p_max·I, which the bound check admits with its n·u slack.
            rls: rls.expect("unreachable: the clamped drift configuration is valid"),
            bias: Vec3::zero(),
            q_w: Quat::identity(),
            a: Mat::zeros(),
            first: Block::zero(),
            current: Block::zero(),
            elapsed: T::zero(),
            turned: T::zero(),
            second: <T::Mask as Mask>::splat(false),
            anchored: <T::Mask as Mask>::splat(false),
            block: T::from_f64(block),
            max: T::from_f64(max),
            gate: T::from_f64(gate),
            inv_noise2: T::from_f64(1.0 / (noise * noise)),
            scale2: T::from_f64(scale * scale),
            nine_d: config.nine_d,
        }
    }

    /// The drift to subtract from the gyroscope, rad/s, sensor frame (the estimate clamped
    /// to the configured norm).
    pub fn bias(&self) -> Vec3<T> {
        self.bias
    }

    /// Sets the drift estimate, rad/s, sensor frame (clamped to the configured norm, as every
    /// estimate is) and keeps its covariance: the estimator goes on from there. `false` (and
    /// nothing changed) if the estimator cannot restart from it (a non-finite `bias`).
    pub fn set_bias(&mut self, bias: Vec3<T>) -> bool {
        let b = clamp_norm(bias, self.max);
        let x = b.to_vector();
        let config = self.rls.config();
        let restarted = Potter::<T, 3>::new(&x, &self.rls.covariance(), config)
            .or_else(|_| Potter::<T, 3>::with_isotropic_prior(&x, self.max * self.max, config));
        match restarted {
            Ok(rls) => {
                self.rls = rls;
                self.bias = b;
                true
            }
            Err(_) => false,
        }
    }

    /// The covariance of the drift estimate, (rad/s)², sensor frame.
    pub fn covariance(&self) -> Mat<T, 3, 3> {
        self.rls.covariance()
    }

    /// The unclamped least-squares estimate, rad/s.
    pub fn estimate(&self) -> Vec3<T> {
        let x = self.rls.estimate();
        Vec3::new(x[0], x[1], x[2])
    }

    /// One sample (in its `step` lanes), with the accelerometer quaternion as a function of
    /// the heading source (`q_a(q_ω)`: 6D takes the heading from its argument).
    pub fn update(&mut self, sample: &DriftSample<T>, q_a: impl Fn(Quat<T>) -> Quat<T>) {
        let DriftSample {
            gyr,
            dt,
            step,
            fused,
            w,
            w_z,
        } = *sample;
        let zero = T::zero();
        // Lanes start their first window at the first step (anchor = the fused orientation).
        let start = step & !self.anchored;
        self.anchored |= step;
        let live = step & !start;

        let rate = gyr - self.bias;
        let q_w = crate::blocks::integrate_gyro(self.q_w, rate, dt);
        let r = q_w.to_rotation_matrix();
        let a = Mat::from_fn(|i, j| r.m[i][j].mul_add(dt, self.a.m[i][j]));
        let theta = (q_w * q_a(q_w).align_to(q_w).conj()).to_rotation_vector();
        let w = T::select(live & theta.is_finite(), w, zero);
        let w_z = T::select(
            self.nine_d_mask(),
            T::select(live & theta.is_finite(), w_z, zero),
            zero,
        );
        let theta = Vec3::select(theta.is_finite(), theta, Vec3::zero());
        let c = &self.current;
        let row_w = [w, w, w_z];
        let th = theta.to_array();
        let mut th_sum = c.theta.to_array();
        for i in 0..3 {
            th_sum[i] = row_w[i].mul_add(th[i], th_sum[i]);
        }
        let next = Block {
            theta: Vec3::from_array(th_sum),
            a: Mat::from_fn(|i, j| row_w[i].mul_add(a.m[i][j], c.a.m[i][j])),
            w_xy: c.w_xy + w,
            w_z: c.w_z + w_z,
            n_xy: c.n_xy + T::select(w.simd_gt(zero), T::one(), zero),
            n_z: c.n_z + T::select(w_z.simd_gt(zero), T::one(), zero),
        };
        self.current = Block::select(live, &next, &self.current);
        self.q_w = Quat::select(live, q_w, self.q_w);
        self.a = Mat::select(live, &a, &self.a);
        self.elapsed = T::select(live, self.elapsed + dt, self.elapsed);
        self.turned = T::select(live, rate.norm().mul_add(dt, self.turned), self.turned);

        let closed = live & self.elapsed.simd_ge(self.block);
        if closed.any() {
            let measure = closed & self.second;
            if measure.any() {
                self.measure(measure);
            }
            // A closed first block is kept; a closed second block ends the window.
            self.first = Block::select(closed & !self.second, &self.current, &self.first);
            self.current = Block::select(closed, &Block::zero(), &self.current);
            self.elapsed = T::select(closed, zero, self.elapsed);
            let ended = measure;
            self.second = (self.second & !closed) | (closed & !self.second);
            // A new window: anchor on the fused orientation, restart the sensitivity.
            let restart = ended | start;
            self.q_w = Quat::select(restart, fused, self.q_w);
            self.a = Mat::select(restart, &Mat::zeros(), &self.a);
            self.turned = T::select(restart, zero, self.turned);
        } else {
            self.q_w = Quat::select(start, fused, self.q_w);
        }
    }

    fn nine_d_mask(&self) -> T::Mask {
        <T::Mask as Mask>::splat(self.nine_d)
    }

    /// The drift measurement of the lanes in `measure` (a closed second block).
    fn measure(&mut self, measure: T::Mask) {
        let zero = T::zero();
        let rows = if self.nine_d { 3 } else { 2 };
        let mut m1 = [(zero, Vector::zeros(), zero); 3];
        let mut m2 = m1;
        for i in 0..rows {
            m1[i] = self.first.mean_row(i);
            m2[i] = self.current.mean_row(i);
        }
        // The linear model holds near the anchor only.
        let mut small = <T::Mask as Mask>::splat(true);
        let g2 = self.gate * self.gate;
        let (mut n1, mut n2) = (zero, zero);
        for i in 0..rows {
            n1 = m1[i].0.mul_add(m1[i].0, n1);
            n2 = m2[i].0.mul_add(m2[i].0, n2);
        }
        small &= n1.simd_le(g2) & n2.simd_le(g2);
        let b = self.bias.to_vector();
        let mut pending = measure;
        for i in 0..rows {
            let h = m2[i].1 - m1[i].1;
            let z = (m2[i].0 - m1[i].0) + h.dot(&b);
            let (w1, w2) = (m1[i].2, m2[i].2);
            let usable = measure & small & w1.simd_gt(zero) & w2.simd_gt(zero);
            // var = noise²·(1/w̄₁ + 1/w̄₂) + (scale·turned)².
            let var = (T::one() / w1 + T::one() / w2) / self.inv_noise2
                + self.scale2 * self.turned * self.turned;
            // Innovation gate: accelerometer errors are correlated over blocks (translation,
            // centripetal acceleration) and a window they corrupt must not teach the estimate.
            let p = self.rls.covariance();
            let ph = p * h;
            let innovation = z - h.dot(&self.rls.estimate());
            let expected = h.dot(&ph) + var;
            let plausible = (innovation * innovation).simd_le(T::from_f64(GATE_SIGMA2) * expected);
            let weight = T::select(usable & plausible, T::one() / var, zero);
            let ok = self.rls.update_with_forgetting(&h, z, weight, pending);
            pending &= !ok;
        }
        let x = self.estimate();
        let updated = measure & !pending;
        self.bias = Vec3::select(updated, clamp_norm(x, self.max), self.bias);
    }
}
