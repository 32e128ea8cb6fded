//! Madgwick's gradient-descent filter [`madgwick`].

use super::LaneParams;
use super::{Dof, OrientationFilter, Rejections, ScreenBounds, Screened, initialise, params};
use crate::{ImuSample, Quat, Vec3};
use rootfuse_lane::{Lane, Mask};

params! {
    /// Parameters of [`Madgwick`].
    pub struct MadgwickParams {
        /// Gradient step gain β (the gyroscope-error rate it can correct). The default lies in
        /// the narrow range (0.0527–0.0541) that matches the reference implementation's BROAD
        /// accuracy on all four trials: larger β follows accelerations (trial 16) better,
        /// smaller β magnetic disturbances (trial 29).
        beta: f64 = 0.053, "rad/s", [0.0, 10.0];
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
/// The gradient is computed in closed form, linear in the unit `q` (`half_gradient`: a
/// symmetric 4×4 matrix from the sample times `q`), which needs no hand-expanded Jacobian; the
/// magnetic reference takes the horizontal and vertical field components from the rotated
/// measurement, so there is no factor-of-2 error in them, one sample old (see `d_y`). The
/// Euler step is normalised by one Newton step where it is within rounding reach of unit
/// length, exactly beyond. Gyro bias (section "gyroscope bias drift compensation" of the
/// paper): `ḃ = ζ·vec(2·q* ⊗ ∇f/|∇f|)`. docs/methods.md states the algebra,
/// docs/flagship_cost.md the cost beside Fusion's C.
#[derive(Clone, Debug)]
pub struct Madgwick<T: Lane> {
    q: Quat<T>,
    bias: Vec3<T>,
    initialized: T::Mask,
    /// The field reference `[0, d_y, d_z]` ([`field_reference`]) formed at the previous
    /// sample with a usable field, through the orientation before it. One sample old, it is
    /// known before this sample's orientation, so its rotation and square root are off the
    /// dependency chain; it carries only the field's dip, which one sample's rotation changes
    /// by no more than the tilt error the step corrects. `set_quat` keeps it (the next sample
    /// with a field replaces it, as after any sample).
    d_y: T,
    d_z: T,
    /// Lanes whose `d_y`, `d_z` have been formed.
    field_known: T::Mask,
    beta: T,
    zeta: T,
    /// `ζ = 0` in every lane (the default): the bias stays where it is, so its update is
    /// skipped (the same bits), which takes it off the dependency chain.
    zeta_off: bool,
    nine_d: bool,
    bounds: ScreenBounds<T>,
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
            d_y: T::zero(),
            d_z: T::zero(),
            field_known: <T::Mask as Mask>::splat(false),
            beta: p.coef(|p| p.beta),
            zeta: p.coef(|p| p.zeta),
            zeta_off: p.sets().iter().all(|set| set.zeta == 0.0),
            nine_d: p.first().dof.uses_magnetometer(),
            bounds: p.first().screen_limits().bounds(),
            rejections: Rejections::default(),
            params: p.first().clone(),
        }
    }
}

/// `base + p ⊗ [0, v]`, the sums as trees (four terms, two levels of additions).
#[inline]
fn plus_times_pure<T: Lane>(base: Quat<T>, p: Quat<T>, v: Vec3<T>) -> Quat<T> {
    let (w, x, y, z) = (p.w, p.x, p.y, p.z);
    Quat::new(
        (base.w - x * v.x) - (y * v.y + z * v.z),
        (base.x + w * v.x) + (y * v.z - z * v.y),
        (base.y + w * v.y) + (z * v.x - x * v.z),
        (base.z + w * v.z) + (x * v.y - y * v.x),
    )
}

