//! The `nalgebra` feature's conversions (on in the facade): the same components both ways.
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use rootfuse_attitude::{Quat, Vec3};

#[test]
fn conversions_keep_the_components() {
    let q = Quat::new(0.5f64, -0.5, 0.5, 0.5);
    let nq: UnitQuaternion<f64> = q.into();
    assert_eq!((nq.w, nq.i, nq.j, nq.k), (0.5, -0.5, 0.5, 0.5));
    let back: Quat<f64> =
        UnitQuaternion::new_unchecked(Quaternion::new(0.5, -0.5, 0.5, 0.5)).into();
    assert_eq!(back, q);
    let v = Vec3::new(1.0f64, -2.0, 3.0);
    let nv: Vector3<f64> = v.into();
    assert_eq!(nv, Vector3::new(1.0, -2.0, 3.0));
    assert_eq!(Vec3::from(nv), v);
}
