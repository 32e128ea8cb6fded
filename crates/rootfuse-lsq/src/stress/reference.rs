//! The stress reference: the forgetting-factor least-squares estimate computed by Givens QR
//! in double-double arithmetic (about 106 significant bits), so that the f64 rows measure
//! accuracy and not agreement between two f64 algorithms.
//!
//! Deliberately independent of [`rls`](crate::rls): a reference that shares code with what it
//! checks would share its mistakes. Double-double arithmetic after Dekker (1971) and
//! Hida, Li & Bailey (2001), "Algorithms for quad-double precision floating point
//! arithmetic": `TwoSum`, `TwoProd` by fused multiply-add, sloppy-free addition.

use core::ops::{Add, Div, Mul, Neg, Sub};

/// An unevaluated sum `hi + lo` with `|lo| ≤ ulp(hi)/2`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Dd {
    hi: f64,
    lo: f64,
}

#[inline]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bp = s - a;
    (s, (a - (s - bp)) + (b - bp))
}

#[inline]
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

impl Dd {
    pub(crate) const ZERO: Dd = Dd { hi: 0.0, lo: 0.0 };

    pub(crate) fn from_f64(x: f64) -> Self {
        Dd { hi: x, lo: 0.0 }
    }

    pub(crate) fn to_f64(self) -> f64 {
        self.hi + self.lo
    }

    /// Newton's step on `hi = sqrt(hi)` in double-double: `x + (a − x²)/(2x)`.
    pub(crate) fn sqrt(self) -> Self {
        if self.hi <= 0.0 {
            return Dd::from_f64(self.hi.max(0.0).sqrt());
        }
        let x = Dd::from_f64(self.hi.sqrt());
        x + (self - x * x) / (x + x)
    }
}

impl Add for Dd {
    type Output = Dd;
    #[inline]
    fn add(self, b: Dd) -> Dd {
        // The accurate ("IEEE") double-double addition of Hida, Li & Bailey.
        let (s, e) = two_sum(self.hi, b.hi);
        let (t, f) = two_sum(self.lo, b.lo);
        let (s, e) = quick_two_sum(s, e + t);
        let (hi, lo) = quick_two_sum(s, e + f);
        Dd { hi, lo }
    }
}

impl Neg for Dd {
    type Output = Dd;
    #[inline]
    fn neg(self) -> Dd {
        Dd {
            hi: -self.hi,
            lo: -self.lo,
        }
    }
}

impl Sub for Dd {
    type Output = Dd;
    #[inline]
    fn sub(self, b: Dd) -> Dd {
        self + (-b)
    }
}

impl Mul for Dd {
    type Output = Dd;
    #[inline]
    fn mul(self, b: Dd) -> Dd {
        let p = self.hi * b.hi;
        let e = self.hi.mul_add(b.hi, -p);
        let (hi, lo) = quick_two_sum(p, e + (self.hi * b.lo + self.lo * b.hi));
        Dd { hi, lo }
    }
}

impl Div for Dd {
    type Output = Dd;
    #[inline]
    fn div(self, b: Dd) -> Dd {
        // Long division: two quotient digits and a correction.
        let q1 = self.hi / b.hi;
        let r = self - b * Dd::from_f64(q1);
        let q2 = r.hi / b.hi;
        let r = r - b * Dd::from_f64(q2);
        let q3 = r.hi / b.hi;
        let (hi, lo) = quick_two_sum(q1, q2);
        Dd { hi, lo } + Dd::from_f64(q3)
    }
}

/// The square-root information recursion `[√λ·R, √λ·ζ; √w·hᵀ, √w·z] → [R⁺, ζ⁺; 0, ε]` by
/// Givens rotations, in double-double.
pub(crate) struct DdInformationQr<const N: usize> {
    r: [[Dd; N]; N],
    zeta: [Dd; N],
    sqrt_lambda: Dd,
}

impl<const N: usize> DdInformationQr<N> {
    /// The prior `x₀ = 0` with covariance `p0·I`: `R = I/√p0`, `ζ = 0`.
    pub(crate) fn new(p0: f64, lambda: f64) -> Self {
        let diag = (Dd::from_f64(1.0) / Dd::from_f64(p0)).sqrt();
        let mut r = [[Dd::ZERO; N]; N];
        for (j, row) in r.iter_mut().enumerate() {
            row[j] = diag;
        }
        Self {
            r,
            zeta: [Dd::ZERO; N],
            sqrt_lambda: Dd::from_f64(lambda).sqrt(),
        }
    }