/// Half the gradient of Madgwick's objective `Σ ½|q* ⊗ d ⊗ q − s|²` over the references `d`
/// and unit measurements `s` of one sample, with respect to the four components of a unit
/// `q`, as `M·q` for a symmetric 4×4 `M` formed from the sample alone.
///
/// For one reference the gradient is `−2·(d ⊗ q) ⊗ (q* ⊗ d ⊗ q − s)`, and
/// `(d ⊗ q) ⊗ q* ⊗ d ⊗ q = −|q|²|d|²·q`, so for `|q| = 1` it is
/// `2·(|d|²·q + (d ⊗ q) ⊗ s)`, linear in `q` (the objective is a quadratic form in `q`,
/// Davenport's). With `d = [0, 0, d_y, d_z]`, `d ⊗ q = d_y·[−y, z, w, −x] + d_z·[−z, −y, x, w]`,
/// so the half gradient over gravity (`d` = up, `s` = acc) and the field is `M·q` with
/// `κ = 1 + |d|²`, `u = acc + d_z·mag`, `v = d_y·mag`: the caller passes `κ`, `u`, `v` with
/// the unusable measurements left out. `M` is known before the orientation, so the dependency
/// chain holds four products and a sum per component.
#[inline]
fn half_gradient<T: Lane>(q: Quat<T>, kappa: T, u: Vec3<T>, v: Vec3<T>) -> Quat<T> {
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    let m00 = kappa - (u.z + v.y);
    let m11 = kappa + (u.z + v.y);
    let m22 = kappa + (u.z - v.y);
    let m33 = kappa - (u.z - v.y);
    let m01 = v.z - u.y;
    let m23 = -(u.y + v.z);
    let (m02, m13, m03) = (u.x, -u.x, -v.x);
    Quat::new(
        (m00 * w + m01 * x) + (m02 * y + m03 * z),
        (m01 * w + m11 * x) + (m03 * y + m13 * z),
        (m02 * w + m03 * x) + (m22 * y + m23 * z),
        (m03 * w + m13 * x) + (m23 * y + m33 * z),
    )
}

/// [`half_gradient`] with no field (`v = 0`, `u` the accelerometer alone): three products
/// per component, the field's terms absent rather than multiplied by zero.
#[inline]
fn half_gradient_gravity<T: Lane>(q: Quat<T>, kappa: T, u: Vec3<T>) -> Quat<T> {
    let (w, x, y, z) = (q.w, q.x, q.y, q.z);
    let (m00, m11) = (kappa - u.z, kappa + u.z);
    Quat::new(
        (m00 * w - u.y * x) + u.x * y,
        (m11 * x - u.y * w) - u.x * z,
        (m11 * y + u.x * w) - u.y * z,
        (m00 * z - u.x * x) - u.y * y,
    )
}

/// The field reference `[0, d_y, d_z]` of a unit sensor-frame field seen through `q`:
/// `d_z = h_z`, the field's vertical part (the third row of the rotation matrix times the
/// field), and `d_y = √(1 − h_z²)`, its horizontal part turned north (the measured dip kept).
#[inline]
fn field_reference<T: Lane>(q: Quat<T>, mag: Vec3<T>) -> (T, T) {
    let h_z = q.up_in_sensor().dot(mag);
    let h_xy2 = (T::one() - h_z * h_z).max(T::zero());
    (h_xy2.sqrt(), h_z)
}

/// `q_raw / |q_raw|` given `|q_raw|²` and `(3 − |q_raw|²)/2`: one Newton step of `1/√n`
/// from 1 ([`Quat::renormalize`]) where `|q_raw|²` is within `√(8ε/3)` of one (`ε` the
/// precision's epsilon; the result's norm is then `1 − 3(|q_raw|² − 1)²/8`, within `ε` of
/// one), the division by the norm in lanes beyond (a large `β·dt` or `|ω|·dt`). The branch is
/// uniform and every lane gets what it would get alone.
#[inline]
fn normalize_near_unit<T: Lane>(q_raw: Quat<T>, n2: T, newton_factor: T) -> Quat<T> {
    let deviation = n2 - T::one();
    let newton = q_raw.scale(newton_factor);
    let far = !(deviation * deviation).simd_le(T::from_f64(8.0 * T::EPSILON / 3.0));
    if far.any() {
        Quat::select(far, q_raw.normalize(), newton)
    } else {
        newton
    }
}

