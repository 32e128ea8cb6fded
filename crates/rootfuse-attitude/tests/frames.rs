//! Typed earth frames: conversions against the coordinate permutations that define NED and
//! NWU, round trips, and the aerospace reading of an FRD sensor in NED.
use proptest::prelude::*;
use rootfuse_attitude::frames::{Attitude, EarthFrame, Enu, Ned, Nwu};
use rootfuse_attitude::{Mat, Quat, Vec3};
use std::f64::consts::FRAC_PI_2;

fn unit_quat() -> impl Strategy<Value = Quat<f64>> {
    prop::array::uniform4(-1.0f64..1.0)
        .prop_filter("not tiny", |a| a.iter().map(|x| x * x).sum::<f64>() > 1e-3)
        .prop_map(|[w, x, y, z]| Quat::new(w, x, y, z).normalize())
}

fn vec3() -> impl Strategy<Value = Vec3<f64>> {
    prop::array::uniform3(-10.0f64..10.0).prop_map(|[x, y, z]| Vec3::new(x, y, z))
}

fn close(a: Vec3<f64>, b: Vec3<f64>, tol: f64) -> bool {
    (a - b).norm() <= tol * (1.0 + b.norm())
}

/// `q` and `−q` are the same rotation.
fn same_rotation(a: Quat<f64>, b: Quat<f64>) -> bool {
    let d = a
        .to_array()
        .iter()
        .zip(b.to_array())
        .map(|(x, y)| x * y)
        .sum::<f64>();
    (d.abs() - 1.0).abs() < 1e-12
}

proptest! {
    /// `v_NED = (v_n, v_e, −v_u)` and `v_NWU = (v_n, −v_e, v_u)` of the ENU vector `(e, n, u)`.
    #[test]
    fn conversions_permute_coordinates(q in unit_quat(), v in vec3()) {
        let enu = Attitude::<f64, Enu>::new(q);
        let e = enu.rotate(v);
        let ned = enu.to::<Ned>().rotate(v);
        let nwu = enu.to::<Nwu>().rotate(v);
        prop_assert!(close(ned, Vec3::new(e.y, e.x, -e.z), 4e-15), "{ned:?} vs {e:?}");
        prop_assert!(close(nwu, Vec3::new(e.y, -e.x, e.z), 4e-15), "{nwu:?} vs {e:?}");
    }

    #[test]
    fn round_trips_return_the_rotation(q in unit_quat()) {
        let back = Attitude::<f64, Enu>::new(q).to::<Ned>().to::<Nwu>().to::<Enu>().quat();
        prop_assert!(same_rotation(back, q), "{back:?} vs {q:?}");
        let ned = Attitude::<f64, Ned>::new(q);
        prop_assert!(same_rotation(ned.to::<Ned>().quat(), q));
    }
}

#[test]
fn up_and_north_per_frame() {
    assert_eq!(Enu::up::<f64>(), Vec3::new(0.0, 0.0, 1.0));
    assert!(close(Ned::up::<f64>(), Vec3::new(0.0, 0.0, -1.0), 1e-15));
    assert!(close(Ned::north::<f64>(), Vec3::new(1.0, 0.0, 0.0), 1e-15));
    assert!(close(Nwu::up::<f64>(), Vec3::new(0.0, 0.0, 1.0), 1e-15));
    assert!(close(Nwu::north::<f64>(), Vec3::new(1.0, 0.0, 0.0), 1e-15));
    assert_eq!([Enu::NAME, Ned::NAME, Nwu::NAME], ["ENU", "NED", "NWU"]);
}

/// An FRD sensor (x forward, y right, z down) pitched up 10° while heading 30° east of
/// north, built in ENU from its axes: in NED it reads yaw 30°, pitch 10°, roll 0; level and
/// heading north it is the identity.
#[test]
fn frd_sensor_reads_aerospace_angles_in_ned() {
    let (psi, theta) = (30f64.to_radians(), 10f64.to_radians());
    // Forward axis in ENU: horizontal direction at heading ψ from north, tilted up by θ.
    let fwd = Vec3::new(
        psi.sin() * theta.cos(),
        psi.cos() * theta.cos(),
        theta.sin(),
    );
    let right = Vec3::new(psi.cos(), -psi.sin(), 0.0);
    let down = fwd.cross(right);
    let m = Mat::from_fn(|i, j| [fwd, right, down][j].to_array()[i]);
    let q = Quat::from_rotation_matrix(&m);
    let (yaw, pitch, roll) = Attitude::<f64, Enu>::new(q).to::<Ned>().euler_zyx();
    assert!((yaw - psi).abs() < 1e-12, "{yaw}");
    assert!((pitch - theta).abs() < 1e-12, "{pitch}");
    assert!(roll.abs() < 1e-12, "{roll}");

    let level_north = Mat::from_fn(|i, j| {
        [
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, -1.0),
        ][j]
            .to_array()[i]
    });
    let ned = Attitude::<f64, Enu>::new(Quat::from_rotation_matrix(&level_north)).to::<Ned>();
    assert!(
        same_rotation(ned.quat(), Quat::identity()),
        "{:?}",
        ned.quat()
    );

    // The same motion with an FLU sensor (x forward, y left, z up) read in NWU: yaw is
    // counter-clockwise from north and a nose-up pitch is negative about the left axis.
    let left = -right;
    let up = fwd.cross(left);
    let m = Mat::from_fn(|i, j| [fwd, left, up][j].to_array()[i]);
    let q = Quat::from_rotation_matrix(&m);
    let (yaw, pitch, roll) = Attitude::<f64, Enu>::new(q).to::<Nwu>().euler_zyx();
    assert!((yaw + psi).abs() < 1e-12, "{yaw}");
    assert!((pitch + theta).abs() < 1e-12, "{pitch}");
    assert!(roll.abs() < 1e-12, "{roll}");
    // In ENU the same sensor's yaw is measured from east: 90° − ψ.
    let (yaw, _, _) = Attitude::<f64, Enu>::new(q).euler_zyx();
    assert!((yaw - (FRAC_PI_2 - psi)).abs() < 1e-12, "{yaw}");
}
