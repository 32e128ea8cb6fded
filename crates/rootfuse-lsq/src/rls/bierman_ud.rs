//! Bierman's U-D form, `P = U D Uᵀ` (`U` unit upper triangular, `D` diagonal), with
//! Thornton's time update for additive process noise.
//!
//! # Measurement update (Bierman 1977, ch. V; whitened data, unit noise variance)
//! Forgetting first: `D ← D/λ`. Then, with `f = Uᵀ h`, `v_j = d_j f_j`, `α₀ = 1`, for
//! `j = 1 … n`:
//! ```text
//! α_j = α_{j−1} + v_j f_j
//! d_j ← d_j α_{j−1} / α_j
//! for i < j:   U_ij ← U_ij − (f_j / α_{j−1}) b_i,   b_i ← b_i + U_ij(old) v_j
//! b_j = v_j
//! ```
//! and the gain is `k = b / α_n`, `x ← x + k (z − hᵀ x)`. Every `d_j` is a ratio of
//! positive numbers times a positive number: `D` stays positive and `P` definite by
//! construction, with no square roots.
//!
//! # Time update (Thornton 1976, modified weighted Gram–Schmidt)
//! [`time_update`](BiermanUd::time_update) adds `Q = diag(q)` (random-walk parameters,
//! `Φ = I`): `U D Uᵀ + Q = W D̄ Wᵀ` with `W = [U  I]`, `D̄ = diag(D, q)`; the rows of `W`
//! are orthogonalised from the last to the first in the `D̄`-weighted inner product, giving
//! the new `U` and `D` without forming `P` (Bierman 1977, ch. VI; Grewal & Andrews,
//! *Kalman Filtering*, §6.5).

use super::{Core, Form, Health, RecursiveLeastSquares, RlsConfig, RlsError, formable, min_max};
use rootfuse_lane::{Lane, Mask, Mat, Vector};

/// Bierman U-D RLS with Thornton's time update. See the [module documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct BiermanUd<T: Lane, const N: usize> {
    x: Vector<T, N>,
    /// Unit upper triangular (ones on the diagonal, zeros below).
    u: Mat<T, N, N>,
    d: Vector<T, N>,
    core: Core<T>,
}

impl<T: Lane, const N: usize> BiermanUd<T, N> {
    /// The unit upper triangular factor `U`.
    pub fn u(&self) -> &Mat<T, N, N> {
        &self.u
    }
    /// The diagonal factor `D` (`d_j > 0`), units of `P`.
    pub fn d(&self) -> &Vector<T, N> {
        &self.d
    }

    /// `trace(P) = Σ_j d_j Σ_i U_ij²`.
    fn trace_p(&self) -> T {
        trace_ud(&self.u, &self.d)
    }

    /// Forgetting plus one whitened measurement (Bierman); (new state, finite, definite).
    fn step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask) {
        let mut u = self.u;
        let mut d = self.d.scale(T::one() / lambda);
        // f = Uᵀ h, v = D f.
        let f = Mat::<T, N, 1>::from_fn(|j, _| {
            let mut s = h[j];
            for i in 0..j {
                s = u.m[i][j].mul_add(h[i], s);
            }
            s
        });
        let mut b = Vector::<T, N>::zeros();
        let mut alpha = T::one();
        for j in 0..N {
            let vj = d[j] * f[j];
            let beta = alpha;
            alpha = vj.mul_add(f[j], alpha);
            let p = -f[j] / beta;
            d[j] = d[j] * beta / alpha;
            for i in 0..j {
                let t = u.m[i][j];
                u.m[i][j] = b[i].mul_add(p, t);
                b[i] = t.mul_add(vj, b[i]);
            }
            b[j] = vj;
        }
        let ke = (z - h.dot(&self.x)) / alpha;
        let x = Mat::from_fn(|i, _| b[i].mul_add(ke, self.x[i]));
        let mut finite = x.is_finite()
            & u.is_finite()
            & d.is_finite()
            & alpha.is_finite()
            & formable::<T, N>(trace_ud(&u, &d));
        for j in 0..N {
            finite &= d[j].simd_gt(T::zero());
        }
        (Self { x, u, d, ..*self }, finite, T::Mask::splat(true))
    }

    /// Adds process noise `Q = diag(q)` to `P` (Thornton's MWGS time update), for parameters
    /// that drift as a random walk (`q_j`: variance added per call, units of `P`).
    ///
    /// Lanes where some `q_j` is negative or not finite are left unchanged and counted as
    /// rejected input. With [`CovarianceBounds`](super::CovarianceBounds), `q` is scaled down
    /// so that `trace(P + Q) ≤ p_max`, a sufficient condition for `eig(P + Q) ≤ p_max` and a
    /// conservative one: once `trace(P) ≥ p_max` (possible, since the bound is on
    /// eigenvalues), no process noise is added at all. Returns the lanes where `Q` was added.
    pub fn time_update(&mut self, q: &Vector<T, N>) -> T::Mask {
        let zero = T::zero();
        let mut input_ok = q.is_finite();
        let mut qsum = zero;
        for j in 0..N {
            input_ok &= q[j].simd_ge(zero);
            qsum += q[j];
        }
        let mut q = Mat::select(input_ok, q, &Mat::zeros());
        if self.core.bounded() {
            let room = (self.core.p_max() - self.trace_p()).max(zero);
            // q_j·(room/qsum) would round the factor room/qsum, which underflows into the
            // subnormals for a huge q (found by fuzzing: q = f64::MAX, room ≈ 1e-7 made the
            // factor 5.6e-316, 1e-8 relative precision, and P ended 2e-12 above p_max);
            // (q_j/qsum)·room has ratios ≤ 1 and rounds twice. qsum > room ≥ 0 guarantees a
            // positive divisor in the lanes that use it.
            let shrink = qsum.simd_gt(room);
            q = Mat::from_fn(|j, _| T::select(shrink, (q[j] / qsum) * room, q[j]));
        }
        // Rows of W = [U | I]: `wu` holds the U part, `wq` the identity part.
        let mut wu = self.u;
        let mut wq = Mat::<T, N, N>::identity();
        let mut u = Mat::<T, N, N>::identity();
        let mut d = Vector::<T, N>::zeros();
        for j in (0..N).rev() {
            let mut dj = zero;
            for k in 0..N {
                dj = (wu.m[j][k] * wu.m[j][k]).mul_add(self.d[k], dj);
                dj = (wq.m[j][k] * wq.m[j][k]).mul_add(q[k], dj);
            }
            d[j] = dj;
            // dj ≥ d_j > 0 (the U part of row j keeps its unit diagonal), so no guard needed
            // for valid states; a non-finite result is caught below.
            let inv = T::one() / dj;
            for i in 0..j {
                let mut s = zero;
                for k in 0..N {
                    s = (wu.m[i][k] * self.d[k]).mul_add(wu.m[j][k], s);
                    s = (wq.m[i][k] * q[k]).mul_add(wq.m[j][k], s);
                }
                let uij = s * inv;
                u.m[i][j] = uij;
                for k in 0..N {
                    wu.m[i][k] = (-uij).mul_add(wu.m[j][k], wu.m[i][k]);
                    wq.m[i][k] = (-uij).mul_add(wq.m[j][k], wq.m[i][k]);
                }
            }
        }
        let mut numeric_ok = u.is_finite() & d.is_finite() & formable::<T, N>(trace_ud(&u, &d));
        for j in 0..N {
            numeric_ok &= d[j].simd_gt(zero);
        }
        let ok = self.core.count(input_ok, numeric_ok);
        self.u = Mat::select(ok, &u, &self.u);
        self.d = Mat::select(ok, &d, &self.d);
        ok
    }
}

