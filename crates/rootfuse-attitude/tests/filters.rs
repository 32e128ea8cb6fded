//! Classic filters: convergence, bias estimation, bad input, lanes equal scalars, registry.
use crate::common::same_bits;
use proptest::prelude::*;
use rootfuse_attitude::registry::{FilterKind, FilterSpec};
use rootfuse_attitude::{ImuSample, Lane, OrientationFilter, Quat, Vec3};

const G: f64 = 9.81;
const DIP: f64 = 64.0 * std::f64::consts::PI / 180.0;

/// Earth field (ENU, northern hemisphere: north and down), µT.
fn earth_field() -> Vec3<f64> {
    Vec3::new(0.0, DIP.cos(), -DIP.sin()) * 50.0
}

/// A noiseless motion with exact truth: rates change every 2 s (smooth enough for every
/// filter), with a constant gyro bias. Returns (samples, truth) at 100 Hz.
fn motion(
    seconds: f64,
    bias: Vec3<f64>,
    start: Quat<f64>,
) -> (Vec<ImuSample<f64>>, Vec<Quat<f64>>) {
    let dt = 0.01;
    let n = (seconds / dt) as usize;
    let mut q = start;
    let (mut samples, mut truth) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n {
        let t = k as f64 * dt;
        let seg = (t / 2.0) as usize;
        let w = match seg % 4 {
            0 => Vec3::new(0.0, 0.0, 0.0),
            1 => Vec3::new(0.4, -0.2, 0.3),
            2 => Vec3::new(-0.3, 0.5, -0.6),
            _ => Vec3::new(0.1, 0.1, 0.8),
        };
        q = (q * Quat::from_rotation_vector(w * dt)).normalize();
        let acc = q.rotate_inverse(Vec3::new(0.0, 0.0, G));
        let mag = q.rotate_inverse(earth_field());
        samples.push(ImuSample::new(w + bias, acc, mag));
        truth.push(q);
    }
    (samples, truth)
}

fn run(
    spec: &FilterSpec,
    samples: &[ImuSample<f64>],
    first: Option<ImuSample<f64>>,
) -> Vec<Quat<f64>> {
    let mut f = spec.build::<f64>();
    if let Some(s) = first {
        f.update(&s, 0.01);
    }
    samples
        .iter()
        .map(|s| {
            f.update(s, 0.01);
            f.quat()
        })
        .collect()
}

fn inclination_error(est: Quat<f64>, truth: Quat<f64>) -> f64 {
    let e = est * truth.conj();
    2.0 * (e.w * e.w + e.z * e.z).sqrt().min(1.0).acos()
}

/// Every filter but gyro-only converges from a 60° wrong start (first sample rotated), 6D in
/// inclination and 9D in total; stated bounds after 30 s, on the last 10 s.
#[test]
fn converges_from_wrong_initial_attitude() {
    let (samples, truth) = motion(40.0, Vec3::zero(), Quat::from_euler_zyx(0.3, -0.2, 0.1));
    let wrong = Quat::<f64>::from_euler_zyx(1.0, 0.6, -0.7);
    let s0 = &samples[0];
    let first = ImuSample::new(
        s0.gyr,
        wrong.rotate_inverse(Vec3::new(0.0, 0.0, G)),
        wrong.rotate_inverse(earth_field()),
    );
    for &kind in FilterKind::ALL {
        if kind == FilterKind::Gyro {
            continue;
        }
        for dof in [6u8, 9] {
            let mut spec = FilterSpec::new(kind.name()).unwrap();
            spec.set_dof(crate::common::dof(dof)).unwrap();
            let est = run(&spec, &samples, Some(first));
            let start = est[0].angle_to(truth[0]).to_degrees();
            assert!(
                start > 30.0,
                "{} {dof}D did not start wrong ({start:.1}°)",
                kind.name()
            );
            let worst = est[3000..]
                .iter()
                .zip(&truth[3000..])
                .map(|(e, t)| {
                    if dof == 9 {
                        e.angle_to(*t)
                    } else {
                        inclination_error(*e, *t)
                    }
                })
                .fold(0.0f64, f64::max)
                .to_degrees();
            let bound = 2.0;
            assert!(
                worst < bound,
                "{} {dof}D: {worst:.3}° after 30 s (bound {bound}°)",
                kind.name()
            );
        }
    }
}

