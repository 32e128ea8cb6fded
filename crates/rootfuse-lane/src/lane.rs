//! The [`Lane`] and [`Mask`] traits.

use core::fmt::Debug;
use core::ops::{
    Add, AddAssign, BitAnd, BitAndAssign, BitOr, BitOrAssign, BitXor, Div, DivAssign, Mul,
    MulAssign, Neg, Not, Sub, SubAssign,
};

/// A per-lane boolean: `bool` for scalars, an all-ones/all-zeros bit pattern per lane for SIMD.
pub trait Mask:
    Copy
    + Debug
    + Send
    + Sync
    + 'static
    + BitAnd<Output = Self>
    + BitOr<Output = Self>
    + BitXor<Output = Self>
    + Not<Output = Self>
    + BitAndAssign
    + BitOrAssign
    + Select<Self>
{
    /// Number of lanes.
    const LANES: usize;
    /// The same boolean in every lane.
    fn splat(value: bool) -> Self;
    /// True if at least one lane is set.
    fn any(self) -> bool;
    /// True if every lane is set.
    fn all(self) -> bool;
    /// True if no lane is set.
    #[inline]
    fn none(self) -> bool {
        !self.any()
    }
    /// Bit `i` is lane `i`.
    fn bitmask(self) -> u64;
    /// Lane `i` (panics if `i >= LANES`, like slice indexing).
    #[inline]
    fn test(self, lane: usize) -> bool {
        assert!(lane < Self::LANES, "lane {lane} out of range");
        (self.bitmask() >> lane) & 1 == 1
    }
}

/// A per-lane choice between two whole values, `if mask { a } else { b }` lane by lane: what
/// a branch-free update uses to keep some lanes' state and take others'.
///
/// Implemented for every [`Lane`] type, masks, [`Mat`](crate::Mat) and arrays; a state struct
/// implements it field by field (the attitude crate's `lane_state!` does so for every field,
/// so a new field cannot be forgotten).
pub trait Select<M>: Sized {
    /// `a` where `mask` is set, `b` elsewhere.
    fn select(mask: M, a: &Self, b: &Self) -> Self;
}

impl<T: Lane> Select<T::Mask> for T {
    #[inline]
    fn select(mask: T::Mask, a: &Self, b: &Self) -> Self {
        T::select(mask, *a, *b)
    }
}

impl Select<bool> for bool {
    #[inline]
    fn select(mask: bool, a: &Self, b: &Self) -> Self {
        if mask { *a } else { *b }
    }
}

impl<M: Copy, S: Select<M>, const N: usize> Select<M> for [S; N] {
    #[inline]
    fn select(mask: M, a: &Self, b: &Self) -> Self {
        core::array::from_fn(|i| S::select(mask, &a[i], &b[i]))
    }
}

impl Mask for bool {
    const LANES: usize = 1;
    #[inline]
    fn splat(value: bool) -> Self {
        value
    }
    #[inline]
    fn any(self) -> bool {
        self
    }
    #[inline]
    fn all(self) -> bool {
        self
    }
    #[inline]
    fn bitmask(self) -> u64 {
        self as u64
    }
}

/// Per-lane event counters (rejected samples, rest time, …): one `u64` per lane.
///
/// Counting is exact for any recording length, unlike a counter kept in an `f32` lane,
/// which stops at 2²⁴.
pub trait Counts: Copy + Default + Debug + Send + Sync + 'static + AsRef<[u64]> {
    /// Adds one to every lane whose bit is set in `bitmask`.
    #[inline]
    fn add_bitmask(&mut self, bitmask: u64)
    where
        Self: AsMut<[u64]>,
    {
        if bitmask != 0 {
            for (i, c) in self.as_mut().iter_mut().enumerate() {
                *c += (bitmask >> i) & 1;
            }
        }
    }
}
impl<const N: usize> Counts for [u64; N] where [u64; N]: Default {}

