//! Small fixed-size matrices over [`Lane`], for filters with a handful of states.
//!
//! Storage is row-major `[[T; C]; R]`, everything is `Copy` and allocation-free, and sizes
//! are checked at compile time. Sums run in index order with [`Lane::mul_add`], so a lane of
//! a SIMD instantiation computes exactly what the scalar instantiation computes.
//!
//! ```
//! use rootfuse_lane::{Lane, Mask, Mat};
//!
//! // P = A·Aᵀ + I is symmetric positive definite; its Cholesky factor solves P·x = b.
//! let a = Mat::<f64, 3, 3>::from_rows([[1.0, 2.0, 0.0], [0.0, 1.0, 3.0], [4.0, 0.0, 1.0]]);
//! let p = a * a.transpose() + Mat::identity();
//! let (l, ok) = p.cholesky();
//! assert!(ok.all());
//! let b = Mat::<f64, 3, 1>::from_rows([[1.0], [2.0], [3.0]]);
//! let x = l.cholesky_solve(&b);
//! assert!(((p * x) - b).max_abs() < 1e-12);
//! ```

use crate::lane::Lane;
use core::ops::{Add, Index, IndexMut, Mul, Neg, Sub};

/// An `R × C` matrix of lanes, row-major.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Mat<T, const R: usize, const C: usize> {
    /// Rows of the matrix: `m[i][j]` is row `i`, column `j`.
    pub m: [[T; C]; R],
}

/// A column vector of `N` lanes.
pub type Vector<T, const N: usize> = Mat<T, N, 1>;

impl<T: Lane, const R: usize, const C: usize> Default for Mat<T, R, C> {
    fn default() -> Self {
        Self::zeros()
    }
}

impl<T: Lane, const R: usize, const C: usize> Mat<T, R, C> {
    /// All zeros.
    #[inline]
    pub fn zeros() -> Self {
        Self {
            m: [[T::zero(); C]; R],
        }
    }
    /// From rows.
    #[inline]
    pub fn from_rows(m: [[T; C]; R]) -> Self {
        Self { m }
    }
    /// Element `(i, j)` is `f(i, j)`.
    #[inline]
    pub fn from_fn(mut f: impl FnMut(usize, usize) -> T) -> Self {
        Self {
            m: core::array::from_fn(|i| core::array::from_fn(|j| f(i, j))),
        }
    }
    /// The transpose.
    #[inline]
    pub fn transpose(&self) -> Mat<T, C, R> {
        Mat::from_fn(|i, j| self.m[j][i])
    }
    /// Every element times `s`.
    #[inline]
    pub fn scale(&self, s: T) -> Self {
        Self::from_fn(|i, j| self.m[i][j] * s)
    }
    /// `if mask { a } else { b }`, per lane, element by element.
    #[inline]
    pub fn select(mask: T::Mask, a: &Self, b: &Self) -> Self {
        Self::from_fn(|i, j| T::select(mask, a.m[i][j], b.m[i][j]))
    }
    /// Per lane: every element finite.
    #[inline]
    pub fn is_finite(&self) -> T::Mask {
        let mut ok = <T::Mask as crate::Mask>::splat(true);
        for row in &self.m {
            for &x in row {
                ok &= x.is_finite();
            }
        }
        ok
    }
    /// Largest absolute element over all lanes, as `f64` (for tests and diagnostics).
    pub fn max_abs(&self) -> f64 {
        let mut worst = 0.0f64;
        for row in &self.m {
            for &x in row {
                for lane in 0..T::LANES {
                    let v: f64 = x.extract(lane).into();
                    worst = if v.abs() > worst || v.is_nan() {
                        v.abs()
                    } else {
                        worst
                    };
                }
            }
        }
        worst
    }
    /// `A · B · Aᵀ` for symmetric `B` (the covariance propagation `F P Fᵀ`, or `K R Kᵀ`),
    /// symmetrised.
    #[inline]
    pub fn congruence(&self, b: &Mat<T, C, C>) -> Mat<T, R, R> {
        (*self * *b * self.transpose()).symmetrize()
    }
    /// Column `j`.
    #[inline]
    pub fn column(&self, j: usize) -> Vector<T, R> {
        Mat::from_fn(|i, _| self.m[i][j])
    }
}

