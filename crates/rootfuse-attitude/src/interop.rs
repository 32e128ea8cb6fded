//! Conversions to and from `nalgebra` (scalar `f32`/`f64` only).
//!
//! `nalgebra::Quaternion::new(w, i, j, k)` is also Hamilton with the same meaning of a rotation,
//! so the conversions copy components; only the storage order differs (`[i, j, k, w]` there).

use crate::{Quat, Vec3};
use nalgebra::{Quaternion, RealField, UnitQuaternion, Vector3};
use rootfuse_lane::Lane;

impl<T: Lane + RealField> From<UnitQuaternion<T>> for Quat<T> {
    fn from(q: UnitQuaternion<T>) -> Self {
        let q = q.into_inner();
        Quat::new(q.w, q.i, q.j, q.k)
    }
}
impl<T: Lane + RealField> From<Quat<T>> for UnitQuaternion<T> {
    /// Normalises (a unit `Quat` stays the same up to rounding).
    fn from(q: Quat<T>) -> Self {
        UnitQuaternion::from_quaternion(Quaternion::new(q.w, q.x, q.y, q.z))
    }
}
impl<T: Lane + RealField> From<Vector3<T>> for Vec3<T> {
    fn from(v: Vector3<T>) -> Self {
        Vec3::new(v.x, v.y, v.z)
    }
}
impl<T: Lane + RealField> From<Vec3<T>> for Vector3<T> {
    fn from(v: Vec3<T>) -> Self {
        Vector3::new(v.x, v.y, v.z)
    }
}
