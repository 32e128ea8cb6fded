//! Potter's square-root covariance form, `P = S Sᵀ`.
//!
//! # Recursion (one scalar measurement, whitened: `h ← √w·h`, `z ← √w·z`, unit noise)
//! ```text
//! S̃ = S / √λ
//! f = S̃ᵀ h,   g = S̃ f (= P̃ h),   α = 1 + fᵀ f,   γ = 1 / (α + √α)
//! x ← x + (g / α) (z − hᵀ x)
//! S ← S̃ − γ g fᵀ                       (S̃ (I − γ f fᵀ))
//! ```
//! `γ` is the root of `(I − γ f fᵀ)² = I − f fᵀ/α` that has no cancellation
//! (J. E. Potter, 1963; Bierman 1977, ch. V). `S` is square but not triangular: the update
//! keeps `P = S Sᵀ` positive semidefinite by construction, and the factor's condition number
//! is the square root of `P`'s, which is why the square-root forms survive in single precision
//! where the covariance forms fail (Verhaegen & Van Dooren 1986).
//!
//! Health reports the diagonal of `P` (row norms of `S`), since `S` is not triangular.

use super::{
    Core, Form, Health, RecursiveLeastSquares, RlsConfig, RlsError, formable, frobenius2, min_max,
    outer_self,
};
use rootfuse_lane::{Lane, Mask, Mat, Vector};

/// Potter square-root RLS. See the [module documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct Potter<T: Lane, const N: usize> {
    x: Vector<T, N>,
    s: Mat<T, N, N>,
    core: Core<T>,
}

impl<T: Lane, const N: usize> Potter<T, N> {
    /// The square-root factor `S` (`P = S Sᵀ`; square, not triangular).
    pub fn factor(&self) -> &Mat<T, N, N> {
        &self.s
    }

    /// Time update with a known state transition and a per-lane forgetting factor:
    /// `x ← F x`, `P ← F P Fᵀ / λ`, i.e. `S ← F S / √λ`.
    ///
    /// This is what recursive least squares needs when the parameters move in a known linear
    /// way between measurements: a polynomial fitted about a moving time origin
    /// (`F` re-expands it about the new origin), an orientation turned by a known rotation.
    /// `F` is an exact reparametrisation of the weighted problem, so the estimate stays the
    /// minimiser of the cost written in the new coordinates. `λ ∈ (0, 1]` per lane is the
    /// forgetting of this step (1 = none); a forgetting factor derived from a time step, e.g.
    /// `λ = τ/(τ + dt)`, gives a memory in seconds whatever the sample rate. Use it with
    /// [`RlsConfig::new(1.0)`](RlsConfig::new) so that measurements do not forget again.
    ///
    /// Lanes where `F` or `λ` is not finite, `λ ∉ (0, 1]`, or the result is not finite are
    /// left unchanged (counted as rejected input or numerical failure). Returns the lanes
    /// where the step was applied. With `F = I` and `λ = 1` a lane keeps its values.
    ///
    /// # Errors
    /// [`RlsError::TransitionWithBounds`] (and nothing changed) when the estimator has
    /// [`CovarianceBounds`](super::CovarianceBounds).
    pub fn predict(&mut self, f: &Mat<T, N, N>, lambda: T) -> Result<T::Mask, RlsError> {
        if self.core.bounded() {
            return Err(RlsError::TransitionWithBounds);
        }
        let zero = T::zero();
        let one = T::one();
        // NaN lands on the reject side: positive, ordered comparisons only.
        let input_ok = f.is_finite() & lambda.simd_gt(zero) & lambda.simd_le(one);
        let f0 = Mat::select(input_ok, f, &Mat::identity());
        let inv_sqrt = one / T::select(input_ok, lambda, one).sqrt();
        let x = f0 * self.x;
        let s = (f0 * self.s).scale(inv_sqrt);
        let finite = x.is_finite() & s.is_finite() & formable::<T, N>(frobenius2(&s));
        let applied = self.core.count(input_ok, finite);
        self.x = Mat::select(applied, &x, &self.x);
        self.s = Mat::select(applied, &s, &self.s);
        Ok(applied)
    }

    /// Forgetting plus one whitened measurement; (new state, finite, definite).
    fn step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask) {
        let st = self.s.scale(T::one() / lambda.sqrt());
        let f = st.transpose() * *h;
        let g = st * f;
        let alpha = f.dot(&f) + T::one();
        let gamma = T::one() / (alpha + alpha.sqrt());
        let ke = (z - h.dot(&self.x)) / alpha;
        let x = Mat::from_fn(|i, _| g.m[i][0].mul_add(ke, self.x.m[i][0]));
        let s = Mat::from_fn(|i, j| (-gamma * g.m[i][0]).mul_add(f.m[j][0], st.m[i][j]));
        let finite =
            x.is_finite() & s.is_finite() & alpha.is_finite() & formable::<T, N>(frobenius2(&s));
        (Self { x, s, ..*self }, finite, T::Mask::splat(true))
    }
}

impl<T: Lane, const N: usize> RecursiveLeastSquares<T, N> for Potter<T, N> {
    const NAME: &'static str = "potter";

    super::shared_form_items!();

    fn new(x0: &Vector<T, N>, p0: &Mat<T, N, N>, config: RlsConfig) -> Result<Self, RlsError> {
        let (core, prior) = Core::new(x0, p0, config)?;
        Ok(Self {
            x: *x0,
            s: prior.l,
            core,
        })
    }

    fn estimate(&self) -> Vector<T, N> {
        self.x
    }

    fn covariance(&self) -> Mat<T, N, N> {
        outer_self(&self.s)
    }

    fn health(&self) -> Health<T> {
        let row2 = |i: usize| {
            let mut s = T::zero();
            for &v in &self.s.m[i] {
                s = v.mul_add(v, s);
            }
            s
        };
        let (lo, hi) = min_max(N, row2);
        self.core.health(lo, hi, frobenius2(&self.s))
    }
}

impl<T: Lane, const N: usize> Form<T, N> for Potter<T, N> {
    super::form_basics!();

    fn regularising_estimate(&self) -> Vector<T, N> {
        self.x
    }

    fn keep(&mut self, accepted: T::Mask, next: &Self) {
        self.x = Mat::select(accepted, &next.x, &self.x);
        self.s = Mat::select(accepted, &next.s, &self.s);
    }
}
