//! The flagship's online estimate of the gyroscope's scale factors (`gyr_scale_window`): the
//! filter's own inclination corrections over a window, regressed on the rotation the
//! gyroscope measured in it (the design in docs/methods.md).

use super::*;
use rootfuse_lane::mat::Vector;

/// The regularisation of the nuisance unknowns (the window's residual bias times its time,
/// rad): only against a singular system, far below any window's own weight.
const BIAS_RIDGE: f64 = 1e-6;

/// Largest scale error taken from a solve (a fraction): a gyroscope further off is broken, not
/// miscalibrated, and such a solution is a regression gone wrong (kept: the last estimate).
const MAX_SCALE_ERROR: f64 = 0.05;

lane_state! {
    /// Per-lane state of the scale-factor estimate.
    pub(super) struct GyroScale<T: Lane> {
        /// The estimated scale error per sensor axis, `s` in `ω_m = (1 + s)·ω` (a fraction).
        scale: Vec3<T>,
        /// `1/(1 + s)` per axis, what the readings are multiplied by.
        factor: Vec3<T>,
        /// The window's sums: `Σ R_xy·diag(ω)·dt` (rad) and `Σ R_xy·dt` (s), `R_xy` the
        /// earth-x and earth-y rows of `R(q6)`, `ω` the corrected bias-free rate.
        rotation: Mat<T, 2, 3>,
        time_sum: Mat<T, 2, 3>,
        /// `Σ |â − up|²` over the window's `samples` usable accelerometer readings (`up` in the
        /// sensor frame), the window's time (s) and the filter's age at its start (s).
        disagreement: T,
        samples: T,
        time: T,
        start_age: T,
        /// The correction `c` at the window's start.
        start: Quat<T>,
        /// The weighted normal equations of every window so far in the unknowns
        /// `[s, δb·T]`: `δb` the residual bias the filter's estimate left, one for every
        /// window so far (a nuisance), times a window's time `T` (rad).
        normal: Mat<T, 6, 6>,
        rhs: Vector<T, 6>,
    }
}

impl<T: Lane> GyroScale<T> {
    /// No estimate yet (factors one), an empty window.
    pub(super) fn new() -> Self {
        let zero = T::zero();
        Self {
            scale: Vec3::zero(),
            factor: Vec3::new(T::one(), T::one(), T::one()),
            rotation: Mat::zeros(),
            time_sum: Mat::zeros(),
            disagreement: zero,
            samples: zero,
            time: zero,
            start_age: zero,
            start: Quat::identity(),
            normal: Mat::zeros(),
            rhs: Mat::zeros(),
        }
    }

    /// The estimated scale error per sensor axis (a fraction; zero before the first estimate
    /// or with the estimate off).
    pub(super) fn scale(&self) -> Vec3<T> {
        self.scale
    }

    /// The gyroscope's readings (rad/s) divided by their estimated scale, `ω_m/(1 + s)` per
    /// axis (the readings themselves, bit for bit, where no estimate was made).
    #[inline(always)]
    pub(super) fn corrected(&self, gyr: Vec3<T>) -> Vec3<T> {
        let f = self.factor;
        Vec3::new(gyr.x * f.x, gyr.y * f.y, gyr.z * f.z)
    }

    /// A new window in the lanes `lanes`, starting from the correction `c` at the filter's
    /// age `age` (s).
    pub(super) fn restart(&mut self, lanes: T::Mask, c: Quat<T>, age: T) {
        let zero = T::zero();
        self.rotation = Mat::select(lanes, &Mat::zeros(), &self.rotation);
        self.time_sum = Mat::select(lanes, &Mat::zeros(), &self.time_sum);
        self.disagreement = T::select(lanes, zero, self.disagreement);
        self.samples = T::select(lanes, zero, self.samples);
        self.time = T::select(lanes, zero, self.time);
        self.start_age = T::select(lanes, age, self.start_age);
        self.start = Quat::select(lanes, c, self.start);
    }

    /// One sample into the window: `r = R(q6)` (sensor to earth), `w` the corrected,
    /// bias-free rate (rad/s), `dt` (s, zero where the sample was skipped), `acc` the unit
    /// specific force where `acc_ok`.
    #[inline]
    pub(super) fn accumulate(
        &mut self,
        r: &Mat<T, 3, 3>,
        w: Vec3<T>,
        dt: T,
        acc: Vec3<T>,
        acc_ok: T::Mask,
    ) {
        let turned = [w.x * dt, w.y * dt, w.z * dt];
        for i in 0..2 {
            for (j, turn) in turned.iter().enumerate() {
                self.rotation.m[i][j] = r.m[i][j].mul_add(*turn, self.rotation.m[i][j]);
                self.time_sum.m[i][j] = r.m[i][j].mul_add(dt, self.time_sum.m[i][j]);
            }
        }
        let up = Vec3::new(r.m[2][0], r.m[2][1], r.m[2][2]);
        let zero = T::zero();
        self.disagreement += T::select(acc_ok, (acc - up).norm_squared(), zero);
        self.samples += T::select(acc_ok, T::one(), zero);
        self.time += dt;
    }

