//! Information-form QR RLS: propagates upper-triangular `R` (`Rᵀ R = P⁻¹`) and `ζ = R x`.
//!
//! # Recursion (Golub & Van Loan, §6.5 "updating the QR factorisation"; Bierman 1977, ch. IV
//! "square-root information filter"; whitened data `h ← √w·h`, `z ← √w·z`)
//! ```text
//!      [ √λ R   √λ ζ ]     [ R⁺   ζ⁺ ]
//! Qᵀ · [  hᵀ      z  ]  =  [ 0ᵀ    ε ]
//! ```
//! with `Qᵀ` a sequence of `n` Givens rotations, rotation `j` acting on row `j` and the
//! measurement row to annihilate its `j`-th entry. Then `R⁺ᵀR⁺ = λ RᵀR + h hᵀ` (the
//! information recursion), `R⁺ x⁺ = ζ⁺` (the normal equations of the weighted problem), and
//! `ε` is the whitened a-posteriori residual. The estimate is formed on demand by back
//! substitution, the covariance from `R⁻¹`. Nothing is subtracted from `P`: the form cannot
//! lose definiteness, and `R_jj = √(R_jj² + h_j²) > 0` stays positive. An update that would
//! leave a pivot `1/R_jj²` of `P` outside the floating-point range (unbounded windup) is not
//! applied and is counted as a numerical rejection.
//!
//! # Compensated accumulation
//! With `λ = 1` the entries of `R` and `ζ` grow like `√k` while each rotation changes them by
//! `O(1/√k)`; plain rounding of `R_ij + δ` then loses `O(u)` relative accuracy per step, and
//! the losses add up over millions of steps (in f32, `u·k ≈ 0.06` at `k = 10⁶`). So each
//! rotation is written as an increment, `R⁺_jk = R_jk + δ` with
//! `δ = (c − 1) R_jk + s h_k` and `c − 1 = −(r − a)/r`, `r − a = b²/(r + a)` (no cancellation),
//! and the increment is added with an error-free transformation (Knuth's TwoSum) whose
//! rounding error is carried into the next increment of that entry (Kahan/Neumaier style
//! compensation). The stored `R` then stays within about an ulp of the exact accumulated sum.
//! With `λ < 1`, `√λ` is applied as an unevaluated sum `hi + lo`, and both the low part and
//! the exact rounding error of `R·hi` (Dekker's product) feed the compensation terms, so the
//! forgetting step is compensated too.
//!
//! [`RlsConfig::without_compensation`] turns the compensation off (plain Givens updates) for
//! users who prefer speed to the last digits.
//!
//! Windup protection's regularising rows need the estimate, one O(n²) back substitution per
//! update, only computed when bounds are configured.

use super::{
    Core, Form, Health, RecursiveLeastSquares, RlsConfig, RlsError, frobenius2, min_max, outer_self,
};
use rootfuse_lane::{Lane, Mask, Mat, Vector};

/// Information-form QR RLS (square-root information filter). See the
/// [module documentation](self).
#[derive(Clone, Copy, Debug)]
pub struct InformationQr<T: Lane, const N: usize> {
    /// Upper triangular, `Rᵀ R = P⁻¹`.
    r: Mat<T, N, N>,
    /// Rounding error of each entry of `r`, carried into its next increment.
    r_lo: Mat<T, N, N>,
    /// `ζ = R x`.
    zeta: Vector<T, N>,
    zeta_lo: Vector<T, N>,
    core: Core<T>,
}

/// `a + b` as an unevaluated sum `(s, e)`, `s = fl(a + b)`, `s + e = a + b` exactly (Knuth).
#[inline]
fn two_sum<T: Lane>(a: T, b: T) -> (T, T) {
    let s = a + b;
    let bp = s - a;
    let ap = s - bp;
    (s, (a - ap) + (b - bp))
}

/// Veltkamp's splitting constant `2^⌈p/2⌉ + 1` for a `p`-bit significand.
#[inline]
fn split_constant<T: Lane>() -> T {
    // EPSILON = 2^(1−p); read p from its exponent field (no `log2` without std).
    let exponent = ((T::EPSILON.to_bits() >> 52) & 0x7ff) as i64 - 1023;
    let half = (1 - exponent + 1) / 2;
    T::from_f64(f64::from_bits(((1023 + half) as u64) << 52) + 1.0)
}

