//! Typed errors of the batch solvers.

use core::fmt;

/// Which input of [`solve`](super::solve) an error refers to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Input {
    /// The design matrix `H`.
    Design,
    /// The observation vector `z`.
    Observations,
    /// The diagonal weights `w`.
    Weights,
    /// The measurement covariance `R` (the weight is `W = R⁻¹`).
    Covariance,
}

impl fmt::Display for Input {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Input::Design => "design matrix H",
            Input::Observations => "observations z",
            Input::Weights => "weights w",
            Input::Covariance => "measurement covariance R",
        })
    }
}

/// Why a batch least-squares solve did not return a solution.
///
/// Small and `Copy`, in the style of faer's own error enums. No variant is ever produced by a
/// panic: every data-dependent failure is reported here.
#[derive(Clone, Copy, Debug, PartialEq)]
#[non_exhaustive]
pub enum LsqError {
    /// `H` has no rows or no columns.
    Empty {
        /// Rows of `H`.
        rows: usize,
        /// Columns of `H`.
        cols: usize,
    },
    /// Fewer observations than parameters.
    Underdetermined {
        /// Rows of `H`.
        rows: usize,
        /// Columns of `H`.
        cols: usize,
    },
    /// An input does not have the size that `H` implies.
    DimensionMismatch {
        /// The offending input.
        input: Input,
        /// Expected rows (and columns, for square inputs).
        expected: usize,
        /// Rows (or columns) found.
        found: usize,
    },
    /// An input holds a NaN or an infinity.
    NonFinite {
        /// The offending input.
        input: Input,
        /// Row of the first non-finite entry.
        row: usize,
        /// Column of the first non-finite entry (0 for vectors).
        col: usize,
    },
    /// A diagonal weight is negative.
    NegativeWeight {
        /// Row of the first negative weight.
        row: usize,
    },
    /// The measurement covariance is not symmetric positive definite (its Cholesky
    /// factorisation failed at this pivot).
    CovarianceNotPositiveDefinite {
        /// The failing pivot.
        pivot: usize,
    },
    /// `W^½ H` is rank deficient to working precision and the method assumes full rank
    /// (use [`Method::PivotedQr`](super::Method::PivotedQr) or [`Method::Svd`](super::Method::Svd)).
    RankDeficient {
        /// Leading columns found numerically independent (the numerical rank for the
        /// rank-revealing methods).
        rank: usize,
        /// Columns of `H`.
        cols: usize,
    },
    /// The Cholesky factorisation of the normal equations broke down: the pivot was not positive,
    /// or cancellation left fewer than one significant digit in it.
    Breakdown {
        /// The failing pivot.
        pivot: usize,
    },
    /// The normal equations are too ill-conditioned for any digit of the solution to be trusted
    /// (`κ(HᵀWH) ≥ 1/ε`).
    IllConditioned {
        /// The condition estimate of the Cholesky factor (`κ(HᵀWH)` is about its square).
        condition: f64,
    },
    /// The SVD did not converge.
    SvdNoConvergence,
    /// Finite inputs produced a non-finite estimate or covariance (overflow).
    NonFiniteResult,
}

impl fmt::Display for LsqError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            LsqError::Empty { rows, cols } => {
                write!(f, "empty least-squares problem ({rows}×{cols})")
            }
            LsqError::Underdetermined { rows, cols } => {
                write!(f, "{rows} observations cannot determine {cols} parameters")
            }
            LsqError::DimensionMismatch {
                input,
                expected,
                found,
            } => {
                write!(f, "{input} has size {found}, expected {expected}")
            }
            LsqError::NonFinite { input, row, col } => {
                write!(f, "non-finite value in {input} at ({row}, {col})")
            }
            LsqError::NegativeWeight { row } => write!(f, "negative weight at row {row}"),
            LsqError::CovarianceNotPositiveDefinite { pivot } => write!(
                f,
                "measurement covariance is not positive definite (pivot {pivot})"
            ),
            LsqError::RankDeficient { rank, cols } => write!(
                f,
                "design matrix has numerical rank {rank} < {cols}; use a rank-revealing method"
            ),
            LsqError::Breakdown { pivot } => {
                write!(f, "normal equations: Cholesky breakdown at pivot {pivot}")
            }
            LsqError::IllConditioned { condition } => write!(
                f,
                "normal equations: condition {condition:.3e} squared exceeds 1/eps"
            ),
            LsqError::SvdNoConvergence => f.write_str("SVD did not converge"),
            LsqError::NonFiniteResult => f.write_str("the solution overflowed"),
        }
    }
}

impl std::error::Error for LsqError {}
