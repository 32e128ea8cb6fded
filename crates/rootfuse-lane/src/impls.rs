//! [`Lane`] and [`Mask`] for the scalars and the `wide` vectors, each written once by macro.

use crate::lane::{Lane, Mask};
use wide::{f32x4, f32x8, f64x2, f64x4};

macro_rules! simd_lane {
    ($t:ident, $s:ident, $n:literal, $bits:ident) => {
        impl Mask for $t {
            const LANES: usize = $n;
            #[inline]
            fn splat(value: bool) -> Self {
                $t::splat($s::from_bits(if value { $bits::MAX } else { 0 }))
            }
            #[inline]
            fn any(self) -> bool {
                $t::any(self)
            }
            #[inline]
            fn all(self) -> bool {
                $t::all(self)
            }
            #[inline]
            fn bitmask(self) -> u64 {
                self.to_bitmask() as u64
            }
        }

        impl Lane for $t {
            type Scalar = $s;
            type Mask = $t;
            type Counts = [u64; $n];
            const LANES: usize = $n;
            const EPSILON: f64 = $s::EPSILON as f64;

            #[inline]
            fn splat(x: $s) -> Self {
                $t::splat(x)
            }
            #[inline]
            fn from_f64(x: f64) -> Self {
                $t::splat(x as $s)
            }
            #[inline]
            fn from_fn(mut f: impl FnMut(usize) -> $s) -> Self {
                $t::new(core::array::from_fn(|i| f(i)))
            }
            #[inline]
            fn extract(self, lane: usize) -> $s {
                self.to_array()[lane]
            }
            #[inline]
            fn set_lane(&mut self, lane: usize, x: $s) {
                if let Some(v) = self.as_mut_array().get_mut(lane) {
                    *v = x;
                }
            }
            #[inline]
            fn transpose_lanes(block: &mut [Self]) -> bool {
                let Ok(square) = <&mut [$t; $n]>::try_from(block) else {
                    return false;
                };
                *square = $t::transpose(*square);
                true
            }
            #[inline]
            fn sqrt(self) -> Self {
                $t::sqrt(self)
            }
            #[inline]
            fn abs(self) -> Self {
                $t::abs(self)
            }
            #[inline]
            fn min(self, other: Self) -> Self {
                $t::simd_lt(self, other).select(self, other)
            }
            #[inline]
            fn max(self, other: Self) -> Self {
                $t::simd_gt(self, other).select(self, other)
            }
            #[inline]
            fn mul_add(self, a: Self, b: Self) -> Self {
                #[cfg(feature = "fast-math")]
                {
                    $t::mul_add(self, a, b)
                }
                #[cfg(not(feature = "fast-math"))]
                {
                    self * a + b
                }
            }
            #[inline]
            fn round(self) -> Self {
                $t::round_ties_even(self)
            }
            #[inline]
            fn floor(self) -> Self {
                $t::floor(self)
            }
            #[inline]
            fn simd_eq(self, other: Self) -> Self {
                $t::simd_eq(self, other)
            }
            #[inline]
            fn simd_ne(self, other: Self) -> Self {
                $t::simd_ne(self, other)
            }
            #[inline]
            fn simd_lt(self, other: Self) -> Self {
                $t::simd_lt(self, other)
            }
            #[inline]
            fn simd_le(self, other: Self) -> Self {
                $t::simd_le(self, other)
            }
            #[inline]
            fn simd_gt(self, other: Self) -> Self {
                $t::simd_gt(self, other)
            }
            #[inline]
            fn simd_ge(self, other: Self) -> Self {
                $t::simd_ge(self, other)
            }
            #[inline]
            fn is_finite(self) -> Self {
                $t::is_finite(self)
            }
            #[inline]
            fn is_nan(self) -> Self {
                $t::is_nan(self)
            }
            #[inline]
            fn select(mask: Self, a: Self, b: Self) -> Self {
                #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
                {
                    <$t as avx::Blend>::blend(mask, a, b)
                }
                #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
                {
                    mask.select(a, b)
                }
            }
            #[inline]
            fn sin_cos(self) -> (Self, Self) {
                $t::sin_cos(self)
            }
            #[inline]
            fn atan2(self, x: Self) -> Self {
                $t::atan2(self, x)
            }
            #[inline]
            fn atan(self) -> Self {
                $t::atan(self)
            }
            #[inline]
            fn asin(self) -> Self {
                $t::asin(self)
            }
            #[inline]
            fn acos(self) -> Self {
                $t::acos(self)
            }
        }
    };
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
macro_rules! avx_blend {
    ($t:ident, $m:ident, $reg:ident, $ps:literal, $f:ident) => {
        /// `mask ? a : b` by the sign bit of each element of `mask`, as one instruction.
        /// Its own function so that the AVX registers are allowed wherever it is
        /// instantiated (a doctest is compiled without the crate's target features).
        #[target_feature(enable = "avx")]
        #[inline]
        fn $f(mask: $m, a: $m, b: $m) -> $m {
            let out: $m;
            // SAFETY: the instruction reads three registers and writes one, nothing else.
            unsafe {
                core::arch::asm!(
                    concat!("vblendv", $ps, " {o}, {b}, {a}, {m}"),
                    o = lateout($reg) out,
                    b = in($reg) b,
                    a = in($reg) a,
                    m = in($reg) mask,
                    options(pure, nomem, nostack, preserves_flags),
                );
            }
            out
        }

        impl Blend for $t {
            #[inline(always)]
            fn blend(mask: Self, a: Self, b: Self) -> Self {
                // SAFETY: this module is compiled only where AVX is enabled for the crate,
                // so the machine running it has AVX; with AVX `wide` keeps the vector as
                // the `__m128`/`__m256` it is (transmute checks the sizes at compile time).
                unsafe {
                    core::mem::transmute::<$m, $t>($f(
                        core::mem::transmute::<$t, $m>(mask),
                        core::mem::transmute::<$t, $m>(a),
                        core::mem::transmute::<$t, $m>(b),
                    ))
                }
            }
        }
    };
}

/// The lane select. Where the compiler sees a plain select whose other side is a load of
/// the place the result is stored to (`x = select(m, y, x)` on a filter's state), LLVM 22
/// folds the three into a masked store (`vmaskmovps`, llvm/llvm-project#145176), which AMD
/// Zen 1–3 execute as a slow microcoded sequence (llvm/llvm-project#213195). The AVX blends
/// below are one instruction the compiler cannot look into, so the state is loaded, blended
/// in registers and stored whole: the flagship's `f32x8` lanes take 24 % less time per update
/// on a Zen 2 (docs/flagship_cost.md). Alone they cost Mahony's lanes 13 % there (the
/// screening, inlined since, recovered it), and where the fold is harmless (Intel, later Zen)
/// they only constrain the compiler: once the toolchain's LLVM has the fix
/// (llvm/llvm-project#214187, which stops the fold on Zen 1–3 and `x86-64-v3`), measure
/// again and drop them. `min`/`max` keep the compiler's select, which becomes one
/// `vminps`/`vmaxps` and does not store back its first operand.
#[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
mod avx {
    use core::arch::x86_64::{__m128, __m128d, __m256, __m256d};
    use wide::{f32x4, f32x8, f64x2, f64x4};

    pub(super) trait Blend: Sized {
        fn blend(mask: Self, a: Self, b: Self) -> Self;
    }

    avx_blend!(f32x4, __m128, xmm_reg, "ps", blendv_ps128);
    avx_blend!(f64x2, __m128d, xmm_reg, "pd", blendv_pd128);
    avx_blend!(f32x8, __m256, ymm_reg, "ps", blendv_ps256);
    avx_blend!(f64x4, __m256d, ymm_reg, "pd", blendv_pd256);
}

simd_lane!(f32x4, f32, 4, u32);
simd_lane!(f32x8, f32, 8, u32);
simd_lane!(f64x2, f64, 2, u64);
simd_lane!(f64x4, f64, 4, u64);

/// Scalars run the functions that have no IEEE definition (rounding to integer, trig) in lane 0
/// of the narrowest `wide` vector (`$v`), so that scalar and lane results come from one
/// implementation.
macro_rules! scalar_lane {
    ($s:ident, $v:ident, $sqrt:path, $fma:path) => {
        impl Lane for $s {
            type Scalar = $s;
            type Mask = bool;
            type Counts = [u64; 1];
            const LANES: usize = 1;
            const EPSILON: f64 = $s::EPSILON as f64;

            #[inline]
            fn splat(x: $s) -> Self {
                x
            }
            #[inline]
            fn from_f64(x: f64) -> Self {
                x as $s
            }
            #[inline]
            fn from_fn(mut f: impl FnMut(usize) -> $s) -> Self {
                f(0)
            }
            #[inline]
            fn extract(self, lane: usize) -> $s {
                assert!(lane == 0, "lane {lane} out of range for a scalar");
                self
            }
            #[inline]
            fn set_lane(&mut self, lane: usize, x: $s) {
                if lane == 0 {
                    *self = x;
                }
            }
            #[inline]
            fn transpose_lanes(block: &mut [Self]) -> bool {
                block.len() == 1
            }
            #[inline]
            fn sqrt(self) -> Self {
                $sqrt(self)
            }
            #[inline]
            fn abs(self) -> Self {
                $s::abs(self)
            }
            #[inline]
            fn min(self, other: Self) -> Self {
                if self < other { self } else { other }
            }
            #[inline]
            fn max(self, other: Self) -> Self {
                if self > other { self } else { other }
            }
            #[inline]
            fn mul_add(self, a: Self, b: Self) -> Self {
                #[cfg(feature = "fast-math")]
                {
                    $fma(self, a, b)
                }
                #[cfg(not(feature = "fast-math"))]
                {
                    self * a + b
                }
            }
            #[inline]
            fn round(self) -> Self {
                $v::splat(self).round_ties_even().to_array()[0]
            }
            #[inline]
            fn floor(self) -> Self {
                $v::splat(self).floor().to_array()[0]
            }
            #[inline]
            fn simd_eq(self, other: Self) -> bool {
                self == other
            }
            #[inline]
            fn simd_ne(self, other: Self) -> bool {
                self != other
            }
            #[inline]
            fn simd_lt(self, other: Self) -> bool {
                self < other
            }
            #[inline]
            fn simd_le(self, other: Self) -> bool {
                self <= other
            }
            #[inline]
            fn simd_gt(self, other: Self) -> bool {
                self > other
            }
            #[inline]
            fn simd_ge(self, other: Self) -> bool {
                self >= other
            }
            #[inline]
            fn is_finite(self) -> bool {
                $s::is_finite(self)
            }
            #[inline]
            fn is_nan(self) -> bool {
                $s::is_nan(self)
            }
            #[inline]
            fn select(mask: bool, a: Self, b: Self) -> Self {
                if mask { a } else { b }
            }
            #[inline]
            fn sin_cos(self) -> (Self, Self) {
                let (s, c) = $v::splat(self).sin_cos();
                (s.to_array()[0], c.to_array()[0])
            }
            #[inline]
            fn atan2(self, x: Self) -> Self {
                $v::splat(self).atan2($v::splat(x)).to_array()[0]
            }
            #[inline]
            fn atan(self) -> Self {
                $v::splat(self).atan().to_array()[0]
            }
            #[inline]
            fn asin(self) -> Self {
                $v::splat(self).asin().to_array()[0]
            }
            #[inline]
            fn acos(self) -> Self {
                $v::splat(self).acos().to_array()[0]
            }
        }
    };
}

#[cfg(feature = "std")]
scalar_lane!(f32, f32x4, f32::sqrt, f32::mul_add);
#[cfg(feature = "std")]
scalar_lane!(f64, f64x2, f64::sqrt, f64::mul_add);
#[cfg(not(feature = "std"))]
scalar_lane!(f32, f32x4, libm::sqrtf, libm::fmaf);
#[cfg(not(feature = "std"))]
scalar_lane!(f64, f64x2, libm::sqrt, libm::fma);
