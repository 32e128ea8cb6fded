//! Recursive least squares: one problem, six numerically different forms.
//!
//! # The problem
//! Every form estimates `x ∈ ℝⁿ` from scalar measurements `z_i = h_iᵀ x + v_i` with weights
//! `w_i > 0` (a weight is an inverse noise variance, `w = 1/σ²`, in the inverse squared unit
//! of `z`), by minimising after `k` accepted measurements
//!
//! ```text
//! J_k(x) = λ^k (x − x₀)ᵀ P₀⁻¹ (x − x₀) + Σᵢ λ^(k−i) wᵢ (zᵢ − hᵢᵀ x)²,     λ ∈ (0, 1]
//! ```
//!
//! The minimiser is `x_k = P_k b_k` with information matrix
//! `P_k⁻¹ = λ^k P₀⁻¹ + Σ λ^(k−i) wᵢ hᵢ hᵢᵀ`. `P_k` is what [`covariance`]
//! returns (with `w = 1/σ²` it is the covariance of the estimate; with λ < 1 it is scaled
//! accordingly).
//!
//! Each update is a *time update* `P̃ = P/λ` (forgetting) followed by a Kalman measurement update
//! with the whitened row `√w·h`, measurement `√w·z` and unit noise variance; the forms differ
//! only in what they store:
//!
//! | form | stores | module |
//! |---|---|---|
//! | conventional | `P` (symmetrised) | [`conventional`] |
//! | Joseph | `P` (Joseph-stabilised) | [`joseph`] |
//! | Potter | `S`, `P = S Sᵀ` (square, not triangular) | [`potter`] |
//! | Bierman U-D | unit upper `U`, diagonal `D`, `P = U D Uᵀ` | [`bierman_ud`] |
//! | inverse QR | lower triangular `S`, `P = S Sᵀ` | [`inverse_qr`] |
//! | information QR | upper triangular `R`, `Rᵀ R = P⁻¹`, `ζ = R x` | [`information_qr`] |
//!
//! # Conventions shared by every form
//! - **Rejection per lane.** A sample whose `h`, `z` or `weight` is not finite, or whose weight
//!   is not `> 0`, is rejected in its lane: that lane's state is left exactly as it was (no
//!   forgetting either, the sample is as if it never arrived) and its `rejected_input` counter
//!   goes up. An update whose result is not finite (overflow) or, for the covariance forms,
//!   visibly not positive definite is likewise not applied and counted in
//!   `rejected_numerical`. Other lanes are never affected: rejected lanes compute on harmless
//!   substitutes and the old state is selected back.
//! - **Vector measurements** (`update_vector`) are processed as sequential scalar updates. That
//!   is exact only for uncorrelated noise (diagonal `R`, the weights being `1/R_ii`); for a
//!   correlated `R = L Lᵀ`, whiten first: use rows of `L⁻¹ H`, `L⁻¹ z` with unit weights.
//!   Forgetting is applied once per call, with the first accepted row of each lane.
//! - **Windup protection** ([`CovarianceBounds`]) is a configuration option of every form; see
//!   its documentation for the guarantee and how it is kept.
//! - Nothing allocates; every step is branch-free per lane, so a SIMD lane computes exactly
//!   what the scalar instantiation computes on the same data.
//!
//! # References
//! G. J. Bierman, *Factorization Methods for Discrete Sequential Estimation*, 1977;
//! M. Verhaegen and P. Van Dooren, "Numerical aspects of different Kalman filter
//! implementations", IEEE TAC 31(10), 1986; S. T. Alexander and A. L. Ghirnikar, "A method for
//! recursive least squares filtering based upon an inverse QR decomposition", IEEE TSP 41(1),
//! 1993; G. H. Golub and C. F. Van Loan, *Matrix Computations*.
//!
//! ```
//! use rootfuse_lane::{Mask, Mat, Vector};
//! use rootfuse_lsq::rls::{BiermanUd, RecursiveLeastSquares, RlsConfig};
//!
//! // Fit z = 2 + 3 t from exact samples.
//! let x0 = Vector::<f64, 2>::zeros();
//! let mut rls = BiermanUd::with_isotropic_prior(&x0, 1e6, RlsConfig::new(1.0)).unwrap();
//! for t in 0..20 {
//!     let t = t as f64;
//!     let h = Vector::from_column([1.0, t]);
//!     assert!(rls.update(&h, 2.0 + 3.0 * t, 1.0).all());
//! }
//! let x = rls.estimate();
//! assert!((x[0] - 2.0).abs() < 1e-4 && (x[1] - 3.0).abs() < 1e-5);
//! ```
//!
//! [`covariance`]: RecursiveLeastSquares::covariance

