//! `Lane::transpose_lanes` against its definition, on every lane type.

use rootfuse_lane::wide::{f32x4, f32x8, f64x2, f64x4};
use rootfuse_lane::{Lane, X2};

/// Lane `j` of vector `i` is `100 i + j` before; lane `i` of vector `j` must be it after.
fn transposes<L: Lane>() {
    let n = L::LANES;
    let value = |i: usize, j: usize| <L::Scalar as Lane>::from_f64((100 * i + j) as f64);
    let mut block: Vec<L> = (0..n).map(|i| L::from_fn(|j| value(i, j))).collect();
    assert!(L::transpose_lanes(&mut block));
    for (j, v) in block.iter().enumerate() {
        for i in 0..n {
            let got: f64 = v.extract(i).into();
            assert_eq!(got, value(i, j).into(), "{n} lanes: vector {j}, lane {i}");
        }
    }
}

#[test]
fn every_lane_type_transposes() {
    transposes::<f32>();
    transposes::<f64>();
    transposes::<f32x4>();
    transposes::<f32x8>();
    transposes::<f64x2>();
    transposes::<f64x4>();
    transposes::<X2<f32x8>>();
    transposes::<X2<f64x4>>();
}

#[test]
fn a_block_of_the_wrong_size_is_refused() {
    let mut block: Vec<f32x8> = (0..7).map(|i| f32x8::splat(i as f32)).collect();
    let before = block.clone();
    assert!(!f32x8::transpose_lanes(&mut block));
    assert!(
        block
            .iter()
            .zip(&before)
            .all(|(a, b)| a.to_array() == b.to_array())
    );
    assert!(!f32::transpose_lanes(&mut []));
}
