//! The flagship filter `sqrt-eskf`: simulated scenarios with stated bounds, the square-root
//! covariance under random (also bad) data in f32, f32 against f64, and its accessors.
use proptest::prelude::*;
use rootfuse_attitude::filters::{SqrtEskf, SqrtEskfParams};
use rootfuse_attitude::registry::{FilterKind, FilterSpec};
use rootfuse_attitude::{ImuSample, Lane, Mask, Mat, OrientationFilter, Quat, Recording, Vec3};
use rootfuse_eval::metrics::{Alignment, evaluate};
use rootfuse_eval::sim::scenario;

fn params(dof: f64) -> SqrtEskfParams {
    SqrtEskfParams {
        dof: crate::common::dof(dof as u8),
        ..SqrtEskfParams::default()
    }
}

/// Runs the filter over a recording; returns the estimates and the filter.
fn run<T: Lane>(rec: &Recording, dof: f64) -> (Vec<Quat<f64>>, SqrtEskf<T>) {
    let mut f = SqrtEskf::<T>::new(&params(dof));
    (rec.estimate(&mut f), f)
}

/// The mean of `inclination(recording, p)` over seeds 0–2 of 60 s of the scenario `name` at
/// 100 Hz, for `a` and for `b`: one parameter against another on the same motion.
fn mean_inclinations(
    name: &str,
    a: &SqrtEskfParams,
    b: &SqrtEskfParams,
    inclination: impl Fn(&Recording, &SqrtEskfParams) -> f64,
) -> (f64, f64) {
    (0..3).fold((0.0, 0.0), |(sa, sb), seed| {
        let rec = scenario(name, seed, 60.0, 100.0).unwrap();
        (
            sa + inclination(&rec, a) / 3.0,
            sb + inclination(&rec, b) / 3.0,
        )
    })
}

/// Smoothed 6D inclination of `rec` with the passes built from `p` as given.
fn smoothed_inclination(rec: &Recording, p: &SqrtEskfParams) -> f64 {
    let out = rootfuse_attitude::smooth::forward_backward(rec, || SqrtEskf::new(p), false).unwrap();
    evaluate(rec, &out.quat, Alignment::SixD)
        .unwrap()
        .inclination
}

fn rmse64(rec: &Recording, dof: f64) -> (f64, f64) {
    let (est, _) = run::<f64>(rec, dof);
    let align = if dof > 7.5 {
        Alignment::NineD
    } else {
        Alignment::SixD
    };
    let r = evaluate(rec, &est, align).unwrap();
    (r.total, r.inclination)
}

