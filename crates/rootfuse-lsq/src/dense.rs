//! Dense weighted least squares on faer: `min ‖W^½ (z − H x)‖₂`, in `f32` or `f64`.
//!
//! One generic implementation ([`solve`]) over [`LsqReal`] (`f32`, `f64`) with four methods:
//!
//! | [`Method`] | rank | accuracy | use it for |
//! |---|---|---|---|
//! | [`Qr`](Method::Qr) (default) | full, else [`LsqError::RankDeficient`] | error ∝ `κ(A)·ε` after refinement | everything well posed |
//! | [`PivotedQr`](Method::PivotedQr) | revealed | as QR | rank-deficient `H`, basic solution |
//! | [`Svd`](Method::Svd) | revealed | as QR, slower | rank-deficient `H`, minimum-norm solution |
//! | [`NormalEquations`](Method::NormalEquations) | full | error ∝ `κ(A)²·ε` | comparison only; reports breakdown |
//!
//! where `A = W^½ H`. How the pieces fit:
//!
//! - **Weights** ([`Weights`]): none, diagonal `w ≥ 0` (a zero weight removes the row), or a full
//!   measurement covariance `R` with `W = R⁻¹`, applied by whitening with the Cholesky factor of
//!   `R` (never by forming `R⁻¹`). With `W = R⁻¹` the estimate is the Markov (BLUE) estimate and
//!   [`LsqSolution::covariance`] `= (HᵀR⁻¹H)⁻¹` is its covariance.
//! - **Equilibration** ([`Options::equilibrate`], on by default): each column of `A` is scaled by
//!   the power of two nearest its 2-norm before factoring, and the scaling is undone afterwards.
//!   Powers of two make the scaling exact, so the scaled problem is the given one; the condition
//!   number that governs rounding becomes the one of the scaled matrix, which is what lets
//!   polynomial fits with columns of wildly different size (NIST Filip, Wampler) keep their digits.
//! - **Iterative refinement** ([`Options::refinement_steps`], 3 by default) for QR, pivoted QR and
//!   SVD when the rank is full and `κ·ε < 10⁻²`: Björck's refinement of the augmented system
//!   `[I A; Aᵀ 0][r; y] = [b; 0]` with residuals accumulated in twice the working precision
//!   (compensated sums and fused products). It removes the `κ²·ε·‖r‖` error term that a
//!   backward-stable solve keeps for large residuals (NIST Wampler4/5 go from 6.6 to 15 digits).
//!   The covariance is not refined: its accuracy is `κ·ε` relative.
//! - **Rank tolerance** ([`Options::rank_tolerance`]): a diagonal entry of `R` (QR methods) or a
//!   singular value (SVD) counts towards the rank when it exceeds `tol` times the largest one.
//!   Default `tol = max(m, n)·ε` (the LAPACK/NumPy convention), applied to the equilibrated
//!   matrix; `ε` is the machine epsilon of `T` ([`LsqReal::EPSILON`]).
//! - **Condition estimate** ([`LsqSolution::condition`]): of the whitened, equilibrated design
//!   matrix. QR methods and normal equations report `κ₁(R) = ‖R‖₁‖R⁻¹‖₁` (within a factor `n` of
//!   `κ₂`); SVD reports `σ_max/σ_min` exactly. Infinite when the rank is deficient.
//! - **R²** ([`RSquaredKind`]): `1 − RSS/TSS` with the weighted total sum of squares either about
//!   the weighted mean (centred) or about zero (uncentred). The default `Auto` picks centred when
//!   `H` has a constant nonzero column (an intercept) and uncentred otherwise, which is the
//!   convention of the NIST StRD certified values (NoInt1 and NoInt2 use the uncentred one).
//!
//! For problems that arrive one measurement at a time with `n` in the hundreds,
//! [`SqrtInfoRls`] is the recursive counterpart: square-root information RLS on faer's rank-one
//! Cholesky update, equal to the batch solution of the same weighted problem.
//!
//! Nothing here panics on data: sizes, non-finite values, negative weights, rank deficiency and
//! breakdown all come back as [`LsqError`].
//!
//! # Example
//!
//! ```
//! use rootfuse_lsq::dense::faer::{col, mat};
//! use rootfuse_lsq::dense::{solve, Method, Options, Weights};
//!
//! // z = 1 + 2 t, observed at t = 0, 1, 2, 3.
//! let h = mat![[1.0, 0.0], [1.0, 1.0], [1.0, 2.0], [1.0, 3.0]];
//! let z = col![1.0, 3.0, 5.0, 7.0];
//! let sol = solve(h.as_ref(), z.as_ref(), Weights::Unit, &Options::default())?;
//! assert!((sol.estimate[0] - 1.0_f64).abs() < 1e-14);
//! assert!((sol.estimate[1] - 2.0_f64).abs() < 1e-14);
//! assert_eq!(sol.rank, 2);
//!
//! // The same fit by SVD, in f32, with the third observation down-weighted.
//! let h32 = h.as_ref().map(|&v| v as f32);
//! let z32 = col![1.0_f32, 3.0, 5.5, 7.0];
//! let w = col![1.0_f32, 1.0, 0.01, 1.0];
//! let sol32 = solve(h32.as_ref(), z32.as_ref(), Weights::Diagonal(w.as_ref()), &Options::with_method(Method::Svd))?;
//! assert!((sol32.estimate[1] - 2.0).abs() < 0.01);
//! # Ok::<(), rootfuse_lsq::dense::LsqError>(())
//! ```

