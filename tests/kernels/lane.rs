//! Every `Lane` operation of every SIMD type equals the scalar operation lane by lane, bit for
//! bit (NaN payloads aside), with NaN, ±∞, ±0, subnormals and huge values among the inputs.
use crate::common::{SpecialFloat, same_bits};
use proptest::prelude::*;
use rootfuse_lane::{Lane, Mask};

fn check_unary<V: Lane, const N: usize>(
    a: [V::Scalar; N],
    vop: impl Fn(V) -> V,
    sop: impl Fn(V::Scalar) -> V::Scalar,
) -> Result<(), TestCaseError>
where
    V::Scalar: SpecialFloat,
{
    let v = vop(V::from_fn(|i| a[i]));
    for i in 0..N {
        let (got, want) = (v.extract(i), sop(a[i]));
        prop_assert!(
            same_bits(got, want),
            "lane {i}: input {:?} -> {got:?} vs {want:?}",
            a[i]
        );
    }
    Ok(())
}

fn check_binary<V: Lane, const N: usize>(
    a: [V::Scalar; N],
    b: [V::Scalar; N],
    vop: impl Fn(V, V) -> V,
    sop: impl Fn(V::Scalar, V::Scalar) -> V::Scalar,
) -> Result<(), TestCaseError>
where
    V::Scalar: SpecialFloat,
{
    let v = vop(V::from_fn(|i| a[i]), V::from_fn(|i| b[i]));
    for i in 0..N {
        let (got, want) = (v.extract(i), sop(a[i], b[i]));
        prop_assert!(
            same_bits(got, want),
            "lane {i}: inputs {:?}, {:?} -> {got:?} vs {want:?}",
            a[i],
            b[i]
        );
    }
    Ok(())
}

fn check_compare<V: Lane, const N: usize>(
    a: [V::Scalar; N],
    b: [V::Scalar; N],
    vop: impl Fn(V, V) -> V::Mask,
    sop: impl Fn(V::Scalar, V::Scalar) -> bool,
) -> Result<(), TestCaseError> {
    let m = vop(V::from_fn(|i| a[i]), V::from_fn(|i| b[i]));
    for i in 0..N {
        prop_assert_eq!(
            m.test(i),
            sop(a[i], b[i]),
            "lane {} of {:?} vs {:?}",
            i,
            a[i],
            b[i]
        );
    }
    Ok(())
}

