//! The 7-state quaternion + gyro-bias extended Kalman filter [`ekf`]: the "plain EKF".

use super::LaneParams;
use super::{
    Dof, OrientationFilter, Rejections, ScreenBounds, Screened, initialise, mag_reference, params,
    up,
};
use super::{StateError, checked_bias, checked_quat, checked_sigma};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask, Mat};

params! {
    /// Parameters of [`Ekf`].
    pub struct EkfParams {
        /// Gyroscope white-noise density.
        gyr_noise: f64 = 0.005, "rad/s/√Hz", [1e-9, 10.0];
        /// Gyro-bias random-walk density.
        bias_walk: f64 = 2e-5, "rad/s²/√Hz", [0.0, 10.0];
        /// Standard deviation of the unit accelerometer direction (includes unmodelled acceleration).
        acc_noise: f64 = 0.05, "1", [1e-6, 10.0];
        /// Standard deviation of the unit magnetometer direction (includes disturbances).
        mag_noise: f64 = 0.1, "1", [1e-6, 10.0];
        /// Accelerometer corrections are skipped when `|‖a‖ − g| > acc_gate·g`.
        acc_gate: f64 = 0.15, "1", [0.0, 100.0];
        /// Gravity magnitude used by the gate.
        gravity: f64 = 9.81, "m/s²", [0.1, 100.0];
        /// Initial standard deviation of each gyro-bias component.
        init_bias_std: f64 = 0.01, "rad/s", [1e-9, 10.0];
        /// 9: use the magnetometer; 6: gravity only.
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// Additive-quaternion EKF with state `x = [q0..q3, bx, by, bz]`:
/// `q_k = q_{k−1} ⊗ exp((ω − b)·T/2)` (the exact map; its Jacobian is taken as
/// `F = [[I + (T/2)·Ω(ω − b), −(T/2)·Ξ(q)], [0, I3]]`), `Q = ΓWΓᵀ` from the gyro noise and
/// bias random walk; measurements are the unit accelerometer (predicted `q* ⊗ up ⊗ q`) and
/// unit magnetometer (predicted `q* ⊗ b ⊗ q`, `b = [0, |h_xy|, h_z]`) with Jacobian
/// `2·vec(L(q* ⊗ d))`. Joseph-form covariance updates; the innovation covariance is
/// Cholesky-factored per lane and a lane whose factorisation fails skips that update
/// (counted as gated).
#[derive(Clone, Debug)]
pub struct Ekf<T: Lane> {
    q: Quat<T>,
    bias: Vec3<T>,
    p: Mat<T, 7, 7>,
    initialized: T::Mask,
    gyr_var: T,
    bias_var: T,
    acc_var: T,
    mag_var: T,
    acc_gate: T,
    gravity: T,
    nine_d: bool,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    /// `init_bias_std²`, rad²/s², for `reset`.
    init_bias_var: T,
    params: EkfParams,
}

impl<T: Lane> Ekf<T> {
    crate::filters::uniform_constructors!(EkfParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(p: &LaneParams<'_, EkfParams, T>) -> Self {
        let init_bias_var = p.coef(|p| p.init_bias_std * p.init_bias_std);
        let x = State::new(init_bias_var);
        Self {
            q: x.q,
            bias: x.bias,
            p: x.p,
            initialized: <T::Mask as Mask>::splat(false),
            gyr_var: p.coef(|p| p.gyr_noise * p.gyr_noise),
            bias_var: p.coef(|p| p.bias_walk * p.bias_walk),
            acc_var: p.coef(|p| p.acc_noise * p.acc_noise),
            mag_var: p.coef(|p| p.mag_noise * p.mag_noise),
            acc_gate: p.coef(|p| p.acc_gate * p.gravity),
            gravity: p.coef(|p| p.gravity),
            nine_d: p.first().dof.uses_magnetometer(),
            bounds: p.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            init_bias_var,
            params: p.first().clone(),
        }
    }
    /// The 7×7 state covariance (quaternion components, then bias).
    pub fn covariance(&self) -> &Mat<T, 7, 7> {
        &self.p
    }

    /// One vector measurement `s ≈ q* ⊗ d ⊗ q`; returns the lanes where it was applied.
    fn correct(&mut self, d: Vec3<T>, s: Vec3<T>, var: T, apply: T::Mask) -> T::Mask {
        let q = self.q;
        let pq = q.conj() * Quat::pure(d);
        let two = T::from_f64(2.0);
        let h = Mat::<T, 3, 7>::from_rows([
            [
                pq.x * two,
                pq.w * two,
                -pq.z * two,
                pq.y * two,
                T::zero(),
                T::zero(),
                T::zero(),
            ],
            [
                pq.y * two,
                pq.z * two,
                pq.w * two,
                -pq.x * two,
                T::zero(),
                T::zero(),
                T::zero(),
            ],
            [
                pq.z * two,
                -pq.y * two,
                pq.x * two,
                pq.w * two,
                T::zero(),
                T::zero(),
                T::zero(),
            ],
        ]);
        let r = Mat::<T, 3, 3>::identity().scale(var);
        let y = (s - q.rotate_inverse(d)).to_vector();
        let state = State {
            q: self.q,
            bias: self.bias,
            p: self.p,
        };
        let (next, accept) = state.update(&h, &y, &r, apply);
        self.rejections.gate(apply & !accept);
        (self.q, self.bias, self.p) = (next.q, next.bias, next.p);
        accept
    }
}

impl<T: Lane> OrientationFilter<T> for Ekf<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let (q_prev, b_prev, p_prev) = (self.q, self.bias, self.p);
        let q = initialise(self.q, &mut self.initialized, &s, self.nine_d);

        let state = State {
            q,
            bias: self.bias,
            p: self.p,
        }
        .predict(s.gyr, s.dt, self.gyr_var, self.bias_var);
        (self.q, self.p) = (state.q, state.p);

        // Corrections.
        let acc_in_gate = (s.acc_norm - self.gravity).abs().simd_le(self.acc_gate);
        self.rejections.gate(s.acc_ok & !acc_in_gate);
        self.correct(up(), s.acc, self.acc_var, s.acc_ok & acc_in_gate);
        // 6D is the same for every lane and discards this update: skipping it changes no bits.
        if self.nine_d {
            let b = mag_reference(self.q, s.mag).try_normalize().0;
            self.correct(b, s.mag, self.mag_var, s.mag_ok);
        }

        self.q = Quat::select(s.step, self.q, q_prev);
        self.bias = Vec3::select(s.step, self.bias, b_prev);
        self.p = Mat::select(s.step, &self.p, &p_prev);
    }
    fn reset(&mut self) {
        let x = State::new(self.init_bias_var);
        (self.q, self.bias, self.p) = (x.q, x.bias, x.p);
        self.initialized = <T::Mask as Mask>::splat(false);
        self.rejections = Rejections::default();
    }
    fn set_quat(&mut self, q: Quat<T>, sigma: Option<T>) -> Result<(), StateError> {
        let q = checked_quat(q)?;
        if let Some(sigma) = sigma {
            let sigma = checked_sigma(sigma, core::f64::consts::PI)?;
            // `δq = ½·Jᵀ·δθ` inverts `δθ = 2·J·δq` (`J·Jᵀ = I`, `J·q = 0`): a global error
            // of `σ²·I` is `P_qq = ¼·σ²·(I − q·qᵀ)`, uncorrelated with the bias.
            let qv = [q.w, q.x, q.y, q.z];
            let quarter = sigma * sigma * T::from_f64(0.25);
            for i in 0..7 {
                for j in 0..7 {
                    if i < 4 && j < 4 {
                        let eye = if i == j { T::one() } else { T::zero() };
                        self.p.m[i][j] = quarter * (eye - qv[i] * qv[j]);
                    } else if (i < 4) != (j < 4) {
                        self.p.m[i][j] = T::zero();
                    }
                }
            }
        }
        self.q = q;
        self.initialized = <T::Mask as Mask>::splat(true);
        Ok(())
    }
    fn set_bias(&mut self, bias: Vec3<T>, sigma: Option<T>) -> Result<(), StateError> {
        let bias = checked_bias(bias)?;
        if let Some(sigma) = sigma {
            set_bias_variance(&mut self.p, checked_sigma(sigma, 1.0)? * sigma);
        }
        self.bias = bias;
        Ok(())
    }
    fn quat(&self) -> Quat<T> {
        self.q
    }
    fn bias(&self) -> Vec3<T> {
        self.bias
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
    fn attitude_covariance(&self) -> Option<Mat<T, 3, 3>> {
        Some(
            State {
                q: self.q,
                bias: self.bias,
                p: self.p,
            }
            .attitude_covariance(),
        )
    }
}

/// The bias block of a 7-state covariance becomes `var·I` (rad²/s²), uncorrelated with the
/// quaternion.
pub(crate) fn set_bias_variance<T: Lane>(p: &mut Mat<T, 7, 7>, var: T) {
    for i in 4..7 {
        for j in 0..7 {
            let v = if i == j { var } else { T::zero() };
            p.m[i][j] = v;
            p.m[j][i] = v;
        }
    }
}

/// The state of a 7-state quaternion + gyro-bias EKF: shared by [`Ekf`] and
/// [`EcfEkf`](super::EcfEkf), so the prediction and the measurement update exist once.
#[derive(Clone, Copy, Debug)]
pub(crate) struct State<T: Lane> {
    /// Orientation, sensor to earth.
    pub q: Quat<T>,
    /// Gyro bias, rad/s.
    pub bias: Vec3<T>,
    /// Covariance of `[q0..q3, bx, by, bz]`.
    pub p: Mat<T, 7, 7>,
}

impl<T: Lane> State<T> {
    /// The quaternion block `P_qq` mapped to the global attitude error (rad², earth frame):
    /// to first order `δq = ½·[0, δθ] ⊗ q`, so `δθ = 2·vec(δq ⊗ q*) = 2·J·δq` with
    /// `J = [−v | w·I + [v]×]` (`q = [w, v]`), and `Σ_θ = 4·J·P_qq·Jᵀ`.
    pub fn attitude_covariance(&self) -> Mat<T, 3, 3> {
        let (w, v) = (self.q.w, [self.q.x, self.q.y, self.q.z]);
        let j = Mat::<T, 3, 4>::from_rows([
            [-v[0], w, -v[2], v[1]],
            [-v[1], v[2], w, -v[0]],
            [-v[2], -v[1], v[0], w],
        ]);
        let p_qq = Mat::<T, 4, 4>::from_fn(|r, c| self.p.m[r][c]);
        j.congruence(&p_qq).scale(T::from_f64(4.0))
    }
    /// The identity orientation with variance 0.01 per quaternion component, zero bias with
    /// variance `init_bias_var` (rad²/s²) per axis.
    pub fn new(init_bias_var: T) -> Self {
        let mut p = Mat::<T, 7, 7>::identity().scale(T::from_f64(0.01));
        for i in 4..7 {
            p.m[i][i] = init_bias_var;
        }
        Self {
            q: Quat::identity(),
            bias: Vec3::zero(),
            p,
        }
    }
    /// Prediction over `dt` with body rate `gyr` (rad/s): `q ⊗ exp((ω − b)·dt/2)`, the bias
    /// held, `P = F·P·Fᵀ + ΓWΓᵀ` with `F = [[I + (T/2)·Ω(ω − b), −(T/2)·Ξ(q)], [0, I3]]`,
    /// the gyro noise variance density `gyr_var` entering through `(T/2)·Ξ(q)` and the bias
    /// random-walk variance density `bias_var` on the bias block.
    pub fn predict(self, gyr: Vec3<T>, dt: T, gyr_var: T, bias_var: T) -> Self {
        let q = self.q;
        let w = gyr - self.bias;
        let half_dt = dt * T::from_f64(0.5);
        let q_pred = (q * Quat::from_rotation_vector(w * dt)).normalize();
        let (wx, wy, wz) = (w.x * half_dt, w.y * half_dt, w.z * half_dt);
        let one = T::one();
        let xi = Mat::<T, 4, 3>::from_rows([
            [-q.x, -q.y, -q.z],
            [q.w, -q.z, q.y],
            [q.z, q.w, -q.x],
            [-q.y, q.x, q.w],
        ]);
        let mut f = Mat::<T, 7, 7>::identity();
        let a = [
            [one, -wx, -wy, -wz],
            [wx, one, wz, -wy],
            [wy, -wz, one, wx],
            [wz, wy, -wx, one],
        ];
        for ((row, a_row), xi_row) in f.m.iter_mut().zip(&a).zip(&xi.m) {
            row[..4].copy_from_slice(a_row);
            for (dst, x) in row[4..].iter_mut().zip(xi_row) {
                *dst = -*x * half_dt;
            }
        }
        let gq = xi.scale(half_dt);
        let q_noise = (gq * gq.transpose()).scale(gyr_var * dt);
        let mut p = f.congruence(&self.p);
        for (row, noise) in p.m.iter_mut().zip(&q_noise.m) {
            for (x, n) in row.iter_mut().zip(noise) {
                *x += *n;
            }
        }
        for i in 4..7 {
            p.m[i][i] += bias_var * dt;
        }
        Self {
            q: q_pred,
            bias: self.bias,
            p,
        }
    }

    /// Measurement update with Jacobian `h` (M×7), residual `y = z − h(x)` and noise `r`,
    /// Joseph form, quaternion renormalised; the innovation covariance is Cholesky-factored per
    /// lane. Returns the new state where `apply` and the update is sound (factorisation
    /// succeeded, everything finite), else the old one, and the mask of applied lanes.
    pub fn update<const M: usize>(
        self,
        h: &Mat<T, M, 7>,
        y: &Mat<T, M, 1>,
        r: &Mat<T, M, M>,
        apply: T::Mask,
    ) -> (Self, T::Mask) {
        let q = self.q;
        let pht = self.p * h.transpose();
        let innovation_cov = *h * pht + *r;
        let (l, ok) = innovation_cov.cholesky();
        // K = P·Hᵀ·S⁻¹, computed as (S⁻¹·H·P)ᵀ since S and P are symmetric.
        let k = l.cholesky_solve(&pht.transpose()).transpose();
        let dx = k * *y;
        let ikh = Mat::<T, 7, 7>::identity() - k * *h;
        let p_new = (ikh.congruence(&self.p) + k.congruence(r)).symmetrize();
        let q_new = Quat::new(q.w + dx[0], q.x + dx[1], q.y + dx[2], q.z + dx[3]);
        let (q_new, q_ok) = q_new.try_normalize();
        let b_new = self.bias + Vec3::new(dx[4], dx[5], dx[6]);
        let accept = apply & ok & q_ok & p_new.is_finite() & b_new.is_finite();
        let next = Self {
            q: Quat::select(accept, q_new, q),
            bias: Vec3::select(accept, b_new, self.bias),
            p: Mat::select(accept, &p_new, &self.p),
        };
        (next, accept)
    }
}
