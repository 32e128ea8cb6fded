//! Mahony's explicit complementary filter [`mahony`].

use super::LaneParams;
use super::{Dof, OrientationFilter, Rejections, ScreenBounds, Screened, initialise, params};
use crate::blocks::{heading_sine_times_previous, integrate_gyro};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask};

params! {
    /// Parameters of [`Mahony`].
    pub struct MahonyParams {
        /// Proportional gain on the vector-alignment error.
        kp: f64 = 0.5, "rad/s", [0.0, 100.0];
        /// Integral gain (gyro-bias estimation).
        ki: f64 = 0.02, "rad/s²", [0.0, 100.0];
        /// Largest bias estimate magnitude the integral may reach (anti-windup).
        max_bias: f64 = 0.2, "rad/s", [0.0, 10.0];
        /// The bias integral learns only while the alignment error `|e|` is below this (about
        /// 6° by default): a large error is a transient (start-up, a disturbance), not bias.
        bias_gate: f64 = 0.1, "1", [0.0, 10.0];
        /// 9: use the magnetometer; 6: gravity only.
        dof: Dof = 9.0, "1", [6.0, 9.0];
    }
}

/// Mahony, Hamel & Pflimlin (2008), "Nonlinear complementary filters on the special
/// orthogonal group", explicit complementary filter with bias:
/// `e = â × v̂ + sin(Δψ)·v̂`, `ω_c = ω − b̂ + Kp·e`, `ḃ = −Ki·e`, `q̇ = ½·q ⊗ ω_c`, with `v̂`
/// the predicted up direction in the sensor frame and `Δψ` the tilt-compensated magnetic
/// heading error (rad).
///
/// The paper's magnetometer term `m̂ × ŵ` has a gain on heading of only `cos²(dip)` (about
/// 0.19 at 64° dip) and also acts on inclination; the heading error about the up axis has
/// unit gain and cannot tilt the estimate, so the same `Kp`/`Ki` serve both axes. Its sine
/// (`h_x/|h_xy|` of the field in the earth frame, ±1 beyond 90°;
/// [`heading_sine_times_previous`](crate::blocks::heading_sine_times_previous)) is normalised
/// by the previous sample's `|h_xy|`, so no square root, division or `atan2` lies between one
/// sample's orientation and the next: the update's cost is that chain's length.
#[derive(Clone, Debug)]
pub struct Mahony<T: Lane> {
    q: Quat<T>,
    bias: Vec3<T>,
    initialized: T::Mask,
    /// `|h_xy|` of the last field that gave a heading (0 before the first): the heading
    /// error's normalisation, one sample old.
    hxy: T,
    /// `2·Kp` and `2·Ki`: the update works with `e/2` (see `update`).
    kp2: T,
    ki2: T,
    max_bias: T,
    /// `max_bias²`: the anti-windup test compares squared norms too.
    max_bias2: T,
    /// `bias_gate²/4`: the gate compares the squared norm of `e/2` (no square root on the
    /// update's dependency chain).
    bias_gate2_quarter: T,
    nine_d: bool,
    bounds: ScreenBounds<T>,
    rejections: Rejections<T>,
    params: MahonyParams,
}

impl<T: Lane> Mahony<T> {
    crate::filters::uniform_constructors!(MahonyParams);

    /// A filter whose lanes may have different parameters ([`LaneParams`]); the structural
    /// ones (`dof`, switches, window lengths, screening limits) come from the first set.
    pub fn with_lane_params(p: &LaneParams<'_, MahonyParams, T>) -> Self {
        Self {
            q: Quat::identity(),
            bias: Vec3::zero(),
            initialized: <T::Mask as Mask>::splat(false),
            hxy: T::zero(),
            kp2: p.coef(|p| 2.0 * p.kp),
            ki2: p.coef(|p| 2.0 * p.ki),
            max_bias: p.coef(|p| p.max_bias),
            max_bias2: p.coef(|p| p.max_bias * p.max_bias),
            bias_gate2_quarter: p.coef(|p| p.bias_gate * p.bias_gate / 4.0),
            nine_d: p.first().dof.uses_magnetometer(),
            bounds: p.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            params: p.first().clone(),
        }
    }
}

impl<T: Lane> OrientationFilter<T> for Mahony<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let q = initialise(self.q, &mut self.initialized, &s, self.nine_d);

        // The error is formed halved, `e/2 = â × v̂/2 + Δψ/2·v̂`, and the factor two folded into
        // the gains: the same bits (scaling by two commutes with rounding), one multiply fewer
        // on the dependency chain.
        let v_half = q.half_up_in_sensor();
        let e_acc = Vec3::select(s.acc_ok, s.acc.cross(v_half), Vec3::zero());
        // 6D is the same for every lane and discards this term: skipping it changes no bits
        // (but the sign of a zero).
        let e_half = if self.nine_d {
            let (sine_hxy, hxy, heading_ok) =
                heading_sine_times_previous(q.rotate(s.mag), self.hxy);
            // 1/|h_xy| of the previous field is known before this sample's orientation: its
            // division is off the dependency chain, and so is its product with `v̂/2`.
            let known = self.hxy.simd_gt(T::zero());
            let v_scaled = v_half * T::select(known, self.hxy.recip(), T::zero());
            let corrects = s.mag_ok & heading_ok;
            self.hxy = T::select(corrects & s.step, hxy, self.hxy);
            e_acc + Vec3::select(corrects, v_scaled * sine_hxy, Vec3::zero())
        } else {
            // Not `e_acc + 0`: IEEE arithmetic cannot fold that addition away (−0 + 0 = +0),
            // and it would lengthen the dependency chain.
            e_acc
        };

        let learn = e_half.norm_squared().simd_lt(self.bias_gate2_quarter);
        let learned = self.bias - e_half * (self.ki2 * s.dt);
        // A uniform branch, predicted, takes the gate's comparison off the dependency chain;
        // every lane gets what the select would give it.
        let bias = if learn.all() {
            learned
        } else {
            Vec3::select(learn, learned, self.bias)
        };
        // Anti-windup: scale the bias back onto the ball of radius max_bias. Inside the ball
        // the bias is kept as it is: `max_bias / max_bias` would be 0/0 with `max_bias = 0`.
        let outside = bias.norm_squared().simd_gt(self.max_bias2);
        // Uniform across lanes and off the dependency chain once predicted: the square root
        // and division are skipped when no lane needs them (the select would keep `bias` in
        // every lane anyway).
        let bias = if outside.any() {
            Vec3::select(outside, bias * (self.max_bias / bias.norm()), bias)
        } else {
            bias
        };
        let omega = s.gyr - bias + e_half * self.kp2;
        let q_new = integrate_gyro(q, omega, s.dt);

        self.q = Quat::select(s.step, q_new, self.q);
        self.bias = Vec3::select(s.step, bias, self.bias);
    }
    crate::filters::quat_bias_state!(hxy: T::zero());
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
