//! Quaternion kernels against closed forms, round trips, nalgebra as an independent
//! reference, and lanes equal to scalars bit for bit.
use crate::common::same_bits;
use nalgebra::{Quaternion, UnitQuaternion, Vector3};
use proptest::prelude::*;
use rootfuse_attitude::{Lane, Quat, Vec3};
use std::f64::consts::{FRAC_PI_2, PI};

fn unit_quat() -> impl Strategy<Value = Quat<f64>> {
    (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64)
        .prop_filter("non-zero", |(w, x, y, z)| {
            w * w + x * x + y * y + z * z > 1e-3
        })
        .prop_map(|(w, x, y, z)| Quat::new(w, x, y, z).normalize())
}
fn vec3(range: f64) -> impl Strategy<Value = Vec3<f64>> {
    (-range..range, -range..range, -range..range).prop_map(|(x, y, z)| Vec3::new(x, y, z))
}
/// nalgebra's quaternion of the same rotation, built from the components (nalgebra's
/// `Quaternion::new` is `w, i, j, k`, Hamilton), independently of the crate's conversions.
fn to_nalgebra(q: Quat<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::new_unchecked(Quaternion::new(q.w, q.x, q.y, q.z))
}
fn from_nalgebra(q: UnitQuaternion<f64>) -> Quat<f64> {
    Quat::new(q.w, q.i, q.j, q.k)
}
fn to_f32(q: Quat<f64>) -> Quat<f32> {
    Quat::new(q.w as f32, q.x as f32, q.y as f32, q.z as f32)
}

/// Closed form: a constant rate about a fixed axis, integrated by the exponential map at
/// several step sizes, equals the rotation by the total angle. The map is exact, so only
/// rounding remains: stated bound `steps · 4 · eps` rad (plus 2 eps).
#[test]
fn exponential_map_integration_matches_closed_form() {
    let axis = Vec3::new(1.0, -2.0, 0.5).try_normalize().0;
    let rate = 3.7; // rad/s
    let duration = 2.0; // s
    let exact = Quat::<f64>::from_axis_angle(axis, rate * duration);
    for steps in [1usize, 10, 100, 1000, 10_000] {
        let dt = duration / steps as f64;
        let mut q64 = Quat::<f64>::identity();
        let mut q32 = Quat::<f32>::identity();
        let w64 = axis * rate;
        let w32 = Vec3::new(w64.x as f32, w64.y as f32, w64.z as f32);
        for _ in 0..steps {
            q64 = (q64 * Quat::from_rotation_vector(w64 * dt)).normalize();
            q32 = (q32 * Quat::from_rotation_vector(w32 * dt as f32)).normalize();
        }
        let e64 = q64.angle_to(exact);
        let e32 = to_f32(exact).angle_to(q32) as f64;
        let bound = |eps: f64| (steps as f64 * 4.0 + 2.0) * eps;
        assert!(
            e64 <= bound(f64::EPSILON),
            "f64, {steps} steps: {e64:e} rad"
        );
        // f32 also pays for rounding ω and dt themselves (a relative 1e-7 of 7.4 rad).
        assert!(
            e32 <= bound(f32::EPSILON as f64) + 2e-6,
            "f32, {steps} steps: {e32:e} rad"
        );
    }
}

