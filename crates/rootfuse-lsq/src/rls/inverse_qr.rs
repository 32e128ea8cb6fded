//! Inverse QR RLS: propagates a lower-triangular `S = P^½` with Givens rotations.
//!
//! # Recursion (Alexander & Ghirnikar 1993; whitened data, unit noise variance)
//! With `S̃ = S/√λ` and `f = S̃ᵀ h`, an orthogonal `Θ` (a sequence of Givens rotations acting
//! on columns) triangularises the prearray:
//! ```text
//! [ 1   fᵀ ]        [ √α   0  ]
//! [ 0   S̃  ]  Θ  =  [ k̄    S⁺ ]        α = 1 + fᵀf,  k̄ = P̃ h / √α
//! ```
//! Comparing `A Aᵀ` on both sides gives `S⁺ S⁺ᵀ = P̃ − P̃ h hᵀ P̃ / α`, the updated `P`, and
//! the gain `k = k̄ / √α`; `x ← x + k (z − hᵀ x)`. Rotating column 0 against columns
//! `n, n−1, …, 1` (in that order) keeps `S⁺` lower triangular: column 0 only picks up rows
//! below the column being eliminated. Orthogonal transformations are backward stable, so
//! `S⁺` is the exact factor of a nearby problem (Golub & Van Loan, §5.1.8; Verhaegen &
//! Van Dooren 1986), and `P = S Sᵀ` cannot lose definiteness except through an exactly
//! singular `S`, visible as a zero pivot `S_jj²`.

use super::{
    Core, Form, Health, RecursiveLeastSquares, RlsConfig, RlsError, formable, frobenius2, min_max,
    outer_self,
};
use rootfuse_lane::{Lane, Mask, Mat, Vector};

/// Inverse QR RLS (square-root covariance with Givens rotations). See the
/// [module documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct InverseQr<T: Lane, const N: usize> {
    x: Vector<T, N>,
    /// Lower triangular, `P = S Sᵀ`.
    s: Mat<T, N, N>,
    core: Core<T>,
}

impl<T: Lane, const N: usize> InverseQr<T, N> {
    /// The lower-triangular factor `S` (`P = S Sᵀ`).
    pub fn factor(&self) -> &Mat<T, N, N> {
        &self.s
    }

    /// Forgetting plus one whitened measurement; (new state, finite, definite).
    fn step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask) {
        let mut s = self.s.scale(T::one() / lambda.sqrt());
        // f = S̃ᵀ h (S̃ lower triangular).
        let mut f = Vector::<T, N>::zeros();
        for j in 0..N {
            let mut acc = T::zero();
            for i in j..N {
                acc = s.m[i][j].mul_add(h[i], acc);
            }
            f[j] = acc;
        }
        let mut top = T::one();
        let mut col0 = Vector::<T, N>::zeros();
        for j in (0..N).rev() {
            // top ≥ 1, so r > 0 and the rotation is always defined.
            let r = top.mul_add(top, f[j] * f[j]).sqrt();
            let c = top / r;
            let sn = f[j] / r;
            for i in j..N {
                let a = col0[i];
                let b = s.m[i][j];
                col0[i] = c.mul_add(a, sn * b);
                s.m[i][j] = c.mul_add(b, -(sn * a));
            }
            top = r;
        }
        // k = k̄ / √α, and √α = top.
        let ke = (z - h.dot(&self.x)) / top;
        let x = Mat::from_fn(|i, _| col0[i].mul_add(ke, self.x[i]));
        let finite =
            x.is_finite() & s.is_finite() & top.is_finite() & formable::<T, N>(frobenius2(&s));
        (Self { x, s, ..*self }, finite, T::Mask::splat(true))
    }
}

impl<T: Lane, const N: usize> RecursiveLeastSquares<T, N> for InverseQr<T, N> {
    const NAME: &'static str = "inverse-qr";

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
        let (lo, hi) = min_max(N, |j| self.s.m[j][j] * self.s.m[j][j]);
        self.core.health(lo, hi, frobenius2(&self.s))
    }
}

impl<T: Lane, const N: usize> Form<T, N> for InverseQr<T, N> {
    super::form_basics!();

    fn regularising_estimate(&self) -> Vector<T, N> {
        self.x
    }

    fn keep(&mut self, accepted: T::Mask, next: &Self) {
        self.x = Mat::select(accepted, &next.x, &self.x);
        self.s = Mat::select(accepted, &next.s, &self.s);
    }
}