macro_rules! lane_suite {
    ($name:ident, $v:ty, $s:ty, $n:literal) => {
        mod $name {
            use super::*;
            type V = $v;
            type S = $s;

            fn arr() -> impl Strategy<Value = [S; $n]> {
                prop::array::uniform::<_, $n>(S::special())
            }

            proptest! {
                #![proptest_config(ProptestConfig::with_cases(256))]

                #[test]
                fn arithmetic(a in arr(), b in arr(), c in arr()) {
                    check_binary::<V, $n>(a, b, |x, y| x + y, |x, y| x + y)?;
                    check_binary::<V, $n>(a, b, |x, y| x - y, |x, y| x - y)?;
                    check_binary::<V, $n>(a, b, |x, y| x * y, |x, y| x * y)?;
                    check_binary::<V, $n>(a, b, |x, y| x / y, |x, y| x / y)?;
                    check_binary::<V, $n>(a, b, |mut x, y| { x += y; x }, |x, y| x + y)?;
                    check_binary::<V, $n>(a, b, |mut x, y| { x -= y; x }, |x, y| x - y)?;
                    check_binary::<V, $n>(a, b, |mut x, y| { x *= y; x }, |x, y| x * y)?;
                    check_binary::<V, $n>(a, b, |mut x, y| { x /= y; x }, |x, y| x / y)?;
                    check_unary::<V, $n>(a, |x| -x, |x| -x)?;
                    let cv = V::from_fn(|i| c[i]);
                    let fused = Lane::mul_add(V::from_fn(|i| a[i]), V::from_fn(|i| b[i]), cv);
                    for i in 0..$n {
                        prop_assert!(same_bits(fused.extract(i), Lane::mul_add(a[i], b[i], c[i])));
                    }
                }

                #[test]
                fn elementary(a in arr(), b in arr(), c in arr()) {
                    check_unary::<V, $n>(a, |x| Lane::sqrt(x), |x| Lane::sqrt(x))?;
                    check_unary::<V, $n>(a, |x| Lane::abs(x), |x| Lane::abs(x))?;
                    check_unary::<V, $n>(a, |x| Lane::round(x), |x| Lane::round(x))?;
                    check_unary::<V, $n>(a, |x| Lane::floor(x), |x| Lane::floor(x))?;
                    check_unary::<V, $n>(a, |x| Lane::recip(x), |x| Lane::recip(x))?;
                    check_unary::<V, $n>(a, |x| Lane::sq(x), |x| Lane::sq(x))?;
                    check_unary::<V, $n>(a, |x| Lane::wrap_pi(x), |x| Lane::wrap_pi(x))?;
                    check_binary::<V, $n>(a, b, |x, y| Lane::min(x, y), |x, y| Lane::min(x, y))?;
                    check_binary::<V, $n>(a, b, |x, y| Lane::max(x, y), |x, y| Lane::max(x, y))?;
                    let (lo, hi) = (V::from_fn(|i| b[i]), V::from_fn(|i| c[i]));
                    let cl = Lane::clamp(V::from_fn(|i| a[i]), lo, hi);
                    for i in 0..$n {
                        prop_assert!(same_bits(cl.extract(i), Lane::clamp(a[i], b[i], c[i])));
                    }
                }

                #[test]
                fn trigonometry(a in arr(), b in arr(), u in prop::array::uniform::<_, $n>(S::unit())) {
                    check_unary::<V, $n>(a, |x| Lane::sin_cos(x).0, |x| Lane::sin_cos(x).0)?;
                    check_unary::<V, $n>(a, |x| Lane::sin_cos(x).1, |x| Lane::sin_cos(x).1)?;
                    check_unary::<V, $n>(a, |x| Lane::sin(x), |x| Lane::sin(x))?;
                    check_unary::<V, $n>(a, |x| Lane::cos(x), |x| Lane::cos(x))?;
                    check_unary::<V, $n>(a, |x| Lane::atan(x), |x| Lane::atan(x))?;
                    check_binary::<V, $n>(a, b, |x, y| Lane::atan2(x, y), |x, y| Lane::atan2(x, y))?;
                    check_unary::<V, $n>(u, |x| Lane::asin(x), |x| Lane::asin(x))?;
                    check_unary::<V, $n>(u, |x| Lane::acos(x), |x| Lane::acos(x))?;
                    check_unary::<V, $n>(a, |x| Lane::asin(x), |x| Lane::asin(x))?;
                    check_unary::<V, $n>(a, |x| Lane::acos(x), |x| Lane::acos(x))?;
                }

                #[test]
                fn comparisons_and_masks(a in arr(), b in arr(), c in arr()) {
                    check_compare::<V, $n>(a, b, |x, y| Lane::simd_eq(x, y), |x, y| x == y)?;
                    check_compare::<V, $n>(a, b, |x, y| Lane::simd_ne(x, y), |x, y| x != y)?;
                    check_compare::<V, $n>(a, b, |x, y| Lane::simd_lt(x, y), |x, y| x < y)?;
                    check_compare::<V, $n>(a, b, |x, y| Lane::simd_le(x, y), |x, y| x <= y)?;
                    check_compare::<V, $n>(a, b, |x, y| Lane::simd_gt(x, y), |x, y| x > y)?;
                    check_compare::<V, $n>(a, b, |x, y| Lane::simd_ge(x, y), |x, y| x >= y)?;
                    check_compare::<V, $n>(a, b, |x, _| Lane::is_finite(x), |x, _| x.is_finite())?;
                    check_compare::<V, $n>(a, b, |x, _| Lane::is_nan(x), |x, _| x.is_nan())?;
                    // Mask algebra and select, per lane.
                    let (va, vb, vc) = (V::from_fn(|i| a[i]), V::from_fn(|i| b[i]), V::from_fn(|i| c[i]));
                    let m1 = Lane::simd_lt(va, vb);
                    let m2 = Lane::is_finite(vc);
                    let combos = [(m1 & m2, 0), (m1 | m2, 1), (m1 ^ m2, 2), (!m1, 3)];
                    for (m, op) in combos {
                        for i in 0..$n {
                            let (x, y) = (a[i] < b[i], c[i].is_finite());
                            let want = match op { 0 => x & y, 1 => x | y, 2 => x ^ y, _ => !x };
                            prop_assert_eq!(m.test(i), want);
                        }
                    }
                    let sel = V::select(m1, va, vc);
                    let mut bits = 0u64;
                    for i in 0..$n {
                        let want = if a[i] < b[i] { a[i] } else { c[i] };
                        prop_assert!(same_bits(sel.extract(i), want));
                        bits |= ((a[i] < b[i]) as u64) << i;
                    }
                    prop_assert_eq!(m1.bitmask(), bits);
                    prop_assert_eq!(m1.any(), bits != 0);
                    prop_assert_eq!(m1.all(), bits == (1u64 << $n) - 1);
                    prop_assert_eq!(m1.none(), bits == 0);
                    // Counters add one exactly in the masked lanes.
                    let mut counts = <V as Lane>::Counts::default();
                    V::count(&mut counts, m1);
                    V::count(&mut counts, m1);
                    for i in 0..$n {
                        prop_assert_eq!(counts.as_ref()[i], 2 * ((bits >> i) & 1));
                    }
                }

                #[test]
                fn construction(a in arr(), x in -1e300f64..1e300) {
                    let v = V::from_fn(|i| a[i]);
                    for i in 0..$n {
                        prop_assert!(same_bits(v.extract(i), a[i]));
                        prop_assert!(same_bits(V::splat(a[i]).extract(0), a[i]));
                        prop_assert!(same_bits(V::from_f64(x).extract(i), S::from_f64(x)));
                    }
                    prop_assert!(<<V as Lane>::Mask as Mask>::splat(true).all());
                    prop_assert!(<<V as Lane>::Mask as Mask>::splat(false).none());
                }
            }
        }
    };
}