/// Mahony and the EKF estimate a constant gyro bias (9D, so all three axes are observable).
#[test]
fn static_bias_is_estimated() {
    let bias = Vec3::new(0.01, -0.02, 0.015);
    let (samples, _) = motion(120.0, bias, Quat::identity());
    for name in ["mahony", "ekf"] {
        let spec = FilterSpec::new(name).unwrap();
        let mut f = spec.build::<f64>();
        for s in &samples {
            f.update(s, 0.01);
        }
        let err = (f.bias() - bias).norm();
        assert!(err < 2e-3, "{name}: bias error {err:e} rad/s");
    }
}

/// Mahony's heading correction, the sine of the heading error normalised by the previous
/// sample's horizontal field: a heading 170° off turns back to north (the full gain past
/// 90°), and a field that turns from nearly vertical to horizontal in one sample turns the
/// estimate no further than an error of 90° would (the sine is clamped: its normalisation,
/// the previous field's horizontal part, was twelve times smaller).
#[test]
fn mahony_heading_recovers_from_behind_and_is_bounded() {
    use rootfuse_attitude::filters::{Mahony, MahonyParams};
    let p = MahonyParams::default();
    let heading = |q: Quat<f64>| 2.0 * q.z.atan2(q.w);
    let sample = |field: Vec3<f64>| ImuSample::new(Vec3::zero(), Vec3::new(0.0, 0.0, G), field);
    let level = sample(earth_field());
    let mut f = Mahony::<f64>::new(&p);
    for _ in 0..10 {
        f.update(&level, 0.01);
    }
    f.set_quat(Quat::from_heading(170f64.to_radians()), None)
        .unwrap();
    for _ in 0..6000 {
        f.update(&level, 0.01);
    }
    let left = heading(f.quat()).to_degrees().abs();
    assert!(left < 0.5, "heading {left:.3}° from north after 60 s");

    let steep = 85f64.to_radians();
    for _ in 0..10 {
        f.update(&sample(Vec3::new(0.0, steep.cos(), -steep.sin())), 0.01);
    }
    f.set_quat(Quat::from_heading(20f64.to_radians()), None)
        .unwrap();
    let before = heading(f.quat());
    f.update(&sample(Vec3::new(0.0, 1.0, 0.0)), 0.01);
    let step = (heading(f.quat()) - before).abs();
    // Unclamped it would be sin 20° / cos 85° = 3.9 times Kp·dt; the bias the recovery
    // left (below 1e-3 rad/s) is the rest.
    assert!(
        step < 1.02 * p.kp * 0.01 && step > 0.98 * p.kp * 0.01,
        "the flat field turned the heading by {step:e} rad (Kp·dt = {:e})",
        p.kp * 0.01
    );
}

fn finite_unit<T: Lane>(q: Quat<T>, tol: f64) -> bool {
    (0..T::LANES).all(|i| {
        let q = q.lane(i);
        let n: f64 = q.norm().into();
        q.to_array()
            .iter()
            .all(|c| Into::<f64>::into(*c).is_finite())
            && (n - 1.0).abs() < tol
    })
}