impl<T: Lane, const N: usize> RecursiveLeastSquares<T, N> for BiermanUd<T, N> {
    const NAME: &'static str = "bierman-ud";

    super::shared_form_items!();

    fn new(x0: &Vector<T, N>, p0: &Mat<T, N, N>, config: RlsConfig) -> Result<Self, RlsError> {
        let (core, prior) = Core::new(x0, p0, config)?;
        let p = prior.p;
        // P = U D Uᵀ, from the last column to the first.
        let mut u = Mat::<T, N, N>::identity();
        let mut d = Vector::<T, N>::zeros();
        let mut ok = T::Mask::splat(true);
        for j in (0..N).rev() {
            let mut dj = p.m[j][j];
            for k in j + 1..N {
                dj = (-d[k] * u.m[j][k]).mul_add(u.m[j][k], dj);
            }
            ok &= dj.simd_gt(T::zero()) & dj.is_finite();
            d[j] = dj;
            for i in 0..j {
                let mut s = p.m[i][j];
                for k in j + 1..N {
                    s = (-d[k] * u.m[i][k]).mul_add(u.m[j][k], s);
                }
                u.m[i][j] = s / dj;
            }
        }
        if !(ok & u.is_finite()).all() {
            return Err(RlsError::PriorNotPositiveDefinite);
        }
        Ok(Self { x: *x0, u, d, core })
    }

    fn estimate(&self) -> Vector<T, N> {
        self.x
    }

    fn covariance(&self) -> Mat<T, N, N> {
        let ud = Mat::from_fn(|i, j| self.u.m[i][j] * self.d[j]);
        (ud * self.u.transpose()).symmetrize()
    }

    fn health(&self) -> Health<T> {
        let (lo, hi) = min_max(N, |j| self.d[j]);
        self.core.health(lo, hi, self.trace_p())
    }
}

/// `trace(U D Uᵀ) = Σ_j d_j Σ_{i≤j} u_ij²`.
fn trace_ud<T: Lane, const N: usize>(u: &Mat<T, N, N>, d: &Vector<T, N>) -> T {
    let mut t = T::zero();
    for j in 0..N {
        let mut c = T::zero();
        for i in 0..=j {
            c = u.m[i][j].mul_add(u.m[i][j], c);
        }
        t = d[j].mul_add(c, t);
    }
    t
}

impl<T: Lane, const N: usize> Form<T, N> for BiermanUd<T, N> {
    super::form_basics!();

    fn regularising_estimate(&self) -> Vector<T, N> {
        self.x
    }

    fn keep(&mut self, accepted: T::Mask, next: &Self) {
        self.x = Mat::select(accepted, &next.x, &self.x);
        self.u = Mat::select(accepted, &next.u, &self.u);
        self.d = Mat::select(accepted, &next.d, &self.d);
    }
}