pub mod bierman_ud;
pub mod conventional;
pub mod information_qr;
pub mod inverse_qr;
pub mod joseph;
pub mod potter;

pub use bierman_ud::BiermanUd;
pub use conventional::Conventional;
pub use information_qr::InformationQr;
pub use inverse_qr::InverseQr;
pub use joseph::Joseph;
pub use potter::Potter;

use rootfuse_lane::{Lane, Mask, Mat, Vector};

/// Windup protection: keep `p_min ≤ eig(P) ≤ p_max` (units of `P`: squared units of `x`).
///
/// # Guarantee
/// With bounds configured and a prior inside them, after every update every eigenvalue of
/// `P` is `≤ p_max`, and `trace(P⁻¹) ≤ 1/p_min`, hence every eigenvalue is `≥ p_min`
/// (exactly in exact arithmetic; in floating point up to the rounding of the stored factor: a
/// relative slack of about `n·u·κ(P)` on the covariance formed from it, which is a few units
/// of roundoff times `n` for a well-conditioned `P`). Requires `n·p_min < p_max`.
///
/// # The covariance forms and the square-root covariance forms at extreme forgetting
/// The conventional and Joseph forms subtract from `P̃ = P/λ_s` itself (`λ_s` the step's
/// forgetting factor: `λ`, or 1 when not forgetting), and Bierman U-D from `D̃ = D/λ_s`, so every row of an update — the
/// measurement rows and, when forgetting, the `n` regularising pseudo-rows
/// (`w‖h‖² = (1 − λ)/p_max`) — rounds at `P̃`'s scale, and a row with
/// `α = 1 + w·hᵀP̃h` also loses about `u·α` relative at the result's scale (`u` the unit
/// roundoff). Potter and inverse QR both work on the square factor `S̃ = S/√λ_s` (Potter by a
/// rank-one correction, inverse QR by Givens rotations of the prearray), so both round at its
/// scale, which is `√(L·‖P‖/λ_s)` in `P`, and lose `u·√α`. With `‖P‖` the size of the `P` the
/// update started from and `L = max(p_max, ‖P‖)`, per update:
///
/// ```text
/// λ_max(P_new) ≤ p_max·(1 + 10·n·u) + λ_s·(λ_max(P) − p_max)⁺
///                + Σ_rows 4·u·(‖P‖/λ_s + α_r·L)              (conventional, Joseph, Bierman U-D)
///                + Σ_rows 4·u·(√(L·‖P‖/λ_s) + √α_r·L)        (Potter, inverse QR)
///                + (Σ_rows 4·u·√(‖P‖/λ_s))²                   (Potter, inverse QR: δS·δSᵀ)
/// α_r = 1 + w_r‖h_r‖²·‖P‖/λ_s
/// ```
///
/// While `λ ≫ u` (covariance forms, Bierman U-D) or `λ ≫ u²` (square-root covariance forms) this is a slack
/// of a few `n·u/λ` (`n·u/√λ`) on `p_max`, and an excess decays by `λ` per forgetting step.
/// For smaller `λ` (f64: `u = 1.1·10⁻¹⁶`, f32: `6·10⁻⁸`) it is not: the direction reset to
/// `p_max` comes out as the rounding remainder of `P/λ`, and the excess compounds (found by
/// fuzzing, f64, `λ = 10⁻³⁰`, `p_max = 10¹⁰`, conventional: `P = 10¹⁰ → 2⁸⁰ ≈ 1.2·10²⁴ →
/// 2¹²⁷ ≈ 1.7·10³⁸`, one ulp of `10⁴⁰` and of `1.2·10⁵⁴`) until `P/λ` overflows and updates
/// are refused (`rejected_numerical`); Potter from `P₀ = 10⁻³·I` with `p_max = 10⁵` ends at
/// `p_max + 4.2` after one update at `λ = 10⁻³⁰`, and with `p_max = 100` at `1.1·10¹²` at
/// `λ = 1.5·10⁻⁴⁷` (below `u²`, where the square of the factor's rounding dominates);
/// inverse QR in f32 at `λ = 1.2·10⁻²⁵` ends `4.9·10⁻⁵` relative above `p_max = 100`, Bierman
/// U-D in f64 at `λ = 4.5·10⁻⁴⁴` `1.2·10⁻¹⁰` relative above it. For information QR, which
/// scales its factor by `√λ` (information shrinks, nothing is divided), fuzzing has found no
/// update beyond the plain `p_max·(1 + 10·n·u·κ(P))` at any `λ`: prefer it when `λ` may be far
/// below one (a forgetting factor below about `0.5` keeps almost no memory anyway).
///
/// # How it is kept (the same for every form)
/// - *Upper bound*, by regularised forgetting: each forgetting step is
///   `P⁻¹ ← λ P⁻¹ + (1 − λ)/p_max · I` instead of `λ P⁻¹`. If `P⁻¹ ⪰ I/p_max` before, it
///   stays so, and a measurement only adds information; the bound is directional, so
///   forgetting goes on in excited directions while unexcited ones settle at `p_max` (no
///   windup, no overflow). Every form adds `α I`, `α = (1 − λ)/p_max`, as `n` pseudo-
///   measurements `√α e_iᵀ x = √α x_i` with zero innovation, through its own (stable)
///   measurement update: O(n³) per update instead of O(n²), paid only with bounds on.
///   With `λ = 1` nothing is added and `P` only shrinks from `P₀ ⪯ p_max I`.
/// - *Lower bound*, by clipping the weight: the information trace obeys the exact recursion
///   `trace(P⁻¹) ← λ·trace(P⁻¹) + n α + w·‖h‖²`, tracked as one scalar per lane; the weight
///   is clipped to `w_eff = min(w, (1/p_min − λ·trace(P⁻¹) − n α) / ‖h‖²)` so the trace never
///   exceeds `1/p_min` (the gain never falls asleep). Forgetting keeps making room, so the
///   clip never freezes the estimator for `λ < 1`; with `λ = 1` and `p_min > 0` learning
///   stops once the bound is reached (use `p_min = 0` there).
/// - [`BiermanUd::time_update`] scales its process noise down so that
///   `trace(P) ≤ p_max` still holds after it (a sufficient condition).
///
/// With the bounds active the recursion no longer solves the exact exponentially weighted
/// problem: updates whose weight was clipped are counted in [`Health::clipped`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CovarianceBounds {
    /// Lower eigenvalue bound, `≥ 0` (`0` disables the lower bound).
    pub p_min: f64,
    /// Upper eigenvalue bound, `> p_min` (`f64::INFINITY` disables the upper bound).
    pub p_max: f64,
}