/// Stated bounds (degrees, total RMSE 9D / 6D and inclination RMSE) on 60 s simulated
/// scenarios at 100 Hz, seed 1. The bounds are about twice what the filter reaches, so
/// they catch regressions without pinning noise.
#[test]
fn simulated_scenarios_within_bounds() {
    // (scenario, 9D total, 6D total, inclination)
    let cases = [
        ("slow-rotation", 1.2, 0.7, 0.6),
        // Known limitation: a 0.02 rad/s bias step (10× the BROAD bias) is tracked only at the
        // bias random-walk rate and through the inclination (no step detection yet).
        ("bias-step", 7.0, 5.0, 4.0),
        ("long-rest", 1.1, 0.8, 0.7),
        ("magnetic-disturbance", 1.1, 0.7, 0.6),
        ("translation", 2.0, 1.6, 1.6),
        ("irregular-dt", 1.2, 0.7, 0.6),
        ("vibration", 3.3, 5.3, 0.9),
    ];
    let mut failures = Vec::new();
    for (name, b9, b6, bi) in cases {
        let rec = scenario(name, 1, 60.0, 100.0).unwrap();
        let (t9, i9) = rmse64(&rec, 9.0);
        let (t6, i6) = rmse64(&rec, 6.0);
        eprintln!("{name:>22}: 9D {t9:.2} / 6D {t6:.2} / incl {i9:.2} {i6:.2}");
        if !(t9 < b9 && t6 < b6 && i9 < bi && i6 < bi) {
            failures.push(format!(
                "{name}: 9D {t9:.2} (<{b9}), 6D {t6:.2} (<{b6}), inclination {i9:.2}/{i6:.2} (<{bi})"
            ));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A magnetic disturbance must not tilt: the 9D inclination equals the 6D inclination
/// (the magnetometer only rotates about earth-z), sample by sample.
#[test]
fn magnetometer_never_tilts() {
    let rec = scenario("magnetic-disturbance", 2, 40.0, 100.0).unwrap();
    let mut f = SqrtEskf::<f64>::new(&params(9.0));
    let mut flagged = 0;
    for i in 0..rec.len() {
        f.update(&rec.sample(i), rec.dt(i));
        let (_, i9) = f.quat9().heading_inclination();
        let (_, i6) = f.quat6().heading_inclination();
        assert!(i9.angle_to(i6) < 1e-9, "sample {i}");
        flagged += f.magnetic_disturbance().unwrap() as usize;
    }
    assert!(flagged > 0, "the disturbance was never detected");
}

/// The rest flag is raised during a long rest and the bias is learned there.
#[test]
fn rest_is_detected_and_bias_learned() {
    let rec = scenario("long-rest", 3, 60.0, 100.0).unwrap();
    let mut f = SqrtEskf::<f64>::new(&params(6.0));
    let mut rest = 0usize;
    for i in 0..rec.len() {
        f.update(&rec.sample(i), rec.dt(i));
        rest += f.rest_detected().unwrap() as usize;
    }
    // 80 % of the run is rest; allow the detection delay.
    assert!(
        rest as f64 > 0.6 * rec.len() as f64,
        "rest {rest} of {}",
        rec.len()
    );
    let sim = rootfuse_eval::sim::scenario_simulation("long-rest", 3, 60.0, 100.0)
        .unwrap()
        .run()
        .unwrap();
    let true_bias = *sim.gyro_bias.last().unwrap();
    let err = (f.bias() - true_bias).norm();
    assert!(err < 2e-3, "bias error {err:e} rad/s");
}

/// f32 follows f64 closely on a long simulated run (angle between the estimates).
///
/// The rest timer sums `dt` in the filter's precision, so f32 may declare rest one sample
/// after f64; the first rest update moves bias and (through their correlation) attitude by
/// a few tenths of a degree at once, and the two runs then differ for a few samples until
/// f32 makes the same update. So: 99.5 % of samples within 0.01°, every sample within 0.5°,
/// and the rest flags equal on all but 0.1 % of the samples.
#[test]
fn f32_agrees_with_f64() {
    let rec = scenario("slow-rotation", 4, 120.0, 100.0).unwrap();
    for dof in [6.0, 9.0] {
        let (a, fa) = run::<f64>(&rec, dof);
        let (b, fb) = run::<f32>(&rec, dof);
        let mut diff: Vec<f64> = a
            .iter()
            .zip(&b)
            .map(|(x, y)| x.angle_to(*y).to_degrees())
            .collect();
        diff.sort_by(f64::total_cmp);
        let p995 = diff[diff.len() * 995 / 1000];
        let worst = diff[diff.len() - 1];
        assert!(
            p995 < 0.01 && worst < 0.5,
            "{dof}D: f32 vs f64 99.5 % {p995:.4}°, max {worst:.4}°"
        );
        assert!(fb.covariance().is_finite().all());
        assert_eq!(
            fa.rest_detected().unwrap(),
            fb.rest_detected().unwrap(),
            "{dof}D: rest flags at the end"
        );
    }
    // Rest flags sample by sample.
    let p = params(6.0);
    let (mut fa, mut fb) = (SqrtEskf::<f64>::new(&p), SqrtEskf::<f32>::new(&p));
    let mut differ = 0usize;
    for i in 0..rec.len() {
        let s = rec.sample(i);
        fa.update(&s, rec.dt(i));
        let v = |x: Vec3<f64>| Vec3::new(x.x as f32, x.y as f32, x.z as f32);
        fb.update(
            &ImuSample::new(v(s.gyr), v(s.acc), v(s.mag)),
            rec.dt(i) as f32,
        );
        differ += usize::from(fa.rest_detected().unwrap() != fb.rest_detected().unwrap());
    }
    assert!(
        differ * 1000 <= rec.len(),
        "rest flags differ on {differ} samples"
    );
}

#[test]
fn registered_with_alias() {
    assert_eq!(
        FilterSpec::new("flagship").unwrap().kind(),
        FilterKind::SqrtEskf
    );
    assert_eq!(FilterKind::SqrtEskf.name(), "sqrt-eskf");
}

fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => -20.0..20.0f64,
        1 => prop::sample::select(vec![f64::NAN, f64::INFINITY, 0.0, 1e30, -1e20]),
    ]
}

/// Symmetric positive (semi)definite in f32 with a bounded condition: `P = S·Sᵀ` has
/// non-negative eigen-structure by construction; check `P` is finite, symmetric to rounding,
/// has a positive diagonal and passes a Cholesky factorisation of `P + ε·I`. The heading's
/// variance starts at 0 (`init_heading_std`: a 6D heading is relative to the start; in 9D it
/// is set when the filter starts from a field) and grows from the first propagated sample, so
/// before then (`started` false: the first sample, perhaps a bad one) it need only be
/// non-negative.
fn check_cov(f: &SqrtEskf<f32>, started: bool) -> Result<(), TestCaseError> {
    let p = f.covariance();
    prop_assert!(p.is_finite().all(), "{p:?}");
    for i in 0..6 {
        if !started && i == 2 {
            prop_assert!(p.m[i][i] >= 0.0, "diag {i}: {p:?}");
        } else {
            prop_assert!(p.m[i][i] > 0.0, "diag {i}: {p:?}");
        }
        for j in 0..6 {
            prop_assert!((p.m[i][j] - p.m[j][i]).abs() <= 1e-6 * (p.m[i][i] * p.m[j][j]).sqrt());
        }
    }
    let eps = f32::from_f64(1e-12);
    let (_, ok) = (p + Mat::identity().scale(eps)).cholesky();
    prop_assert!(ok, "not PD: {p:?}");
    let a = f.attitude_covariance().unwrap();
    prop_assert!(a.is_finite().all() && a.m[0][0] > 0.0);
    let heading_ok = if !started {
        a.m[2][2] >= 0.0
    } else {
        a.m[2][2] > 0.0
    };
    prop_assert!(heading_ok, "heading variance {}", a.m[2][2]);
    // The inclination block is that of the full covariance off the diagonal, and the diagonal
    // adds the model error, which is never negative. Both to rounding: the report applies the
    // deferred time update in closed form where `covariance` folds it (and, with nothing
    // pending, a zero noise) into a copy of the factor by reflections, which change its last
    // bits. By Cauchy–Schwarz no term of `P01` exceeds `√(P00·P11)`, which scales it. (The
    // same in `f64` at 1e-12 with a time update pending: the unit tests of `update.rs`.)
    let scale = (p.m[0][0] * p.m[1][1]).sqrt();
    for (i, j) in [(0, 1), (1, 0)] {
        prop_assert!(
            (a.m[i][j] - p.m[i][j]).abs() <= 1e-5 * scale,
            "{i}{j}: {a:?} vs {p:?}"
        );
    }
    for i in 0..2 {
        prop_assert!(
            a.m[i][i] >= p.m[i][i] * (1.0 - 1e-5),
            "{i}: {} < {}",
            a.m[i][i],
            p.m[i][i]
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// A long f32 run over random motion with bad samples mixed in keeps the covariance
    /// symmetric positive definite and the quaternion unit.
    #[test]
    fn covariance_stays_pd_in_f32(
        seed in 0u64..1000,
        bad in prop::collection::vec((0usize..4000, prop::array::uniform9(value()), -1.0..0.1f64), 0..40),
        dof in prop::sample::select(vec![6.0, 9.0]),
    ) {
        let rec = scenario("fast-rotation", seed, 40.0, 100.0).unwrap();
        let mut f = SqrtEskf::<f32>::new(&params(dof));
        let c = |v: Vec3<f64>| Vec3::new(v.x as f32, v.y as f32, v.z as f32);
        for i in 0..rec.len() {
            let s = rec.sample(i);
            let (mut sample, mut dt) = (ImuSample::new(c(s.gyr), c(s.acc), c(s.mag)), rec.dt(i) as f32);
            if let Some((_, v, d)) = bad.iter().find(|(k, _, _)| *k == i) {
                sample = ImuSample::new(
                    Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32),
                    Vec3::new(v[3] as f32, v[4] as f32, v[5] as f32),
                    Vec3::new(v[6] as f32, v[7] as f32, v[8] as f32),
                );
                if *d < 0.0 { dt = *d as f32; }
            }
            f.update(&sample, dt);
            if i % 500 == 0 {
                check_cov(&f, i > 0)?;
            }
            prop_assert!((f.quat().norm() - 1.0).abs() < 1e-5);
        }
        check_cov(&f, true)?;
    }
}

/// The forward-backward smoother: on a simulated run it is more accurate than the forward
/// filter alone, in 9D and 6D (each sample's estimate then uses the whole recording).
#[test]
fn smoother_beats_the_forward_filter() {
    use rootfuse_attitude::smooth::forward_backward;
    for (name, seed) in [("slow-rotation", 2), ("translation", 3)] {
        let rec = scenario(name, seed, 60.0, 100.0).unwrap();
        for (dof, align) in [(9.0, Alignment::NineD), (6.0, Alignment::SixD)] {
            let p = params(dof).for_smoothing();
            let out = forward_backward(&rec, || SqrtEskf::new(&p), dof > 7.5).unwrap();
            assert_eq!(out.forward_only, 0);
            let smooth = evaluate(&rec, &out.quat, align).unwrap().total;
            let (fwd, _) = rmse64(&rec, dof);
            eprintln!("{name} {dof}D: forward {fwd:.3}°, smoothed {smooth:.3}°");
            assert!(
                smooth < 0.9 * fwd,
                "{name} {dof}D: smoothed {smooth:.3}° vs forward {fwd:.3}°"
            );
        }
    }
}

/// Offline the passes' accelerometer time constants (`for_smoothing`: the long window longer
/// than online, the short one shorter) lower the smoothed inclination error under motion
/// acceleration: in each pass the lag is cancelled by the other pass, the acceleration the
/// long window removes is not. Measured (3 seeds, 60 s, 6D, two windows, without the
/// gyroscope refinement): pendulum 0.715° → 0.703°, handheld translation 0.621° → 0.539°,
/// vehicle 7.60° → 7.25° (both windows longer, the earlier design: 0.692°, 0.577°, 7.18°).
#[test]
fn smoothing_time_constant_lowers_the_inclination_error() {
    // The two-filter fusion alone (no gyroscope refinement after it), the passes' other
    // settings (`for_smoothing`) in both: only the time constants differ.
    let p = SqrtEskfParams {
        smoothing_gyro_tau: 0.0,
        ..params(6.0)
    };
    let same_tau = SqrtEskfParams {
        smoothing_tau_scale: 1.0,
        smoothing_short_tau_scale: 1.0,
        ..p.clone()
    };
    for (name, most) in [
        ("pendulum-6d", 0.99),
        ("handheld-translation-6d", 0.9),
        ("vehicle-6d", 0.97),
    ] {
        let (online, offline) = mean_inclinations(
            name,
            &same_tau.for_smoothing(),
            &p.for_smoothing(),
            smoothed_inclination,
        );
        eprintln!("{name}: smoothed inclination {online:.3}° (online tau_acc), {offline:.3}°");
        assert!(
            offline < most * online,
            "{name}: {offline:.3}° with for_smoothing, {online:.3}° without"
        );
    }
}

/// The second accelerometer window (`tau_acc_long`) lowers the online inclination error where
/// the motion is translation, and leaves rotation alone, where its weight stays low. Measured
/// (3 seeds, 60 s, 6D, one window → two): pendulum 0.918° → 0.643°, handheld translation
/// 1.197° → 0.879°, translation 0.862° → 0.690°, vehicle 10.21° → 9.43°; fast rotation 0.879° →
/// 0.879°, slow rotation 0.345° → 0.343°.
#[test]
fn second_window_serves_translation_and_leaves_rotation_alone() {
    for (name, most) in [
        ("pendulum-6d", 0.8),
        ("handheld-translation-6d", 0.85),
        ("translation", 0.9),
        ("vehicle-6d", 0.97),
        ("fast-rotation", 1.01),
        ("slow-rotation", 1.01),
    ] {
        let one_window = SqrtEskfParams {
            tau_acc_long: 0.0,
            ..params(6.0)
        };
        let (one, two) = mean_inclinations(name, &one_window, &params(6.0), |rec, p| {
            let est = rec.estimate(&mut SqrtEskf::<f64>::new(p));
            evaluate(rec, &est, Alignment::SixD).unwrap().inclination
        });
        eprintln!("{name}: inclination {one:.3}° with one window, {two:.3}° with two");
        assert!(
            two < most * one,
            "{name}: {two:.3}° with two windows, {one:.3}° with one (at most {most}×)"
        );
    }
}

/// The smoother's gyroscope refinement (`smoothing_gyro_tau`) takes out motion acceleration
/// the two passes let through: the smoothed inclination on the simulated pendulum and
/// handheld translation falls (3 seeds, 60 s, 6D, the smoother's parameters: 0.703° → 0.671°,
/// 0.539° → 0.442°), and on slow rotation, with nothing to take out, it stays within 2 %
/// (0.341° → 0.334°).
#[test]
fn gyro_refinement_lowers_the_smoothed_inclination() {
    let unrefined = SqrtEskfParams {
        smoothing_gyro_tau: 0.0,
        ..params(6.0)
    };
    for (name, most) in [
        ("pendulum-6d", 0.98),
        ("handheld-translation-6d", 0.92),
        ("slow-rotation", 1.02),
    ] {
        let (plain, refined) = mean_inclinations(
            name,
            &unrefined.for_smoothing(),
            &params(6.0).for_smoothing(),
            smoothed_inclination,
        );
        eprintln!("{name}: smoothed inclination {plain:.3}° → {refined:.3}° refined");
        assert!(
            refined < most * plain,
            "{name}: {refined:.3}° refined, {plain:.3}° without"
        );
    }
}

/// A filter without an attitude covariance cannot be smoothed (typed error); bad samples
/// neither panic nor leak NaN into the smoothed estimates.
#[test]
fn smoother_errors_and_bad_samples() {
    use rootfuse_attitude::filters::{Mahony, MahonyParams};
    use rootfuse_attitude::smooth::{SmoothError, forward_backward};
    let mut rec = scenario("slow-rotation", 5, 20.0, 100.0).unwrap();
    let mp = MahonyParams::default();
    assert_eq!(
        forward_backward(&rec, || Mahony::new(&mp), true).unwrap_err(),
        SmoothError::NoCovariance
    );
    for i in [0, 1, 700, 701, 1999] {
        rec.gyr[i] = Vec3::new(f64::NAN, 0.0, 0.0);
    }
    rec.acc[900] = Vec3::new(f64::INFINITY, 0.0, 9.81);
    rec.t[1200] = rec.t[1199];
    let p = params(9.0);
    let out = forward_backward(&rec, || SqrtEskf::new(&p), true).unwrap();
    assert_eq!(out.quat.len(), rec.len());
    assert!(out.quat.iter().all(|q| q.is_finite()));
    let err = evaluate(&rec, &out.quat, Alignment::NineD).unwrap().total;
    assert!(err < 2.0, "smoothed error {err:.3}° with bad samples");
}

/// A sample the filter skips whole (a gyroscope spike beyond `max_gyr`, a step beyond
/// `max_dt`) is skipped by the smoother's refinement by the gyroscope too: the smoothed
/// estimates stay where those of the clean recording are, as the online ones do. Before,
/// the refinement turned by the spike (tens of degrees for seconds) or by the gap's rate
/// over 30 s.
#[test]
fn the_smoothers_refinement_skips_what_the_filter_skipped() {
    use rootfuse_attitude::smooth::smooth_spec;
    let clean = scenario("slow-rotation", 5, 20.0, 100.0).unwrap();
    let spec = FilterSpec::new("flagship").unwrap();
    let reference = smooth_spec(&clean, &spec, true).unwrap().quat;
    let mut spike = clean.clone();
    spike.gyr[700] = Vec3::new(1000.0, 0.0, 0.0);
    let mut gap = clean.clone();
    for t in &mut gap.t[1200..] {
        *t += 30.0;
    }
    for (name, rec) in [("spike", &spike), ("gap", &gap)] {
        let out = smooth_spec(rec, &spec, true).unwrap();
        let worst = out
            .quat
            .iter()
            .zip(&reference)
            .map(|(a, b)| a.angle_to(*b).to_degrees())
            .fold(0.0, f64::max);
        assert!(
            worst < 1.0,
            "{name}: smoothed estimates {worst:.3}° from the clean run's"
        );
        let skipped = out.rejections.gyr[0] + out.rejections.dt[0];
        assert_eq!(skipped, 1, "{name}: the one sample is skipped and counted");
    }
}

/// A lone sample between gaps, and a gap after the first sample or before the last, is
/// estimated from its own readings (it was left at the filter's initial state, the identity,
/// 60° from the truth here); a time that is not a number next to a gap does not hide it.
#[test]
fn the_smoother_estimates_lone_samples_between_gaps() {
    use rootfuse_attitude::smooth::smooth_spec;
    let spec = FilterSpec::new("flagship").unwrap();
    let mut rec = scenario("static", 2, 20.0, 100.0).unwrap();
    let tilt = Quat::from_rotation_vector(Vec3::new(1.047, 0.0, 0.0));
    for (a, m) in rec.acc.iter_mut().zip(rec.mag.as_mut().unwrap()) {
        *a = tilt.conj().rotate(*a);
        *m = tilt.conj().rotate(*m);
    }
    let truth = rec.truth.as_ref().unwrap()[0] * tilt;
    // Gaps after sample 0, around sample 1000, before the last sample.
    let n = rec.len();
    for k in 1..n {
        let jumps = [1, 1000, 1001, n - 1].iter().filter(|&&g| k >= g).count();
        rec.t[k] += 30.0 * jumps as f64;
    }
    let mut nan_time = rec.clone();
    nan_time.t[500] = f64::NAN;
    for t in &mut nan_time.t[501..] {
        *t += 30.0;
    }
    // Skipped steps: one per gap, and the sample whose time is not a number.
    for (name, rec, skipped) in [("lone", &rec, 4), ("nan", &nan_time, 6u64)] {
        let out = smooth_spec(rec, &spec, true).unwrap();
        // A lone sample's inclination is its accelerometer's; its heading comes from one
        // magnetometer reading through the filter's start-up (measured: 0.1–0.7° in tilt,
        // 2.3–2.6° in all).
        for k in [0, 1000, n - 1] {
            let off = tilt_of(out.quat[k], truth);
            let all = out.quat[k].angle_to(truth).to_degrees();
            assert!(
                off < 1.5 && all < 4.0,
                "{name}: lone sample {k} is tilted {off:.1}° off, {all:.1}° in all"
            );
        }
        for k in [499, 502, 999, 1002] {
            let off = out.quat[k].angle_to(truth).to_degrees();
            assert!(off < 3.0, "{name}: sample {k} is {off:.1}° from the truth");
        }
        assert_eq!(out.rejections.dt[0], skipped, "{name}: each counted once");
    }
    // Every step beyond max_dt: every sample is a lone one, each estimated and counted once
    // (the copy held over a step of its own was skipped, and the estimate dropped).
    let mut every = spec.clone();
    every.set("max_dt=0.005").unwrap();
    let short = rec.slice(2..300);
    let out = smooth_spec(&short, &every, true).unwrap();
    assert_eq!(out.quat.len(), short.len());
    assert_eq!(out.rejections.dt[0], short.len() as u64 - 1);
    let worst = out
        .quat
        .iter()
        .map(|q| tilt_of(*q, truth))
        .fold(0.0, f64::max);
    assert!(worst < 1.5, "a lone sample tilted {worst:.1}° off");
}

/// The angle (degrees) between the vertical as `q` and as `truth` see it.
fn tilt_of(q: Quat<f64>, truth: Quat<f64>) -> f64 {
    let up = Vec3::new(0.0, 0.0, 1.0);
    let (a, b) = (q.rotate_inverse(up), truth.rotate_inverse(up));
    a.cross(b).norm().atan2(a.dot(b)).to_degrees()
}

/// Samples missing (30 s of a 60 s rotation dropped, the time stamps kept): each stretch
/// between the gap is smoothed on its own, as well as with the samples there. A pass that
/// carried its orientation across the gap moved the estimates on the gap's other side by 18°
/// (slow rotation, 9D) to 116° (fast rotation).
#[test]
fn the_smoother_starts_again_after_samples_missing() {
    use rootfuse_attitude::smooth::smooth_spec;
    let spec = FilterSpec::new("flagship").unwrap();
    for (name, nine_d) in [
        ("slow-rotation", true),
        ("fast-rotation", true),
        ("slow-rotation", false),
    ] {
        let clean = scenario(name, 5, 60.0, 100.0).unwrap();
        let kept: Vec<usize> = (0..2000).chain(5000..clean.len()).collect();
        let pick = |v: &[Vec3<f64>]| kept.iter().map(|&i| v[i]).collect::<Vec<_>>();
        let gap = Recording {
            t: kept.iter().map(|&i| clean.t[i]).collect(),
            gyr: pick(&clean.gyr),
            acc: pick(&clean.acc),
            mag: clean.mag.as_deref().map(pick),
            truth: clean
                .truth
                .as_ref()
                .map(|q| kept.iter().map(|&i| q[i]).collect()),
            ..Recording::default()
        };
        let out = smooth_spec(&gap, &spec, nine_d).unwrap();
        assert_eq!(out.quat.len(), gap.len());
        assert_eq!(out.rejections.dt[0], 1, "{name}: the gap is counted");
        let align = if nine_d {
            Alignment::NineD
        } else {
            Alignment::SixD
        };
        // Each side against the same samples smoothed without the gap, each aligned on its
        // own (a 6D heading after a gap is anyone's).
        let whole = smooth_spec(&clean, &spec, nine_d).unwrap().quat;
        for (side, at) in [("before", 0..2000), ("after", 2000..gap.len())] {
            let with_gap = evaluate(&gap.slice(at.clone()), &out.quat[at.clone()], align).unwrap();
            let reference: Vec<Quat<f64>> = at.clone().map(|i| whole[kept[i]]).collect();
            let without = evaluate(&gap.slice(at.clone()), &reference, align).unwrap();
            // Measured: totals within 1.0° (a shorter stretch settles heading less),
            // inclinations within 0.06°; before the fix 2.3–25° and 0.16–21°.
            assert!(
                with_gap.total < without.total + 1.5
                    && with_gap.inclination < without.inclination + 0.1,
                "{name}, 9D {nine_d}, {side} the gap: total {:.3}° (without the gap {:.3}°), \
                 inclination {:.3}° ({:.3}°)",
                with_gap.total,
                without.total,
                with_gap.inclination,
                without.inclination
            );
        }
    }
}

type F64x2 = rootfuse_lane::wide::f64x2;

/// The flagship whose forward lane (0) reports a NaN covariance at chosen updates: the
/// smoother cannot fuse those samples.
struct NanCovarianceAt {
    inner: SqrtEskf<F64x2>,
    steps: Vec<usize>,
    done: usize,
}

impl OrientationFilter<F64x2> for NanCovarianceAt {
    fn update(&mut self, sample: &ImuSample<F64x2>, dt: F64x2) {
        self.inner.update(sample, dt);
        self.done += 1;
    }
    fn quat(&self) -> Quat<F64x2> {
        self.inner.quat()
    }
    fn rejections(&self) -> &rootfuse_attitude::filters::Rejections<F64x2> {
        self.inner.rejections()
    }
    fn attitude_covariance(&self) -> Option<Mat<F64x2, 3, 3>> {
        let mut p = self.inner.attitude_covariance()?;
        if self.steps.contains(&(self.done.wrapping_sub(1))) {
            p.m[1][1].set_lane(0, f64::NAN);
        }
        Some(p)
    }
    fn reset(&mut self) {
        self.inner.reset();
        self.done = 0;
    }
    fn set_quat(
        &mut self,
        q: Quat<F64x2>,
        sigma: Option<F64x2>,
    ) -> Result<(), rootfuse_attitude::filters::StateError> {
        self.inner.set_quat(q, sigma)
    }
}

/// The fusion runs four samples at a time: a sample that cannot be fused (here a NaN in the
/// forward covariance, at samples across chunk boundaries and in the last, partial chunk)
/// keeps its forward estimate and is counted, and every other sample equals the smoother
/// without the NaN bit for bit.
#[test]
fn samples_that_cannot_be_fused_keep_the_forward_estimate() {
    use rootfuse_attitude::smooth::forward_backward;
    let rec = scenario("slow-rotation", 3, 1.01, 100.0).unwrap();
    let n = rec.len();
    assert_eq!(n % 4, 1, "the last chunk must be partial");
    // The fusion alone: the gyroscope refinement after it would spread a kept sample.
    let p = SqrtEskfParams {
        smoothing_gyro_tau: 0.0,
        ..params(9.0)
    };
    let bad = vec![3, 4, 7, 8, 9, n - 1];
    let plain = forward_backward(&rec, || SqrtEskf::new(&p), true).unwrap();
    let out = forward_backward(
        &rec,
        || NanCovarianceAt {
            inner: SqrtEskf::new(&p),
            steps: bad.clone(),
            done: 0,
        },
        true,
    )
    .unwrap();
    let (forward, _) = run::<f64>(&rec, 9.0);
    assert_eq!(out.forward_only, bad.len());
    assert_eq!(plain.forward_only, 0);
    for k in 0..n {
        let want = if bad.contains(&k) {
            forward[k]
        } else {
            plain.quat[k]
        };
        assert_eq!(out.quat[k].to_array(), want.to_array(), "sample {k}");
    }
}

/// Every time constant and noise density is in seconds, not samples: the same simulated
/// motion sampled at 50, 100, 200 and 400 Hz gives the same accuracy (spread of total RMSE
/// below 0.2°, 9D and 6D; measured 0.13° at most). A filter tuned in samples would change its
/// bandwidth 8× over this range.
#[test]
fn accuracy_does_not_depend_on_the_sample_rate() {
    for name in ["slow-rotation", "translation", "irregular-dt", "long-rest"] {
        for dof in [9.0, 6.0] {
            let errs: Vec<f64> = [50.0, 100.0, 200.0, 400.0]
                .iter()
                .map(|&hz| rmse64(&scenario(name, 1, 60.0, hz).unwrap(), dof).0)
                .collect();
            let (lo, hi) = errs
                .iter()
                .fold((f64::MAX, 0.0f64), |(lo, hi), &e| (lo.min(e), hi.max(e)));
            assert!(
                hi - lo < 0.2,
                "{name} {dof}D: total RMSE over 50–400 Hz {errs:.3?}"
            );
        }
    }
}

/// `reset` then the same samples gives the same bits as a new filter: estimates, bias and
/// covariance factor, 9D and 6D, f64 and f32.
#[test]
fn reset_is_a_new_filter() {
    fn check<T: Lane>(rec: &Recording, dof: f64) {
        let (fresh_est, fresh) = run::<T>(rec, dof);
        let mut f = SqrtEskf::<T>::new(&params(dof));
        let _ = rec.estimate(&mut f);
        f.reset();
        let est = rec.estimate(&mut f);
        let bits = |q: &Quat<f64>| [q.w, q.x, q.y, q.z].map(f64::to_bits);
        assert!(
            est.iter().map(bits).eq(fresh_est.iter().map(bits)),
            "{dof}D estimates differ after reset"
        );
        let fb = |v: Vec3<T>| [v.x, v.y, v.z].map(|x| x.extract(0).into().to_bits());
        assert_eq!(fb(f.bias()), fb(fresh.bias()));
        let fm = |m: &Mat<T, 6, 6>| m.m.map(|r| r.map(|x| x.extract(0).into().to_bits()));
        assert_eq!(fm(&f.covariance_factor()), fm(&fresh.covariance_factor()));
    }
    let rec = scenario("slow-rotation", 3, 20.0, 100.0).unwrap();
    for dof in [9.0, 6.0] {
        check::<f64>(&rec, dof);
        check::<f32>(&rec, dof);
    }
}

/// `set_quat` with a `sigma` sets the attitude covariance with the orientation: read back as
/// `sigma²·I` at once, kept through the first sample when set before it (not replaced by
/// the initial covariance), and refused with nothing changed for a NaN, negative or too
/// large `sigma` and a quaternion far from unit norm.
#[test]
fn set_quat_with_sigma_sets_the_covariance() {
    let rec = scenario("slow-rotation", 3, 10.0, 100.0).unwrap();
    let q = Quat::from_euler_zyx(0.4, 0.05, -0.1);
    for dof in [9.0, 6.0] {
        // Running: σ² on the diagonal at once, no correlation left.
        let (_, mut f) = run::<f64>(&rec, dof);
        f.set_quat(q, Some(0.03)).unwrap();
        let p = f.attitude_covariance().unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 0.03 * 0.03 } else { 0.0 };
                assert!(
                    (p.m[i][j] - want).abs() < 1e-15,
                    "{dof}D P[{i}][{j}] = {}",
                    p.m[i][j]
                );
            }
        }
        assert!(f.quat().angle_to(q) < 1e-12, "{dof}D orientation");
        // Before the first sample: the first sample keeps σ (grown by one step's noise only),
        // where a plain `set_quat` starts from the initial covariance.
        let first = &rec.sample(0);
        let mut with = SqrtEskf::<f64>::new(&params(dof));
        with.set_quat(q, Some(0.001)).unwrap();
        with.update(first, rec.dt(0));
        let mut plain = SqrtEskf::<f64>::new(&params(dof));
        plain.set_quat(q, None).unwrap();
        plain.update(first, rec.dt(0));
        let (pw, pp) = (
            with.attitude_covariance().unwrap(),
            plain.attitude_covariance().unwrap(),
        );
        assert!(
            pw.m[0][0] < 2.0 * 0.001 * 0.001 && pw.m[0][0] < pp.m[0][0] / 4.0,
            "{dof}D: σ² = 1e-6 became {} (plain preset {})",
            pw.m[0][0],
            pp.m[0][0]
        );
        // Refusals leave the state as it was.
        let before = f.clone();
        for (q_bad, sigma) in [
            (q, f64::NAN),
            (q, -0.1),
            (q, 4.0),
            (Quat::new(1e-16, 1e-16, 0.0, 0.0), 0.1),
            (Quat::new(f64::NAN, 0.0, 0.0, 0.0), 0.1),
        ] {
            let e = f.set_quat(q_bad, Some(sigma)).unwrap_err();
            assert!(e.to_string().contains("outside"), "{e}");
        }
        assert_eq!(format!("{f:?}"), format!("{before:?}"));
    }
}

