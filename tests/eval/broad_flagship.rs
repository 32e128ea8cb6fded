//! The flagship on every BROAD trial (not only the four of `broad.rs`), 9D and 6D: total RMSE
//! in f64 pinned to 0.01°, so that no change of the update mechanics (issue #18: cost per
//! update) moves the accuracy unseen, and f32 within 0.01° of f64 on every trial.
//! Parameters: the defaults.
use crate::common::broad_dir;
use rootfuse_attitude::filters::{SqrtEskf, SqrtEskfParams};
use rootfuse_attitude::{Dof, Recording};
use rootfuse_eval::metrics::{Alignment, evaluate};
use rootfuse_io::read_dir;

/// Per trial (file name order): total RMSE in degrees for 9D and 6D in f64, as the flagship
/// with two accelerometer windows and the gyroscope's scale estimated gives them (`rootfuse run --precision f64` +
/// `rootfuse eval --json`). The test prints its own numbers in this form when it fails.
#[rustfmt::skip]
const PINNED: &[[f64; 2]] = &[
    [1.057, 0.500], // 02_undisturbed_slow_rotation_B
    [0.744, 1.335], // 04_undisturbed_slow_rotation_with_breaks_A
    [1.649, 1.532], // 07_undisturbed_fast_rotation_B
    [3.118, 6.602], // 08_undisturbed_fast_rotation_with_breaks_A
    [1.367, 1.052], // 10_undisturbed_slow_translation_A
    [1.435, 1.383], // 12_undisturbed_slow_translation_C
    [0.805, 0.667], // 16_undisturbed_fast_translation_B
    [0.777, 0.822], // 18_undisturbed_fast_translation_with_breaks_B
    [1.284, 0.843], // 24_disturbed_tapping_A
    [6.927, 1.709], // 27_disturbed_phone_vibration_B
    [1.920, 4.656], // 29_disturbed_stationary_magnet_B
    [1.865, 3.068], // 31_disturbed_stationary_magnet_D
    [2.032, 2.538], // 33_disturbed_attached_magnet_2cm
    [2.656, 2.956], // 35_disturbed_attached_magnet_4cm
];

/// The flagship over `rec` with `p` (in f32 lanes or f64): total and inclination RMSE,
/// degrees, scored as its `dof` is.
fn scores(rec: &Recording, p: &SqrtEskfParams, f32_lanes: bool) -> [f64; 2] {
    let est = if f32_lanes {
        rec.estimate(&mut SqrtEskf::<f32>::new(p))
    } else {
        rec.estimate(&mut SqrtEskf::<f64>::new(p))
    };
    let align = if p.dof.uses_magnetometer() {
        Alignment::NineD
    } else {
        Alignment::SixD
    };
    let m = evaluate(rec, &est, align).expect("BROAD trials have truth");
    [m.total, m.inclination]
}

/// The defaults' total RMSE in `dof` (6 or 9).
fn total(rec: &Recording, dof: u8, f32_lanes: bool) -> f64 {
    let p = SqrtEskfParams {
        dof: Dof::from_count(dof).expect("6 or 9"),
        ..SqrtEskfParams::default()
    };
    scores(rec, &p, f32_lanes)[0]
}

/// The flagship (f64) over `rec`: its estimate and reported attitude covariance (upper
/// triangle, row by row) after every sample.
#[allow(clippy::type_complexity)]
fn with_covariance(
    rec: &Recording,
    params: &SqrtEskfParams,
) -> (Vec<rootfuse_attitude::Quat<f64>>, Vec<[f64; 6]>) {
    use rootfuse_attitude::OrientationFilter;
    let mut f = SqrtEskf::<f64>::new(params);
    let (mut q, mut cov) = (Vec::new(), Vec::new());
    for i in 0..rec.len() {
        f.update(&rec.sample(i), rec.dt(i));
        q.push(f.quat());
        let a = f.attitude_covariance().expect("the flagship carries one");
        cov.push(rootfuse_eval::consistency::upper_triangle(&a));
    }
    (q, cov)
}