mod error;
mod factor;
mod refine;
mod scalar;
mod sqrt_information_rls;

pub use error::{Input, LsqError};
pub use scalar::LsqReal;
pub use sqrt_information_rls::SqrtInfoRls;

/// The faer version this module is built on, so callers can build `MatRef`/`ColRef` arguments
/// without a second, possibly mismatched, faer dependency.
pub use faer;

use faer::{Col, ColRef, Mat, MatRef, Side};

/// The factorisation [`solve`] uses. See the [module documentation](self) for the trade-offs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Method {
    /// Householder QR without pivoting; full column rank required.
    #[default]
    Qr,
    /// Householder QR with column pivoting; reveals the rank and returns the basic solution
    /// (parameters outside the numerically independent set are 0, their covariance rows 0).
    PivotedQr,
    /// Singular value decomposition; reveals the rank and returns the minimum-norm solution with
    /// the pseudo-inverse of `HᵀWH` as covariance.
    Svd,
    /// Cholesky on `HᵀWH`. A comparison method: it reports [`LsqError::Breakdown`] or
    /// [`LsqError::IllConditioned`] where it would lose every digit.
    NormalEquations,
}

/// Which total sum of squares the coefficient of determination uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum RSquaredKind {
    /// Centred if `H` has a constant nonzero column (an intercept), uncentred otherwise.
    #[default]
    Auto,
    /// `TSS = Σ wᵢ (zᵢ − z̄_w)²` (with a full covariance: the residual sum of squares of the
    /// intercept-only model).
    Centred,
    /// `TSS = Σ wᵢ zᵢ²`, for models through the origin.
    Uncentred,
}

/// The weight `W` in `‖W^½ (z − H x)‖`.
#[derive(Clone, Copy, Debug)]
pub enum Weights<'a, T> {
    /// `W = I`.
    Unit,
    /// `W = diag(w)` with `w ≥ 0`; a zero weight removes the observation (and its degree of
    /// freedom).
    Diagonal(ColRef<'a, T>),
    /// `W = R⁻¹` for a symmetric positive definite measurement covariance `R` (only its lower
    /// triangle is read).
    Covariance(MatRef<'a, T>),
}

/// Options of [`solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options<T> {
    /// The factorisation.
    pub method: Method,
    /// Relative rank tolerance; `None` means `max(m, n)·ε`. Ignored by
    /// [`Method::NormalEquations`], which has its own breakdown tests.
    pub rank_tolerance: Option<T>,
    /// Scale the columns of `W^½H` to unit norm before factoring (recommended; see the module
    /// documentation).
    pub equilibrate: bool,
    /// Centred or uncentred R².
    pub r_squared: RSquaredKind,
    /// Steps of iterative refinement for QR, pivoted QR and SVD (full rank only; see the module
    /// documentation); 0 turns it off.
    pub refinement_steps: usize,
}