/// `set_bias` with a `sigma` sets the bias and its covariance `σ²·I`, removes the attitude–bias
/// correlation and keeps the attitude covariance; refusals change nothing.
#[test]
fn set_bias_with_sigma_keeps_the_attitude_covariance() {
    let rec = scenario("slow-rotation", 3, 10.0, 100.0).unwrap();
    for dof in [9.0, 6.0] {
        let (_, mut f) = run::<f64>(&rec, dof);
        let before = f.attitude_covariance().unwrap();
        let b = Vec3::new(0.01, -0.003, 0.002);
        f.set_bias(b, Some(2e-3)).unwrap();
        assert_eq!(f.bias(), b);
        let after = f.attitude_covariance().unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let d = (after.m[i][j] - before.m[i][j]).abs();
                assert!(
                    d <= 1e-12 * before.m[i][i].max(before.m[j][j]),
                    "{dof}D P[{i}][{j}]"
                );
            }
        }
        let s = f.covariance_factor();
        for i in 0..6 {
            for j in 0..6 {
                // P = S·Sᵀ: row i against row j.
                let pij: f64 = (0..6).map(|k| s.m[i][k] * s.m[j][k]).sum();
                let want = match (i < 3, j < 3) {
                    (false, false) if i == j => 4e-6,
                    (true, true) => pij,
                    _ => 0.0,
                };
                assert!((pij - want).abs() < 1e-18, "{dof}D P[{i}][{j}] = {pij}");
            }
        }
        let kept = format!("{f:?}");
        for (bias, sigma) in [
            (Vec3::new(f64::NAN, 0.0, 0.0), 1e-3),
            (Vec3::new(0.0, 2.0, 0.0), 1e-3),
            (b, f64::NAN),
            (b, -1.0),
        ] {
            assert!(f.set_bias(bias, Some(sigma)).is_err());
        }
        assert_eq!(format!("{f:?}"), kept);
        // The filter runs on from there.
        let _ = rec.estimate(&mut f);
        assert!(f.quat().w.is_finite());
    }
}

