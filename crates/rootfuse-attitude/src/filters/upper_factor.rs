//! Kernels on an upper-triangular covariance factor `P = U·Uᵀ` that keep it upper triangular:
//! Carlson's scalar measurement update and the addition of diagonal process noise.
//!
//! The flagship ([`SqrtEskf`](super::SqrtEskf)) keeps its factor in this form because its
//! transition `F = [[I, −R·dt], [0, I]]` is block upper triangular: `F·U` is again upper
//! triangular (only the off-diagonal block changes), so the time update needs no general
//! re-triangularisation — only the diagonal noise has to be folded in. Potter's update
//! (`U ← U − γ/α·(U·f)·fᵀ`) would fill the factor; Carlson's (`U ← U·W` with `W` upper
//! triangular) does not. Both are products with the old factor, so `P` stays symmetric
//! positive semidefinite by construction in f32 as in f64.

// Row/column indices follow the formulas; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use rootfuse_lane::{Lane, Mat};

/// The dimension of the flagship's error state: the kernels are written for it so that every
/// loop bound is a constant and the loops unroll completely (a generic `N` left the index
/// arithmetic of the triangular loops in the hot path: a third of the instructions).
pub(crate) const N: usize = 6;

/// Carlson's square-root scalar update (Carlson 1973, "Fast triangular formulation of the
/// square root filter", AIAA J. 11; Bierman 1977, ch. V) of the upper-triangular `u`
/// (`P = U·Uᵀ`) with measurement row `h` and noise variance `r > 0`; `h_i = 0` for
/// `i < FIRST`.
///
/// With `f = Uᵀh` and `α_j = r + Σ_{k≤j} f_k²`, `I − f·fᵀ/α_n = W·Wᵀ` with `W` upper triangular,
/// `W_jj = √(α_{j−1}/α_j)`, `W_ij = −f_i·f_j/√(α_{j−1}·α_j)` (`i < j`), and the updated factor
/// is `U·W`, computed column by column. Because `U` is upper triangular, `f_j = 0` for
/// `j < FIRST`, so those columns of `W` are the identity and are skipped (a measurement of
/// the bias alone costs half a full update). Returns (updated factor, `U·f` (the
/// unnormalised gain: `K = U·f/α_n`), `α_n` (the innovation variance)). Lanes with `r ≤ 0`
/// come out non-finite. The filter runs the two halves itself ([`carlson_gains`], then
/// [`carlson_apply`] in place where the gate accepts); this composition is what the tests
/// check against the covariance update `P − P·hᵀ·h·P/α`.
#[cfg(test)]
pub(crate) fn carlson_update<T: Lane, const FIRST: usize>(
    u: &Mat<T, N, N>,
    h: &[T; N],
    r: T,
) -> (Mat<T, N, N>, [T; N], T) {
    let gains = carlson_gains::<T, FIRST>(u, h, r);
    let mut out = *u;
    let uf = carlson_apply::<T, FIRST>(
        &mut out,
        &gains,
        <T::Mask as rootfuse_lane::Mask>::splat(true),
    );
    (out, uf, gains.innovation_variance())
}

/// The first half of [`carlson_update`]: `f = Uᵀh` and the running `α_j`, which is all the
/// χ² gate needs, before anything is written.
#[derive(Clone, Copy)]
pub(crate) struct CarlsonGains<T: Lane> {
    /// `f_j` for `j ≥ FIRST` (zero below).
    f: [T; N],
    /// `α_j = r + Σ_{k≤j} f_k²` (`r` below `FIRST`).
    alpha: [T; N],
    r: T,
}

impl<T: Lane> CarlsonGains<T> {
    /// `α_n = h·P·hᵀ + r`, the innovation variance.
    #[inline]
    pub(crate) fn innovation_variance(&self) -> T {
        self.alpha[N - 1]
    }

    /// The same `f = Uᵀh` with measurement variance `r`: `α_j = r + Σ_{k≤j} f_k²`, summed as
    /// [`carlson_gains`] sums (so the `r` it was made with gives the same bits).
    #[inline(always)]
    pub(crate) fn with_noise<const FIRST: usize>(&self, r: T) -> Self {
        let mut g = Self {
            f: self.f,
            alpha: [r; N],
            r,
        };
        let mut alpha = r;
        for j in FIRST..N {
            alpha += self.f[j] * self.f[j];
            g.alpha[j] = alpha;
        }
        g
    }
}

/// `f = Uᵀh` and `α` of [`carlson_update`]. The sums skip the entries `h_i = 0`, `i < FIRST`
/// (adding their `±0` products to a `+0` sum changes no bit).
#[inline(always)]
pub(crate) fn carlson_gains<T: Lane, const FIRST: usize>(
    u: &Mat<T, N, N>,
    h: &[T; N],
    r: T,
) -> CarlsonGains<T> {
    let mut g = CarlsonGains {
        f: [T::zero(); N],
        alpha: [r; N],
        r,
    };
    let mut alpha = r;
    for j in FIRST..N {
        let mut f = T::zero();
        for i in FIRST..=j {
            f += u.m[i][j] * h[i];
        }
        alpha += f * f;
        g.f[j] = f;
        g.alpha[j] = alpha;
    }
    g
}

