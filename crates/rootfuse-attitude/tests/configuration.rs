//! Typed filter configuration: parameter kinds, 6D/9D, screening limits as parameters, state
//! control (set quaternion, bias, heading) and per-sample flags, for every registered filter.
use rootfuse_attitude::filters::{ParamError, ParamKind, SampleFlags, StateError};
use rootfuse_attitude::registry::{Assignment, FilterKind, FilterSpec, RegistryError};
use rootfuse_attitude::{Dof, ImuSample, Lane, OrientationFilter, Quat, Vec3};
use rootfuse_eval::sim::scenario;

/// A registered filter in f64 with its defaults at `dof`, and a name for messages.
fn filter(kind: FilterKind, dof: Dof) -> (String, rootfuse_attitude::registry::AnyFilter<f64>) {
    let mut spec = FilterSpec::new(kind.name()).unwrap();
    spec.set_dof(dof).unwrap();
    (format!("{} {dof}", kind.name()), spec.build())
}

fn level_sample() -> ImuSample<f64> {
    ImuSample::new(
        Vec3::zero(),
        Vec3::new(0.0, 0.0, 9.81),
        Vec3::new(0.0, 20.0, -40.0),
    )
}

/// Every default is a value of its parameter's type, and `get` reads it back as listed.
#[test]
fn defaults_are_values_of_their_kind() {
    for &kind in FilterKind::ALL {
        let spec = FilterSpec::new(kind.name()).unwrap();
        for info in kind.params() {
            assert_eq!(
                spec.get(info.name),
                Some(info.default),
                "{} {}",
                kind.name(),
                info.name
            );
            assert!(
                (info.min..=info.max).contains(&info.default),
                "{} {}",
                kind.name(),
                info.name
            );
        }
        // The screening limits are parameters of every filter, never lane-varying.
        for name in ["max_dt", "max_gyr", "max_acc", "max_mag"] {
            let info = kind.params().iter().find(|i| i.name == name).unwrap();
            assert!(!info.per_lane, "{} {name}", kind.name());
        }
    }
}

/// A whole number, a switch or `dof` given a value it does not take is refused, never rounded.
#[test]
fn fractions_and_wrong_kinds_are_refused() {
    let wrong_kind = |name: &str, assignment: &str| {
        let mut spec = FilterSpec::new(name).unwrap();
        let before = spec.clone();
        let err = spec.set(assignment).unwrap_err();
        assert!(
            matches!(err, RegistryError::Param(ParamError::WrongKind { .. })),
            "{name} {assignment}: {err}"
        );
        assert_eq!(spec, before, "{name} {assignment}: nothing changed");
        err.to_string()
    };
    assert!(wrong_kind("mahony", "dof=7").contains("6 or 9"));
    assert!(wrong_kind("mahony", "dof=8").contains("6 or 9"));
    assert!(wrong_kind("ecf-ekf", "window=2.5").contains("whole number"));
    assert!(wrong_kind("gyro", "init_from_acc=0.5").contains("0 or 1"));
    assert!(wrong_kind("complementary-reconstruction", "alpha_rule=0.3").contains("whole"));

    let mut spec = FilterSpec::new("ecf-ekf").unwrap();
    spec.set("window=3").unwrap();
    assert_eq!(spec.get("window"), Some(3.0));
    spec.set("dof=6").unwrap();
    assert_eq!(spec.dof(), Some(Dof::Six));
    assert!(!spec.uses_magnetometer());
    // gyro never reads the magnetometer: no dof, whatever is asked.
    let mut gyro = FilterSpec::new("gyro").unwrap();
    gyro.set_dof(Dof::Nine).unwrap();
    assert_eq!(gyro.dof(), None);
    assert!(!gyro.uses_magnetometer());
    // Every kind is listed as what it is.
    let kind_of = |filter: &str, name: &str| {
        FilterKind::from_name(filter)
            .unwrap()
            .params()
            .iter()
            .find(|i| i.name == name)
            .unwrap()
            .kind
    };
    assert_eq!(kind_of("mahony", "dof"), ParamKind::Dof);
    assert_eq!(kind_of("ecf-ekf", "window"), ParamKind::Integer);
    assert_eq!(kind_of("gyro", "init_from_acc"), ParamKind::Switch);
    assert_eq!(kind_of("mahony", "kp"), ParamKind::Real);
}