impl<T> Default for Options<T> {
    fn default() -> Self {
        Options {
            method: Method::Qr,
            rank_tolerance: None,
            equilibrate: true,
            r_squared: RSquaredKind::Auto,
            refinement_steps: 3,
        }
    }
}

impl<T> Options<T> {
    /// The defaults with another method.
    pub fn with_method(method: Method) -> Self {
        Options {
            method,
            ..Options::default()
        }
    }
}

/// The result of [`solve`].
#[derive(Clone, Debug)]
pub struct LsqSolution<T> {
    /// The estimate `x̂`.
    pub estimate: Col<T>,
    /// Unweighted residuals `z − H x̂`.
    pub residuals: Col<T>,
    /// Weighted residual sum of squares `‖W^½ (z − H x̂)‖²`.
    pub rss: T,
    /// Degrees of freedom: observations with nonzero weight minus the rank.
    pub dof: usize,
    /// Residual variance `rss / dof` (the regression's `s²`); `None` when `dof = 0`.
    pub residual_variance: Option<T>,
    /// `(HᵀWH)⁻¹`, not scaled by the residual variance: the covariance of `x̂` when `W = R⁻¹` is
    /// the true measurement covariance. Rank-deficient solutions get the covariance of the basic
    /// solution ([`Method::PivotedQr`]) or the pseudo-inverse ([`Method::Svd`]).
    pub covariance: Mat<T>,
    /// Coefficient of determination; `None` when the total sum of squares is zero.
    pub r_squared: Option<T>,
    /// The total sum of squares actually used (never `Auto`).
    pub r_squared_kind: RSquaredKind,
    /// Condition estimate of the whitened, equilibrated design matrix (see the module
    /// documentation); infinite for rank-deficient problems.
    pub condition: T,
    /// Numerical rank of `W^½H`.
    pub rank: usize,
    /// The method that produced this solution.
    pub method: Method,
}

impl<T: LsqReal> LsqSolution<T> {
    /// Residual standard deviation `√(rss / dof)`, `None` when `dof = 0`.
    pub fn residual_std(&self) -> Option<T> {
        self.residual_variance.map(LsqReal::sqrt)
    }

    /// Standard errors of the regression, `√(s² · diag (HᵀWH)⁻¹)` (what NIST certifies as the
    /// "standard deviation of the estimate"); `None` when `dof = 0`.
    pub fn standard_errors(&self) -> Option<Col<T>> {
        let s2 = self.residual_variance?;
        Some(Col::from_fn(self.estimate.nrows(), |j| {
            (s2 * self.covariance[(j, j)]).sqrt()
        }))
    }
}

/// How the weight is applied: rows scaled by `√w`, or a triangular solve with `chol(R)`.
enum Whitener<T> {
    Unit,
    Diagonal(Vec<T>),
    Cholesky(Mat<T>),
}

impl<T: LsqReal> Whitener<T> {
    /// `W^½ v` for each column of `v`, in place.
    fn apply(&self, mut v: faer::MatMut<'_, T>) {
        match self {
            Whitener::Unit => {}
            Whitener::Diagonal(s) => {
                for j in 0..v.ncols() {
                    for (i, &si) in s.iter().enumerate() {
                        v[(i, j)] *= si;
                    }
                }
            }
            Whitener::Cholesky(l) => l.as_ref().solve_lower_triangular_in_place(v),
        }
    }
}

fn check_finite_mat<T: LsqReal>(a: MatRef<'_, T>, input: Input) -> Result<(), LsqError> {
    for i in 0..a.nrows() {
        for j in 0..a.ncols() {
            if !a[(i, j)].is_finite() {
                return Err(LsqError::NonFinite {
                    input,
                    row: i,
                    col: j,
                });
            }
        }
    }
    Ok(())
}

fn check_finite_col<T: LsqReal>(v: ColRef<'_, T>, input: Input) -> Result<(), LsqError> {
    match (0..v.nrows()).find(|&i| !v[i].is_finite()) {
        Some(row) => Err(LsqError::NonFinite { input, row, col: 0 }),
        None => Ok(()),
    }
}