/// The second half of [`carlson_update`]: `U ← U·W` in place, in the lanes `accept` (the
/// others keep `U` bit for bit). Returns `U·f` of the factor before the update.
#[inline(always)]
pub(crate) fn carlson_apply<T: Lane, const FIRST: usize>(
    u: &mut Mat<T, N, N>,
    g: &CarlsonGains<T>,
    accept: T::Mask,
) -> [T; N] {
    let root = g.r.sqrt();
    let mut c = Carlson {
        w: [T::zero(); N],
        root,
        inv_root: T::one() / root,
        accept,
    };
    // `FIRST` is a constant: the tests fold away.
    if FIRST == 0 {
        c.column::<0>(u, g);
    }
    if FIRST <= 1 {
        c.column::<1>(u, g);
    }
    if FIRST <= 2 {
        c.column::<2>(u, g);
    }
    if FIRST <= 3 {
        c.column::<3>(u, g);
    }
    if FIRST <= 4 {
        c.column::<4>(u, g);
    }
    c.column::<5>(u, g);
    c.w
}

/// The running quantities of [`carlson_apply`] after the columns done so far.
struct Carlson<T: Lane> {
    /// `Σ_{k<j} U_{·k}·f_k`: the gain accumulated over the columns done so far.
    w: [T; N],
    /// `√α_{j−1}` and its inverse.
    root: T,
    inv_root: T,
    accept: T::Mask,
}

impl<T: Lane> Carlson<T> {
    /// Column `J` of `U·W` (a constant, so the triangular loops unroll).
    #[inline(always)]
    fn column<const J: usize>(&mut self, u: &mut Mat<T, N, N>, g: &CarlsonGains<T>) {
        let f = g.f[J];
        let root = g.alpha[J].sqrt();
        let inv_root = T::one() / root;
        let beta = self.root * inv_root;
        let gamma = f * inv_root * self.inv_root;
        for i in 0..=J {
            let uij = u.m[i][J];
            u.m[i][J] = T::select(self.accept, beta * uij - gamma * self.w[i], uij);
            self.w[i] += uij * f;
        }
        self.root = root;
        self.inv_root = inv_root;
    }
}

/// `U'` upper triangular with a non-negative diagonal and `U'·U'ᵀ = U·Uᵀ + diag(q, 0)²`, for
/// an upper-triangular `u` and noise on the first `M` states: the square-root time update's
/// noise step, by Householder reflections from the right over `[U, diag(q)]` processed from
/// row `M − 1` up (rows `≥ M` have no noise: their reflection is the identity). Row `i`'s
/// reflection mixes column `i` of `U` only with the noise columns `i ≤ k < M` (the others
/// are still zero in rows `≤ i`), and touches rows `0..=i` only, so it costs a fraction of a
/// general `N×(N+M)` re-triangularisation, and noise on the first three states alone a
/// fraction of noise on all six. A zero row stays zero.
#[inline]
pub(crate) fn add_diagonal_noise<T: Lane, const M: usize>(u: &mut Mat<T, N, N>, q: &[T; M]) {
    // noise[p][k]: row p of noise column k (initially diag(q)).
    let mut noise = [[T::zero(); M]; N];
    for k in 0..M {
        noise[k][k] = q[k];
    }
    // `M` is a constant: the tests fold away.
    if M > 5 {
        fold_row::<T, 5, M>(u, &mut noise);
    }
    if M > 4 {
        fold_row::<T, 4, M>(u, &mut noise);
    }
    if M > 3 {
        fold_row::<T, 3, M>(u, &mut noise);
    }
    if M > 2 {
        fold_row::<T, 2, M>(u, &mut noise);
    }
    if M > 1 {
        fold_row::<T, 1, M>(u, &mut noise);
    }
    fold_row::<T, 0, M>(u, &mut noise);
}

