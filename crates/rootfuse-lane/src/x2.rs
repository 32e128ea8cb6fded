//! [`X2`]: two SIMD vectors run as one lane type, to hide latency.
//!
//! A filter update is one long dependency chain per vector (each step needs the previous
//! orientation; square roots, divisions and trigonometry sit on it), so one `f32x8` chain
//! leaves most of the core's execution ports idle and the out-of-order window cannot reach
//! the next independent chunk (a whole update is hundreds of instructions). `X2<f32x8>` runs
//! two independent `f32x8` vectors through every operation side by side, so two chains share
//! the same instructions' latency. Every operation is the inner vector's operation on each
//! half, so each lane's result is bit for bit that of the inner type (and of the scalar).

use crate::lane::{Lane, Mask};
use core::ops::{
    Add, AddAssign, BitAnd, BitAndAssign, BitOr, BitOrAssign, BitXor, Div, DivAssign, Mul,
    MulAssign, Neg, Not, Sub, SubAssign,
};
use wide::{f32x8, f64x4};

/// Two vectors of type `V` as one lane type of `2 × V::LANES` lanes: lane `i` is lane
/// `i % V::LANES` of half `i / V::LANES`. Implemented for `f32x8` (16 lanes) and `f64x4`
/// (8 lanes). Used as a mask too (`X2<f32x8>` is its own mask type, like `f32x8`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct X2<V>(pub [V; 2]);

macro_rules! binop {
    ($tr:ident, $f:ident, $tra:ident, $fa:ident) => {
        impl<V: Copy + $tr<Output = V>> $tr for X2<V> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                X2([self.0[0].$f(o.0[0]), self.0[1].$f(o.0[1])])
            }
        }
        impl<V: Copy + $tr<Output = V>> $tra for X2<V> {
            #[inline(always)]
            fn $fa(&mut self, o: Self) {
                *self = (*self).$f(o);
            }
        }
    };
}
binop!(Add, add, AddAssign, add_assign);
binop!(Sub, sub, SubAssign, sub_assign);
binop!(Mul, mul, MulAssign, mul_assign);
binop!(Div, div, DivAssign, div_assign);
binop!(BitAnd, bitand, BitAndAssign, bitand_assign);
binop!(BitOr, bitor, BitOrAssign, bitor_assign);

impl<V: Copy + BitXor<Output = V>> BitXor for X2<V> {
    type Output = Self;
    #[inline(always)]
    fn bitxor(self, o: Self) -> Self {
        X2([self.0[0] ^ o.0[0], self.0[1] ^ o.0[1]])
    }
}
impl<V: Copy + Neg<Output = V>> Neg for X2<V> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        X2([-self.0[0], -self.0[1]])
    }
}
impl<V: Copy + Not<Output = V>> Not for X2<V> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        X2([!self.0[0], !self.0[1]])
    }
}