#[test]
fn closed_form_rotations() {
    let q = Quat::<f64>::from_axis_angle(Vec3::new(0.0, 0.0, 1.0), FRAC_PI_2);
    // 90° about up turns east into north (ENU) and the matrix agrees.
    let v = q.rotate(Vec3::new(1.0, 0.0, 0.0));
    assert!((v - Vec3::new(0.0, 1.0, 0.0)).max_abs() < 1e-15);
    let m = q.to_rotation_matrix();
    assert!((m.m[1][0] - 1.0).abs() < 1e-15 && m.m[0][1] + 1.0 < 1e-15);
    // Euler yaw is the heading; pitch tips x (east) toward down.
    let (yaw, pitch, roll) = q.to_euler_zyx();
    assert!((yaw - FRAC_PI_2).abs() < 1e-15 && pitch.abs() < 1e-15 && roll.abs() < 1e-15);
    let p = Quat::<f64>::from_euler_zyx(0.0, 0.3, 0.0);
    let v = p.rotate(Vec3::new(1.0, 0.0, 0.0));
    assert!((v - Vec3::new(0.3f64.cos(), 0.0, -0.3f64.sin())).max_abs() < 1e-15);
    // exp of a pure quaternion, and its series branch.
    let e = Quat::<f64>::exp(Vec3::new(0.0, 0.0, 1e-9));
    assert!((e.w - 1.0).abs() < 1e-16 && (e.z - 1e-9).abs() < 1e-24);
    let e = Quat::<f32>::exp(Vec3::new(0.0, 0.0, 0.0));
    assert_eq!(e.to_array(), [1.0, 0.0, 0.0, 0.0]);
    // Heading split of a pure heading and a pure tilt.
    let (h, incl) = Quat::<f64>::from_heading(2.5).heading_inclination();
    assert!((h - 2.5).abs() < 1e-14 && incl.angle_to(Quat::identity()) < 1e-14);
    let tilt = Quat::<f64>::from_axis_angle(Vec3::new(0.6, 0.8, 0.0), 0.4);
    let (h, incl) = tilt.heading_inclination();
    assert!(h.abs() < 1e-15 && incl.angle_to(tilt) < 1e-15);
    // Slerp: endpoints and the midpoint angle.
    let a = Quat::<f64>::from_axis_angle(Vec3::new(0.0, 1.0, 0.0), 0.2);
    let b = Quat::<f64>::from_axis_angle(Vec3::new(0.0, 1.0, 0.0), 1.4);
    assert!(a.slerp(b, 0.0).angle_to(a) < 1e-14 && a.slerp(-b, 1.0).angle_to(b) < 1e-14);
    let mid = a.slerp(b, 0.5);
    assert!((mid.angle_to(a) - 0.6).abs() < 1e-14 && (mid.angle_to(b) - 0.6).abs() < 1e-14);
}