/// One reflection of [`add_diagonal_noise`]: row `I` (a constant, so the loops unroll).
#[inline(always)]
fn fold_row<T: Lane, const I: usize, const M: usize>(
    u: &mut Mat<T, N, N>,
    noise: &mut [[T; M]; N],
) {
    let zero = T::zero();
    let x0 = u.m[I][I];
    let mut tail = zero;
    for k in I..M {
        tail += noise[I][k] * noise[I][k];
    }
    let norm = (x0 * x0 + tail).sqrt();
    // The reflection maps the row onto −sign(x0)·‖row‖ at the pivot (no cancellation in
    // v0); the column sign is flipped afterwards.
    let alpha = T::select(x0.simd_ge(zero), -norm, norm);
    let v0 = x0 - alpha;
    let vtv = v0 * v0 + tail;
    let ok = vtv.simd_gt(zero) & vtv.is_finite();
    let beta = T::select(ok, T::from_f64(2.0) / T::select(ok, vtv, T::one()), zero);
    let pivot = T::select(ok, alpha, x0);
    let flip = pivot.simd_lt(zero);
    for p in 0..I {
        let mut d = u.m[p][I] * v0;
        for k in I..M {
            d += noise[p][k] * noise[I][k];
        }
        let d = d * beta;
        let upi = u.m[p][I] - d * v0;
        // Column sign flipped with the pivot's, so the diagonal is non-negative
        // (U·Uᵀ does not change).
        u.m[p][I] = T::select(flip, -upi, upi);
        for k in I..M {
            noise[p][k] -= d * noise[I][k];
        }
    }
    // Row I itself becomes (pivot, 0, …): set exactly.
    u.m[I][I] = T::select(flip, -pivot, pivot);
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn upper(v: &[f64]) -> Mat<f64, N, N> {
        let mut u = Mat::zeros();
        let mut it = v.iter();
        for i in 0..N {
            for j in i..N {
                u.m[i][j] = *it.next().unwrap();
            }
        }
        u
    }

    /// [`add_diagonal_noise`] of `q` on the upper factor made from `v` gives
    /// `U·Uᵀ + diag(q, 0…)²`, upper triangular, with a non-negative diagonal in the rows with
    /// noise (the others are not touched).
    fn noise_check<const M: usize>(
        v: &[f64],
        q: &[f64; M],
    ) -> Result<(), proptest::test_runner::TestCaseError> {
        let mut u = upper(v);
        let mut expected = u * u.transpose();
        for k in 0..M {
            expected.m[k][k] += q[k] * q[k];
        }
        add_diagonal_noise(&mut u, q);
        prop_assert!(
            max_diff(&(u * u.transpose()), &expected) <= 1e-9 * (1.0 + expected.max_abs())
        );
        for i in 0..N {
            prop_assert!(i >= M || u.m[i][i] >= 0.0);
            for j in 0..i {
                prop_assert_eq!(u.m[i][j], 0.0);
            }
        }
        Ok(())
    }

    fn max_diff(a: &Mat<f64, N, N>, b: &Mat<f64, N, N>) -> f64 {
        let mut m: f64 = 0.0;
        for i in 0..N {
            for j in 0..N {
                m = m.max((a.m[i][j] - b.m[i][j]).abs());
            }
        }
        m
    }

    proptest! {
        /// Carlson's update gives the Kalman covariance `P − P·h·hᵀ·P/α` and gain, and an
        /// upper-triangular factor.
        #[test]
        fn carlson_matches_the_covariance_form(
            v in prop::collection::vec(-2.0..2.0f64, 21),
            h in prop::array::uniform6(-2.0..2.0f64),
            r in 0.01..5.0f64,
        ) {
            let u = upper(&v);
            let p = u * u.transpose();
            let (u2, uf, alpha) = carlson_update::<f64, 0>(&u, &h, r);
            // The same measurement with its leading zeros skipped.
            let mut h2 = h;
            h2[0] = 0.0;
            h2[1] = 0.0;
            let (u3, uf3, alpha3) = carlson_update::<f64, 2>(&u, &h2, r);
            let (u4, uf4, alpha4) = carlson_update::<f64, 0>(&u, &h2, r);
            prop_assert!((alpha3 - alpha4).abs() <= 1e-12 * alpha4);
            prop_assert!(max_diff(&u3, &u4) <= 1e-12 * (1.0 + u.max_abs()));
            for i in 0..N {
                prop_assert!((uf3[i] - uf4[i]).abs() <= 1e-12 * (1.0 + p.max_abs()));
            }
            let ph: [f64; N] = core::array::from_fn(|i| (0..N).map(|j| p.m[i][j] * h[j]).sum());
            let a: f64 = r + (0..N).map(|i| h[i] * ph[i]).sum::<f64>();
            prop_assert!((alpha - a).abs() <= 1e-9 * a);
            let expected = Mat::<f64, N, N>::from_fn(|i, j| p.m[i][j] - ph[i] * ph[j] / a);
            prop_assert!(max_diff(&(u2 * u2.transpose()), &expected) <= 1e-9 * (1.0 + p.max_abs()));
            for i in 0..N {
                prop_assert!((uf[i] - ph[i]).abs() <= 1e-9 * (1.0 + p.max_abs()));
                for j in 0..i {
                    prop_assert_eq!(u2.m[i][j], 0.0);
                }
            }
        }

        /// Folding diagonal noise in gives `U·Uᵀ + diag(q)²`, upper triangular with a
        /// non-negative diagonal.
        #[test]
        fn noise_is_added_exactly(
            v in prop::collection::vec(-2.0..2.0f64, 21),
            q in prop::array::uniform6(0.0..1.0f64),
        ) {
            noise_check(&v, &q)?;
        }

        /// Noise on the first three states only: `U·Uᵀ + diag(q, 0, 0, 0)²`.
        #[test]
        fn noise_on_the_leading_states_is_added_exactly(
            v in prop::collection::vec(-2.0..2.0f64, 21),
            q in prop::array::uniform3(0.0..1.0f64),
        ) {
            noise_check(&v, &q)?;
        }
    }
}