fn bad_value() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -20.0..20.0f64,
        1 => prop::sample::select(vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0, 1e30, -1e30, 1e300, 5e-324, 1e20]),
    ]
}
fn bad_sample() -> impl Strategy<Value = (ImuSample<f64>, f64)> {
    (prop::array::uniform9(bad_value()), prop_oneof![4 => 0.001..0.05f64, 1 => prop::sample::select(vec![0.0, -0.01, f64::NAN, f64::INFINITY, 1e9, 5.0])])
        .prop_map(|(v, dt)| {
            (ImuSample::new(Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]), Vec3::new(v[6], v[7], v[8])), dt)
        })
}
fn to_f32(s: &ImuSample<f64>) -> ImuSample<f32> {
    let c = |v: Vec3<f64>| Vec3::new(v.x as f32, v.y as f32, v.z as f32);
    ImuSample::new(c(s.gyr), c(s.acc), c(s.mag))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Arbitrary samples (NaN, ±∞, zero vectors, huge values, dt ≤ 0, huge dt): no panic, the
    /// state stays finite with a unit quaternion, and every unusable part is counted.
    #[test]
    fn bad_input_is_rejected_and_counted(samples in prop::collection::vec(bad_sample(), 1..80)) {
        for &kind in FilterKind::ALL {
            for dof in [6u8, 9] {
                let mut spec = FilterSpec::new(kind.name()).unwrap();
                spec.set_dof(crate::common::dof(dof)).unwrap();
                let mut f64_filter = spec.build::<f64>();
                let mut f32_filter = spec.build::<f32>();
                let (mut bad_dt, mut bad_gyr) = (0u64, 0u64);
                for (s, dt) in &samples {
                    f64_filter.update(s, *dt);
                    f32_filter.update(&to_f32(s), *dt as f32);
                    let dt_ok = *dt > 0.0 && *dt <= 1.0;
                    bad_dt += !dt_ok as u64;
                    let gyr_ok = s.gyr.norm() <= 35.0; // false for NaN too
                    bad_gyr += (dt_ok && !gyr_ok) as u64;
                    prop_assert!(finite_unit(f64_filter.quat(), 1e-9), "{} {dof}D f64: {:?}", kind.name(), f64_filter.quat());
                    prop_assert!(finite_unit(f32_filter.quat(), 1e-5), "{} {dof}D f32: {:?}", kind.name(), f32_filter.quat());
                    prop_assert!(f64_filter.bias().is_finite() && f32_filter.bias().is_finite());
                }
                let r = f64_filter.rejections();
                prop_assert_eq!(r.dt[0], bad_dt, "{} dt count", kind.name());
                prop_assert_eq!(r.gyr[0], bad_gyr, "{} gyro count", kind.name());
            }
        }
    }

    /// Eight channels in f32x8 lanes equal eight scalar f32 runs bit for bit, with bad
    /// samples sprinkled into single lanes (they must not leak into the neighbours).
    #[test]
    fn lanes_equal_scalar_runs(lanes in prop::array::uniform8(prop::collection::vec(bad_sample(), 40)), seed in 0u64..1000) {
        type V = wide::f32x8;
        let (good, _) = motion(0.4, Vec3::new(0.01, 0.0, -0.01), Quat::from_euler_zyx(seed as f64 * 0.01, 0.2, -0.1));
        for &kind in FilterKind::ALL {
            let spec = FilterSpec::new(kind.name()).unwrap();
            let mut lane_filter = spec.build::<V>();
            let mut scalar: Vec<_> = (0..8).map(|_| spec.build::<f32>()).collect();
            for k in 0..40 {
                // Mostly good data, with lane i's own arbitrary sample every (i + 3)-th step.
                let pick = |i: usize| if k % (i + 3) == 0 { lanes[i][k] } else { (good[k], 0.01) };
                let s = |i: usize| to_f32(&pick(i).0);
                let sample = ImuSample::new(
                    Vec3::<V>::from_lanes(|i| s(i).gyr),
                    Vec3::<V>::from_lanes(|i| s(i).acc),
                    Vec3::<V>::from_lanes(|i| s(i).mag),
                );
                lane_filter.update(&sample, V::from_fn(|i| pick(i).1 as f32));
                for (i, f) in scalar.iter_mut().enumerate() {
                    f.update(&s(i), pick(i).1 as f32);
                }
            }
            for (i, f) in scalar.iter().enumerate() {
                let (a, b) = (lane_filter.quat().lane(i), f.quat());
                for (x, y) in a.to_array().into_iter().zip(b.to_array()) {
                    prop_assert!(same_bits(x, y), "{} lane {i}: {a:?} vs {b:?}", kind.name());
                }
                let r = lane_filter.rejections();
                prop_assert_eq!(r.dt[i], f.rejections().dt[0]);
                prop_assert_eq!(r.acc[i], f.rejections().acc[0]);
                prop_assert_eq!(r.mag[i], f.rejections().mag[0]);
                prop_assert_eq!(r.gated[i], f.rejections().gated[0]);
            }
        }
    }
}