impl<T: Lane, const R: usize, const C: usize> crate::Select<T::Mask> for Mat<T, R, C> {
    #[inline]
    fn select(mask: T::Mask, a: &Self, b: &Self) -> Self {
        Mat::select(mask, a, b)
    }
}

impl<T: Lane, const N: usize> Mat<T, N, N> {
    /// The identity matrix.
    #[inline]
    pub fn identity() -> Self {
        Self::from_fn(|i, j| if i == j { T::one() } else { T::zero() })
    }
    /// Diagonal matrix from a vector.
    #[inline]
    pub fn from_diagonal(d: &Vector<T, N>) -> Self {
        Self::from_fn(|i, j| if i == j { d.m[i][0] } else { T::zero() })
    }
    /// The diagonal as a vector.
    #[inline]
    pub fn diagonal(&self) -> Vector<T, N> {
        Mat::from_fn(|i, _| self.m[i][i])
    }
    /// Sum of the diagonal.
    #[inline]
    pub fn trace(&self) -> T {
        let mut t = T::zero();
        for i in 0..N {
            t += self.m[i][i];
        }
        t
    }
    /// `(A + Aᵀ) / 2`: removes the asymmetry that rounding leaves in a covariance update.
    ///
    /// Computed as `a/2 + b/2` (the diagonal kept as it is), which rounds to the same value as
    /// `(a + b)/2` but cannot overflow for finite `a`, `b`: a covariance entry near the largest
    /// float stays finite (found by fuzzing the Bierman time update).
    #[inline]
    pub fn symmetrize(&self) -> Self {
        let half = T::from_f64(0.5);
        Self::from_fn(|i, j| {
            if i == j {
                self.m[i][i]
            } else {
                self.m[i][j].mul_add(half, self.m[j][i] * half)
            }
        })
    }
    /// Symmetric rank-one update `A += alpha · v · vᵀ`.
    #[inline]
    pub fn rank_one_update(&mut self, alpha: T, v: &Vector<T, N>) {
        for i in 0..N {
            let avi = alpha * v.m[i][0];
            for j in 0..N {
                self.m[i][j] = avi.mul_add(v.m[j][0], self.m[i][j]);
            }
        }
    }

    /// Cholesky factorisation `A = L·Lᵀ` of a symmetric matrix (only the lower triangle is read).
    ///
    /// Returns the lower-triangular `L` and a per-lane mask that is false where a pivot was
    /// not positive and finite (the matrix is not positive definite in that lane, or holds
    /// NaN/∞). In such a lane the failing pivot is replaced by 1 so the other lanes and the
    /// returned numbers stay finite for finite input; the factor itself is meaningless there.
    pub fn cholesky(&self) -> (Self, T::Mask) {
        let mut l = Self::zeros();
        let mut ok = <T::Mask as crate::Mask>::splat(true);
        for j in 0..N {
            let mut d = self.m[j][j];
            for k in 0..j {
                d = (-l.m[j][k]).mul_add(l.m[j][k], d);
            }
            let pivot_ok = d.simd_gt(T::zero()) & d.is_finite();
            ok &= pivot_ok;
            let ljj = T::select(pivot_ok, d.sqrt(), T::one());
            l.m[j][j] = ljj;
            for i in j + 1..N {
                let mut s = self.m[i][j];
                for k in 0..j {
                    s = (-l.m[i][k]).mul_add(l.m[j][k], s);
                }
                l.m[i][j] = s / ljj;
            }
        }
        (l, ok)
    }

    /// Solves `L·X = B` by forward substitution, `self` lower-triangular (upper part ignored).
    pub fn solve_lower<const C: usize>(&self, b: &Mat<T, N, C>) -> Mat<T, N, C> {
        let mut x = *b;
        for c in 0..C {
            for i in 0..N {
                let mut s = x.m[i][c];
                for k in 0..i {
                    s = (-self.m[i][k]).mul_add(x.m[k][c], s);
                }
                x.m[i][c] = s / self.m[i][i];
            }
        }
        x
    }