/// Configuration shared by every form.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RlsConfig {
    /// Forgetting factor `λ ∈ (0, 1]` (`1` = no forgetting; memory ≈ `1/(1 − λ)` samples).
    pub lambda: f64,
    /// Optional windup protection.
    pub bounds: Option<CovarianceBounds>,
    /// [`InformationQr`] only (the other forms ignore it): accumulate `R` and `ζ` with
    /// compensated sums (the default, see its documentation). Off, the form does plain
    /// Givens updates: about 25 % cheaper in `f32x8` lanes (within noise in scalars), but
    /// with λ = 1 its accumulated `R` loses about `u·k` (in f32 3.5e-5 relative after
    /// 2·10⁵ steps, against 4.7e-8 compensated).
    pub compensated: bool,
}

impl RlsConfig {
    /// Forgetting factor `lambda`, no covariance bounds, compensated information form.
    pub const fn new(lambda: f64) -> Self {
        Self {
            lambda,
            bounds: None,
            compensated: true,
        }
    }
    /// The same configuration with windup protection `p_min ≤ eig(P) ≤ p_max`.
    pub const fn with_bounds(self, p_min: f64, p_max: f64) -> Self {
        Self {
            bounds: Some(CovarianceBounds { p_min, p_max }),
            ..self
        }
    }
    /// The same configuration with plain (uncompensated) accumulation in [`InformationQr`].
    pub const fn without_compensation(self) -> Self {
        Self {
            compensated: false,
            ..self
        }
    }
    fn validate(&self) -> Result<(), RlsError> {
        if !(self.lambda > 0.0 && self.lambda <= 1.0) {
            return Err(RlsError::InvalidForgettingFactor);
        }
        if let Some(b) = self.bounds {
            // p_max may be +inf; NaN fails every comparison below.
            if !(b.p_min >= 0.0 && b.p_min.is_finite() && b.p_max > b.p_min) {
                return Err(RlsError::InvalidBounds);
            }
        }
        Ok(())
    }
}

impl Default for RlsConfig {
    /// `λ = 1`, no bounds: ordinary recursive least squares.
    fn default() -> Self {
        Self::new(1.0)
    }
}

