//! Square-root information RLS for large, dynamic `n` on faer.

use faer::diag::Diag;
use faer::linalg::cholesky::llt::update::rank_r_update_clobber;
use faer::{Col, ColRef, Mat, MatRef};

use super::{Input, LsqError, LsqReal};

/// Exponentially weighted recursive least squares in square-root information form, for `n` in
/// the hundreds (the const-generic forms in [`rls`](crate::rls) are for small `n`).
///
/// It keeps the lower Cholesky factor `L` of the information matrix
/// `Λₖ = λᵏ δ I + Σᵢ λᵏ⁻ⁱ wᵢ hᵢ hᵢᵀ` and the information vector `ηₖ = Σᵢ λᵏ⁻ⁱ wᵢ zᵢ hᵢ`. An update
/// scales `L` by `√λ` and applies faer's rank-one Cholesky update with `√w h`: `O(n²)`, never
/// forming `Λ` or inverting anything, so the factor stays positive definite by construction.
/// The estimate `Λ⁻¹η` costs two triangular solves and is computed on demand.
///
/// After `k` updates the estimate is exactly the batch weighted least-squares solution of the
/// stacked problem `[H; I] x ≈ [z; 0]` with weights `[wᵢ λᵏ⁻ⁱ; δ λᵏ]`, which is how it is tested.
/// There is no windup protection: with `λ < 1` and no excitation in some direction, `L` decays
/// there geometrically (watch [`SqrtInfoRls::diagonal_ratio`]).
///
/// # Example
///
/// ```
/// use rootfuse_lsq::dense::SqrtInfoRls;
/// use rootfuse_lsq::dense::faer::Col;
///
/// // A small linear congruential generator keeps the example free of dependencies.
/// let mut state = 1u64;
/// let mut noise = move || {
///     state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
///     (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
/// };
/// let n = 200;
/// let truth = Col::<f64>::from_fn(n, |j| (j as f64).sin());
/// let mut rls = SqrtInfoRls::new(n, 1e-6, 1.0)?;
/// for _ in 0..400 {
///     let h = Col::<f64>::from_fn(n, |_| noise());
///     let z = (0..n).map(|j| h[j] * truth[j]).sum::<f64>();
///     rls.update(h.as_ref(), z, 1.0)?;
/// }
/// let x = rls.estimate();
/// assert!((0..n).all(|j| (x[j] - truth[j]).abs() < 1e-6));
/// # Ok::<(), rootfuse_lsq::dense::LsqError>(())
/// ```
#[derive(Clone, Debug)]
pub struct SqrtInfoRls<T> {
    l: Mat<T>,
    eta: Col<T>,
    sqrt_lambda: T,
    lambda: T,
    updates: u64,
}

impl<T: LsqReal> SqrtInfoRls<T> {
    /// A filter for `n` parameters with prior information `δ I` (prior estimate 0, prior
    /// covariance `I/δ`) and forgetting factor `λ ∈ (0, 1]`.
    ///
    /// # Errors
    ///
    /// [`LsqError::Empty`] for `n = 0`; [`LsqError::NonFinite`] (input [`Input::Weights`]) unless
    /// `δ > 0` and `0 < λ ≤ 1` are finite.
    pub fn new(n: usize, prior_precision: T, lambda: T) -> Result<Self, LsqError> {
        if n == 0 {
            return Err(LsqError::Empty { rows: 0, cols: 0 });
        }
        let zero = T::zero_impl();
        let valid = prior_precision > zero
            && prior_precision.is_finite()
            && lambda > zero
            && lambda <= T::one_impl();
        if !valid {
            return Err(LsqError::NonFinite {
                input: Input::Weights,
                row: 0,
                col: 0,
            });
        }
        let d = prior_precision.sqrt();
        Ok(SqrtInfoRls {
            l: Mat::from_fn(n, n, |i, j| if i == j { d } else { zero }),
            eta: Col::zeros(n),
            sqrt_lambda: lambda.sqrt(),
            lambda,
            updates: 0,
        })
    }

    /// Number of parameters.
    pub fn dim(&self) -> usize {
        self.eta.nrows()
    }

    /// Number of accepted updates.
    pub fn updates(&self) -> u64 {
        self.updates
    }