impl<T: Lane> OrientationFilter<T> for Madgwick<T> {
    fn update(&mut self, sample: &ImuSample<T>, dt: T) {
        let s = Screened::for_dof(sample, dt, &self.bounds, &mut self.rejections, self.nine_d);
        let q = initialise(self.q, &mut self.initialized, &s, self.nine_d);

        let u_acc = Vec3::select(s.acc_ok, s.acc, Vec3::zero());
        let kappa_acc = T::select(s.acc_ok, T::one(), T::zero());
        // 6D is the same for every lane and has no field terms.
        let g = if self.nine_d {
            // A lane's first field has no previous reference: it takes this sample's (a
            // uniform branch, taken once).
            let now = field_reference(q, s.mag);
            let (d_y, d_z) = if self.field_known.all() {
                (self.d_y, self.d_z)
            } else {
                (
                    T::select(self.field_known, self.d_y, now.0),
                    T::select(self.field_known, self.d_z, now.1),
                )
            };
            let update = s.mag_ok & s.step;
            self.d_y = T::select(update, now.0, self.d_y);
            self.d_z = T::select(update, now.1, self.d_z);
            self.field_known |= update;
            let u = u_acc + Vec3::select(s.mag_ok, s.mag * d_z, Vec3::zero());
            let v = Vec3::select(s.mag_ok, s.mag * d_y, Vec3::zero());
            let kappa = kappa_acc + T::select(s.mag_ok, d_y.mul_add(d_y, d_z * d_z), T::zero());
            half_gradient(q, kappa, u, v)
        } else {
            half_gradient_gravity(q, kappa_acc, u_acc)
        };
        // The step is `β·dt·g/|g|`; `1/|g|` as `√G·(1/G)`, `G = |g|²`, so that the square root
        // and the division run side by side rather than one after the other on the
        // dependency chain (rounding apart, the same number).
        let g2 = (g.w * g.w + g.x * g.x) + (g.y * g.y + g.z * g.z);
        let has_step = g2.simd_gt(T::from_f64(0.25e-30)) & g2.is_finite();
        let beta_dt = self.beta * s.dt;
        let inv_g2 = g2.recip();
        let c = T::select(has_step, (beta_dt * g2.sqrt()) * inv_g2, T::zero());

        let bias = if self.zeta_off {
            self.bias
        } else {
            let step = g.scale(T::select(has_step, g2.sqrt() * inv_g2, T::zero()));
            let omega_err = (q.conj() * step).vector() * T::from_f64(2.0);
            self.bias + omega_err * (self.zeta * s.dt)
        };
        // q + (½·q ⊗ ω − β·∇/|∇|)·dt = a − c·g. Its squared norm |a|² − 2c·(a·g) + (β·dt)²
        // (where there is a step) and the Newton factor (3 − that)/2 are formed from parts
        // known before `c`: the normalisation waits for `c` by one multiply-add, not a dot
        // product, a square root and a division.
        let a = plus_times_pure(q, q, (s.gyr - bias) * (T::from_f64(0.5) * s.dt));
        let a2 = a.norm_squared() + T::select(has_step, beta_dt * beta_dt, T::zero());
        let ag = a.dot(g);
        let n2 = (c + c).mul_add(-ag, a2);
        let newton_factor = c.mul_add(ag, T::from_f64(0.5).mul_add(-a2, T::from_f64(1.5)));
        let q_raw = Quat::new(
            c.mul_add(-g.w, a.w),
            c.mul_add(-g.x, a.x),
            c.mul_add(-g.y, a.y),
            c.mul_add(-g.z, a.z),
        );
        let q_new = normalize_near_unit(q_raw, n2, newton_factor);
        self.q = Quat::select(s.step, q_new, self.q);
        self.bias = Vec3::select(s.step, bias, self.bias);
    }
    crate::filters::quat_bias_state!(
        d_y: T::zero(),
        d_z: T::zero(),
        field_known: <T::Mask as Mask>::splat(false),
    );
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

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn unit_quat(v: [f64; 4]) -> Option<Quat<f64>> {
        let (q, ok) = Quat::new(v[0], v[1], v[2], v[3]).try_normalize();
        (ok && Quat::new(v[0], v[1], v[2], v[3]).norm() > 0.1).then_some(q)
    }

    fn unit_vec(v: [f64; 3]) -> Option<Vec3<f64>> {
        let n = v[0].hypot(v[1]).hypot(v[2]);
        (n > 0.1).then(|| Vec3::new(v[0] / n, v[1] / n, v[2] / n))
    }