/// Why a construction or a scalar [`Conventional::try_update`] failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RlsError {
    /// `λ` is not in `(0, 1]`.
    InvalidForgettingFactor,
    /// The covariance bounds are not `0 ≤ n·p_min < p_max` (or are NaN).
    InvalidBounds,
    /// `x₀` is not finite in some lane (for the information form also: `R₀ x₀` overflows).
    NonFinitePrior,
    /// `P₀` is not symmetric positive definite (or not finite) in some lane.
    PriorNotPositiveDefinite,
    /// `P₀` violates the configured covariance bounds in some lane.
    PriorOutsideBounds,
    /// The sample was rejected: non-finite `h`, `‖h‖²`, `z` or weight, or weight `≤ 0`.
    RejectedSample,
    /// The update would have produced a non-finite state; it was not applied.
    NumericalFailure,
    /// The covariance is no longer positive definite (detected by the conventional or Joseph
    /// form); the update was not applied.
    LostDefiniteness,
    /// A state transition ([`Potter::predict`]) was asked of an estimator with
    /// [`CovarianceBounds`]: a general transition moves `P` and `trace(P⁻¹)` in ways the
    /// bounded recursion does not track, so the bounds could no longer be guaranteed.
    TransitionWithBounds,
}

impl core::fmt::Display for RlsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(match self {
            Self::InvalidForgettingFactor => "forgetting factor not in (0, 1]",
            Self::InvalidBounds => "covariance bounds not 0 <= p_min < p_max",
            Self::NonFinitePrior => "initial estimate not finite",
            Self::PriorNotPositiveDefinite => "initial covariance not positive definite",
            Self::PriorOutsideBounds => "initial covariance outside the configured bounds",
            Self::RejectedSample => "sample rejected (non-finite data or weight <= 0)",
            Self::NumericalFailure => "update would produce a non-finite state",
            Self::LostDefiniteness => "covariance lost positive definiteness",
            Self::TransitionWithBounds => "state transition with covariance bounds configured",
        })
    }
}

impl core::error::Error for RlsError {}

/// Cheap diagnostics of one estimator, per lane.
///
/// `min_pivot`/`max_pivot` are the pivots of `P` that the form's factor exposes without extra
/// work: `d_j` for Bierman U-D, `S_jj²` for inverse QR (the `L D Lᵀ` pivots of `P`),
/// `1/R_jj²` for information QR (the `U D Uᵀ` pivots of `P`), and the diagonal of `P` for the
/// conventional, Joseph and Potter forms (a weaker proxy: a positive diagonal does not prove
/// definiteness). `max_pivot / min_pivot` ([`pivot_ratio`](Health::pivot_ratio)) is a cheap
/// lower bound of the condition number of `P`; a triangular factor is positive definite iff
/// every pivot is `> 0`.
#[derive(Clone, Copy, Debug)]
pub struct Health<T: Lane> {
    /// Smallest pivot (see above), units of `P`.
    pub min_pivot: T,
    /// Largest pivot, units of `P`.
    pub max_pivot: T,
    /// `trace(P)`.
    pub trace: T,
    /// Running `trace(P⁻¹)` of the bounded-forgetting recursion (only maintained when
    /// [`CovarianceBounds`] are configured; otherwise the prior's value).
    pub information_trace: T,
    /// Lanes where the form detected lost positive definiteness (conventional and Joseph
    /// forms; sticky). Always false for the factored forms, whose `P` is definite by
    /// construction.
    pub lost_definiteness: T::Mask,
    /// Accepted updates per lane.
    pub accepted: T::Counts,
    /// Samples rejected for their data (non-finite `h`/`‖h‖²`/`z`/weight, weight `≤ 0`), per
    /// lane.
    pub rejected_input: T::Counts,
    /// Updates not applied because the result was non-finite or not definite, per lane.
    pub rejected_numerical: T::Counts,
    /// Accepted updates whose weight windup protection clipped (lower bound), per lane.
    pub clipped: T::Counts,
}

impl<T: Lane> Health<T> {
    /// `max_pivot / min_pivot`: a cheap lower bound of the condition number of `P`.
    pub fn pivot_ratio(&self) -> T {
        self.max_pivot / self.min_pivot
    }
}

/// The interface every recursive form implements (see the [module documentation](self)).
pub trait RecursiveLeastSquares<T: Lane, const N: usize>: Sized {
    /// Short name of the form (`"conventional"`, `"bierman-ud"`, …).
    const NAME: &'static str;

    /// Starts from estimate `x0` and covariance `p0` (only its lower triangle is read).
    ///
    /// Fails if the configuration is invalid, `x0` is not finite or `p0` is not positive
    /// definite (or outside the bounds) in any lane.
    fn new(x0: &Vector<T, N>, p0: &Mat<T, N, N>, config: RlsConfig) -> Result<Self, RlsError>;