/// The 9D field test: a still sensor in a 50 µT field (dip 64°), 100 Hz. Sample-to-sample
/// noise of ±4 % on the field norm is not a disturbance (the tests see the norm low-passed,
/// `mag_lowpass_tau`); without the low-pass a 3 % threshold rejects every other sample and
/// the field never settles. A field
/// 30 % too strong for 1 s is flagged while it lasts and for `mag_settle_time` after it ends,
/// then the heading is corrected again.
#[test]
fn a_disturbance_is_flagged_until_the_field_has_settled() {
    let dip = 64f64.to_radians();
    let field = Vec3::new(0.0, dip.cos(), -dip.sin()) * 50.0;
    let acc = Vec3::new(0.0, 0.0, 9.81);
    let dt = 0.01;
    // The share of samples flagged as magnetically disturbed in [from, to) seconds.
    let flagged = |p: &SqrtEskfParams, scale: &dyn Fn(usize) -> f64, from: f64, to: f64| {
        let mut f = SqrtEskf::<f64>::new(p);
        let (mut n, mut hits) = (0, 0);
        for i in 0..1500 {
            f.update(&ImuSample::new(Vec3::zero(), acc, field * scale(i)), dt);
            let t = i as f64 * dt;
            if t >= from - 1e-9 && t < to - 1e-9 {
                n += 1;
                hits += usize::from(f.magnetic_disturbance() == Some(true));
            }
        }
        hits as f64 / n as f64
    };
    // The first sample, which sets the reference, is the true field.
    let noisy = |i: usize| match i {
        0 => 1.0,
        _ if i.is_multiple_of(2) => 1.04,
        _ => 0.96,
    };
    // Every reading tested on its own: the mean of `mag_update_every` readings would average
    // the alternation away before the low-pass sees it.
    let tight = |tau: f64| SqrtEskfParams {
        mag_norm_th: 0.03,
        mag_lowpass_tau: tau,
        mag_update_every: 1.0,
        ..params(9.0)
    };
    assert_eq!(flagged(&tight(0.05), &noisy, 1.0, 15.0), 0.0);
    // Unfiltered, every other sample fails the test, so the field never settles.
    assert_eq!(flagged(&tight(0.0), &noisy, 1.0, 15.0), 1.0);

    let pulse = |i: usize| if (500..600).contains(&i) { 1.3 } else { 1.0 };
    let p = params(9.0);
    let settle = p.mag_settle_time;
    assert_eq!(flagged(&p, &pulse, 1.0, 5.0), 0.0, "before the disturbance");
    // The low-pass (50 ms) takes a few samples to cross the 7 % threshold each way.
    assert_eq!(
        flagged(&p, &pulse, 5.05, 6.0 + settle),
        1.0,
        "while disturbed and settling"
    );
    assert_eq!(flagged(&p, &pulse, 6.1 + settle, 15.0), 0.0, "settled");
}