/// The two estimates agree bit for bit at every sample.
fn same_bits(a: &[rootfuse_attitude::Quat<f64>], b: &[rootfuse_attitude::Quat<f64>]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(a, b)| a.to_array().map(f64::to_bits) == b.to_array().map(f64::to_bits))
}

/// The simulated scenario `name` (seeds 0–2, 60 s at 100 Hz, 9D) run with `with` and
/// `without`, whose estimates must be the same bit for bit: the mean inclination coverage of
/// the 95 % ellipse that each reports (first 10 % skipped, no floor).
fn simulated_coverage(name: &str, with: &SqrtEskfParams, without: &SqrtEskfParams) -> (f64, f64) {
    let [with, without] = simulated_coverages(name, (3, 60.0), with, without);
    (with.coverage_inclination, without.coverage_inclination)
}

/// [`simulated_coverage`] over `seeds` seeds of `seconds` each, both coverages (total and
/// inclination) of each parameter set, means over the seeds, scored as `with.dof` is.
fn simulated_coverages(
    name: &str,
    (seeds, seconds): (u64, f64),
    with: &SqrtEskfParams,
    without: &SqrtEskfParams,
) -> [Coverage; 2] {
    use rootfuse_eval::consistency::consistency;
    let align = if with.dof.uses_magnetometer() {
        Alignment::NineD
    } else {
        Alignment::SixD
    };
    let mut mean = [Coverage::default(); 2];
    for seed in 0..seeds {
        let rec = rootfuse_eval::sim::scenario(name, seed, seconds, 100.0).unwrap();
        let truth = rec.truth.as_ref().unwrap();
        let runs = [with_covariance(&rec, with), with_covariance(&rec, without)];
        assert!(
            same_bits(&runs[0].0, &runs[1].0),
            "{name} seed {seed}: estimates differ"
        );
        for (m, (q, c)) in mean.iter_mut().zip(&runs) {
            let r = consistency(q, c, truth, None, align, 0.0, 0.1).unwrap();
            m.coverage_total += r.coverage_total / seeds as f64;
            m.coverage_inclination += r.coverage_inclination / seeds as f64;
        }
    }
    mean
}

/// Mean shares of samples inside the 95 % ellipsoid (total) and ellipse (inclination).
#[derive(Clone, Copy, Default)]
struct Coverage {
    coverage_total: f64,
    coverage_inclination: f64,
}

#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn flagship_rmse_pinned_on_every_trial() {
    let Some(dir) = broad_dir() else { return };
    let recs: Vec<Recording> = read_dir(&dir).unwrap();
    assert_eq!(recs.len(), 14, "the 14 shared BROAD trials");
    let mut failures = Vec::new();
    let mut table = String::new();
    for (rec, pinned) in recs.iter().zip(PINNED) {
        let got = [total(rec, 9, false), total(rec, 6, false)];
        let got32 = [total(rec, 9, true), total(rec, 6, true)];
        table += &format!("    [{:.3}, {:.3}], // {}\n", got[0], got[1], rec.name);
        for k in 0..2 {
            let dof = [9, 6][k];
            if (got[k] - pinned[k]).abs() > 0.01 {
                failures.push(format!(
                    "{} {dof}D f64: {:.3} vs {:.3} before",
                    rec.name, got[k], pinned[k]
                ));
            }
            // f32 makes the same update as f64 (positive definite by construction).
            if (got32[k] - got[k]).abs() > 0.01 {
                failures.push(format!(
                    "{} {dof}D f32 {:.3} vs f64 {:.3}",
                    rec.name, got32[k], got[k]
                ));
            }
        }
    }
    assert_eq!(PINNED.len(), recs.len(), "every trial is pinned");
    assert!(
        failures.is_empty(),
        "flagship BROAD RMSE changed:\n{}\nnow (f64):\n{table}",
        failures.join("\n")
    );
}