/// `a · b` as an unevaluated sum `(p, e)`, `p = fl(a·b)`, `p + e = a·b` exactly (Dekker's
/// product without a fused multiply-add, so lanes and scalars agree bit for bit). Valid while
/// `|a|, |b|` stay far below `MAX / split`, true for any usable factor.
#[inline]
fn two_prod<T: Lane>(a: T, b: T, split: T) -> (T, T) {
    let p = a * b;
    let halves = |v: T| {
        let t = split * v;
        let hi = t - (t - v);
        (hi, v - hi)
    };
    let (ah, al) = halves(a);
    let (bh, bl) = halves(b);
    let e = (ah * bh - p) + ah * bl + al * bh + al * bl;
    (p, e)
}

/// Per lane: `P = R⁻¹R⁻ᵀ` can be formed without overflow. `R` finite with positive pivots does
/// not make `R⁻¹` representable (found by fuzzing: a prior near the largest float, grown by
/// forgetting). With `M(R)` the comparison matrix (`|r_jj|` on the diagonal, `−|r_jk|` above),
/// `|R⁻¹| ≤ M(R)⁻¹` entrywise, so `y = M(R)⁻¹·1` (one O(n²) back substitution) bounds every
/// row sum of `|R⁻¹|` and `|P_ij| ≤ y_i·y_j`; `n·max(y)²` finite is sufficient.
fn covariance_representable<T: Lane, const N: usize>(r: &Mat<T, N, N>) -> T::Mask {
    let mut y = [T::zero(); N];
    let mut y_max = T::zero();
    for j in (0..N).rev() {
        let mut acc = T::one();
        for (r_jk, y_k) in r.m[j][j + 1..].iter().zip(&y[j + 1..]) {
            acc = r_jk.abs().mul_add(*y_k, acc);
        }
        y[j] = acc / r.m[j][j].abs();
        y_max = y_max.max(y[j]);
    }
    (y_max * y_max * T::from_f64(N as f64)).is_finite()
}

impl<T: Lane, const N: usize> InformationQr<T, N> {
    /// The upper-triangular square-root information matrix `R` (`Rᵀ R = P⁻¹`).
    pub fn factor(&self) -> &Mat<T, N, N> {
        &self.r
    }

    /// Forgetting plus one whitened row, by Givens rotations with compensated accumulation;
    /// (new state, finite, definite).
    fn step(&self, h: &Vector<T, N>, z: T, lambda: T) -> (Self, T::Mask, T::Mask) {
        let zero = T::zero();
        let one = T::one();
        // A rounded √λ would change the memory length systematically (by 2u/(1 − λ) relative:
        // 10⁻³ in f32 at λ = 0.9999), so its low part goes into the compensation terms.
        let (sl, sl_lo) = self.core.sqrt_lambda(lambda);
        let split = split_constant::<T>();
        // The switch is the same for every lane: a uniform branch, no lane sees the other path.
        let compensated = self.core.config().compensated;
        let scale = |v: T, lo: T| {
            if compensated {
                let (p, e) = two_prod(v, sl, split);
                (p, v.mul_add(sl_lo, lo.mul_add(sl, e)))
            } else {
                (v * sl, zero)
            }
        };
        let add = |a: T, b: T| {
            if compensated {
                two_sum(a, b)
            } else {
                (a + b, zero)
            }
        };
        let mut r = self.r;
        let mut r_lo = self.r_lo;
        for i in 0..N {
            for j in i..N {
                (r.m[i][j], r_lo.m[i][j]) = scale(self.r.m[i][j], self.r_lo.m[i][j]);
            }
        }
        let mut zeta = self.zeta;
        let mut zeta_lo = self.zeta_lo;
        for i in 0..N {
            (zeta[i], zeta_lo[i]) = scale(self.zeta[i], self.zeta_lo[i]);
        }
        let mut row = *h;
        let mut zr = z;
        for j in 0..N {
            let a = r.m[j][j];
            let b = row[j];
            let rr = a.mul_add(a, b * b).sqrt();
            let nz = rr.simd_gt(zero);
            // a ≥ 0, so r − a = b²/(r + a) without cancellation.
            let grow = T::select(nz, (b * b) / (rr + a), zero);
            let c = T::select(nz, a / rr, one);
            let s = T::select(nz, b / rr, zero);
            let cm1 = T::select(nz, -grow / rr, zero);
            let (v, lo) = add(a, grow + r_lo.m[j][j]);
            r.m[j][j] = v;
            r_lo.m[j][j] = lo;
            row[j] = zero;
            for k in j + 1..N {
                let rv = r.m[j][k];
                let hv = row[k];
                let delta = cm1.mul_add(rv, s * hv);
                row[k] = c.mul_add(hv, -(s * rv));
                let (v, lo) = add(rv, delta + r_lo.m[j][k]);
                r.m[j][k] = v;
                r_lo.m[j][k] = lo;
            }
            let zv = zeta[j];
            let delta = cm1.mul_add(zv, s * zr);
            zr = c.mul_add(zr, -(s * zv));
            let (v, lo) = add(zv, delta + zeta_lo[j]);
            zeta[j] = v;
            zeta_lo[j] = lo;
        }
        let mut numeric_ok =
            r.is_finite() & zeta.is_finite() & r_lo.is_finite() & zeta_lo.is_finite();
        for j in 0..N {
            // A pivot so small that P's pivot 1/R_jj² overflows is windup that forgetting
            // drove below the floating-point range: refuse it rather than report P = ∞.
            let rjj = r.m[j][j];
            numeric_ok &= rjj.simd_gt(zero) & (one / (rjj * rjj)).is_finite();
        }
        // R and ζ finite do not make x = R⁻¹ζ finite: the back substitution can overflow
        // (found by fuzzing). One O(n²) solve, the same order as the update itself.
        numeric_ok &= r.solve_upper(&zeta).is_finite();
        numeric_ok &= covariance_representable(&r);
        let state = Self {
            r,
            r_lo,
            zeta,
            zeta_lo,
            ..*self
        };
        (state, numeric_ok, T::Mask::splat(true))
    }