/// Validates the inputs and builds the whitener; returns it with the number of rows that carry
/// weight.
fn whitener<T: LsqReal>(
    m: usize,
    weights: Weights<'_, T>,
) -> Result<(Whitener<T>, usize), LsqError> {
    match weights {
        Weights::Unit => Ok((Whitener::Unit, m)),
        Weights::Diagonal(w) => {
            if w.nrows() != m {
                return Err(LsqError::DimensionMismatch {
                    input: Input::Weights,
                    expected: m,
                    found: w.nrows(),
                });
            }
            check_finite_col(w, Input::Weights)?;
            if let Some(row) = (0..m).find(|&i| w[i] < T::zero_impl()) {
                return Err(LsqError::NegativeWeight { row });
            }
            let active = (0..m).filter(|&i| w[i] > T::zero_impl()).count();
            Ok((
                Whitener::Diagonal((0..m).map(|i| w[i].sqrt()).collect()),
                active,
            ))
        }
        Weights::Covariance(r) => {
            for found in [r.nrows(), r.ncols()] {
                if found != m {
                    return Err(LsqError::DimensionMismatch {
                        input: Input::Covariance,
                        expected: m,
                        found,
                    });
                }
            }
            check_finite_mat(r, Input::Covariance)?;
            let llt = faer::linalg::solvers::Llt::new(r, Side::Lower).map_err(|e| match e {
                faer::linalg::solvers::LltError::NonPositivePivot { index } => {
                    LsqError::CovarianceNotPositiveDefinite { pivot: index }
                }
            })?;
            Ok((Whitener::Cholesky(llt.L().to_owned()), m))
        }
    }
}

/// Solves the weighted least-squares problem `min ‖W^½ (z − H x)‖₂`.
///
/// `h` is `m × n` with `m ≥ n ≥ 1`, `z` has `m` rows. See the [module documentation](self) for the
/// methods, the rank tolerance, the condition estimate and the R² convention, and for an example.
///
/// # Errors
///
/// Every data-dependent failure is an [`LsqError`]: wrong sizes, non-finite inputs (with their
/// position), negative weights, a covariance that is not positive definite, rank deficiency for
/// [`Method::Qr`], breakdown of [`Method::NormalEquations`], SVD non-convergence, overflow.
pub fn solve<T: LsqReal>(
    h: MatRef<'_, T>,
    z: ColRef<'_, T>,
    weights: Weights<'_, T>,
    options: &Options<T>,
) -> Result<LsqSolution<T>, LsqError> {
    let (m, n) = (h.nrows(), h.ncols());
    if m == 0 || n == 0 {
        return Err(LsqError::Empty { rows: m, cols: n });
    }
    if z.nrows() != m {
        return Err(LsqError::DimensionMismatch {
            input: Input::Observations,
            expected: m,
            found: z.nrows(),
        });
    }
    if m < n {
        return Err(LsqError::Underdetermined { rows: m, cols: n });
    }
    check_finite_mat(h, Input::Design)?;
    check_finite_col(z, Input::Observations)?;
    let (white, active_rows) = whitener(m, weights)?;

    // Whitened system [A b 1w] = W^½ [H z 1]; the whitened ones column serves the centred R².
    let mut sys = Mat::<T>::from_fn(m, n + 2, |i, j| match j {
        j if j < n => h[(i, j)],
        j if j == n => z[i],
        _ => T::one_impl(),
    });
    white.apply(sys.as_mut());

    let scale = if options.equilibrate {
        equilibrate(&mut sys, n)
    } else {
        vec![T::one_impl(); n]
    };
    let a = sys.as_ref().get(.., ..n);
    let b = sys.as_ref().col(n);
    let tol = options
        .rank_tolerance
        .unwrap_or_else(|| T::from_f64(m.max(n) as f64) * T::EPSILON);

    let f = match options.method {
        Method::Qr => factor::qr(a, b, tol, options.refinement_steps)?,
        Method::PivotedQr => factor::pivoted_qr(a, b, tol, options.refinement_steps)?,
        Method::Svd => factor::svd(a, b, tol, options.refinement_steps)?,
        Method::NormalEquations => factor::normal_equations(a, b)?,
    };

    let estimate = Col::from_fn(n, |j| f.y[j] / scale[j]);
    let covariance = Mat::from_fn(n, n, |i, j| f.cov[(i, j)] / (scale[i] * scale[j]));
    let finite =
        (0..n).all(|i| estimate[i].is_finite() && (0..n).all(|j| covariance[(i, j)].is_finite()));
    if !finite {
        return Err(LsqError::NonFiniteResult);
    }

    // Residuals from the original data, not from Qᵀb: they are what the user will check against.
    let mut residuals = Col::<T>::zeros(m);
    for i in 0..m {
        let mut hx = T::zero_impl();
        for j in 0..n {
            hx += h[(i, j)] * estimate[j];
        }
        residuals[i] = z[i] - hx;
    }
    let mut wr = Mat::<T>::from_fn(m, 1, |i, _| residuals[i]);
    white.apply(wr.as_mut());
    let rss = sum_sq((0..m).map(|i| wr[(i, 0)]));

    let dof = active_rows.saturating_sub(f.rank);
    let residual_variance = (dof > 0).then(|| rss / T::from_f64(dof as f64));

    let kind = match options.r_squared {
        RSquaredKind::Auto if has_intercept(h) => RSquaredKind::Centred,
        RSquaredKind::Auto => RSquaredKind::Uncentred,
        k => k,
    };
    let tss = total_sum_of_squares(&sys, n, kind);
    let r_squared = (tss > T::zero_impl()).then(|| T::one_impl() - rss / tss);

    Ok(LsqSolution {
        estimate,
        residuals,
        rss,
        dof,
        residual_variance,
        covariance,
        r_squared,
        r_squared_kind: kind,
        condition: f.condition,
        rank: f.rank,
        method: options.method,
    })
}

