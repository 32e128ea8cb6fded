//! The Joseph-stabilised covariance form.
//!
//! # Recursion (one scalar measurement, whitened: `h ← √w·h`, `z ← √w·z`, unit noise)
//! ```text
//! P̃ = P / λ,   u = P̃ h,   α = 1 + hᵀ u,   k = u / α
//! x ← x + k (z − hᵀ x)
//! P ← (I − k hᵀ) P̃ (I − k hᵀ)ᵀ + k kᵀ,   then symmetrised
//! ```
//! The Joseph form is a sum of positive semidefinite terms and is insensitive to first-order
//! errors in the gain `k` (Bucy & Joseph 1968; Bierman 1977, ch. II).
//!
//! # Which evaluation
//! The result depends on how the product is evaluated, and this form does *not* use the
//! textbook one. Because `I − k hᵀ` is a rank-one correction of the identity, both products
//! are evaluated in O(n²) without forming it: `M = P̃ − k uᵀ` (one fused multiply-add per
//! entry), then `P = M − (M h) kᵀ + k kᵀ`, then symmetrised. Why: the textbook evaluation
//! forms `A = I − k hᵀ` in working precision and multiplies `A P̃ Aᵀ` (O(n³)); each entry of
//! the rounded `A` carries an absolute error of about `u`, which the products carry into
//! every entry of `P`, while here `k − M h` is a small difference of two nearly equal vectors
//! (`M h = k` exactly) and the error of the rank-one terms scales with `P`'s own entries. In
//! the Dyer–McReynolds example in f32 the textbook evaluation is already indefinite after the
//! second measurement at `δ = 10⁻³` (smallest eigenvalue `−9·10⁻⁶`; the exact one is
//! `δ²/6 ≈ 1.7·10⁻⁷`), this one keeps `1.8·10⁻⁷` there and fails at `δ = 10⁻⁴`, like the
//! conventional form (test `rls::joseph_evaluation_keeps_dyer_mcreynolds_definite_where_the_textbook_product_does_not`).
//! It does not protect against errors in `P̃` itself (in the Dyer–McReynolds example it fails
//! like the conventional form), so it carries the same definiteness checks as the
//! [conventional](super::conventional) form (flagged in
//! [`Health::lost_definiteness`](super::Health::lost_definiteness)).

use super::{Core, Form, Health, RecursiveLeastSquares, RlsConfig, RlsError, is_definite, min_max};
use rootfuse_lane::{Lane, Mat, Vector};

/// Joseph-stabilised covariance-form RLS. See the [module documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct Joseph<T: Lane, const N: usize> {
    x: Vector<T, N>,
    p: Mat<T, N, N>,
    core: Core<T>,
}

impl<T: Lane, const N: usize> Joseph<T, N> {
    /// Forgetting plus one whitened measurement; (new state, finite, definite).
    fn step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask) {
        let pt = self.p.scale(T::one() / lambda);
        let u = pt * *h;
        let hu = h.dot(&u);
        let k = u.scale(T::one() / (hu + T::one()));
        let e = z - h.dot(&self.x);
        let x = Mat::from_fn(|i, _| k.m[i][0].mul_add(e, self.x.m[i][0]));
        // M = (I − k hᵀ) P̃ = P̃ − k uᵀ (P̃ symmetric).
        let m = Mat::<T, N, N>::from_fn(|i, j| (-k.m[i][0]).mul_add(u.m[j][0], pt.m[i][j]));
        // P = M (I − k hᵀ)ᵀ + k kᵀ = M − (M h) kᵀ + k kᵀ.
        let mh = m * *h;
        let p = Mat::from_fn(|i, j| {
            let t = (k.m[i][0] - mh.m[i][0]) * k.m[j][0];
            m.m[i][j] + t
        })
        .symmetrize();
        let definite = hu.simd_ge(T::zero()) & is_definite(&p);
        let finite = x.is_finite() & p.is_finite() & hu.is_finite();
        (Self { x, p, ..*self }, finite, definite)
    }
}

impl<T: Lane, const N: usize> RecursiveLeastSquares<T, N> for Joseph<T, N> {
    const NAME: &'static str = "joseph";

    super::shared_form_items!();

    fn new(x0: &Vector<T, N>, p0: &Mat<T, N, N>, config: RlsConfig) -> Result<Self, RlsError> {
        let (core, prior) = Core::new(x0, p0, config)?;
        Ok(Self {
            x: *x0,
            p: prior.p,
            core,
        })
    }

    fn estimate(&self) -> Vector<T, N> {
        self.x
    }

    fn covariance(&self) -> Mat<T, N, N> {
        self.p
    }

    fn health(&self) -> Health<T> {
        let (lo, hi) = min_max(N, |j| self.p.m[j][j]);
        self.core.health(lo, hi, self.p.trace())
    }
}

impl<T: Lane, const N: usize> Form<T, N> for Joseph<T, N> {
    super::form_basics!();

    fn regularising_estimate(&self) -> Vector<T, N> {
        self.x
    }
    fn judge(&mut self, input_ok: T::Mask, finite: T::Mask, definite: T::Mask) -> T::Mask {
        self.core.lost |= input_ok & finite & !definite;
        definite & finite
    }

    fn keep(&mut self, accepted: T::Mask, next: &Self) {
        self.x = Mat::select(accepted, &next.x, &self.x);
        self.p = Mat::select(accepted, &next.p, &self.p);
    }
}