    /// The paper's gradient of one reference, `−2·(d ⊗ q) ⊗ (q* ⊗ d ⊗ q − s)`, halved.
    fn paper_half_gradient(q: Quat<f64>, d: Vec3<f64>, s: Vec3<f64>) -> Quat<f64> {
        let f = q.rotate_inverse(d) - s;
        (Quat::pure(d) * q * Quat::pure(f)).scale(-1.0)
    }

    proptest! {
        /// `M·q` is the paper's gradient (both references, or gravity alone) for unit `q`.
        #[test]
        fn half_gradient_is_the_papers(
            q in prop::array::uniform4(-1.0f64..1.0),
            acc in prop::array::uniform3(-1.0f64..1.0),
            mag in prop::array::uniform3(-1.0f64..1.0),
            dip in -1.5f64..1.5,
        ) {
            let (Some(q), Some(acc), Some(mag)) = (unit_quat(q), unit_vec(acc), unit_vec(mag))
            else {
                return Ok(());
            };
            let (d_y, d_z) = (dip.cos(), dip.sin());
            let up = Vec3::new(0.0, 0.0, 1.0);
            let paper = paper_half_gradient(q, up, acc)
                + paper_half_gradient(q, Vec3::new(0.0, d_y, d_z), mag);
            let ours = half_gradient(q, 2.0, acc + mag * d_z, mag * d_y);
            prop_assert!((ours - paper).norm() < 1e-12, "{ours:?} vs {paper:?}");
            let paper = paper_half_gradient(q, up, acc);
            let ours = half_gradient_gravity(q, 1.0, acc);
            prop_assert!((ours - paper).norm() < 1e-12, "{ours:?} vs {paper:?}");
        }

        /// The field reference is [`mag_reference`]'s (the rotated field's horizontal part
        /// turned north), from the third row of the rotation alone.
        #[test]
        fn field_reference_is_the_rotated_field(
            q in prop::array::uniform4(-1.0f64..1.0),
            mag in prop::array::uniform3(-1.0f64..1.0),
        ) {
            let (Some(q), Some(mag)) = (unit_quat(q), unit_vec(mag)) else {
                return Ok(());
            };
            let (d_y, d_z) = field_reference(q, mag);
            let h = q.rotate(mag);
            prop_assert!((d_z - h.z).abs() < 1e-12);
            prop_assert!((d_y - h.x.hypot(h.y)).abs() < 1e-7, "{d_y} vs {}", h.x.hypot(h.y));
        }
    }

    /// Near unit length the Newton step leaves a norm within the precision's epsilon of one;
    /// beyond (a large `β·dt`, one lane of eight) that lane is divided by its norm and its
    /// neighbours keep their Newton step.
    #[test]
    fn normalize_near_unit_is_unit_in_every_lane() {
        use rootfuse_lane::wide::f32x8;
        for (scale, tol) in [(1.0f32 + 2e-4, f64::from(f32::EPSILON)), (1.3, 1e-6)] {
            let q32 = Quat::new(0.6 * scale, 0.0, 0.8 * scale, 0.0);
            let n2 = q32.norm_squared();
            let unit = normalize_near_unit(q32, n2, 1.5 - 0.5 * n2);
            assert!(
                (f64::from(unit.norm()) - 1.0).abs() <= tol,
                "{scale}: {unit:?}"
            );
        }
        let lanes = Quat::new(
            f32x8::from([0.6, 0.6, 0.6, 0.78, 0.6, 0.6, 0.6, 0.6]),
            f32x8::splat(0.0),
            f32x8::splat(0.8 * (1.0 + 1e-4)),
            f32x8::splat(0.0),
        );
        let n2 = lanes.norm_squared();
        let out = normalize_near_unit(lanes, n2, f32x8::splat(1.5) - f32x8::splat(0.5) * n2);
        for lane in 0..8 {
            let alone = Quat::new(
                lanes.w.extract(lane),
                lanes.x.extract(lane),
                lanes.y.extract(lane),
                lanes.z.extract(lane),
            );
            let n2 = alone.norm_squared();
            let want = normalize_near_unit(alone, n2, 1.5 - 0.5 * n2);
            let got = Quat::new(
                out.w.extract(lane),
                out.x.extract(lane),
                out.y.extract(lane),
                out.z.extract(lane),
            );
            assert_eq!(got, want, "lane {lane}");
            assert!((f64::from(got.norm()) - 1.0).abs() < 1e-6, "lane {lane}");
        }
    }
}