macro_rules! x2_lane {
    ($v:ident, $s:ident, $n:literal) => {
        impl Mask for X2<$v> {
            const LANES: usize = 2 * $n;
            #[inline(always)]
            fn splat(value: bool) -> Self {
                let m = <$v as Mask>::splat(value);
                X2([m, m])
            }
            #[inline(always)]
            fn any(self) -> bool {
                (self.0[0] | self.0[1]).any()
            }
            #[inline(always)]
            fn all(self) -> bool {
                (self.0[0] & self.0[1]).all()
            }
            #[inline(always)]
            fn bitmask(self) -> u64 {
                self.0[0].bitmask() | (self.0[1].bitmask() << $n)
            }
        }

        impl Lane for X2<$v> {
            type Scalar = $s;
            type Mask = Self;
            type Counts = [u64; 2 * $n];
            const LANES: usize = 2 * $n;
            const EPSILON: f64 = $s::EPSILON as f64;

            #[inline(always)]
            fn splat(x: $s) -> Self {
                X2([$v::splat(x), $v::splat(x)])
            }
            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                <Self as Lane>::splat(x as $s)
            }
            #[inline]
            fn from_fn(mut f: impl FnMut(usize) -> $s) -> Self {
                let a = <$v as Lane>::from_fn(&mut f);
                let b = <$v as Lane>::from_fn(|i| f(i + $n));
                X2([a, b])
            }
            #[inline]
            fn extract(self, lane: usize) -> $s {
                self.0[lane / $n].to_array()[lane % $n]
            }
            #[inline]
            fn set_lane(&mut self, lane: usize, x: $s) {
                if let Some(v) = self.0.get_mut(lane / $n) {
                    v.set_lane(lane % $n, x);
                }
            }
            /// Four transposes of the halves: quadrant (rows `r`, half `c`) becomes
            /// (rows `c`, half `r`).
            #[inline]
            fn transpose_lanes(block: &mut [Self]) -> bool {
                let Ok(square) = <&mut [Self; 2 * $n]>::try_from(block) else {
                    return false;
                };
                let quadrant = |r: usize, c: usize| -> [$v; $n] {
                    $v::transpose(core::array::from_fn(|i| square[r * $n + i].0[c]))
                };
                let t = [
                    [quadrant(0, 0), quadrant(0, 1)],
                    [quadrant(1, 0), quadrant(1, 1)],
                ];
                for c in 0..2 {
                    for k in 0..$n {
                        square[c * $n + k] = X2([t[0][c][k], t[1][c][k]]);
                    }
                }
                true
            }
            #[inline(always)]
            fn sqrt(self) -> Self {
                X2([self.0[0].sqrt(), self.0[1].sqrt()])
            }
            #[inline(always)]
            fn abs(self) -> Self {
                X2([self.0[0].abs(), self.0[1].abs()])
            }
            #[inline(always)]
            fn min(self, o: Self) -> Self {
                X2([Lane::min(self.0[0], o.0[0]), Lane::min(self.0[1], o.0[1])])
            }
            #[inline(always)]
            fn max(self, o: Self) -> Self {
                X2([Lane::max(self.0[0], o.0[0]), Lane::max(self.0[1], o.0[1])])
            }
            #[inline(always)]
            fn mul_add(self, a: Self, b: Self) -> Self {
                X2([
                    Lane::mul_add(self.0[0], a.0[0], b.0[0]),
                    Lane::mul_add(self.0[1], a.0[1], b.0[1]),
                ])
            }
            #[inline(always)]
            fn round(self) -> Self {
                X2([Lane::round(self.0[0]), Lane::round(self.0[1])])
            }
            #[inline(always)]
            fn floor(self) -> Self {
                X2([Lane::floor(self.0[0]), Lane::floor(self.0[1])])
            }
            #[inline(always)]
            fn simd_eq(self, o: Self) -> Self {
                X2([
                    Lane::simd_eq(self.0[0], o.0[0]),
                    Lane::simd_eq(self.0[1], o.0[1]),
                ])
            }
            #[inline(always)]
            fn simd_ne(self, o: Self) -> Self {
                X2([
                    Lane::simd_ne(self.0[0], o.0[0]),
                    Lane::simd_ne(self.0[1], o.0[1]),
                ])
            }
            #[inline(always)]
            fn simd_lt(self, o: Self) -> Self {
                X2([
                    Lane::simd_lt(self.0[0], o.0[0]),
                    Lane::simd_lt(self.0[1], o.0[1]),
                ])
            }
            #[inline(always)]
            fn simd_le(self, o: Self) -> Self {
                X2([
                    Lane::simd_le(self.0[0], o.0[0]),
                    Lane::simd_le(self.0[1], o.0[1]),
                ])
            }
            #[inline(always)]
            fn simd_gt(self, o: Self) -> Self {
                X2([
                    Lane::simd_gt(self.0[0], o.0[0]),
                    Lane::simd_gt(self.0[1], o.0[1]),
                ])
            }
            #[inline(always)]
            fn simd_ge(self, o: Self) -> Self {
                X2([
                    Lane::simd_ge(self.0[0], o.0[0]),
                    Lane::simd_ge(self.0[1], o.0[1]),
                ])
            }
            #[inline(always)]
            fn is_finite(self) -> Self {
                X2([Lane::is_finite(self.0[0]), Lane::is_finite(self.0[1])])
            }
            #[inline(always)]
            fn is_nan(self) -> Self {
                X2([Lane::is_nan(self.0[0]), Lane::is_nan(self.0[1])])
            }
            #[inline(always)]
            fn select(m: Self, a: Self, b: Self) -> Self {
                X2([
                    <$v as Lane>::select(m.0[0], a.0[0], b.0[0]),
                    <$v as Lane>::select(m.0[1], a.0[1], b.0[1]),
                ])
            }
            #[inline(always)]
            fn sin_cos(self) -> (Self, Self) {
                let (s0, c0) = Lane::sin_cos(self.0[0]);
                let (s1, c1) = Lane::sin_cos(self.0[1]);
                (X2([s0, s1]), X2([c0, c1]))
            }
            #[inline(always)]
            fn atan2(self, x: Self) -> Self {
                X2([
                    Lane::atan2(self.0[0], x.0[0]),
                    Lane::atan2(self.0[1], x.0[1]),
                ])
            }
            #[inline(always)]
            fn atan(self) -> Self {
                X2([Lane::atan(self.0[0]), Lane::atan(self.0[1])])
            }
            #[inline(always)]
            fn asin(self) -> Self {
                X2([Lane::asin(self.0[0]), Lane::asin(self.0[1])])
            }
            #[inline(always)]
            fn acos(self) -> Self {
                X2([Lane::acos(self.0[0]), Lane::acos(self.0[1])])
            }
        }
    };
}

x2_lane!(f32x8, f32, 8);
x2_lane!(f64x4, f64, 4);
