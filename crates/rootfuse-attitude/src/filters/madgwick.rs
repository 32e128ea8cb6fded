//! Madgwick's gradient-descent filter [`madgwick`].

use super::LaneParams;
use super::{
    Dof, OrientationFilter, Rejections, ScreenLimits, Screened, initialise, mag_reference, params,
};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask};

params! {
    /// Parameters of [`Madgwick`].
    pub struct MadgwickParams {
        /// Gradient step gain β (the gyroscope-error rate it can correct). The default is the
        /// one value that matches the reference implementation's BROAD accuracy on all four
        /// trials: larger β follows accelerations (trial 16) better, smaller β magnetic
        /// disturbances (trial 29).
        beta: f64 = 0.0525, "rad/s", [0.0, 10.0];
        /// Gyro-bias drift gain ζ of the paper's MARG variant (0 disables bias estimation).
        zeta: f64 = 0.0, "rad/s²", [0.0, 10.0];
        /// 9: use the magnetometer; 6: gravity only.
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// Madgwick, Harrison & Vaidyanathan (2011): `q̇ = ½·q ⊗ (ω − b) − β·∇f/|∇f|`, with
/// `f = q* ⊗ d ⊗ q − s` for the reference directions `d` (up; and the field reference
/// `[0, |h_xy|, h_z]` in ENU) and the measured unit vectors `s`.
///
/// The gradient is computed in closed form as `∇(½|f|²) = −2·d ⊗ q ⊗ f` (pure quaternions),
/// which needs no hand-expanded Jacobian; the magnetic reference takes the horizontal and
/// vertical field components from the rotated measurement, so there is no factor-of-2 error
/// in them. Gyro bias (section "gyroscope bias drift compensation" of the paper):
/// `ḃ = ζ·vec(2·q* ⊗ ∇f/|∇f|)`.
#[derive(Clone, Debug)]
pub struct Madgwick<T: Lane> {
    q: Quat<T>,
    bias: Vec3<T>,
    initialized: T::Mask,
    beta: T,
    zeta: T,
    /// `ζ = 0` in every lane (the default): the bias stays where it is, so its update is
    /// skipped (the same bits), which takes it off the dependency chain.
    zeta_off: bool,
    nine_d: bool,
    limits: ScreenLimits,
    rejections: Rejections<T>,
    params: MadgwickParams,
}

impl<T: Lane> Madgwick<T> {
    crate::filters::uniform_constructors!(MadgwickParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(p: &LaneParams<'_, MadgwickParams, T>) -> Self {
        Self {
            q: Quat::identity(),
            bias: Vec3::zero(),
            initialized: <T::Mask as Mask>::splat(false),
            beta: p.coef(|p| p.beta),
            zeta: p.coef(|p| p.zeta),
            zeta_off: p.sets().iter().all(|set| set.zeta == 0.0),
            nine_d: p.first().dof.uses_magnetometer(),
            limits: p.first().screen_limits(),
            rejections: Rejections::default(),
            params: p.first().clone(),
        }
    }
}

/// `∇(½|q* ⊗ d ⊗ q − s|²)` with respect to the four components of `q`.
#[inline]
fn gradient<T: Lane>(q: Quat<T>, d: Vec3<T>, s: Vec3<T>) -> Quat<T> {
    let f = q.rotate_inverse(d) - s;
    (Quat::pure(d) * q).times_pure(f).scale(T::from_f64(-2.0))
}

/// [`gradient`] for `d` = up: `q* ⊗ up ⊗ q` is [`Quat::up_in_sensor`] and `[0, up] ⊗ q` is
/// `[−z, −y, x, w]`, a permutation, in a third of the operations.
#[inline]
fn gradient_up<T: Lane>(q: Quat<T>, s: Vec3<T>) -> Quat<T> {
    let f = q.up_in_sensor() - s;
    Quat::new(-q.z, -q.y, q.x, q.w)
        .times_pure(f)
        .scale(T::from_f64(-2.0))
}

impl<T: Lane> OrientationFilter<T> for Madgwick<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.limits, &mut self.rejections, self.nine_d);
        let q = initialise(self.q, &mut self.initialized, &s, self.nine_d);

        let zero = Quat::new(T::zero(), T::zero(), T::zero(), T::zero());
        let g_acc = Quat::select(s.acc_ok, gradient_up(q, s.acc), zero);
        // 6D is the same for every lane and discards this term: skipping it changes no bits.
        let g_mag = if self.nine_d {
            Quat::select(s.mag_ok, gradient(q, mag_reference(q, s.mag), s.mag), zero)
        } else {
            zero
        };
        let (step, has_step) = (g_acc + g_mag).try_normalize();
        let step = Quat::select(has_step, step, zero);

        let bias = if self.zeta_off {
            self.bias
        } else {
            let omega_err = (q.conj() * step).vector() * T::from_f64(2.0);
            self.bias + omega_err * (self.zeta * s.dt)
        };
        let q_dot = (q * Quat::pure(s.gyr - bias)).scale(T::from_f64(0.5)) - step.scale(self.beta);
        let q_new = (q + q_dot.scale(s.dt)).normalize();
        self.q = Quat::select(s.step, q_new, self.q);
        self.bias = Vec3::select(s.step, bias, self.bias);
    }
    crate::filters::quat_bias_state!();
    fn quat(&self) -> Quat<T> {
        self.q
    }
    fn bias(&self) -> Vec3<T> {
        self.bias
    }
    fn rejections(&self) -> &Rejections<T> {
        &self.rejections
    }
}