    /// Solves `U·X = B` by back substitution, `self` upper-triangular (lower part ignored).
    pub fn solve_upper<const C: usize>(&self, b: &Mat<T, N, C>) -> Mat<T, N, C> {
        let mut x = *b;
        for c in 0..C {
            for i in (0..N).rev() {
                let mut s = x.m[i][c];
                for k in i + 1..N {
                    s = (-self.m[i][k]).mul_add(x.m[k][c], s);
                }
                x.m[i][c] = s / self.m[i][i];
            }
        }
        x
    }

    /// Solves `Lᵀ·X = B`, `self` lower-triangular, without forming the transpose.
    pub fn solve_lower_transposed<const C: usize>(&self, b: &Mat<T, N, C>) -> Mat<T, N, C> {
        let mut x = *b;
        for c in 0..C {
            for i in (0..N).rev() {
                let mut s = x.m[i][c];
                for k in i + 1..N {
                    s = (-self.m[k][i]).mul_add(x.m[k][c], s);
                }
                x.m[i][c] = s / self.m[i][i];
            }
        }
        x
    }

    /// Solves `A·X = B` given `self = L`, the Cholesky factor of `A`.
    #[inline]
    pub fn cholesky_solve<const C: usize>(&self, b: &Mat<T, N, C>) -> Mat<T, N, C> {
        self.solve_lower_transposed(&self.solve_lower(b))
    }
}

impl<T: Lane, const N: usize> Mat<T, N, 1> {
    /// From a column of values.
    #[inline]
    pub fn from_column(v: [T; N]) -> Self {
        Self::from_fn(|i, _| v[i])
    }
    /// `self · other`.
    #[inline]
    pub fn dot(&self, other: &Self) -> T {
        let mut s = T::zero();
        for i in 0..N {
            s = self.m[i][0].mul_add(other.m[i][0], s);
        }
        s
    }
}

impl<T: Lane, const N: usize> Index<usize> for Mat<T, N, 1> {
    type Output = T;
    #[inline]
    fn index(&self, i: usize) -> &T {
        &self.m[i][0]
    }
}
impl<T: Lane, const N: usize> IndexMut<usize> for Mat<T, N, 1> {
    #[inline]
    fn index_mut(&mut self, i: usize) -> &mut T {
        &mut self.m[i][0]
    }
}
impl<T: Lane, const R: usize, const C: usize> Index<(usize, usize)> for Mat<T, R, C> {
    type Output = T;
    #[inline]
    fn index(&self, (i, j): (usize, usize)) -> &T {
        &self.m[i][j]
    }
}
impl<T: Lane, const R: usize, const C: usize> IndexMut<(usize, usize)> for Mat<T, R, C> {
    #[inline]
    fn index_mut(&mut self, (i, j): (usize, usize)) -> &mut T {
        &mut self.m[i][j]
    }
}

impl<T: Lane, const R: usize, const K: usize, const C: usize> Mul<Mat<T, K, C>> for Mat<T, R, K> {
    type Output = Mat<T, R, C>;
    #[inline]
    fn mul(self, rhs: Mat<T, K, C>) -> Mat<T, R, C> {
        Mat::from_fn(|i, j| {
            let mut s = T::zero();
            for k in 0..K {
                s = self.m[i][k].mul_add(rhs.m[k][j], s);
            }
            s
        })
    }
}
impl<T: Lane, const R: usize, const C: usize> Add for Mat<T, R, C> {
    type Output = Self;
    #[inline]
    fn add(self, rhs: Self) -> Self {
        Self::from_fn(|i, j| self.m[i][j] + rhs.m[i][j])
    }
}
impl<T: Lane, const R: usize, const C: usize> Sub for Mat<T, R, C> {
    type Output = Self;
    #[inline]
    fn sub(self, rhs: Self) -> Self {
        Self::from_fn(|i, j| self.m[i][j] - rhs.m[i][j])
    }
}
impl<T: Lane, const R: usize, const C: usize> Neg for Mat<T, R, C> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self::from_fn(|i, j| -self.m[i][j])
    }
}