/// Innovation covariance matching (`acc_adapt_window`) is a claim on two sides, made on the
/// one-window filter (`tau_acc_long = 0`, whose innovations it was designed on): on the
/// simulated pendulum (6D, seeds 0–4, 120 s at 100 Hz) it lowers the inclination RMSE from
/// 1.17° to 0.90° (VQF online: 0.92°, `benches/python/accuracy_peers.py`), and on BROAD trial
/// 07, whose innovations never exceed their prediction, every estimate is bit for bit that of
/// the filter without it.
#[test]
fn covariance_matching_helps_the_pendulum_and_leaves_broad_alone() {
    let params = |window: f64| SqrtEskfParams {
        dof: Dof::Six,
        acc_adapt_window: window,
        tau_acc_long: 0.0,
        ..SqrtEskfParams::default()
    };
    let inclination = |window: f64| {
        (0..5)
            .map(|seed| {
                let rec = rootfuse_eval::sim::scenario("pendulum-6d", seed, 120.0, 100.0).unwrap();
                let est = rec.estimate(&mut SqrtEskf::<f64>::new(&params(window)));
                evaluate(&rec, &est, Alignment::SixD).unwrap().inclination
            })
            .sum::<f64>()
            / 5.0
    };
    let (with, without) = (inclination(0.3), inclination(0.0));
    assert!(
        with < 0.93 && without > 1.1,
        "with {with}°, without {without}°"
    );
    let Some(dir) = broad_dir() else { return };
    let rec = rootfuse_io::read_csv(dir.join("07_undisturbed_fast_rotation_B.csv")).unwrap();
    for dof in [Dof::Six, Dof::Nine] {
        let run = |window: f64| {
            let p = SqrtEskfParams {
                dof,
                ..params(window)
            };
            rec.estimate(&mut SqrtEskf::<f32>::new(&p))
        };
        let (a, b) = (run(0.3), run(0.0));
        assert!(
            a.iter()
                .zip(&b)
                .all(|(x, y)| x.to_array().map(f64::to_bits) == y.to_array().map(f64::to_bits)),
            "{dof:?}: estimates differ"
        );
    }
}

/// The reported covariance with the model error (`model_error_scale`, default 0.6) holds the
/// 95 % ellipse on the simulated hard cases with motion acceleration, where `P` alone
/// (`model_error_scale = 0`) is overconfident; the estimates are bit for bit the same.
/// Measured (3 seeds, 60 s, 9D, inclination coverage, this term alone): pendulum 0.95,
/// translation 0.90, handheld-translation 0.88; with 0: 0.59, 0.47, 0.45 (docs/accuracy.md;
/// the acceleration-excess term, left out here, takes the three to 0.97 / 0.92 / 0.92).
#[test]
fn model_error_makes_the_covariance_honest() {
    // The inclination innovation's term alone: no scale-factor or acceleration term beside it.
    let params = |scale: f64| SqrtEskfParams {
        model_error_scale: scale,
        model_error_rotation_scale: scale,
        gyr_scale_error: 0.0,
        acc_excess_scale: 0.0,
        ..SqrtEskfParams::default()
    };
    let default = SqrtEskfParams::default().model_error_scale;
    for (name, min_with, max_without) in [
        ("pendulum", 0.93, 0.6),
        ("translation", 0.88, 0.6),
        ("handheld-translation", 0.86, 0.6),
    ] {
        let (with, without) = simulated_coverage(name, &params(default), &params(0.0));
        eprintln!("{name}: inclination coverage {with:.3} (model error), {without:.3} (P alone)");
        assert!(
            with >= min_with && without <= max_without,
            "{name}: coverage {with:.3} with the model error, {without:.3} without"
        );
    }
}