    /// Starts from `x0` and `P₀ = p0·I` (`p0 > 0` in every lane).
    fn with_isotropic_prior(x0: &Vector<T, N>, p0: T, config: RlsConfig) -> Result<Self, RlsError> {
        Self::new(x0, &Mat::identity().scale(p0), config)
    }

    /// One scalar measurement `z = hᵀx + v` with weight `1/var(v)`; lanes where `forget` is
    /// set apply the forgetting factor first (the others keep `λ = 1` for this step).
    ///
    /// Returns the lanes where the update was applied.
    fn update_with_forgetting(
        &mut self,
        h: &Vector<T, N>,
        z: T,
        weight: T,
        forget: T::Mask,
    ) -> T::Mask;

    /// One scalar measurement with forgetting; returns the lanes where it was applied.
    #[inline]
    fn update(&mut self, h: &Vector<T, N>, z: T, weight: T) -> T::Mask {
        self.update_with_forgetting(h, z, weight, T::Mask::splat(true))
    }

    /// A vector measurement `z = H x + v` with uncorrelated noise, `weights[i] = 1/var(v_i)`,
    /// as sequential scalar updates (whiten a correlated noise first, see the module
    /// documentation). Forgetting is applied once per lane, with its first accepted row.
    ///
    /// Returns the lanes where every row was applied.
    fn update_vector<const M: usize>(
        &mut self,
        h: &Mat<T, M, N>,
        z: &Vector<T, M>,
        weights: &Vector<T, M>,
    ) -> T::Mask {
        let mut pending = T::Mask::splat(true);
        let mut all = T::Mask::splat(true);
        for i in 0..M {
            let row = Vector::from_column(h.m[i]);
            let ok = self.update_with_forgetting(&row, z[i], weights[i], pending);
            pending &= !ok;
            all &= ok;
        }
        all
    }

    /// The current estimate `x`.
    fn estimate(&self) -> Vector<T, N>;

    /// The covariance `P` (formed from the factor for the factored forms), exactly symmetric.
    fn covariance(&self) -> Mat<T, N, N>;

    /// Cheap diagnostics and per-lane counters.
    fn health(&self) -> Health<T>;

    /// The configuration the estimator was built with.
    fn config(&self) -> RlsConfig;
}

/// What distinguishes one form's update from another's; [`update_form`] does the rest, so
/// the six forms share one update path (validation, regularised forgetting, counting,
/// per-lane acceptance).
pub(crate) trait Form<T: Lane, const N: usize>: Copy {
    fn core(&self) -> &Core<T>;
    fn core_mut(&mut self) -> &mut Core<T>;
    /// Forgetting plus one whitened measurement: (new state, finite, definite).
    fn form_step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask);
    /// The estimate the regularising pseudo-rows of bounded forgetting are built on.
    fn regularising_estimate(&self) -> Vector<T, N>;
    /// Lanes whose step may be taken; the covariance forms also require definiteness and
    /// record its loss.
    fn judge(&mut self, _input_ok: T::Mask, finite: T::Mask, _definite: T::Mask) -> T::Mask {
        finite
    }
    /// Takes `next`'s numeric state in `accepted` lanes (the counters stay in `Core`).
    fn keep(&mut self, accepted: T::Mask, next: &Self);
}

/// The update every form runs: [`RecursiveLeastSquares::update_with_forgetting`].
pub(crate) fn update_form<T: Lane, F: Form<T, N>, const N: usize>(
    form: &mut F,
    h: &Vector<T, N>,
    z: T,
    weight: T,
    forget: T::Mask,
) -> T::Mask {
    let step = form.core().prepare(h, z, weight, forget);
    let x = form.regularising_estimate();
    let (next, finite, definite) = form.core().run(form, &x, &step, F::form_step);
    let numeric_ok = form.judge(step.input_ok, finite, definite);
    let accepted = form.core_mut().finish(&step, numeric_ok);
    form.keep(accepted, &next);
    accepted
}

/// The trait items every form implements the same way (through [`Form`]).
macro_rules! shared_form_items {
    () => {
        fn update_with_forgetting(
            &mut self,
            h: &Vector<T, N>,
            z: T,
            weight: T,
            forget: T::Mask,
        ) -> T::Mask {
            super::update_form(self, h, z, weight, forget)
        }

        fn config(&self) -> RlsConfig {
            self.core.config()
        }
    };
}
use shared_form_items;