/// A room-fixed disturbance that is homogeneous and stable for longer than `mag_new_time`
/// (the simulated `pendulum-disturbed`, 9D, three seeds of 120 s) is adopted as a new
/// reference with its own azimuth, not as north: the heading error stays a fraction of what
/// it is when the adopted field becomes north at once (`mag_azimuth_tau = 0`). Without the
/// home field's return (`mag_home_time = 0`), which gives the heading back when the
/// disturbance ends either way ([`the_home_field_gives_the_heading_back`]).
#[test]
fn an_adopted_field_keeps_the_heading() {
    let rmse = |tau: f64| {
        let p = SqrtEskfParams {
            mag_azimuth_tau: tau,
            mag_home_time: 0.0,
            ..params(9.0)
        };
        disturbed_pendulum_rmse(&p, 120.0)
    };
    let (kept, north) = (rmse(params(9.0).mag_azimuth_tau), rmse(0.0));
    eprintln!("pendulum-disturbed 9D: {kept:.2}° keeping the heading, {north:.2}° adopting north");
    assert!(kept < 0.4 * north, "{kept} vs {north}");
}

/// Where a lasting disturbance has been adopted and the field then returns to the home field
/// (the simulated `pendulum-disturbed` over 300 s: a room-fixed disturbance from 90 s to
/// 165 s, adopted after `mag_new_time`), the home field is the reference again at once,
/// pointing north, instead of being rejected for `mag_new_time` and then adopted with the
/// azimuth the turned heading gives it: the heading error over the run is well under what it
/// is without the return (`mag_home_time = 0`).
#[test]
fn the_home_field_gives_the_heading_back() {
    let rmse = |home_time: f64| {
        let p = SqrtEskfParams {
            mag_home_time: home_time,
            ..params(9.0)
        };
        disturbed_pendulum_rmse(&p, 300.0)
    };
    let (home, without) = (rmse(params(9.0).mag_home_time), rmse(0.0));
    eprintln!(
        "pendulum-disturbed 9D, 300 s: {home:.2}° with the home field, {without:.2}° without"
    );
    assert!(home < 0.6 * without, "{home} vs {without}");
}

