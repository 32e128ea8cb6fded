//! The scalar types the batch solvers run in.

use core::fmt::Debug;
use core::ops::Neg;

use faer::traits::RealField;

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// A real scalar the batch least-squares solvers accept: `f32` or `f64`.
///
/// faer's [`RealField`] supplies the arithmetic the factorisations need; this trait adds the few
/// things the solvers need beyond it (unit roundoff, conversions for reporting, finiteness).
/// Sealed: the tolerances in [`batch`](super) are tuned to IEEE binary32/binary64.
pub trait LsqReal: RealField + Copy + Debug + Neg<Output = Self> + sealed::Sealed {
    /// Machine epsilon (the gap between 1 and the next representable number).
    const EPSILON: Self;
    /// Rounds an `f64` to this type.
    fn from_f64(x: f64) -> Self;
    /// Widens (or keeps) this value as `f64`.
    fn to_f64(self) -> f64;
    /// Square root.
    fn sqrt(self) -> Self;
    /// Absolute value.
    fn abs(self) -> Self;
    /// Neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// `self · a + b` with a single rounding (always fused: the compensated residuals of the
    /// iterative refinement rely on it to recover the exact rounding error of a product).
    fn fused_mul_add(self, a: Self, b: Self) -> Self;
}

macro_rules! lsq_real {
    ($t:ty) => {
        impl LsqReal for $t {
            const EPSILON: Self = <$t>::EPSILON;
            #[inline]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn sqrt(self) -> Self {
                <$t>::sqrt(self)
            }
            #[inline]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
            #[inline]
            fn fused_mul_add(self, a: Self, b: Self) -> Self {
                <$t>::mul_add(self, a, b)
            }
        }
    };
}

lsq_real!(f32);
lsq_real!(f64);