/// The [`Form`] items every form implements the same way (its `core` field, its inherent
/// `step`).
macro_rules! form_basics {
    () => {
        fn core(&self) -> &Core<T> {
            &self.core
        }

        fn core_mut(&mut self) -> &mut Core<T> {
            &mut self.core
        }

        fn form_step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask) {
            self.step(h, z, lambda)
        }
    };
}
use form_basics;

/// State and logic every form shares: configuration in lanes, counters, windup recursion.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Core<T: Lane> {
    config: RlsConfig,
    lambda: T,
    /// `√λ` as an unevaluated sum `hi + lo` (from f64), for the information form's scaling.
    sqrt_lambda: (T, T),
    bounded: bool,
    p_max: T,
    inv_p_min: T,
    /// Running `trace(P⁻¹)` (exact recursion, see [`CovarianceBounds`]).
    info_trace: T,
    pub(crate) lost: T::Mask,
    accepted: T::Counts,
    rejected_input: T::Counts,
    rejected_numerical: T::Counts,
    clipped: T::Counts,
}

/// One prepared measurement: sanitised, whitened, with the step's effective forgetting factor.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Step<T: Lane, const N: usize> {
    /// Lanes whose sample is valid.
    pub(crate) input_ok: T::Mask,
    /// Forgetting factor of this step (`1` where not forgetting).
    pub(crate) lambda: T,
    /// Regularisation `(1 − λ)/p_max` added to the information (0 without bounds).
    alpha: T,
    /// `√w_eff · h` (zero in rejected lanes).
    pub(crate) h: Vector<T, N>,
    /// `√w_eff · z` (zero in rejected lanes).
    pub(crate) z: T,
    clipped: T::Mask,
}

/// The checked prior: its mirrored covariance and lower Cholesky factor.
pub(crate) struct Prior<T: Lane, const N: usize> {
    pub(crate) p: Mat<T, N, N>,
    pub(crate) l: Mat<T, N, N>,
}

impl<T: Lane> Core<T> {
    /// Validates the configuration and the prior; returns the shared core and the prior's
    /// mirrored covariance and Cholesky factor.
    pub(crate) fn new<const N: usize>(
        x0: &Vector<T, N>,
        p0: &Mat<T, N, N>,
        config: RlsConfig,
    ) -> Result<(Self, Prior<T, N>), RlsError> {
        config.validate()?;
        if !x0.is_finite().all() {
            return Err(RlsError::NonFinitePrior);
        }
        let p = Mat::from_fn(|i, j| if i >= j { p0.m[i][j] } else { p0.m[j][i] });
        let (l, ok) = p.cholesky();
        if !ok.all() {
            return Err(RlsError::PriorNotPositiveDefinite);
        }
        // trace(P₀⁻¹) = ‖L⁻¹‖²_F.
        let linv = l.solve_lower(&Mat::<T, N, N>::identity());
        let mut info_trace = T::zero();
        for row in &linv.m {
            for &v in row {
                info_trace = v.mul_add(v, info_trace);
            }
        }
        let (bounded, p_max, inv_p_min) = match config.bounds {
            Some(b) => (true, T::from_f64(b.p_max), T::one() / T::from_f64(b.p_min)),
            None => (
                false,
                T::from_f64(f64::INFINITY),
                T::from_f64(f64::INFINITY),
            ),
        };
        if !(info_trace.is_finite() & info_trace.simd_gt(T::zero())).all() {
            return Err(RlsError::PriorNotPositiveDefinite);
        }
        if let Some(b) = config.bounds {
            // `validate` already rejected NaN bounds.
            if N as f64 * b.p_min >= b.p_max {
                return Err(RlsError::InvalidBounds);
            }
            // eig(P₀) ≤ p_max ⇔ p_max·I − P₀ ⪰ 0; a relative slack of n·u admits P₀ = p_max·I.
            let slack = T::from_f64(1.0 + N as f64 * T::EPSILON);
            let room = Mat::<T, N, N>::identity().scale(p_max * slack) - p;
            let below_max = if b.p_max.is_finite() {
                room.cholesky().1
            } else {
                T::Mask::splat(true)
            };
            if !(below_max & info_trace.simd_le(inv_p_min)).all() {
                return Err(RlsError::PriorOutsideBounds);
            }
        }
        let core = Self {
            config,
            lambda: T::from_f64(config.lambda),
            sqrt_lambda: {
                let root = config.lambda.sqrt();
                let hi = T::from_f64(root);
                let hi64: f64 = hi.extract(0).into();
                (hi, T::from_f64(root - hi64))
            },
            bounded,
            p_max,
            inv_p_min,
            info_trace,
            lost: T::Mask::splat(false),
            accepted: T::Counts::default(),
            rejected_input: T::Counts::default(),
            rejected_numerical: T::Counts::default(),
            clipped: T::Counts::default(),
        };
        Ok((core, Prior { p, l }))
    }