/// The defaults' reported covariance on the hard cases of issue #35 (seeds 0–4, 120 s at 100
/// Hz, 6D and 9D with a disturbed field): the 95 % ellipse holds the inclination error at
/// 0.93–0.97 of the samples on every one, and the ellipsoid the total error too, except the 6D
/// vehicle's (measured 0.986: its heading's variance, grown from the gyroscope noise, is wider
/// than its drift). With one model-error scale (`model_error_rotation_scale` =
/// `model_error_scale`) the pendulum is above the band (0.98 inclination) while the handheld
/// translation is at its lower edge; the estimates are bit for bit the same either way.
/// `examples/flagship_coverage.rs` prints the table of docs/accuracy.md.
#[test]
fn coverage_in_the_band_on_the_hard_cases() {
    let defaults = SqrtEskfParams::default();
    let one_scale = SqrtEskfParams {
        model_error_rotation_scale: defaults.model_error_scale,
        ..defaults.clone()
    };
    let mut failures = Vec::new();
    for name in rootfuse_eval::sim::HARD_CASES {
        let dof = if name.ends_with("-6d") {
            Dof::Six
        } else {
            Dof::Nine
        };
        let with_dof = |p: &SqrtEskfParams| SqrtEskfParams { dof, ..p.clone() };
        let [c, one] = simulated_coverages(
            name,
            (5, 120.0),
            &with_dof(&defaults),
            &with_dof(&one_scale),
        );
        eprintln!(
            "{name}: total / inclination {:.3} / {:.3} (one scale {:.3} / {:.3})",
            c.coverage_total, c.coverage_inclination, one.coverage_total, one.coverage_inclination
        );
        let band = 0.93..=0.97;
        let total_max = if name == "vehicle-6d" { 0.99 } else { 0.97 };
        if !band.contains(&c.coverage_inclination)
            || !(0.93..=total_max).contains(&c.coverage_total)
        {
            failures.push(format!(
                "{name}: {:.3} / {:.3}",
                c.coverage_total, c.coverage_inclination
            ));
        }
        if name.starts_with("pendulum") && one.coverage_inclination <= 0.97 {
            failures.push(format!(
                "{name}: one scale {:.3}, above the band before",
                one.coverage_inclination
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// Over ten minutes of a disturbed field the flagship adopts a lasting disturbance as its
/// reference, each time with the azimuth today's heading gives it, decaying toward north: the
/// heading's variance against the adopted field is no longer its variance against north.
/// With the adopted field's azimuth error in the report (`adopted_field_error_scale`, default
/// 1: the heading's variance at adoption, decaying with the azimuth, plus the square of the
/// turn that decay has made) the 95 % ellipsoid holds the total error on the three disturbed
/// hard cases 0.958 / 0.925 / 0.960 of the time (5 × 600 s; the vehicle just below the issue's
/// 0.93); without it 0.864 / 0.869 / 0.861. The estimates are bit for bit the same.
#[test]
fn adopted_field_error_covers_the_heading_over_ten_minutes() {
    let defaults = SqrtEskfParams::default();
    let without = SqrtEskfParams {
        adopted_field_error_scale: 0.0,
        ..defaults.clone()
    };
    let mut failures = Vec::new();
    for name in rootfuse_eval::sim::HARD_CASES {
        if name.ends_with("-6d") {
            continue;
        }
        let [c, w] = simulated_coverages(name, (5, 600.0), &defaults, &without);
        eprintln!(
            "{name}: total {:.3} (without the adopted field's error {:.3})",
            c.coverage_total, w.coverage_total
        );
        if !(0.92..=0.97).contains(&c.coverage_total) || w.coverage_total > 0.9 {
            failures.push(format!(
                "{name}: {:.3}, without {:.3}",
                c.coverage_total, w.coverage_total
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
}

/// The 9D heading's model error (`heading_model_error_scale`, default 2) on BROAD: the
/// estimates are bit for bit those of `P` alone, and the mean share of samples inside the 95 %
/// ellipsoid, with the 0.5° floor for the optical truth's own error, rises from 0.897 to 0.973
/// (0.972 at 1; the issue asks 0.90–0.98; the other parameters the defaults): `P` alone stays
/// short of 0.93. Trial 27 (a phone's vibration motor beside the sensor) holds its 5–8° heading
/// error outside the ellipsoid at every sample with `P` alone and inside with the model error.
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn heading_model_error_covers_broad_with_the_floor() {
    use rootfuse_eval::consistency::consistency;
    let Some(dir) = broad_dir() else { return };
    let recs: Vec<Recording> = read_dir(&dir).unwrap();
    assert_eq!(recs.len(), 14, "the 14 shared BROAD trials");
    let run = |rec: &Recording, scale: f64| {
        with_covariance(
            rec,
            &SqrtEskfParams {
                heading_model_error_scale: scale,
                ..SqrtEskfParams::default()
            },
        )
    };
    let floor = 0.5_f64.to_radians();
    let (mut with, mut without) = (Vec::new(), Vec::new());
    for rec in &recs {
        let truth = rec.truth.as_ref().expect("BROAD trials have truth");
        let cover = |(q, c): &(Vec<_>, Vec<_>)| {
            consistency(
                q,
                c,
                truth,
                rec.use_mask.as_deref(),
                Alignment::NineD,
                floor,
                0.1,
            )
            .unwrap()
            .coverage_total
        };
        let default = SqrtEskfParams::default().heading_model_error_scale;
        let (modelled, alone) = (run(rec, default), run(rec, 0.0));
        assert!(
            same_bits(&modelled.0, &alone.0),
            "{}: estimates differ",
            rec.name
        );
        with.push(cover(&modelled));
        without.push(cover(&alone));
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (with_mean, without_mean) = (mean(&with), mean(&without));
    eprintln!(
        "BROAD 9D coverage with the 0.5° floor: {with_mean:.3} (model error), {without_mean:.3} (P alone)"
    );
    let i27 = recs.iter().position(|r| r.name.starts_with("27_")).unwrap();
    assert!(
        (0.95..=0.98).contains(&with_mean) && without_mean < 0.93,
        "coverage {with_mean:.3} with the heading model error, {without_mean:.3} without"
    );
    assert!(
        with[i27] > 0.95 && without[i27] < 0.05,
        "trial 27: {:.2} with, {:.2} without",
        with[i27],
        without[i27]
    );
}

/// The gyroscope scale-factor model error (`gyr_scale_error`) on the simulated fast rotation,
/// whose IMU has a 0.3 % scale-factor and 0.1 % misalignment error: with its own value
/// (0.003) the 95 % ellipse holds the inclination error at 0.95 of the samples (3 seeds,
/// 60 s at 100 Hz, 9D), with 0 at 0.47; the estimates are bit for bit the same. The
/// acceleration-excess term is left out here (with it: 0.98 and 0.66).
#[test]
fn scale_factor_model_error_covers_fast_rotation() {
    let params = |sf: f64| SqrtEskfParams {
        gyr_scale_error: sf,
        acc_excess_scale: 0.0,
        ..SqrtEskfParams::default()
    };
    let (with, without) = simulated_coverage("fast-rotation", &params(0.003), &params(0.0));
    eprintln!("fast-rotation inclination coverage {with:.3} (0.003), {without:.3} (0)");
    assert!(
        (0.93..=0.99).contains(&with) && without < 0.6,
        "coverage {with:.3} with the scale-factor model error, {without:.3} without"
    );
}

/// The sustained-acceleration model error (`acc_excess_scale`, default 0.15) on the
/// simulated vehicle, whose turns hold a 1–4 m/s² centripetal acceleration for seconds while
/// the innovation vanishes: with it the 95 % ellipse holds the inclination error at 0.94 of
/// the samples (3 seeds, 60 s at 100 Hz, 9D, the other parameters the defaults), with 0 at
/// 0.35; the estimates are bit for bit the same (docs/accuracy.md).
#[test]
fn acceleration_excess_covers_the_vehicle() {
    let params = |k: f64| SqrtEskfParams {
        acc_excess_scale: k,
        ..SqrtEskfParams::default()
    };
    let default = SqrtEskfParams::default().acc_excess_scale;
    let (with, without) = simulated_coverage("vehicle", &params(default), &params(0.0));
    eprintln!("vehicle inclination coverage {with:.3} (default), {without:.3} (0)");
    assert!(
        with >= 0.92 && without < 0.5,
        "coverage {with:.3} with the acceleration excess, {without:.3} without"
    );
}

/// The 9D heading's model error on the simulated vehicle with a disturbed field (seeds 0–4,
/// 120 s at 100 Hz: its turns drift the heading by the gyroscope's 0.3 % scale factor while
/// no field is adopted, which `P`'s white noise does not model): at the default scale (2) the
/// 95 % ellipsoid holds the total error at 0.961 of the samples, at 1 (the mean square itself)
/// at 0.921, short of the 0.93–0.97 the issue asks; estimates bit for bit the same.
#[test]
fn heading_model_error_covers_the_disturbed_vehicle() {
    let params = |scale: f64| SqrtEskfParams {
        heading_model_error_scale: scale,
        ..SqrtEskfParams::default()
    };
    let default = SqrtEskfParams::default().heading_model_error_scale;
    let [with, at_one] = simulated_coverages(
        "vehicle-disturbed",
        (5, 120.0),
        &params(default),
        &params(1.0),
    )
    .map(|c| c.coverage_total);
    eprintln!("vehicle-disturbed total coverage {with:.3} (default), {at_one:.3} (1)");
    assert!(
        (0.93..=0.97).contains(&with) && at_one < 0.93,
        "coverage {with:.3} at the default heading model error, {at_one:.3} at 1"
    );
}

/// Every BROAD trial, 9D and 6D, total and inclination, with `every` set to 8 and to 1 by
/// `set`: the trials where the two differ by more than 0.002°.
fn differences_at_eight_and_one(set: fn(&mut SqrtEskfParams, f64)) -> Vec<String> {
    let Some(dir) = broad_dir() else {
        return Vec::new();
    };
    let recs: Vec<Recording> = read_dir(&dir).unwrap();
    let mut failures = Vec::new();
    for rec in &recs {
        for dof in [9, 6] {
            let score = |every: f64| {
                let mut p = SqrtEskfParams {
                    dof: Dof::from_count(dof).expect("6 or 9"),
                    ..SqrtEskfParams::default()
                };
                set(&mut p, every);
                scores(rec, &p, false)
            };
            let (every, each) = (score(8.0), score(1.0));
            // A 6D heading is the scale estimate's times the net rotation about up, which on
            // the trials that turn one way many times (04, 08: up to 19 turns) makes a
            // difference of the corrections a difference of the heading.
            let total_within = if dof == 6 { 0.01 } else { 0.002 };
            for (what, a, b, within) in [
                ("total", every[0], each[0], total_within),
                ("inclination", every[1], each[1], 0.002),
            ] {
                if (a - b).abs() > within {
                    failures.push(format!(
                        "{} {dof}D {what}: {a:.4} every 8th sample, {b:.4} every sample",
                        rec.name
                    ));
                }
            }
        }
    }
    failures
}

/// The inclination corrected every `acc_update_every` samples (the default, 8) with the
/// information of all of them is the filter corrected every sample, to within 0.002° on every
/// BROAD trial, 9D and 6D, total and inclination, but 0.01° for the 6D total (measured:
/// 0.0001°, 0.0055° for 08's 6D total since the gyroscope's scale is estimated from the
/// corrections; 0.0008° offline). A
/// correction that did not stand for the skipped samples (the one-sample variance) would
/// correct eight times more slowly and move every trial by far more.
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn correcting_every_eighth_sample_keeps_the_accuracy() {
    assert_eq!(SqrtEskfParams::default().acc_update_every, 8.0);
    let failures = differences_at_eight_and_one(|p, every| p.acc_update_every = every);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The gyro bias measured at rest every `rest_update_every` samples (the default, 8), each
/// measurement standing for the time since the last, is the filter that measures it at every
/// sample, to within 0.002° on every BROAD trial, 9D and 6D, total and inclination (measured:
/// 0.001°; the trials rest for seconds at their start and end).
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn measuring_the_bias_at_rest_every_eighth_sample_keeps_the_accuracy() {
    assert_eq!(SqrtEskfParams::default().rest_update_every, 8.0);
    let failures = differences_at_eight_and_one(|p, every| p.rest_update_every = every);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The field tested every `mag_update_every` readings (the default, 4) on their mean: the 9D
/// mean over the BROAD trials is no worse than testing every reading (measured 2.050° against
/// 2.057°), and on the undisturbed slow trials (02, 04, 10, 12, 16, 18), where no test can
/// flip a field decision, the total moves by under 0.01° (measured ≤ 0.002°).
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn testing_the_field_every_fourth_reading_keeps_the_accuracy() {
    let Some(dir) = broad_dir() else { return };
    let recs: Vec<Recording> = read_dir(&dir).unwrap();
    assert_eq!(SqrtEskfParams::default().mag_update_every, 4.0);
    let score = |rec: &Recording, every: f64| {
        let p = SqrtEskfParams {
            mag_update_every: every,
            ..SqrtEskfParams::default()
        };
        scores(rec, &p, false)[0]
    };
    let (mut sum4, mut sum1) = (0.0, 0.0);
    for rec in &recs {
        let (a, b) = (score(rec, 4.0), score(rec, 1.0));
        sum4 += a;
        sum1 += b;
        let quiet = ["02_", "04_", "10_", "12_", "16_", "18_"];
        if quiet.iter().any(|p| rec.name.starts_with(p)) {
            assert!(
                (a - b).abs() < 0.01,
                "{}: {a:.4} every 4th reading, {b:.4} every reading",
                rec.name
            );
        }
    }
    let n = recs.len() as f64;
    assert!(
        sum4 / n <= sum1 / n + 1e-9,
        "9D mean {:.4} every 4th reading, {:.4} every reading",
        sum4 / n,
        sum1 / n
    );
}

/// `acc_noise_rotation_share` 0.1 (off by default, docs/accuracy.md "Motion-dependent
/// accelerometer noise"): on the 14 BROAD trials the 9D online mean total is better than the
/// defaults' and the inclination not (measured 1.950 / 0.684 against 1.974 / 0.680; before the
/// gyroscope's scale was estimated it gained both, 2.013 / 0.717 against 2.050 / 0.722), and 1
/// is the defaults bit for bit.
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn motion_dependent_accelerometer_noise_gains_on_broad() {
    let Some(dir) = broad_dir() else { return };
    let recs: Vec<Recording> = read_dir(&dir).unwrap();
    let share = |s: f64| SqrtEskfParams {
        acc_noise_rotation_share: s,
        ..SqrtEskfParams::default()
    };
    assert_eq!(SqrtEskfParams::default().acc_noise_rotation_share, 1.0);
    let (mut on, mut off) = ([0.0; 2], [0.0; 2]);
    for rec in &recs {
        let (a, b) = (
            scores(rec, &share(0.1), false),
            scores(rec, &share(1.0), false),
        );
        assert_eq!(
            b,
            scores(rec, &SqrtEskfParams::default(), false),
            "{}",
            rec.name
        );
        for i in 0..2 {
            on[i] += a[i] / recs.len() as f64;
            off[i] += b[i] / recs.len() as f64;
        }
    }
    eprintln!("share 0.1: {on:.4?}, defaults: {off:.4?}");
    // With the gyroscope's scale estimated the 9D total still gains and the inclination no
    // longer does (measured 1.9501 / 0.6835 against 1.9736 / 0.6801).
    assert!(
        on[0] <= off[0] - 0.015 && on[1] >= off[1],
        "share 0.1 {on:.4?} against the defaults' {off:.4?}"
    );
}