/// Mean 9D total RMSE (degrees) of the simulated `pendulum-disturbed`, seeds 0–2, `seconds`
/// long.
fn disturbed_pendulum_rmse(p: &SqrtEskfParams, seconds: f64) -> f64 {
    let mut sum = 0.0;
    for seed in 0..3 {
        let rec = scenario("pendulum-disturbed", seed, seconds, 100.0).unwrap();
        let est = rec.estimate(&mut SqrtEskf::<f64>::new(p));
        sum += evaluate(&rec, &est, Alignment::NineD).unwrap().total / 3.0;
    }
    sum
}

/// A lane whose magnetometer readings start only after the first 2 s (NaN before) takes its
/// first reading as the field reference and corrects the heading from there, as a lane with
/// readings from the start does, instead of rejecting the field until a candidate is adopted
/// (`mag_new_time`, 20 s): 1 s after the readings start the heading is within 2° of that of
/// a filter that had them from the start. `forget_field_reference` does the same for a
/// running filter.
#[test]
fn a_late_field_becomes_the_reference() {
    let rec = scenario("slow-rotation", 2, 12.0, 100.0).unwrap();
    let late = |i: usize, s: ImuSample<f64>| {
        if i < 200 {
            ImuSample::new(s.gyr, s.acc, Vec3::new(f64::NAN, f64::NAN, f64::NAN))
        } else {
            s
        }
    };
    let heading = |f: &SqrtEskf<f64>| f.quat().heading_inclination().0;
    let (mut full, mut delayed, mut forgot) = (
        SqrtEskf::<f64>::new(&params(9.0)),
        SqrtEskf::<f64>::new(&params(9.0)),
        SqrtEskf::<f64>::new(&params(9.0)),
    );
    for i in 0..300 {
        let s = rec.sample(i);
        full.update(&s, rec.dt(i));
        delayed.update(&late(i, s), rec.dt(i));
        // A field 20 % stronger from 1 s on, known to the filter as a new calibration.
        let scaled = ImuSample::new(s.gyr, s.acc, s.mag * if i >= 100 { 1.2 } else { 1.0 });
        if i == 100 {
            forgot.forget_field_reference(true);
        }
        forgot.update(&scaled, rec.dt(i));
        if i >= 100 {
            assert_eq!(forgot.magnetic_disturbance(), Some(false), "sample {i}");
        }
    }
    let gap = |f: &SqrtEskf<f64>| {
        let d = (heading(f) - heading(&full)).to_degrees();
        (d + 180.0).rem_euclid(360.0) - 180.0
    };
    assert!(gap(&delayed).abs() < 2.0, "{}", gap(&delayed));
    assert_eq!(delayed.magnetic_disturbance(), Some(false));
    assert!(gap(&forgot).abs() < 2.0, "{}", gap(&forgot));
}