/// `set_all` takes each parameter once: a second value (different or the same) is refused
/// naming both sources, and the spec is left as it was; any other refusal names its source.
#[test]
fn set_all_refuses_a_parameter_given_twice() {
    let mut spec = FilterSpec::new("mahony").unwrap();
    let before = spec.clone();
    for (second, value) in [("--param max_dt=3", "3"), ("--param max_dt=2", "2")] {
        let err = spec
            .set_all(&[
                Assignment::from_source("kp=0.7", "--param kp=0.7"),
                Assignment::from_source("max_dt=2", "--max-dt 2"),
                Assignment::from_source(format!("max_dt={value}"), second),
            ])
            .unwrap_err();
        assert_eq!(
            err,
            RegistryError::Param(ParamError::Repeated {
                name: "max_dt".into(),
                first: "--max-dt 2".into(),
                second: second.into(),
            })
        );
        assert_eq!(
            err.to_string(),
            format!("`max_dt` is given twice: by --max-dt 2 and by {second}; give it once")
        );
        assert_eq!(spec, before, "nothing applied");
    }
    // The key is compared as `set` reads it: surrounding blanks do not make it another.
    let err = spec
        .set_all(&[Assignment::new("kp=1"), Assignment::new(" kp =2")])
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        "`kp` is given twice: by kp=1 and by  kp =2; give it once"
    );
    let err = spec
        .set_all(&[Assignment::from_source("kp=-1", "--param kp=-1")])
        .unwrap_err();
    assert!(
        matches!(&err, RegistryError::Given { source, error }
            if source == "--param kp=-1"
                && matches!(**error, RegistryError::Param(ParamError::OutOfRange { .. }))),
        "{err:?}"
    );
    assert!(
        err.to_string()
            .starts_with("--param kp=-1: parameter `kp` = -1"),
        "{err}"
    );
    spec.set_all(&[Assignment::new("kp=0.7"), Assignment::new("dof=6")])
        .unwrap();
    assert_eq!((spec.get("kp"), spec.dof()), (Some(0.7), Some(Dof::Six)));
}

/// Asking `gyro` (no 6D/9D choice) for a dof is an error naming the filter and the filters
/// that have one, through `set` and `set_all`; `set_dof`, for loops over every filter,
/// leaves it as it is.
#[test]
fn dof_for_a_filter_without_one_is_refused() {
    let with_dof: Vec<&str> = FilterKind::ALL
        .iter()
        .filter(|k| **k != FilterKind::Gyro)
        .map(|k| k.name())
        .collect();
    let mut gyro = FilterSpec::new("gyro").unwrap();
    let err = gyro.set("dof=6").unwrap_err();
    assert_eq!(
        err,
        RegistryError::NoDof {
            filter: "gyro",
            with_dof: with_dof.clone()
        }
    );
    let err = gyro
        .set_all(&[Assignment::from_source("dof=9", "--dof 9")])
        .unwrap_err();
    assert_eq!(
        err.to_string(),
        format!(
            "--dof 9: filter `gyro` has no 6D/9D choice (no `dof` parameter); leave dof out, or choose a filter that has one: {}",
            with_dof.join(", ")
        )
    );
    assert_eq!(gyro, FilterSpec::new("gyro").unwrap());
    gyro.set_dof(Dof::Six).unwrap();
    assert_eq!(gyro.dof(), None);
}

