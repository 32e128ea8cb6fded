//! The flagship's reported attitude covariance ([`OrientationFilter::attitude_covariance`]):
//! the attitude block of `P = S·Sᵀ` and the model errors the report adds to it.

use super::update::row_norm2;
use super::*;

impl<T: Lane> SqrtEskf<T> {
    /// The upper-triangular covariance factor `S` of the error
    /// state `[δθ (rad, earth frame of q6), δb (rad/s, sensor frame)]`: `P = S·Sᵀ`, with the
    /// time update since the last measurement update applied (on a copy: the filter defers it
    /// to the samples where a measurement may read it).
    pub fn covariance_factor(&self) -> Mat<T, 6, 6> {
        let mut st = self.state;
        st.fold_pending(<T::Mask as Mask>::splat(true), None);
        st.factor
    }

    /// The error-state covariance `P = S·Sᵀ` (symmetric PSD by construction).
    pub fn covariance(&self) -> Mat<T, 6, 6> {
        let s = self.covariance_factor();
        s * s.transpose()
    }

    /// [`OrientationFilter::attitude_covariance`] without its `Option`.
    pub(super) fn attitude_block(&self) -> Mat<T, 3, 3> {
        // The attitude block of `S·Sᵀ` only (`S` upper triangular: `S_ik = 0` for `k < i`),
        // with the deferred time update ([`SqrtEskf::time_update`]) applied in closed form:
        // `A·Aᵀ + B'·B'ᵀ + diag(noise)`, `B' = B − M·D`, which is what the next flush will
        // make of it, without the flush's reflections (where nothing is pending, `B' = B` and
        // these are the same sums in the same order as `S·Sᵀ`'s).
        let st = &self.state;
        let (s, b) = (&st.factor, st.transitioned_block());
        let mut a = Mat::<T, 3, 3>::from_fn(|i, j| {
            let mut v = T::zero();
            for k in i.max(j)..3 {
                v = s.m[i][k].mul_add(s.m[j][k], v);
            }
            for k in 0..3 {
                v = b.m[i][k].mul_add(b.m[j][k], v);
            }
            v
        });
        a.m[0][0] += st.tilt_noise_var;
        a.m[1][1] += st.tilt_noise_var;
        a.m[2][2] += st.yaw_noise_var;
        if self.nine_d {
            for i in 0..2 {
                a.m[i][2] = T::zero();
                a.m[2][i] = T::zero();
            }
            // The heading variance the next flush adds to the offset's.
            let pending = a.m[2][2] - row_norm2(s, 2);
            a.m[2][2] = self.state.heading_offset_var
                + pending.max(T::zero())
                + self.state.heading_innovation_ms * self.coef.heading_model_error_scale
                + self.state.field.azimuth_error_var() * self.coef.adopted_field_error_scale;
        }
        let e = self.state.innovation_ms * self.model_error_scale_now() + self.state.scale_error2;
        a.m[0][0] += e;
        a.m[1][1] += e;
        a
    }
}

impl<T: Lane> FieldReference<T> {
    /// The variance (rad²) of the reference's azimuth against north: what it inherited at
    /// adoption (decayed with the azimuth) and the square of the turn its decay toward north
    /// has made since, an error where the field is not the earth's.
    pub(super) fn azimuth_error_var(&self) -> T {
        let turn = self.adopted_azimuth - self.azimuth;
        self.azimuth_var + turn * turn
    }
}