    /// One measurement `z = hᵀx` with weight `w` (inverse variance); samples that are not
    /// finite or not positively weighted are ignored, as every form rejects them.
    pub(crate) fn update(&mut self, h: &[f64; N], z: f64, w: f64) {
        if !(w > 0.0 && w.is_finite() && z.is_finite() && h.iter().all(|v| v.is_finite())) {
            return;
        }
        let sw = Dd::from_f64(w).sqrt();
        let mut row: [Dd; N] = core::array::from_fn(|j| sw * Dd::from_f64(h[j]));
        let mut rhs = sw * Dd::from_f64(z);
        let sl = self.sqrt_lambda;
        for j in 0..N {
            for k in j..N {
                self.r[j][k] = sl * self.r[j][k];
            }
            self.zeta[j] = sl * self.zeta[j];
        }
        for j in 0..N {
            let (a, b) = (self.r[j][j], row[j]);
            if b.hi == 0.0 && b.lo == 0.0 {
                continue;
            }
            let rho = (a * a + b * b).sqrt();
            let (c, s) = (a / rho, b / rho);
            self.r[j][j] = rho;
            row[j] = Dd::ZERO;
            for (r_jk, h_k) in self.r[j][j + 1..].iter_mut().zip(&mut row[j + 1..]) {
                let (u, v) = (*r_jk, *h_k);
                *r_jk = c * u + s * v;
                *h_k = c * v - s * u;
            }
            let (u, v) = (self.zeta[j], rhs);
            self.zeta[j] = c * u + s * v;
            rhs = c * v - s * u;
        }
    }

    /// `x = R⁻¹ζ` by back substitution, rounded to f64.
    pub(crate) fn estimate(&self) -> [f64; N] {
        let mut x = [Dd::ZERO; N];
        for j in (0..N).rev() {
            let mut acc = self.zeta[j];
            for (r_jk, x_k) in self.r[j][j + 1..].iter().zip(&x[j + 1..]) {
                acc = acc - *r_jk * *x_k;
            }
            x[j] = acc / self.r[j][j];
        }
        x.map(Dd::to_f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn double_double_carries_106_bits() {
        // (1 + 2⁻⁶⁰)² = 1 + 2⁻⁵⁹ + 2⁻¹²⁰: the middle term is lost in f64, kept here.
        let x = Dd::from_f64(1.0) + Dd::from_f64(2f64.powi(-60));
        let sq = x * x;
        assert_eq!(sq.hi, 1.0);
        assert_eq!(sq.lo, 2f64.powi(-59));
        // 1/3 · 3 = 1 to within 2⁻¹⁰⁴.
        let third = Dd::from_f64(1.0) / Dd::from_f64(3.0);
        let one = third * Dd::from_f64(3.0) - Dd::from_f64(1.0);
        assert!(one.to_f64().abs() < 2f64.powi(-104), "{one:?}");
        // √2² = 2 to within 2⁻¹⁰³.
        let r = Dd::from_f64(2.0).sqrt();
        assert!((r * r - Dd::from_f64(2.0)).to_f64().abs() < 2f64.powi(-103));
    }

    #[test]
    fn dyer_mcreynolds_exact_solution() {
        // P0 = I, rows [1,1,1] and [1,1,1+δ], z = hᵀx for x = (1, 1.5, 2), weights 1/δ², δ = 1e-7
        // (an f64 condition number of the normal equations near 1e14). The exact minimiser of
        // ‖x‖² + Σ w(z − hᵀx)² for these f64 inputs, solved in rational arithmetic:
        let exact = [1.4374999884526476, 1.4374999884526476, 1.6250000418446955];
        let delta = 1e-7;
        let x_true = [1.0, 1.5, 2.0];
        let mut f = DdInformationQr::<3>::new(1.0, 1.0);
        for h in [[1.0, 1.0, 1.0], [1.0, 1.0, 1.0 + delta]] {
            let z: f64 = h.iter().zip(&x_true).map(|(a, b)| a * b).sum();
            f.update(&h, z, 1.0 / (delta * delta));
        }
        let x = f.estimate();
        for (a, b) in x.iter().zip(exact) {
            assert!((a - b).abs() <= 2.0 * f64::EPSILON * b, "{x:?}");
        }
    }
}
