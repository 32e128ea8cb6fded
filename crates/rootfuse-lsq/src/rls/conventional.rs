//! The conventional covariance form, symmetrised, with detection of lost definiteness.
//!
//! # Recursion (one scalar measurement, whitened: `h ← √w·h`, `z ← √w·z`)
//! ```text
//! P̃ = P / λ
//! u = P̃ h,   α = 1 + hᵀ u,   k = u / α
//! x ← x + k (z − hᵀ x)
//! P ← P̃ − (k uᵀ + u kᵀ) / 2
//! ```
//! The symmetric average of the two rank-one terms keeps `P` exactly symmetric; it does not
//! keep it definite: the subtraction cancels catastrophically when a measurement is much more
//! precise than the prior (Bierman 1977, ch. II; Verhaegen & Van Dooren 1986), and the
//! rounded `P` can become indefinite (the Dyer–McReynolds example).
//!
//! # Detection
//! Before applying a step the form checks, per lane, `hᵀ P̃ h ≥ 0` (a direct witness of
//! indefiniteness of the current `P`) and that the new `P` admits a Cholesky factorisation in
//! its own precision whose every pivot `l_jj²` exceeds `n·u·p_jj` (a smaller pivot is rounding
//! noise and its sign proves nothing). That costs O(n³/6) per update, more than the O(n²)
//! update itself, and is what it takes to *detect* lost definiteness: cheaper necessary
//! conditions (positive diagonal, 2×2 minors) and a plain Cholesky both miss the
//! Dyer–McReynolds failure in f32. The test is conservative: a `P` with a condition number
//! beyond about `1/(n·u)` fails it even if it is mathematically definite, which is where the
//! covariance form stops being trustworthy anyway. With covariance bounds the check runs
//! for each of the `n + 1` internal steps (regularisation rows, then the measurement). A lane failing either check keeps its previous state, is counted in
//! `rejected_numerical` and is flagged in [`Health::lost_definiteness`] (sticky). For scalar
//! types, [`try_update`](Conventional::try_update) turns the outcome into a [`Result`].
//!
//! With covariance bounds and a forgetting factor near the unit roundoff the upper bound holds
//! only up to the per-update rounding stated on [`CovarianceBounds`](super::CovarianceBounds)
//! (the same for the [Joseph](super::joseph) form).
//!
//! [`Health::lost_definiteness`]: super::Health::lost_definiteness

use super::{Core, Form, Health, RecursiveLeastSquares, RlsConfig, RlsError, is_definite, min_max};
use rootfuse_lane::{Lane, Mask, Mat, Vector};

/// Conventional (symmetrised) covariance-form RLS. See the [module documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct Conventional<T: Lane, const N: usize> {
    x: Vector<T, N>,
    p: Mat<T, N, N>,
    core: Core<T>,
    /// Last step's (valid input, passed the definiteness checks), for `try_update`.
    last: (T::Mask, T::Mask),
}

impl<T: Lane, const N: usize> RecursiveLeastSquares<T, N> for Conventional<T, N> {
    const NAME: &'static str = "conventional";

    super::shared_form_items!();

    fn new(x0: &Vector<T, N>, p0: &Mat<T, N, N>, config: RlsConfig) -> Result<Self, RlsError> {
        let (core, prior) = Core::new(x0, p0, config)?;
        Ok(Self {
            x: *x0,
            p: prior.p,
            core,
            last: (T::Mask::splat(true), T::Mask::splat(true)),
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

impl<T: Lane, const N: usize> Conventional<T, N> {
    /// Forgetting plus one whitened measurement; (new state, finite, definite).
    fn step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask) {
        let (x, p, hu) = covariance_step(&self.x, &self.p, h, z, lambda);
        let definite = hu.simd_ge(T::zero()) & is_definite(&p);
        let finite = x.is_finite() & p.is_finite() & hu.is_finite();
        (Self { x, p, ..*self }, finite, definite)
    }
}

impl<T: Lane<Mask = bool>, const N: usize> Conventional<T, N> {
    /// Scalar convenience: [`update`](RecursiveLeastSquares::update) with the outcome as a
    /// `Result` (the state is unchanged on error).
    ///
    /// # Errors
    /// [`RlsError::RejectedSample`] for invalid data, [`RlsError::LostDefiniteness`] when this
    /// step detected an indefinite covariance, [`RlsError::NumericalFailure`] on overflow.
    pub fn try_update(&mut self, h: &Vector<T, N>, z: T, weight: T) -> Result<(), RlsError> {
        if self.update(h, z, weight) {
            return Ok(());
        }
        let (input_ok, definite) = self.last;
        if !input_ok {
            Err(RlsError::RejectedSample)
        } else if !definite {
            Err(RlsError::LostDefiniteness)
        } else {
            Err(RlsError::NumericalFailure)
        }
    }
}

/// The conventional step on whitened data: returns the new `x`, the new symmetrised `P` and
/// `hᵀ P̃ h` (shared with the Joseph form for its estimate and gain).
pub(crate) fn covariance_step<T: Lane, const N: usize>(
    x: &Vector<T, N>,
    p: &Mat<T, N, N>,
    h: &Vector<T, N>,
    z: T,
    lambda: T,
) -> (Vector<T, N>, Mat<T, N, N>, T) {
    let pt = p.scale(T::one() / lambda);
    let u = pt * *h;
    let hu = h.dot(&u);
    let alpha = hu + T::one();
    let k = u.scale(T::one() / alpha);
    let e = z - h.dot(x);
    let x_new = Mat::from_fn(|i, _| k.m[i][0].mul_add(e, x.m[i][0]));
    let half = T::from_f64(0.5);
    // (k_i u_j + k_j u_i) is the same sum in both triangles, so P stays exactly symmetric.
    let p_new = Mat::from_fn(|i, j| {
        let t = k.m[i][0] * u.m[j][0] + k.m[j][0] * u.m[i][0];
        (-half).mul_add(t, pt.m[i][j])
    });
    (x_new, p_new, hu)
}

impl<T: Lane, const N: usize> Form<T, N> for Conventional<T, N> {
    super::form_basics!();

    fn regularising_estimate(&self) -> Vector<T, N> {
        self.x
    }
    fn judge(&mut self, input_ok: T::Mask, finite: T::Mask, definite: T::Mask) -> T::Mask {
        self.core.lost |= input_ok & finite & !definite;
        self.last = (input_ok, definite);
        definite & finite
    }

    fn keep(&mut self, accepted: T::Mask, next: &Self) {
        self.x = Mat::select(accepted, &next.x, &self.x);
        self.p = Mat::select(accepted, &next.p, &self.p);
    }
}