    fn r_inverse(&self) -> Mat<T, N, N> {
        self.r.solve_upper(&Mat::identity())
    }
}

impl<T: Lane, const N: usize> RecursiveLeastSquares<T, N> for InformationQr<T, N> {
    const NAME: &'static str = "information-qr";

    super::shared_form_items!();

    fn new(x0: &Vector<T, N>, p0: &Mat<T, N, N>, config: RlsConfig) -> Result<Self, RlsError> {
        let (core, prior) = Core::new(x0, p0, config)?;
        // P₀ = L Lᵀ ⇒ P₀⁻¹ = L⁻ᵀ L⁻¹; its Cholesky factor G gives R = Gᵀ.
        let linv = prior.l.solve_lower(&Mat::identity());
        let info = linv.transpose() * linv;
        let info = info.symmetrize();
        let (g, ok) = info.cholesky();
        if !ok.all() {
            return Err(RlsError::PriorNotPositiveDefinite);
        }
        let r = g.transpose();
        let zeta = r * *x0;
        // ζ = R x₀ overflows for a huge (finite) x₀ with a small P₀ (found by fuzzing).
        if !(zeta.is_finite() & r.solve_upper(&zeta).is_finite()).all() {
            return Err(RlsError::NonFinitePrior);
        }
        if !covariance_representable(&r).all() {
            return Err(RlsError::NumericalFailure);
        }
        Ok(Self {
            r,
            r_lo: Mat::zeros(),
            zeta,
            zeta_lo: Vector::zeros(),
            core,
        })
    }

    fn estimate(&self) -> Vector<T, N> {
        self.r.solve_upper(&self.zeta)
    }

    fn covariance(&self) -> Mat<T, N, N> {
        outer_self(&self.r_inverse())
    }

    fn health(&self) -> Health<T> {
        // The U D Uᵀ pivots of P = R⁻¹R⁻ᵀ are 1/R_jj².
        let (lo, hi) = min_max(N, |j| T::one() / (self.r.m[j][j] * self.r.m[j][j]));
        self.core.health(lo, hi, frobenius2(&self.r_inverse()))
    }
}

impl<T: Lane, const N: usize> Form<T, N> for InformationQr<T, N> {
    super::form_basics!();

    /// Only the regularising rows of bounded forgetting need the estimate (a solve here).
    fn regularising_estimate(&self) -> Vector<T, N> {
        if self.core.bounded() {
            self.estimate()
        } else {
            Vector::zeros()
        }
    }

    fn keep(&mut self, accepted: T::Mask, next: &Self) {
        self.r = Mat::select(accepted, &next.r, &self.r);
        self.zeta = Mat::select(accepted, &next.zeta, &self.zeta);
        // Without compensation the low parts stay zero.
        if self.core.config().compensated {
            self.r_lo = Mat::select(accepted, &next.r_lo, &self.r_lo);
            self.zeta_lo = Mat::select(accepted, &next.zeta_lo, &self.zeta_lo);
        }
    }
}
