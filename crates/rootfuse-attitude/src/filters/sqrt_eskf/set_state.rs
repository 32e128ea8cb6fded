//! The flagship's state set from outside: back to a new filter, and the orientation or the
//! bias set with (or without) its uncertainty.
//! The state itself (`q6 = c ⊗ q_gyr`, `q9 = qz(δ) ⊗ q6`, `P = S·Sᵀ`) is described on
//! [`SqrtEskf`].

use super::*;
use crate::filters::{StateError, checked_bias, checked_quat, checked_sigma};

impl<T: Lane> SqrtEskf<T> {
    /// [`OrientationFilter::reset`]: the state, the counters and the per-`dt` cache rebuilt
    /// from the coefficients.
    pub(super) fn reset_state(&mut self) {
        self.state = State::new(&self.coef);
        self.rejections = Rejections::default();
        self.per_dt = Cached::new(&self.coef);
        self.per_interval = Cached::new(&self.coef);
        self.per_heading = Cached::new(&self.coef);
    }

    /// [`OrientationFilter::set_quat`]: with `sigma`, rows 0–2 of the upper factor `S`
    /// become `[σ·I | 0]` (`P_θθ = σ²·I`, `P_θb = 0`, `P_bb` kept) and the model error seen so
    /// far is forgotten (the given σ is the whole uncertainty).
    pub(super) fn set_orientation(
        &mut self,
        q: Quat<T>,
        sigma: Option<T>,
    ) -> Result<(), StateError> {
        let q = checked_quat(q)?;
        let sigma = sigma
            .map(|s| checked_sigma(s, core::f64::consts::PI))
            .transpose()?;
        self.move_to(q);
        // The factor is set from here on: the time update deferred so far first.
        self.flush_time_update();
        let st = &mut self.state;
        match sigma {
            Some(sigma) => {
                for i in 0..3 {
                    for j in 0..6 {
                        st.factor.m[i][j] = if i == j { sigma } else { T::zero() };
                    }
                }
                st.heading_offset_var = sigma * sigma;
                st.innovation_ms = T::zero();
                st.heading_innovation_ms = T::zero();
                st.scale_error2 = T::zero();
                st.preset_covariance |= !st.initialized;
            }
            // A plain preset of a filter that has not started starts from the initial
            // covariance.
            None => st.preset_covariance &= st.initialized,
        }
        Ok(())
    }

    /// The orientation moved to `q` (unit), the covariance untouched. `q6 = c ⊗ strapdown`
    /// and `q9 = qz(δ) ⊗ q6`: with `δ = 0` both become `q`. A running filter keeps `c` and
    /// moves the strapdown frame, so that the low-passed specific force, kept in the
    /// quasi-inertial frame, still points along gravity there; a filter that has not started
    /// yet starts from `q` instead of the first accelerometer sample.
    fn move_to(&mut self, q: Quat<T>) {
        let st = &mut self.state;
        let moved = (st.correction.conj() * q).normalize();
        let running = st.initialized;
        st.strapdown = Quat::select(running, moved, Quat::identity());
        st.correction = Quat::select(running, st.correction, q);
        let r = st.strapdown.to_rotation_matrix();
        st.window.move_rotation(running, &r);
        st.long.lowpass.move_rotation(running, &r);
        st.heading_offset = T::zero();
        st.preset |= !running;
        // The window's sums were taken in the frame the strapdown has just left.
        st.gyro_scale.restart(running, st.correction, st.age);
    }

    /// [`OrientationFilter::set_bias`]: with `sigma`, the bias rows of the factor become
    /// `σ·I` and the attitude block is refactored on its own (no attitude–bias correlation,
    /// `P_θθ` kept). Before the first sample the bias is used from the first gyro step on.
    pub(super) fn set_gyro_bias(
        &mut self,
        bias: Vec3<T>,
        sigma: Option<T>,
    ) -> Result<(), StateError> {
        let bias = checked_bias(bias)?;
        let sigma = sigma.map(|s| checked_sigma(s, 1.0)).transpose()?;
        // A window runs with one residual bias: a new bias starts a new window.
        let st = &mut self.state;
        st.gyro_scale.restart(st.initialized, st.correction, st.age);
        let Some(sigma) = sigma else {
            self.state.bias = bias;
            return Ok(());
        };
        // The attitude block `P_θθ = S_θθ·S_θθᵀ + S_θb·S_θbᵀ` refactored as an upper
        // triangle of its own (`S_θb` then zero: no correlation), the bias rows `σ·I`; the
        // time update deferred so far first.
        self.flush_time_update();
        let st = &mut self.state;
        let s = &st.factor;
        let p = Mat::<T, 3, 3>::from_fn(|i, j| {
            let mut v = T::zero();
            for k in i.max(j)..6 {
                v = s.m[i][k].mul_add(s.m[j][k], v);
            }
            v
        });
        let u = upper_cholesky3(&p);
        for i in 0..6 {
            for j in 0..6 {
                st.factor.m[i][j] = match (i < 3, j < 3) {
                    (true, true) => u.m[i][j],
                    (false, false) if i == j => sigma,
                    _ => T::zero(),
                };
            }
        }
        // σ is the whole bias uncertainty: no random walk is still to be added.
        st.bias_noise_pending = T::zero();
        st.bias = bias;
        Ok(())
    }
}

/// The upper-triangular `U` with `U·Uᵀ = p` of a symmetric positive semi-definite 3×3 `p`
/// (a negative pivot from rounding is taken as zero, and its column as zero). Not
/// `Mat::cholesky`: that factor is lower triangular and replaces a zero pivot by 1, where a
/// semi-definite block (σ = 0 set for an axis) must keep its zero.
fn upper_cholesky3<T: Lane>(p: &Mat<T, 3, 3>) -> Mat<T, 3, 3> {
    let zero = T::zero();
    let div = |a: T, d: T| T::select(d.simd_gt(zero), a / d, zero);
    let u22 = p.m[2][2].max(zero).sqrt();
    let u12 = div(p.m[1][2], u22);
    let u02 = div(p.m[0][2], u22);
    let u11 = (p.m[1][1] - u12 * u12).max(zero).sqrt();
    let u01 = div(p.m[0][1] - u02 * u12, u11);
    let u00 = (p.m[0][0] - u01 * u01 - u02 * u02).max(zero).sqrt();
    Mat::from_rows([[u00, u01, u02], [zero, u11, u12], [zero, zero, u22]])
}