/// One scalar abstraction over `f32`, `f64`, `f32x4`, `f32x8`, `f64x2` and `f64x4`.
///
/// Semantics shared by every implementation (so that lanes equal scalars bit for bit):
/// - arithmetic, [`sqrt`](Lane::sqrt) and division are IEEE-754, correctly rounded;
/// - [`mul_add`](Lane::mul_add) is `a * b + c` with two roundings, unless the `fast-math`
///   feature makes it fused;
/// - [`min`](Lane::min)/[`max`](Lane::max) are `if a < b { a } else { b }` (resp. `>`): if
///   either input is NaN the result is `b`;
/// - comparisons are ordered: any comparison with NaN is false except [`simd_ne`](Lane::simd_ne);
/// - trigonometric functions use one polynomial implementation (the `wide` crate's) for
///   every width; scalars run it in lane 0 of the narrowest vector. Accuracy: within 3 ulp
///   of `std` on the primary range (measured at most 2; `tests/accuracy.rs` of this crate).
pub trait Lane:
    Copy
    + Debug
    + Default
    + Send
    + Sync
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
{
    /// The element type of one lane (`f32` or `f64`).
    type Scalar: Lane<Scalar = Self::Scalar, Mask = bool> + PartialOrd + Into<f64>;
    /// The per-lane boolean.
    type Mask: Mask;
    /// Per-lane `u64` counters.
    type Counts: Counts + AsMut<[u64]>;
    /// Number of lanes.
    const LANES: usize;
    /// Machine epsilon of one lane (2⁻²³ for f32, 2⁻⁵² for f64).
    const EPSILON: f64;

    /// The same value in every lane.
    fn splat(x: Self::Scalar) -> Self;
    /// Converts an `f64` constant (rounded to nearest for f32).
    fn from_f64(x: f64) -> Self;
    /// Builds a value lane by lane.
    fn from_fn(f: impl FnMut(usize) -> Self::Scalar) -> Self;
    /// Lane `i` (panics if `i >= LANES`).
    fn extract(self, lane: usize) -> Self::Scalar;
    /// Sets lane `lane` to `x` in place, leaving the others (a lane `>= LANES` is ignored).
    /// One scalar store into the vector's memory: how the batch engine packs struct-of-arrays
    /// tiles channel by channel without building whole vectors from scattered scalars.
    ///
    /// ```
    /// use rootfuse_lane::{Lane, wide::f32x8};
    /// let mut v = f32x8::splat(1.0);
    /// v.set_lane(3, 5.0);
    /// assert_eq!((v.extract(2), v.extract(3)), (1.0, 5.0));
    /// ```
    fn set_lane(&mut self, lane: usize, x: Self::Scalar);
    /// Transposes `block`, `LANES` vectors seen as a square matrix, in place: afterwards lane
    /// `i` of `block[j]` holds what lane `j` of `block[i]` held. The batch engine loads
    /// `LANES` consecutive values of each of `LANES` channels (one vector per channel) and
    /// transposes them into one vector per value (lane `i` from channel `i`) in registers,
    /// instead of one scalar store per value ([`set_lane`](Lane::set_lane)).
    ///
    /// Returns `false`, leaving `block` as it is, unless `block.len() == LANES`.
    ///
    /// ```
    /// use rootfuse_lane::{Lane, wide::f64x4};
    /// let mut b: Vec<f64x4> = (0..4).map(|i| f64x4::from_fn(|j| (10 * i + j) as f64)).collect();
    /// assert!(Lane::transpose_lanes(&mut b));
    /// assert_eq!((b[1].extract(2), b[2].extract(1)), (21.0, 12.0));
    /// ```
    fn transpose_lanes(block: &mut [Self]) -> bool;
    /// `0` in every lane.
    #[inline]
    fn zero() -> Self {
        Self::from_f64(0.0)
    }
    /// `1` in every lane.
    #[inline]
    fn one() -> Self {
        Self::from_f64(1.0)
    }

    /// Square root (correctly rounded; NaN for negative input).
    fn sqrt(self) -> Self;
    /// Absolute value (clears the sign bit).
    fn abs(self) -> Self;
    /// `if self < other { self } else { other }`, per lane.
    fn min(self, other: Self) -> Self;
    /// `if self > other { self } else { other }`, per lane.
    fn max(self, other: Self) -> Self;
    /// `self * a + b`; fused only with the `fast-math` feature.
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// Rounds to the nearest integer, ties to even.
    fn round(self) -> Self;
    /// Largest integer not greater than `self`.
    fn floor(self) -> Self;

    /// `self == other`, per lane.
    fn simd_eq(self, other: Self) -> Self::Mask;
    /// `self != other`, per lane (true where either is NaN).
    fn simd_ne(self, other: Self) -> Self::Mask;
    /// `self < other`, per lane.
    fn simd_lt(self, other: Self) -> Self::Mask;
    /// `self <= other`, per lane.
    fn simd_le(self, other: Self) -> Self::Mask;
    /// `self > other`, per lane.
    fn simd_gt(self, other: Self) -> Self::Mask;
    /// `self >= other`, per lane.
    fn simd_ge(self, other: Self) -> Self::Mask;
    /// Neither NaN nor ±∞, per lane.
    fn is_finite(self) -> Self::Mask;
    /// NaN, per lane.
    fn is_nan(self) -> Self::Mask;
    /// `if mask { a } else { b }`, per lane.
    fn select(mask: Self::Mask, a: Self, b: Self) -> Self;

    /// Sine and cosine of an angle in radians.
    fn sin_cos(self) -> (Self, Self);
    /// Four-quadrant arc tangent of `self / x` (`self` is y), in `[-π, π]`.
    fn atan2(self, x: Self) -> Self;
    /// Arc tangent, in `[-π/2, π/2]`.
    fn atan(self) -> Self;
    /// Arc sine, in `[-π/2, π/2]`; NaN outside `[-1, 1]`.
    fn asin(self) -> Self;
    /// Arc cosine, in `[0, π]`; NaN outside `[-1, 1]`.
    fn acos(self) -> Self;

    /// Sine.
    #[inline]
    fn sin(self) -> Self {
        self.sin_cos().0
    }
    /// Cosine.
    #[inline]
    fn cos(self) -> Self {
        self.sin_cos().1
    }
    /// `self.max(lo).min(hi)` with the NaN rules of [`max`](Lane::max) and
    /// [`min`](Lane::min): a NaN input returns `lo`.
    #[inline]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        self.max(lo).min(hi)
    }
    /// `self * self`.
    #[inline]
    fn sq(self) -> Self {
        self * self
    }
    /// `1 / self`, exact IEEE division (never the approximate hardware reciprocal).
    #[inline]
    fn recip(self) -> Self {
        Self::one() / self
    }
    /// Wraps an angle to `[-π, π]` (radians).
    #[inline]
    fn wrap_pi(self) -> Self {
        let two_pi = Self::from_f64(core::f64::consts::TAU);
        self - two_pi * (self / two_pi).round()
    }
    /// Adds one to `counts` in every lane where `mask` is set.
    #[inline]
    fn count(counts: &mut Self::Counts, mask: Self::Mask) {
        counts.add_bitmask(mask.bitmask());
    }
}