/// `max_gyr` decides what a saturated gyroscope is: a 50 rad/s sample (about 2900 °/s) is
/// skipped with the default 35 rad/s and used with `max_gyr=80`; `max_dt` likewise for gaps.
#[test]
fn screening_limits_are_parameters() {
    for &kind in FilterKind::ALL {
        let fast = ImuSample::new(
            Vec3::new(0.0, 0.0, 50.0),
            level_sample().acc,
            level_sample().mag,
        );
        let mut default = FilterSpec::new(kind.name()).unwrap().build::<f64>();
        default.update(&level_sample(), 0.01);
        default.update(&fast, 0.01);
        assert_eq!(default.rejections().gyr, [1], "{}", kind.name());
        assert_eq!(
            default.flags().bits(0) & SampleFlags::<f64>::GYR,
            SampleFlags::<f64>::GYR
        );

        let mut spec = FilterSpec::new(kind.name()).unwrap();
        spec.set("max_gyr=80").unwrap();
        spec.set("max_dt=5").unwrap();
        let mut wide = spec.build::<f64>();
        wide.update(&level_sample(), 0.01);
        wide.update(&fast, 0.01);
        wide.update(&level_sample(), 2.0);
        assert_eq!(wide.rejections().gyr, [0], "{}", kind.name());
        assert_eq!(
            wide.rejections().dt,
            [0],
            "{}: a 2 s gap within max_dt=5",
            kind.name()
        );
        assert_eq!(wide.flags().bits(0) & 3, 0, "{}", kind.name());
    }
}

/// Per-sample flags say what happened to that sample only: a NaN gyroscope skips the
/// sample (bit 2), a zero accelerometer skips its correction (bit 4), the next good sample
/// has neither; the counters agree.
#[test]
fn flags_describe_the_last_sample() {
    for &kind in FilterKind::ALL {
        let mut f = FilterSpec::new(kind.name()).unwrap().build::<f64>();
        let name = kind.name();
        f.update(&level_sample(), 0.01);
        let mut bad_gyr = level_sample();
        bad_gyr.gyr.x = f64::NAN;
        f.update(&bad_gyr, 0.01);
        assert_eq!(
            f.flags().bits(0) & 0b1111,
            SampleFlags::<f64>::GYR,
            "{name}"
        );
        let mut no_acc = level_sample();
        no_acc.acc = Vec3::zero();
        f.update(&no_acc, 0.01);
        assert_eq!(
            f.flags().bits(0) & 0b1111,
            SampleFlags::<f64>::ACC,
            "{name}"
        );
        f.update(&level_sample(), -1.0);
        assert_eq!(f.flags().bits(0) & 0b1111, SampleFlags::<f64>::DT, "{name}");
        f.update(&level_sample(), 0.01);
        assert_eq!(f.flags().bits(0) & 0b1111, 0, "{name}");
        let r = f.rejections();
        assert_eq!([r.dt[0], r.gyr[0], r.acc[0]], [1, 1, 1], "{name}");
    }
}

/// set_quat makes the estimate that orientation at once, and the filter goes on from there;
/// set_heading turns it about up only; set_bias is kept where the filter has a bias.
#[test]
fn state_control() {
    let target = Quat::from_euler_zyx(0.7, 0.2, -0.1);
    for &kind in FilterKind::ALL {
        for dof in [Dof::Six, Dof::Nine] {
            let (name, mut f) = filter(kind, dof);
            f.update(&level_sample(), 0.01);
            f.set_quat(target, None).unwrap();
            assert!(f.quat().angle_to(target) < 1e-9, "{name}: set_quat");

            f.set_heading(-1.2).unwrap();
            let (heading, incl) = f.quat().heading_inclination();
            let (_, target_incl) = target.heading_inclination();
            assert!((heading + 1.2).abs() < 1e-9, "{name}: heading {heading}");
            assert!(
                incl.angle_to(target_incl) < 1e-9,
                "{name}: inclination kept"
            );

            let bias = Vec3::new(0.01, -0.02, 0.005);
            match f.set_bias(bias, None) {
                Ok(()) => assert_eq!(f.bias(), bias, "{name}: set_bias"),
                Err(StateError::Unsupported(_)) => {
                    assert_eq!(f.bias(), Vec3::zero(), "{name}: no bias")
                }
                Err(e) => panic!("{name}: {e}"),
            }
            // The filter keeps running from there: the same orientation at rest stays put
            // (within what one correction can move it).
            let at_target = ImuSample::new(
                Vec3::zero(),
                f.quat().rotate_inverse(Vec3::new(0.0, 0.0, 9.81)),
                f.quat().rotate_inverse(Vec3::new(0.0, 20.0, -40.0)),
            );
            let before = f.quat();
            f.update(&at_target, 0.01);
            assert!(
                f.quat().angle_to(before) < 0.05,
                "{name}: continues from the set state"
            );
        }
    }
}