#[test]
fn degenerate_inputs_stay_finite() {
    for bad in [
        Quat::new(0.0, 0.0, 0.0, 0.0),
        Quat::new(f32::NAN, 0.0, 0.0, 0.0),
        Quat::new(1e20, 1e20, 1e20, 1e20),
    ] {
        let (q, ok) = bad.try_normalize();
        assert!(!ok);
        assert_eq!(q.to_array(), [1.0, 0.0, 0.0, 0.0]);
    }
    let (v, ok) = Vec3::<f32>::new(1e20, 1e20, 1e20).try_normalize();
    assert!(!ok && v.to_array() == [0.0; 3]);
    // Heading is undefined at 180° inclination: reported as 0, inclination kept.
    let flip = Quat::<f64>::from_axis_angle(Vec3::new(1.0, 0.0, 0.0), PI);
    let (h, incl) = flip.heading_inclination();
    assert_eq!(h, 0.0);
    assert!(incl.angle_to(flip) < 1e-15);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// nalgebra is an independent implementation of the same convention.
    #[test]
    fn agrees_with_nalgebra(q in unit_quat(), v in vec3(10.0), e in (-PI..PI, -1.5..1.5f64, -PI..PI)) {
        let nq = to_nalgebra(q);
        let nv: Vector3<f64> = nq * Vector3::new(v.x, v.y, v.z);
        prop_assert!((Vec3::new(nv.x, nv.y, nv.z) - q.rotate(v)).max_abs() < 1e-13);
        prop_assert!((q.rotate_inverse(q.rotate(v)) - v).max_abs() < 1e-13);
        prop_assert!(from_nalgebra(nq).angle_to(q) < 4.0 * f64::EPSILON);
        let (yaw, pitch, roll) = e;
        let ne = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
        prop_assert!(from_nalgebra(ne).angle_to(Quat::from_euler_zyx(yaw, pitch, roll)) < 1e-14);
        let m = q.to_rotation_matrix();
        let nm = nq.to_rotation_matrix();
        for i in 0..3 { for j in 0..3 { prop_assert!((m.m[i][j] - nm[(i, j)]).abs() < 1e-14); } }
        let mut a = [0.0; 3];
        for (k, x) in a.iter_mut().enumerate() { *x = v.to_array()[k] * 0.1; }
        let rv = Vec3::from_array(a);
        let nr = UnitQuaternion::from_scaled_axis(Vector3::new(rv.x, rv.y, rv.z));
        prop_assert!(from_nalgebra(nr).angle_to(Quat::from_rotation_vector(rv)) < 1e-14);
    }

    /// `renormalize` is `normalize` to rounding on products of unit quaternions, the only
    /// inputs it is for, in f64 and f32 (chained products too: the error does not grow).
    #[test]
    fn renormalize_is_normalize_on_products(a in unit_quat(), b in unit_quat()) {
        let p = a * b;
        let d = p.renormalize().to_array().iter().zip(p.normalize().to_array())
            .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
        prop_assert!(d <= 4.0 * f64::EPSILON, "f64: {d:e}");
        let (a32, b32) = (to_f32(a), to_f32(b));
        let mut q = a32;
        for _ in 0..1000 {
            q = (q * b32).renormalize();
        }
        let n = q.norm_squared();
        prop_assert!((n - 1.0).abs() <= 4.0 * f32::EPSILON, "f32 after 1000 products: |q|² = {n}");
        let d32 = (a32 * b32).renormalize().to_array().iter().zip((a32 * b32).normalize().to_array())
            .fold(0.0f32, |m, (x, y)| m.max((x - y).abs()));
        prop_assert!(d32 <= 4.0 * f32::EPSILON, "f32: {d32:e}");
    }

    /// Matrix ↔ quaternion ↔ Euler round trips, including near 180° and near gimbal lock.
    #[test]
    fn round_trips(q in unit_quat(), axis in vec3(1.0), delta in prop::sample::select(vec![0.0, 1e-12, 1e-8, 1e-5, 1e-3, 0.1]),
                   yaw in -PI..PI, roll in -PI..PI, sign in prop::bool::ANY) {
        prop_assume!(axis.norm() > 1e-3);
        let axis = axis.try_normalize().0;
        let near_pi = Quat::<f64>::from_axis_angle(axis, PI - delta);
        let pitch = if sign { FRAC_PI_2 - delta } else { -FRAC_PI_2 + delta };
        let near_lock = Quat::<f64>::from_euler_zyx(yaw, pitch, roll);
        for q in [q, near_pi, near_lock] {
            let via_matrix = Quat::from_rotation_matrix(&q.to_rotation_matrix());
            prop_assert!(via_matrix.angle_to(q) < 1e-14, "matrix round trip {:e}", via_matrix.angle_to(q));
            prop_assert!(via_matrix.w >= 0.0);
            let (y, p, r) = q.to_euler_zyx();
            let via_euler = Quat::from_euler_zyx(y, p, r);
            // Near gimbal lock the angles are ill-conditioned: the rotation is what must agree.
            prop_assert!(via_euler.angle_to(q) < 5e-8, "euler round trip {:e}", via_euler.angle_to(q));
            let via_log = Quat::from_rotation_vector(q.to_rotation_vector());
            prop_assert!(via_log.angle_to(q) < 1e-14);
            let (h, incl) = q.heading_inclination();
            prop_assert!(incl.z == 0.0);
            prop_assert!((Quat::from_heading(h) * incl).angle_to(q) < 1e-14);
            // The same in f32, with a bound scaled to its epsilon.
            let q32 = to_f32(q);
            let m32 = Quat::from_rotation_matrix(&q32.to_rotation_matrix());
            prop_assert!(m32.angle_to(q32) < 2e-6, "f32 matrix round trip {:e}", m32.angle_to(q32));
            let (y, p, r) = q32.to_euler_zyx();
            let e32 = Quat::from_euler_zyx(y, p, r).angle_to(q32);
            prop_assert!(e32 < 1e-3, "f32 euler round trip {e32:e}");
        }
    }

    /// Below `|v| = 1/4` the exponential is a series: it agrees with `[cos a, sin a·v/a]`
    /// (std's trigonometry in f64) to a few ulps on both sides of the switch, in f64 and f32.
    #[test]
    fn exponential_series_matches_trigonometry(
        v in vec3(1.0),
        a in prop::sample::select(vec![1e-9, 1e-4, 0.01, 0.1, 0.2, 0.2499, 0.2501, 0.5, 2.0]),
    ) {
        let n = v.norm();
        prop_assume!(n > 1e-3);
        let v = v * (a / n);
        let expected = [a.cos(), v.x * a.sin() / a, v.y * a.sin() / a, v.z * a.sin() / a];
        let got = Quat::<f64>::exp(v).to_array();
        let got32 = Quat::<f32>::exp(Vec3::new(v.x as f32, v.y as f32, v.z as f32)).to_array();
        for k in 0..4 {
            prop_assert!((got[k] - expected[k]).abs() <= 4.0 * f64::EPSILON, "f64 {k}: {} vs {}", got[k], expected[k]);
            prop_assert!((got32[k] as f64 - expected[k]).abs() <= 4.0 * f32::EPSILON as f64, "f32 {k}");
        }
    }

    /// The kernels instantiated with `f32x8` (and `f64x4`) equal 8 (4) scalar runs bit for bit.
    #[test]
    fn lanes_equal_scalar_runs(qs in prop::array::uniform8(unit_quat()), ps in prop::array::uniform8(unit_quat()),
                               vs in prop::array::uniform8(vec3(5.0)), t in 0.0..1.0f64) {
        type V = wide::f32x8;
        let q = Quat::<V>::from_lanes(|i| to_f32(qs[i]));
        let p = Quat::<V>::from_lanes(|i| to_f32(ps[i]));
        let v = Vec3::<V>::from_lanes(|i| Vec3::new(vs[i].x as f32, vs[i].y as f32, vs[i].z as f32));
        let tv = V::splat(t as f32);
        let lane_quats = [q * p, q.conj(), q.normalize(), Quat::from_rotation_vector(v), Quat::exp(v), Quat::exp(v * V::splat(0.04)),
            Quat::from_rotation_matrix(&q.to_rotation_matrix()), q.slerp(p, tv), q.nlerp(p, tv), p.align_to(q),
            q.heading_inclination().1];
        let lane_vecs = [q.rotate(v), q.rotate_inverse(v), q.log(), q.to_rotation_vector()];
        let (ly, lp, lr) = q.to_euler_zyx();
        let le = Quat::from_euler_zyx(v.x, v.y, v.z);
        for i in 0..8 {
            let (qi, pi, vi, ti) = (q.lane(i), p.lane(i), v.lane(i), t as f32);
            let scalar_quats = [qi * pi, qi.conj(), qi.normalize(), Quat::from_rotation_vector(vi), Quat::exp(vi), Quat::exp(vi * 0.04),
                Quat::from_rotation_matrix(&qi.to_rotation_matrix()), qi.slerp(pi, ti), qi.nlerp(pi, ti), pi.align_to(qi),
                qi.heading_inclination().1];
            for (lq, sq) in lane_quats.iter().zip(scalar_quats) {
                for (a, b) in lq.lane(i).to_array().into_iter().zip(sq.to_array()) { prop_assert!(same_bits(a, b)); }
            }
            let scalar_vecs = [qi.rotate(vi), qi.rotate_inverse(vi), qi.log(), qi.to_rotation_vector()];
            for (lv, sv) in lane_vecs.iter().zip(scalar_vecs) {
                for (a, b) in lv.lane(i).to_array().into_iter().zip(sv.to_array()) { prop_assert!(same_bits(a, b)); }
            }
            let (sy, sp, sr) = qi.to_euler_zyx();
            prop_assert!(same_bits(ly.extract(i), sy) && same_bits(lp.extract(i), sp) && same_bits(lr.extract(i), sr));
            let se = Quat::from_euler_zyx(vi.x, vi.y, vi.z);
            for (a, b) in le.lane(i).to_array().into_iter().zip(se.to_array()) { prop_assert!(same_bits(a, b)); }
            prop_assert!(same_bits(q.angle_to(p).extract(i), qi.angle_to(pi)));
        }
        // f64x4 against f64.
        let q4 = Quat::<wide::f64x4>::from_lanes(|i| qs[i]);
        let v4 = Vec3::<wide::f64x4>::from_lanes(|i| vs[i]);
        let r4 = q4.rotate(v4);
        let m4 = Quat::from_rotation_matrix(&(q4 * Quat::from_rotation_vector(v4)).to_rotation_matrix());
        for i in 0..4 {
            let r = qs[i].rotate(vs[i]);
            let m = Quat::from_rotation_matrix(&(qs[i] * Quat::from_rotation_vector(vs[i])).to_rotation_matrix());
            for (a, b) in r4.lane(i).to_array().into_iter().zip(r.to_array()) { prop_assert!(same_bits(a, b)); }
            for (a, b) in m4.lane(i).to_array().into_iter().zip(m.to_array()) { prop_assert!(same_bits(a, b)); }
        }
    }
}