    /// Adds the scalar measurement `z = hᵀx + noise` with weight `w ≥ 0` (the inverse noise
    /// variance). On error nothing changes.
    ///
    /// # Errors
    ///
    /// [`LsqError::DimensionMismatch`] if `h` has the wrong length, [`LsqError::NonFinite`] for a
    /// NaN or infinity in `h`, `z` or `w`, [`LsqError::NegativeWeight`] for `w < 0`,
    /// [`LsqError::Breakdown`] if the factor update fails (possible only through overflow).
    pub fn update(&mut self, h: ColRef<'_, T>, z: T, w: T) -> Result<(), LsqError> {
        let n = self.dim();
        if h.nrows() != n {
            return Err(LsqError::DimensionMismatch {
                input: Input::Design,
                expected: n,
                found: h.nrows(),
            });
        }
        if let Some(col) = (0..n).find(|&j| !h[j].is_finite()) {
            return Err(LsqError::NonFinite {
                input: Input::Design,
                row: 0,
                col,
            });
        }
        if !z.is_finite() {
            return Err(LsqError::NonFinite {
                input: Input::Observations,
                row: 0,
                col: 0,
            });
        }
        if !w.is_finite() {
            return Err(LsqError::NonFinite {
                input: Input::Weights,
                row: 0,
                col: 0,
            });
        }
        if w < T::zero_impl() {
            return Err(LsqError::NegativeWeight { row: 0 });
        }

        // Work on a copy so that a failed update leaves the filter as it was.
        let mut l = self.l.clone();
        if self.lambda != T::one_impl() {
            for j in 0..n {
                for i in j..n {
                    l[(i, j)] *= self.sqrt_lambda;
                }
            }
        }
        let mut v = Mat::<T>::from_fn(n, 1, |j, _| h[j]);
        let mut alpha = Diag::<T>::zeros(1);
        alpha.column_vector_mut()[0] = w;
        rank_r_update_clobber(l.as_mut(), v.as_mut(), alpha.as_mut())
            .map_err(|_| LsqError::Breakdown { pivot: 0 })?;
        if !(0..n).all(|j| l[(j, j)].is_finite()) {
            return Err(LsqError::NonFiniteResult);
        }
        self.l = l;
        let wz = w * z;
        for j in 0..n {
            self.eta[j] = self.lambda * self.eta[j] + wz * h[j];
        }
        self.updates += 1;
        Ok(())
    }

    /// The estimate `Λ⁻¹η` (two triangular solves, `O(n²)`).
    pub fn estimate(&self) -> Col<T> {
        let n = self.dim();
        let mut x = Mat::<T>::from_fn(n, 1, |j, _| self.eta[j]);
        self.l.as_ref().solve_lower_triangular_in_place(x.as_mut());
        self.l
            .as_ref()
            .transpose()
            .solve_upper_triangular_in_place(x.as_mut());
        Col::from_fn(n, |j| x[(j, 0)])
    }

    /// The covariance `P = Λ⁻¹ = L⁻ᵀ L⁻¹` (`O(n³)`; formed only on request).
    pub fn covariance(&self) -> Mat<T> {
        let n = self.dim();
        let mut inv = Mat::<T>::identity(n, n);
        self.l
            .as_ref()
            .solve_lower_triangular_in_place(inv.as_mut());
        let mut p = Mat::<T>::zeros(n, n);
        faer::linalg::matmul::matmul(
            p.as_mut(),
            faer::Accum::Replace,
            inv.transpose(),
            inv.as_ref(),
            T::one_impl(),
            faer::Par::Seq,
        );
        p
    }

    /// The lower Cholesky factor `L` of the information matrix.
    pub fn sqrt_information(&self) -> MatRef<'_, T> {
        self.l.as_ref()
    }

    /// `min l_jj / max l_jj`: a cheap health figure. Its square bounds the reciprocal condition
    /// of `Λ` from above; values near `√ε` mean the information in some direction has decayed or
    /// was never there.
    pub fn diagonal_ratio(&self) -> T {
        let n = self.dim();
        let (mut lo, mut hi) = (self.l[(0, 0)], self.l[(0, 0)]);
        for j in 1..n {
            let d = self.l[(j, j)];
            if d < lo {
                lo = d;
            }
            if d > hi {
                hi = d;
            }
        }
        lo / hi
    }
}