/// A forgotten reference stays forgotten until a reading gives an azimuth: readings of a
/// field within a degree of vertical do not make a reference, and the first usable one
/// resets the heading with the initial heading uncertainty (30°), not the converged one.
#[test]
fn a_new_reference_waits_for_an_azimuth_and_starts_uncertain() {
    let rec = scenario("slow-rotation", 2, 12.0, 100.0).unwrap();
    let heading = |f: &SqrtEskf<f64>| f.quat().heading_inclination().0;
    let heading_var = |f: &SqrtEskf<f64>| f.attitude_covariance().unwrap().m[2][2];
    let (mut full, mut forgot) = (
        SqrtEskf::<f64>::new(&params(9.0)),
        SqrtEskf::<f64>::new(&params(9.0)),
    );
    for i in 0..400 {
        let s = rec.sample(i);
        full.update(&s, rec.dt(i));
        if i == 100 {
            assert!(heading_var(&forgot) < 0.05, "{}", heading_var(&forgot));
            forgot.forget_field_reference(true);
        }
        // From 1 s on a field 20 % stronger, first pointing up (no azimuth) for 0.2 s.
        let mag = match i {
            0..100 => s.mag,
            100..120 => s.acc * (1.2 * s.mag.norm() / s.acc.norm()),
            _ => s.mag * 1.2,
        };
        forgot.update(&ImuSample::new(s.gyr, s.acc, mag), rec.dt(i));
        if i == 120 {
            assert!(heading_var(&forgot) >= 0.25, "{}", heading_var(&forgot));
        }
        if i >= 120 {
            assert_eq!(forgot.magnetic_disturbance(), Some(false), "sample {i}");
        }
    }
    let d = (heading(&forgot) - heading(&full)).to_degrees();
    let gap = (d + 180.0).rem_euclid(360.0) - 180.0;
    assert!(gap.abs() < 2.0, "{gap}");
}