lane_suite!(f32x4_vs_f32, wide::f32x4, f32, 4);
lane_suite!(f32x8_vs_f32, wide::f32x8, f32, 8);
lane_suite!(f64x2_vs_f64, wide::f64x2, f64, 2);
lane_suite!(f64x4_vs_f64, wide::f64x4, f64, 4);

/// The shared trig implementation is accurate: compared with `std` (correctly rounded or
/// nearly so) on the ranges the filters use. Stated bounds: 4 ulp f32 and 8 ulp (f64) absolute
/// error in units of the result's magnitude-1 ulp.
#[test]
fn trig_accuracy_against_std() {
    let mut worst32 = 0.0f64;
    let mut worst64 = 0.0f64;
    for k in -20000..=20000 {
        let x = k as f64 * 1e-3; // [-20, 20] rad
        let u = k as f64 / 20000.0; // [-1, 1]
        let e32 = [
            (x as f32).sin() as f64 - Lane::sin(x as f32) as f64,
            (x as f32).cos() as f64 - Lane::cos(x as f32) as f64,
            (x as f32).atan() as f64 - Lane::atan(x as f32) as f64,
            (x as f32).atan2(0.7) as f64 - Lane::atan2(x as f32, 0.7) as f64,
            (u as f32).asin() as f64 - Lane::asin(u as f32) as f64,
            (u as f32).acos() as f64 - Lane::acos(u as f32) as f64,
        ];
        let e64 = [
            x.sin() - Lane::sin(x),
            x.cos() - Lane::cos(x),
            x.atan() - Lane::atan(x),
            x.atan2(-0.3) - Lane::atan2(x, -0.3),
            u.asin() - Lane::asin(u),
            u.acos() - Lane::acos(u),
        ];
        for e in e32 {
            worst32 = worst32.max(e.abs() / f32::EPSILON as f64);
        }
        for e in e64 {
            worst64 = worst64.max(e.abs() / f64::EPSILON);
        }
    }
    assert!(worst32 <= 4.0, "f32 trig error {worst32} eps");
    assert!(worst64 <= 8.0, "f64 trig error {worst64} eps");
}
