//! The flagship's reported attitude covariance ([`OrientationFilter::attitude_covariance`]):
//! the attitude block of `P = S·Sᵀ` and the model errors the report adds to it.

use super::*;

impl<T: Lane> SqrtEskf<T> {
    /// [`OrientationFilter::attitude_covariance`] without its `Option`.
    pub(super) fn attitude_block(&self) -> Mat<T, 3, 3> {
        // The attitude block of `S·Sᵀ` only (`S` upper triangular: `S_ik = 0` for `k < i`):
        // a quarter of the full product, the same sums in the same order.
        let s = &self.state.factor;
        let mut a = Mat::<T, 3, 3>::from_fn(|i, j| {
            let mut v = T::zero();
            for k in i.max(j)..6 {
                v = s.m[i][k].mul_add(s.m[j][k], v);
            }
            v
        });
        if self.nine_d {
            for i in 0..2 {
                a.m[i][2] = T::zero();
                a.m[2][i] = T::zero();
            }
            a.m[2][2] = self.state.heading_offset_var
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