/// Scales each of the first `n` columns of `sys` by the power of two nearest its 2-norm's
/// inverse and returns the scales (1 for a zero column or one whose scale is not finite).
fn equilibrate<T: LsqReal>(sys: &mut Mat<T>, n: usize) -> Vec<T> {
    let m = sys.nrows();
    let mut scale = vec![T::one_impl(); n];
    for (j, s) in scale.iter_mut().enumerate() {
        // The nearest power of two: scaling by it is exact, so the equilibrated problem is
        // the given problem, not a rounded neighbour of it.
        let norm = sys.as_ref().col(j).norm_l2().to_f64();
        let pow2 = T::from_f64(2f64.powi(norm.log2().round() as i32));
        let inv = T::one_impl() / pow2;
        if norm > 0.0
            && pow2.is_finite()
            && pow2 > T::zero_impl()
            && inv.is_finite()
            && inv > T::zero_impl()
        {
            *s = pow2;
            for i in 0..m {
                sys[(i, j)] *= inv;
            }
        }
    }
    scale
}

/// The total sum of squares of the whitened observations (column `n` of `sys`): about their
/// weighted mean (column `n + 1` holds the whitened ones) for the centred R², about zero
/// otherwise.
fn total_sum_of_squares<T: LsqReal>(sys: &Mat<T>, n: usize, kind: RSquaredKind) -> T {
    let b = sys.as_ref().col(n);
    let m = sys.nrows();
    match kind {
        RSquaredKind::Centred => {
            let o = sys.as_ref().col(n + 1);
            let oo = sum_sq((0..m).map(|i| o[i]));
            let mut ob = T::zero_impl();
            for i in 0..m {
                ob += o[i] * b[i];
            }
            let mean = if oo > T::zero_impl() {
                ob / oo
            } else {
                T::zero_impl()
            };
            sum_sq((0..m).map(|i| b[i] - mean * o[i]))
        }
        _ => sum_sq((0..m).map(|i| b[i])),
    }
}

fn sum_sq<T: LsqReal>(it: impl Iterator<Item = T>) -> T {
    let mut s = T::zero_impl();
    for v in it {
        s += v * v;
    }
    s
}

/// A constant nonzero column is an intercept, whatever its value.
fn has_intercept<T: LsqReal>(h: MatRef<'_, T>) -> bool {
    (0..h.ncols()).any(|j| {
        let c = h[(0, j)];
        c != T::zero_impl() && (1..h.nrows()).all(|i| h[(i, j)] == c)
    })
}