/// The flagship told its orientation before the first sample starts there: its first
/// estimate is the set one (turned by one gyro step), not the accelerometer's.
#[test]
fn flagship_starts_from_a_preset_orientation() {
    let preset = Quat::from_euler_zyx(1.0, 0.0, 0.0);
    let mut spec = FilterSpec::new("sqrt-eskf").unwrap();
    spec.set_dof(Dof::Six).unwrap();
    let mut f = spec.build::<f64>();
    f.set_quat(preset, None).unwrap();
    // Level and at rest: gravity agrees with the preset (whose heading is 1 rad).
    f.update(&level_sample(), 0.01);
    assert!(f.quat().angle_to(preset) < 1e-6, "{:?}", f.quat());
    // Without the preset the 6D heading starts at zero.
    let mut fresh = spec.build::<f64>();
    fresh.update(&level_sample(), 0.01);
    assert!(fresh.quat().angle_to(preset) > 0.9);
}

/// `validate()` (no_std) checks a parameter struct as `Params::set` checks one value: a struct
/// literal with a value out of range or NaN is refused by `validate` and `try_new`, naming the
/// parameter; the defaults pass; the error converts into the registry's `ParamError`.
#[test]
fn struct_literals_are_validated() {
    use rootfuse_attitude::filters::{
        Complementary, ComplementaryParams, InvalidParam, Mahony, MahonyParams, SqrtEskf,
        SqrtEskfParams,
    };
    let bad = SqrtEskfParams {
        gyr_noise: -1.0,
        ..Default::default()
    };
    let err = bad.validate().unwrap_err();
    assert_eq!(err.name, "gyr_noise");
    assert!(err.to_string().contains("gyr_noise"), "{err}");
    assert!(SqrtEskf::<f64>::try_new(&bad).is_err());
    assert!(SqrtEskf::<f64>::try_new(&SqrtEskfParams::default()).is_ok());
    let nan = MahonyParams {
        kp: f64::NAN,
        ..Default::default()
    };
    assert_eq!(nan.validate().unwrap_err().name, "kp");
    assert!(Mahony::<f32>::try_new(&nan).is_err());
    let limit = ComplementaryParams {
        max_acc: 0.0,
        ..Default::default()
    };
    let e: InvalidParam = Complementary::<f64>::try_new(&limit).unwrap_err();
    assert_eq!(e.name, "max_acc");
    assert!(matches!(
        ParamError::from(e),
        ParamError::OutOfRange {
            name: "max_acc",
            ..
        }
    ));
}