    pub(crate) fn config(&self) -> RlsConfig {
        self.config
    }

    /// `√λ` as `(hi, lo)` in lanes where `lambda` is the configured factor, `(1, 0)` where it
    /// is 1 (not forgetting this step).
    pub(crate) fn sqrt_lambda(&self, lambda: T) -> (T, T) {
        let forgetting = lambda.simd_ne(T::one());
        (
            T::select(forgetting, self.sqrt_lambda.0, T::one()),
            T::select(forgetting, self.sqrt_lambda.1, T::zero()),
        )
    }

    pub(crate) fn bounded(&self) -> bool {
        self.bounded
    }

    pub(crate) fn p_max(&self) -> T {
        self.p_max
    }

    /// Validates and whitens one sample and fixes the step's forgetting factor, regularisation
    /// and weight.
    pub(crate) fn prepare<const N: usize>(
        &self,
        h: &Vector<T, N>,
        z: T,
        weight: T,
        forget: T::Mask,
    ) -> Step<T, N> {
        let zero = T::zero();
        let one = T::one();
        // NaN must land on the reject side: every test is a positive, ordered comparison.
        // A regressor whose squared norm overflows is rejected as input too: no form could
        // use it, and clipping its weight to zero would silently accept it.
        let input_ok = h.is_finite()
            & h.dot(h).is_finite()
            & z.is_finite()
            & weight.is_finite()
            & weight.simd_gt(zero);
        let h0 = Mat::select(input_ok, h, &Mat::zeros());
        let z0 = T::select(input_ok, z, zero);
        let w0 = T::select(input_ok, weight, one);
        let lambda = T::select(forget, self.lambda, one);
        let mut w = w0;
        let mut clipped = T::Mask::splat(false);
        let mut alpha = zero;
        if self.bounded {
            // Regularised forgetting: α = (1 − λ)/p_max (0 with p_max = ∞ or λ = 1).
            alpha = (one - lambda) / self.p_max;
            let n_alpha = T::from_f64(N as f64) * alpha;
            let h2 = h0.dot(&h0);
            let room = (self.inv_p_min - lambda.mul_add(self.info_trace, n_alpha)).max(zero);
            let cap = T::select(h2.simd_gt(zero), room / h2, T::from_f64(f64::INFINITY));
            w = w0.min(cap);
            clipped = w.simd_lt(w0);
        }
        let sw = w.sqrt();
        Step {
            input_ok,
            lambda,
            alpha,
            h: h0.scale(sw),
            z: z0 * sw,
            clipped,
        }
    }

    /// Runs one step of a form: with bounds, first the forgetting and the `n` regularising
    /// pseudo-measurements `√α x_i` on `√α e_i` (zero innovation: they add `α I` to the
    /// information and leave the estimate), then the measurement. `step(state, h, z, λ)`
    /// is the form's own forgetting-plus-measurement update on whitened data, returning the
    /// new state, a finite mask and a definiteness mask.
    pub(crate) fn run<S: Copy, const N: usize>(
        &self,
        start: &S,
        x: &Vector<T, N>,
        step: &Step<T, N>,
        form_step: impl Fn(&S, &Vector<T, N>, T, T) -> (S, T::Mask, T::Mask),
    ) -> (S, T::Mask, T::Mask) {
        if !self.bounded {
            return form_step(start, &step.h, step.z, step.lambda);
        }
        let sa = step.alpha.sqrt();
        let mut state = *start;
        let mut finite = T::Mask::splat(true);
        let mut definite = T::Mask::splat(true);
        let mut lambda = step.lambda;
        for i in 0..N {
            let e = Vector::from_fn(|j, _| if j == i { sa } else { T::zero() });
            let (next, f, d) = form_step(&state, &e, sa * x[i], lambda);
            state = next;
            finite &= f;
            definite &= d;
            lambda = T::one();
        }
        let (next, f, d) = form_step(&state, &step.h, step.z, lambda);
        (next, finite & f, definite & d)
    }