#[test]
fn registry_names_and_errors() {
    assert_eq!(
        FilterKind::NAMES,
        [
            "gyro",
            "complementary",
            "mahony",
            "madgwick",
            "ekf",
            "sqrt-eskf",
            "ecf-ekf",
            "complementary-reconstruction",
            "lsq-fusion",
            "heading-pipeline"
        ]
    );
    let e = FilterSpec::new("kalman").unwrap_err().to_string();
    assert!(
        e.contains("unknown filter `kalman`")
            && e.contains("mahony")
            && !e.contains("did you mean"),
        "{e}"
    );
    // A misspelling or another case is answered with the name meant; the alias is listed.
    for (given, meant) in [
        ("Flagship", "flagship"),
        ("madgwik", "madgwick"),
        ("sqrt_eskf", "sqrt-eskf"),
    ] {
        let e = FilterSpec::new(given).unwrap_err().to_string();
        assert!(
            e.contains(&format!("did you mean `{meant}`?")) && e.contains("valid: flagship"),
            "{e}"
        );
    }
    // A value out of range names the parameter's range and unit (none for a pure number).
    let e = FilterSpec::new("flagship")
        .unwrap()
        .set("max_gyr=1e9")
        .unwrap_err()
        .to_string();
    assert!(e.ends_with("is outside [0.001, 100000] rad/s"), "{e}");
    let e = FilterSpec::new("flagship")
        .unwrap()
        .set("gyr_scale_error=-1")
        .unwrap_err()
        .to_string();
    assert!(e.ends_with(']'), "{e}");
    let mut spec = FilterSpec::new("mahony").unwrap();
    assert!(spec.set("kp=2").is_ok() && spec.get("kp") == Some(2.0));
    assert!(
        spec.set("kp=-1")
            .unwrap_err()
            .to_string()
            .contains("outside")
    );
    assert!(
        spec.set("kp")
            .unwrap_err()
            .to_string()
            .contains("key=value")
    );
    assert!(
        spec.set("zeta=1")
            .unwrap_err()
            .to_string()
            .contains("valid: kp, ki")
    );
    assert!(
        spec.set("kp=fast")
            .unwrap_err()
            .to_string()
            .contains("not a number")
    );
    for &kind in FilterKind::ALL {
        for p in kind.params() {
            assert!(
                p.min <= p.default && p.default <= p.max && !p.doc.is_empty(),
                "{}.{}",
                kind.name(),
                p.name
            );
        }
    }
}

/// The flagship's `init_heading_std` is report only: 6D and 9D estimates are those of another
/// value to rounding (measured on BROAD: ≤ 4e-14 in f64), while the 6D heading variance
/// starts at its square (0 by default) and grows from there.
#[test]
fn initial_heading_std_moves_only_the_report() {
    use rootfuse_attitude::Dof;
    use rootfuse_attitude::filters::{SqrtEskf, SqrtEskfParams};
    let (samples, _) = motion(40.0, Vec3::new(0.01, -0.02, 0.015), Quat::identity());
    for dof in [Dof::Six, Dof::Nine] {
        let make = |std: f64| {
            SqrtEskf::<f64>::new(&SqrtEskfParams {
                init_heading_std: std,
                dof,
                ..SqrtEskfParams::default()
            })
        };
        let (mut zero, mut tenth) = (make(0.0), make(0.1));
        let mut worst = 0.0_f64;
        for (k, s) in samples.iter().enumerate() {
            zero.update(s, 0.01);
            tenth.update(s, 0.01);
            let (a, b) = (zero.quat(), tenth.quat());
            for d in [a.w - b.w, a.x - b.x, a.y - b.y, a.z - b.z] {
                worst = worst.max(d.abs());
            }
            if k == 0 && dof == Dof::Six {
                let (p0, p1) = (zero.attitude_covariance(), tenth.attitude_covariance());
                let (h0, h1) = (
                    p0.map_or(f64::NAN, |p| p.m[2][2]),
                    p1.map_or(f64::NAN, |p| p.m[2][2]),
                );
                assert!(
                    h0 < 1e-6 && h1 > 0.0099,
                    "6D heading variance after one sample: {h0:e} / {h1:e}"
                );
            }
        }
        assert!(worst < 1e-9, "{dof:?}: estimates differ by {worst:e}");
    }
}

