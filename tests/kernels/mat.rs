//! Small-matrix kernels: closed forms, per-lane Cholesky failure, lanes equal scalars.
use crate::common::same_bits;
use proptest::prelude::*;
use rootfuse_lane::{Lane, Mask, Mat};

fn spd(a: [[f64; 7]; 7], shift: f64) -> Mat<f64, 7, 7> {
    let a = Mat::from_rows(a);
    a * a.transpose() + Mat::<f64, 7, 7>::identity().scale(shift)
}

#[test]
fn cholesky_closed_form() {
    // [[4, 2], [2, 3]] = L·Lᵀ with L = [[2, 0], [1, √2]].
    let (l, ok) = Mat::<f64, 2, 2>::from_rows([[4.0, 2.0], [2.0, 3.0]]).cholesky();
    assert!(ok);
    assert_eq!(l.m, [[2.0, 0.0], [1.0, 2f64.sqrt()]]);
    // Indefinite and NaN inputs are reported, and the factor stays finite.
    let (l, ok) = Mat::<f64, 2, 2>::from_rows([[1.0, 2.0], [2.0, 1.0]]).cholesky();
    assert!(!ok && l.is_finite());
    let (_, ok) = Mat::<f32, 2, 2>::from_rows([[f32::NAN, 0.0], [0.0, 1.0]]).cholesky();
    assert!(!ok);
}

#[test]
fn cholesky_failure_is_per_lane() {
    type V = wide::f32x8;
    // Lane 3 is indefinite, lane 5 holds NaN, the rest are SPD: only 3 and 5 fail.
    let m = Mat::<V, 3, 3>::from_fn(|i, j| {
        V::from_fn(|lane| {
            let base = if i == j { 2.0 } else { 0.5 };
            match lane {
                3 if i != j => 5.0,
                5 if i == 1 && j == 1 => f32::NAN,
                _ => base,
            }
        })
    });
    let (l, ok) = m.cholesky();
    assert_eq!(ok.bitmask(), 0b1101_0111);
    let (l0, ok0) = Mat::<f32, 3, 3>::from_fn(|i, j| m.m[i][j].extract(0)).cholesky();
    assert!(ok0);
    for i in 0..3 {
        for j in 0..3 {
            assert_eq!(l.m[i][j].extract(7).to_bits(), l0.m[i][j].to_bits());
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn factor_and_solve(a in prop::array::uniform7(prop::array::uniform7(-3.0..3.0f64)), b in prop::array::uniform7(-10.0..10.0f64)) {
        let p = spd(a, 0.5);
        let (l, ok) = p.cholesky();
        prop_assert!(ok);
        prop_assert!(((l * l.transpose()) - p).max_abs() < 1e-12 * p.max_abs().max(1.0));
        let b = Mat::<f64, 7, 1>::from_column(b);
        let x = l.cholesky_solve(&b);
        prop_assert!(((p * x) - b).max_abs() < 1e-9);
        let y = l.solve_lower(&b);
        prop_assert!(((l * y) - b).max_abs() < 1e-10);
        let u = l.transpose();
        prop_assert!(((u * u.solve_upper(&b)) - b).max_abs() < 1e-9);
        let mut r = p;
        r.rank_one_update(2.0, &b);
        prop_assert!((r - (p + b * b.transpose().scale(2.0))).max_abs() < 1e-12 * r.max_abs());
        let s = (p + Mat::from_fn(|i, j| (i as f64) - (j as f64))).symmetrize();
        prop_assert!((s - s.transpose()).max_abs() == 0.0);
        prop_assert!((p.congruence(&p) - p * p * p).max_abs() < 1e-10 * p.max_abs().powi(3));
    }

    #[test]
    fn lanes_equal_scalar_runs(a in prop::array::uniform8(prop::array::uniform7(prop::array::uniform7(-3.0..3.0f64))),
                               b in prop::array::uniform7(-10.0..10.0f32)) {
        type V = wide::f32x8;
        let p = Mat::<V, 7, 7>::from_fn(|i, j| V::from_fn(|k| spd(a[k], 0.5).m[i][j] as f32));
        let bv = Mat::<V, 7, 1>::from_fn(|i, _| V::splat(b[i]));
        let (l, _) = p.cholesky();
        let x = l.cholesky_solve(&bv);
        let q = p.congruence(&l);
        for k in 0..8 {
            let ps = Mat::<f32, 7, 7>::from_fn(|i, j| p.m[i][j].extract(k));
            let (ls, _) = ps.cholesky();
            let xs = ls.cholesky_solve(&Mat::from_column(b));
            let qs = ps.congruence(&ls);
            for i in 0..7 {
                prop_assert!(same_bits(x.m[i][0].extract(k), xs.m[i][0]));
                for j in 0..7 {
                    prop_assert!(same_bits(l.m[i][j].extract(k), ls.m[i][j]));
                    prop_assert!(same_bits(q.m[i][j].extract(k), qs.m[i][j]));
                }
            }
        }
    }
}

proptest! {
    /// `symmetrize` rounds exactly like `(a + b)/2` wherever that does not overflow or reach
    /// subnormals, and stays finite where it would overflow.
    #[test]
    fn symmetrize_is_the_rounded_average(
        entries in prop::array::uniform9(-1e300f64..1e300),
        exponent in -100i32..100,
    ) {
        let scale = 2f64.powi(exponent);
        let a = Mat::<f64, 3, 3>::from_fn(|i, j| entries[3 * i + j] * scale * 1e-8);
        let s = a.symmetrize();
        for i in 0..3 {
            for j in 0..3 {
                let plain = (a.m[i][j] + a.m[j][i]) * 0.5;
                if plain.is_finite() && plain.abs() > 1e-290 {
                    prop_assert_eq!(s.m[i][j].to_bits(), plain.to_bits());
                }
            }
        }
    }
}

#[test]
fn symmetrize_does_not_overflow_near_the_largest_float() {
    let big = f64::MAX;
    let a = Mat::<f64, 2, 2>::from_rows([[big, big], [big * 0.75, big]]);
    let s = a.symmetrize();
    assert_eq!(s.m[0][0], big);
    assert_eq!(s.m[0][1], big * 0.875);
    assert_eq!(s.m[1][0], s.m[0][1]);
}