    /// Counts the outcome of a step and advances the windup recursion in accepted lanes.
    /// Returns the accepted lanes.
    pub(crate) fn finish<const N: usize>(
        &mut self,
        step: &Step<T, N>,
        numeric_ok: T::Mask,
    ) -> T::Mask {
        let accepted = step.input_ok & numeric_ok;
        T::count(&mut self.accepted, accepted);
        T::count(&mut self.rejected_input, !step.input_ok);
        T::count(&mut self.rejected_numerical, step.input_ok & !numeric_ok);
        T::count(&mut self.clipped, accepted & step.clipped);
        if self.bounded {
            let n_alpha = T::from_f64(N as f64) * step.alpha;
            let next = step.lambda.mul_add(self.info_trace, n_alpha) + step.h.dot(&step.h);
            self.info_trace = T::select(accepted, next, self.info_trace);
        }
        accepted
    }

    /// Counts an operation that is not a measurement (e.g. a time update).
    pub(crate) fn count(&mut self, input_ok: T::Mask, numeric_ok: T::Mask) -> T::Mask {
        T::count(&mut self.rejected_input, !input_ok);
        T::count(&mut self.rejected_numerical, input_ok & !numeric_ok);
        input_ok & numeric_ok
    }

    /// Health record around the form-specific pivots and trace.
    pub(crate) fn health(&self, min_pivot: T, max_pivot: T, trace: T) -> Health<T> {
        Health {
            min_pivot,
            max_pivot,
            trace,
            information_trace: self.info_trace,
            lost_definiteness: self.lost,
            accepted: self.accepted,
            rejected_input: self.rejected_input,
            rejected_numerical: self.rejected_numerical,
            clipped: self.clipped,
        }
    }
}

/// Smallest and largest of `f(0) … f(n−1)`, lane by lane (NaN-propagating towards the
/// reported minimum so a broken pivot is visible).
pub(crate) fn min_max<T: Lane>(n: usize, f: impl Fn(usize) -> T) -> (T, T) {
    let mut lo = f(0);
    let mut hi = lo;
    for j in 1..n {
        let v = f(j);
        // Once NaN, stay NaN; a NaN `v` also wins (neither comparison holds for it).
        lo = T::select(lo.is_nan() | v.simd_ge(lo), lo, v);
        hi = hi.max(v);
    }
    (lo, hi)
}

/// `‖A‖²_F`, the trace of `A Aᵀ`.
/// Per lane: a covariance with this trace can be formed from its factor without overflow.
/// `P` is positive semidefinite, so `|P_ij| ≤ max P_ii ≤ trace(P)`, and the partial sums of
/// `P_ij = Σ_k F_ik F_jk` are bounded by `√(P_ii P_jj)` (Cauchy–Schwarz): `n·trace` finite is
/// enough. A factor can stay finite while `P` overflows (found by fuzzing: a prior near
/// `√MAX` grown by forgetting), so the factored forms refuse such updates.
pub(crate) fn formable<T: Lane, const N: usize>(trace: T) -> T::Mask {
    (trace * T::from_f64(N as f64)).is_finite()
}

pub(crate) fn frobenius2<T: Lane, const N: usize>(a: &Mat<T, N, N>) -> T {
    let mut s = T::zero();
    for row in &a.m {
        for &v in row {
            s = v.mul_add(v, s);
        }
    }
    s
}

/// `A Aᵀ`, exactly symmetric (both triangles run the same products in the same order).
pub(crate) fn outer_self<T: Lane, const N: usize>(a: &Mat<T, N, N>) -> Mat<T, N, N> {
    Mat::from_fn(|i, j| {
        let mut s = T::zero();
        for k in 0..N {
            // Multiply in a fixed (i, j)-independent order so that (i, j) and (j, i) agree.
            let (p, q) = if i <= j {
                (a.m[i][k], a.m[j][k])
            } else {
                (a.m[j][k], a.m[i][k])
            };
            s = p.mul_add(q, s);
        }
        s
    })
}

/// Per lane: `P` is *numerically* definite: it admits a Cholesky factorisation whose every
/// pivot `l_jj²` exceeds `n·u·p_jj` (`u` the unit roundoff). A smaller pivot is below the
/// rounding noise of the factorisation itself, so its sign proves nothing; in the
/// Dyer–McReynolds example the f32 factorisation of an indefinite `P` succeeds with such a
/// pivot. O(n³/6), against O(n²) for the update: the price of detecting, rather than
/// propagating, a lost definiteness.
pub(crate) fn is_definite<T: Lane, const N: usize>(p: &Mat<T, N, N>) -> T::Mask {
    let (l, mut ok) = p.cholesky();
    let tol = T::from_f64(N as f64 * T::EPSILON * 0.5);
    for j in 0..N {
        ok &= (l.m[j][j] * l.m[j][j]).simd_gt(tol * p.m[j][j]);
    }
    ok
}