    /// Where a lane's window has reached `gyr_scale_window`: the window's equations added to
    /// the normal equations and the scale solved for, then a new window from the correction
    /// `c` (the filter's age `age`, s). Over the window the tilt part of the correction's
    /// change, `Δc_xy`, answers the drift the scale error made: `Δc_xy ≈ −A·(s − ŝ) − B̄·δb·T`
    /// (`A`, `B̄ = B/T` the window's sums, `ŝ` the estimate the window ran with), weighted by
    /// `1/(1 + (d/gate)⁴)` of the accelerometer's rms disagreement `d` with up (a window
    /// with motion acceleration says less); windows that started during the start-up, or
    /// without a usable accelerometer reading, count nothing.
    pub(super) fn close(&mut self, c: Quat<T>, age: T, coef: &Coefficients<T>) {
        let zero = T::zero();
        let one = T::one();
        let due = self.time.simd_ge(coef.gyr_scale_window) & coef.gyr_scale_window.simd_gt(zero);
        if !due.any() {
            return;
        }
        let counted = due & self.start_age.simd_ge(coef.startup_time) & self.samples.simd_gt(zero);
        let x2 = self.disagreement / (self.samples.max(one) * coef.gyr_scale_gate2);
        let weight = T::select(counted, one / x2.mul_add(x2, one), zero);
        let turn = (c * self.start.conj()).to_rotation_vector();
        let per_time = one / self.time.max(coef.gyr_scale_window);
        let mut normal = self.normal;
        let mut rhs = self.rhs;
        for (i, dc) in [turn.x, turn.y].into_iter().enumerate() {
            let a = self.rotation.m[i];
            let b = self.time_sum.m[i];
            let row = [
                -a[0],
                -a[1],
                -a[2],
                -(b[0] * per_time),
                -(b[1] * per_time),
                -(b[2] * per_time),
            ];
            let predicted = a[0] * self.scale.x + a[1] * self.scale.y + a[2] * self.scale.z;
            let y = dc - predicted;
            for p in 0..6 {
                let wp = weight * row[p];
                for q in 0..6 {
                    normal.m[p][q] = wp.mul_add(row[q], normal.m[p][q]);
                }
                rhs.m[p][0] = wp.mul_add(y, rhs.m[p][0]);
            }
        }
        self.normal = Mat::select(counted, &normal, &self.normal);
        self.rhs = Mat::select(counted, &rhs, &self.rhs);
        // The prior on `s`: `gyr_scale_ridge` on the axes' mean and `gyr_scale_axis_ridge` on
        // their differences from it, `λ_d·I + (λ_c − λ_d)/3·11ᵀ`.
        let mut regularised = self.normal;
        for k in 0..3 {
            for l in 0..3 {
                regularised.m[k][l] += coef.gyr_scale_common;
            }
            regularised.m[k][k] += coef.gyr_scale_axis_ridge;
            regularised.m[k + 3][k + 3] += T::from_f64(BIAS_RIDGE);
        }
        let (l, solved) = regularised.cholesky();
        let x = l.cholesky_solve(&self.rhs);
        let scale = Vec3::new(x.m[0][0], x.m[1][0], x.m[2][0]);
        let limit = T::from_f64(MAX_SCALE_ERROR);
        let plausible = scale.x.abs().simd_lt(limit)
            & scale.y.abs().simd_lt(limit)
            & scale.z.abs().simd_lt(limit);
        let take = counted & solved & plausible;
        self.scale = Vec3::select(take, scale, self.scale);
        let factor = Vec3::new(
            one / (one + scale.x),
            one / (one + scale.y),
            one / (one + scale.z),
        );
        self.factor = Vec3::select(take, factor, self.factor);
        self.restart(due, c, age);
    }
}

impl<T: Lane> SqrtEskf<T> {
    /// Whether any lane estimates the gyroscope's scale (`gyr_scale_window > 0`).
    #[inline]
    pub(super) fn estimates_gyro_scale(&self) -> bool {
        self.coef.gyr_scale_window.simd_gt(T::zero()).any()
    }
}