/// Filters that carry a covariance report one that is symmetric positive semi-definite at
/// every step and says what is observable: in 6D the heading variance ends far above the
/// inclination variances (gravity carries no heading; it can shrink only through what is
/// learnt of the bias, never below what the gyro noise added); the magnetometer (9D) holds it
/// lower and from growing over the second half (measured, 9D/6D heading variance at 40 s:
/// 0.003 for ekf, 0.69 for sqrt-eskf, whose 6D heading variance starts at 0).
#[test]
fn attitude_covariance_says_what_is_observable() {
    let (samples, _) = motion(40.0, Vec3::new(0.01, -0.02, 0.015), Quat::identity());
    let mut carrying = 0;
    for &kind in FilterKind::ALL {
        let mut end_heading_var = [0.0; 2];
        let mut mid_heading_var = [0.0; 2];
        for (d, dof) in [6u8, 9].into_iter().enumerate() {
            let mut spec = FilterSpec::new(kind.name()).unwrap();
            spec.set_dof(crate::common::dof(dof)).unwrap();
            let mut f = spec.build::<f64>();
            let what = format!("{} {dof}D", kind.name());
            for (k, s) in samples.iter().enumerate() {
                f.update(s, 0.01);
                let Some(p) = f.attitude_covariance() else {
                    break;
                };
                let m = p.m;
                let sym = (0..3).all(|i| (0..3).all(|j| m[i][j] == m[j][i]));
                let minor2 = m[0][0] * m[1][1] - m[0][1] * m[1][0];
                let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                    - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                    + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
                let scale = m[0][0] * m[1][1] * m[2][2];
                assert!(
                    sym && m[0][0] > 0.0 && minor2 > 0.0 && det > -1e-9 * scale,
                    "{what} at {k}: {m:?}"
                );
                end_heading_var[d] = m[2][2];
                if k == samples.len() / 2 {
                    mid_heading_var[d] = m[2][2];
                }
                if k == samples.len() - 1 && dof == 6 {
                    let tilt_var = m[0][0].max(m[1][1]);
                    assert!(m[2][2] > 10.0 * tilt_var, "{what}: {m:?}");
                }
            }
        }
        if end_heading_var[0] > 0.0 {
            carrying += 1;
            let what = kind.name();
            eprintln!(
                "{what}: heading variance at 20 s / 40 s, 6D {:.3e} / {:.3e}, 9D {:.3e} / {:.3e}",
                mid_heading_var[0], end_heading_var[0], mid_heading_var[1], end_heading_var[1]
            );
            assert!(
                end_heading_var[1] < 0.8 * end_heading_var[0]
                    && end_heading_var[1] <= mid_heading_var[1],
                "{what}: 9D {:?} vs 6D {:?} (20 s, 40 s)",
                [mid_heading_var[1], end_heading_var[1]],
                [mid_heading_var[0], end_heading_var[0]]
            );
        }
    }
    assert!(carrying >= 2, "sqrt-eskf and ekf carry a covariance");
}

/// Every parameter at either end of its accepted range (the ends are inclusive) keeps every
/// filter finite and unit in f32 and f64, 6D and 9D, on motion with bad samples mixed in.
/// Found by fuzzing (`fuzz/corpus/filter_update`): Mahony with `max_bias = 0` scaled its
/// bias by `0/0`.
#[test]
fn parameters_at_the_ends_of_their_ranges_stay_finite() {
    let (good, _) = motion(3.0, Vec3::new(0.01, -0.02, 0.005), Quat::identity());
    let bad = [f64::NAN, f64::INFINITY, 0.0, 1e30];
    for &kind in FilterKind::ALL {
        for p in kind.params() {
            for (value, dof) in [(p.min, 6u8), (p.min, 9), (p.max, 6), (p.max, 9)] {
                let mut spec = FilterSpec::new(kind.name()).unwrap();
                spec.set_dof(crate::common::dof(dof)).unwrap();
                spec.set(&format!("{}={value:?}", p.name)).unwrap();
                let (mut f64_filter, mut f32_filter) = (spec.build::<f64>(), spec.build::<f32>());
                for (k, s) in good.iter().enumerate() {
                    let mut s = *s;
                    if k % 7 == 3 {
                        s.acc.x = bad[k % 4];
                        s.mag.y = bad[(k + 1) % 4];
                    }
                    f64_filter.update(&s, 0.01);
                    f32_filter.update(&to_f32(&s), 0.01);
                    let what = format!("{} {}={value} {dof}D step {k}", kind.name(), p.name);
                    assert!(
                        finite_unit(f64_filter.quat(), 1e-9),
                        "{what}: {:?}",
                        f64_filter.quat()
                    );
                    assert!(
                        finite_unit(f32_filter.quat(), 1e-5),
                        "{what}: {:?}",
                        f32_filter.quat()
                    );
                    assert!(
                        f64_filter.bias().is_finite() && f32_filter.bias().is_finite(),
                        "{what}: bias"
                    );
                }
            }
        }
    }
}
