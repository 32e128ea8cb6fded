//! The flagship's state set from outside: back to a new filter, and the orientation or the
//! bias set with its uncertainty.
//! The state itself (`q6 = c ⊗ q_gyr`, `q9 = qz(δ) ⊗ q6`, `P = S·Sᵀ`) is described on
//! [`SqrtEskf`].

use super::*;

impl<T: Lane> SqrtEskf<T> {
    /// Back to the state of a new filter with the same parameters: the samples that follow
    /// give the same bits as they would in `SqrtEskf::new` (orientation, bias, covariance,
    /// low-pass and rest states, counters).
    ///
    /// ```
    /// use rootfuse_attitude::{ImuSample, OrientationFilter, SqrtEskf, SqrtEskfParams, Vec3};
    /// let s = ImuSample::new(Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 0.0, 9.81), Vec3::zero());
    /// let mut f = SqrtEskf::<f64>::new(&SqrtEskfParams::default());
    /// f.update(&s, 0.01);
    /// f.reset();
    /// f.update(&s, 0.01);
    /// let mut fresh = SqrtEskf::<f64>::new(&SqrtEskfParams::default());
    /// fresh.update(&s, 0.01);
    /// assert_eq!(f.quat(), fresh.quat());
    /// ```
    pub fn reset(&mut self) {
        self.state = State::new(&self.coef);
        self.rejections = Rejections::default();
        self.per_dt = PerDt::new(&self.coef);
    }

    /// Sets the orientation `q` (sensor to earth, ENU; normalised here) as
    /// [`set_quat`](OrientationFilter::set_quat) does, and its uncertainty: the attitude error
    /// becomes `sigma`² · I (rad², per earth axis, every lane its own `sigma`; the model error
    /// seen so far is forgotten), uncorrelated with the bias error, whose covariance is kept.
    /// [`attitude_covariance`](Self::attitude_covariance) reads `sigma`² back on the diagonal.
    ///
    /// Refused, with nothing changed: a non-finite `q` or one whose norm is outside
    /// [0.5, 2] (not an orientation that was meant), and a `sigma` that is NaN, negative or
    /// above π. The error names the value of the first lane that fails.
    ///
    /// ```
    /// use rootfuse_attitude::{Quat, SqrtEskf, SqrtEskfParams};
    /// let mut f = SqrtEskf::<f64>::new(&SqrtEskfParams::default());
    /// f.set_quat_with_sigma(Quat::from_euler_zyx(0.5, 0.1, 0.0), 0.02).unwrap();
    /// assert!((f.attitude_covariance().m[2][2] - 0.02 * 0.02).abs() < 1e-15);
    /// assert!(f.set_quat_with_sigma(Quat::identity(), f64::NAN).is_err());
    /// ```
    pub fn set_quat_with_sigma(
        &mut self,
        q: Quat<T>,
        sigma: T,
    ) -> Result<(), crate::filters::InvalidParam> {
        let norm = (q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z).sqrt();
        let first_bad = |value: T, ok: T::Mask| {
            (0..T::LANES)
                .find(|&i| !ok.test(i))
                .map(|i| value.extract(i).into())
        };
        let norm_ok = norm.simd_ge(T::from_f64(0.5)) & norm.simd_le(T::from_f64(2.0));
        if let Some(value) = first_bad(norm, norm_ok) {
            return Err(crate::filters::InvalidParam {
                name: "|q|",
                value,
                min: 0.5,
                max: 2.0,
            });
        }
        let sigma_ok = sigma.simd_ge(T::zero()) & sigma.simd_le(T::from_f64(core::f64::consts::PI));
        if let Some(value) = first_bad(sigma, sigma_ok) {
            return Err(crate::filters::InvalidParam {
                name: "sigma",
                value,
                min: 0.0,
                max: core::f64::consts::PI,
            });
        }
        self.set_quat(q);
        // Rows 0–2 of the upper factor `S` become `[σ·I | 0]`: `P_θθ = σ²·I`, `P_θb = 0`,
        // and `P_bb = S_bb·S_bbᵀ` (rows 3–5) is untouched.
        let st = &mut self.state;
        for i in 0..3 {
            for j in 0..6 {
                st.factor.m[i][j] = if i == j { sigma } else { T::zero() };
            }
        }
        st.heading_offset_var = sigma * sigma;
        // The given σ is the whole uncertainty: the model error seen so far is forgotten.
        st.innovation_ms = T::zero();
        st.preset_covariance |= !st.initialized;
        Ok(())
    }

    /// Sets the gyro-bias estimate `bias` (rad/s, sensor frame) and its uncertainty: the bias
    /// error becomes `sigma`² · I (rad²/s², every lane its own `sigma`), uncorrelated with the
    /// attitude error, whose covariance is kept. Before the first sample the bias is used from
    /// the first gyro step on.
    ///
    /// Refused, with nothing changed: a non-finite bias or one above 1 rad/s in a component
    /// (no gyroscope bias is that large; it is a unit error), and a `sigma` that is NaN,
    /// negative or above 1 rad/s.
    ///
    /// ```
    /// use rootfuse_attitude::{OrientationFilter, SqrtEskf, SqrtEskfParams, Vec3};
    /// let mut f = SqrtEskf::<f64>::new(&SqrtEskfParams::default());
    /// f.set_bias_with_sigma(Vec3::new(0.01, 0.0, -0.002), 1e-3).unwrap();
    /// assert_eq!(f.bias().x, 0.01);
    /// let s = f.covariance_factor();
    /// assert!((s.m[5][5] * s.m[5][5] - 1e-6).abs() < 1e-18);
    /// assert!(f.set_bias_with_sigma(Vec3::new(f64::NAN, 0.0, 0.0), 1e-3).is_err());
    /// ```
    pub fn set_bias_with_sigma(
        &mut self,
        bias: Vec3<T>,
        sigma: T,
    ) -> Result<(), crate::filters::InvalidParam> {
        let largest = bias.x.abs().max(bias.y.abs()).max(bias.z.abs());
        let nan = bias.x.is_nan() | bias.y.is_nan() | bias.z.is_nan();
        let bias_ok = largest.simd_le(T::one()) & !nan;
        if let Some(i) = (0..T::LANES).find(|&i| !bias_ok.test(i)) {
            return Err(crate::filters::InvalidParam {
                name: "bias",
                value: T::select(nan, T::from_f64(f64::NAN), largest)
                    .extract(i)
                    .into(),
                min: -1.0,
                max: 1.0,
            });
        }
        let sigma_ok = sigma.simd_ge(T::zero()) & sigma.simd_le(T::one());
        if let Some(i) = (0..T::LANES).find(|&i| !sigma_ok.test(i)) {
            return Err(crate::filters::InvalidParam {
                name: "sigma",
                value: sigma.extract(i).into(),
                min: 0.0,
                max: 1.0,
            });
        }
        // The attitude block `P_θθ = S_θθ·S_θθᵀ + S_θb·S_θbᵀ` refactored as an upper
        // triangle of its own (`S_θb` then zero: no correlation), the bias rows `σ·I`.
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