/// `reset` then the same samples gives the same bits as a new filter, for every registered
/// filter in 6D and 9D, f64 and f32x8: orientation, bias, covariance and flags, on a
/// recording with motion, rest and a magnetic disturbance, reset after a different one.
#[test]
fn reset_is_a_new_filter_for_every_filter() {
    fn bits<T: Lane>(f: &impl OrientationFilter<T>) -> Vec<u64> {
        let q = f.quat();
        let b = f.bias();
        let mut v: Vec<T> = vec![q.w, q.x, q.y, q.z, b.x, b.y, b.z];
        if let Some(p) = f.attitude_covariance() {
            v.extend(p.m.iter().flatten().copied());
        }
        let mut out: Vec<u64> = v
            .iter()
            .flat_map(|x| (0..T::LANES).map(move |i| x.extract(i).into().to_bits()))
            .collect();
        let flags = f.flags();
        out.extend((0..T::LANES).map(|i| u64::from(flags.bits(i))));
        out
    }
    fn check<T: Lane>(spec: &FilterSpec, name: &str) {
        let first = scenario("long-rest", 1, 8.0, 100.0).unwrap();
        let then = scenario("magnetic-disturbance", 2, 8.0, 100.0).unwrap();
        let feed = |f: &mut rootfuse_attitude::registry::AnyFilter<T>,
                    i: usize,
                    rec: &rootfuse_attitude::Recording| {
            let s = rec.sample(i);
            let lane =
                |v: Vec3<f64>| Vec3::new(T::from_f64(v.x), T::from_f64(v.y), T::from_f64(v.z));
            f.update(
                &ImuSample::new(lane(s.gyr), lane(s.acc), lane(s.mag)),
                T::from_f64(rec.dt(i)),
            );
        };
        let mut fresh = spec.build::<T>();
        let mut used = spec.build::<T>();
        for i in 0..first.len() {
            feed(&mut used, i, &first);
        }
        used.reset();
        for i in 0..then.len() {
            feed(&mut fresh, i, &then);
            feed(&mut used, i, &then);
            assert_eq!(bits(&used), bits(&fresh), "{name}: sample {i} after reset");
        }
    }
    for &kind in FilterKind::ALL {
        for dof in [Dof::Six, Dof::Nine] {
            let mut spec = FilterSpec::new(kind.name()).unwrap();
            spec.set_dof(dof).unwrap();
            let name = format!("{} {dof}", kind.name());
            check::<f64>(&spec, &name);
            check::<wide::f32x8>(&spec, &name);
        }
    }
}

/// The setters refuse a NaN or absurd value with nothing changed, in every filter; a
/// `sigma` is read back from `attitude_covariance` where the filter carries one and refused
/// as unsupported where it does not.
#[test]
fn setters_refuse_bad_values_and_set_sigma() {
    let q = Quat::from_euler_zyx(0.4, 0.1, -0.05);
    for &kind in FilterKind::ALL {
        for dof in [Dof::Six, Dof::Nine] {
            let (name, mut f) = filter(kind, dof);
            for _ in 0..300 {
                f.update(&level_sample(), 0.01);
            }
            let kept = format!("{f:?}");
            let nan = f64::NAN;
            let refused = [
                f.set_quat(Quat::new(nan, 0.0, 0.0, 0.0), None),
                f.set_quat(Quat::new(3.0, 0.0, 0.0, 0.0), None),
                f.set_quat(q, Some(nan)),
                f.set_quat(q, Some(-0.1)),
                f.set_bias(Vec3::new(nan, 0.0, 0.0), None),
                f.set_bias(Vec3::new(0.0, 2.0, 0.0), None),
                f.set_bias(Vec3::zero(), Some(nan)),
                f.set_heading(nan),
            ];
            for (i, r) in refused.iter().enumerate() {
                assert!(r.is_err(), "{name}: case {i} accepted");
            }
            assert_eq!(
                format!("{f:?}"),
                kept,
                "{name}: a refusal changed the state"
            );

            let has_cov = f.attitude_covariance().is_some();
            match f.set_quat(q, Some(0.02)) {
                Ok(()) => {
                    assert!(has_cov, "{name}: sigma taken without a covariance");
                    let p = f.attitude_covariance().unwrap();
                    for i in 0..3 {
                        for j in 0..3 {
                            let want = if i == j { 0.02 * 0.02 } else { 0.0 };
                            assert!((p.m[i][j] - want).abs() < 1e-12, "{name}: P[{i}][{j}]");
                        }
                    }
                    assert!(f.quat().angle_to(q) < 1e-9, "{name}: orientation");
                }
                Err(StateError::Unsupported(_)) => {
                    assert!(!has_cov, "{name}: sigma refused with a covariance");
                    assert_eq!(format!("{f:?}"), kept, "{name}: state changed");
                }
                Err(e) => panic!("{name}: {e}"),
            }
        }
    }
}
