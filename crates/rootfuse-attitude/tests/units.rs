//! Units: a recording in other units than declared is named with the unit its readings fit,
//! on simulated motion and on every BROAD trial; the right units give no finding.
use crate::common::broad_dir;
use rootfuse_attitude::Recording;
use rootfuse_attitude::units::{DECIDED_SAMPLES, Sensor, UnitCheck, UnitFinding, Units};

/// The check of `rec`'s readings as written, declared in `declared`.
fn checked(rec: &Recording, declared: &str) -> UnitCheck {
    let mut check = UnitCheck::new(&declared.parse::<Units>().unwrap());
    for i in 0..rec.len() {
        let mag = rec.mag.as_ref().map(|m| m[i]);
        check.add(rec.t[i], rec.gyr[i], rec.acc[i], mag);
    }
    check
}

fn findings(rec: &Recording, declared: &str) -> Vec<UnitFinding> {
    checked(rec, declared).findings()
}

/// The recording as written in `units` (the inverse of reading it in them).
fn written_in(rec: &Recording, units: &str) -> Recording {
    let units: Units = units.parse().unwrap();
    let mut out = rec.clone();
    let f = |s: Sensor| 1.0 / units.get(s).factor();
    out.t.iter_mut().for_each(|t| *t *= f(Sensor::Time));
    out.gyr
        .iter_mut()
        .for_each(|v| *v = *v * f(Sensor::Gyroscope));
    out.acc
        .iter_mut()
        .for_each(|v| *v = *v * f(Sensor::Accelerometer));
    if let Some(m) = &mut out.mag {
        m.iter_mut().for_each(|v| *v = *v * f(Sensor::Magnetometer));
    }
    out
}

/// Each sensor written in another unit is found, with that unit; declared, nothing is found.
fn every_unit_is_named(rec: &Recording) {
    assert_eq!(findings(rec, ""), [], "{}: SI data, SI declared", rec.name);
    for (units, sensor, likely) in [
        ("time=ms", Sensor::Time, "ms"),
        ("time=us", Sensor::Time, "us"),
        ("time=ns", Sensor::Time, "ns"),
        ("gyro=deg/s", Sensor::Gyroscope, "deg/s"),
        ("acc=g", Sensor::Accelerometer, "g"),
        ("acc=mg", Sensor::Accelerometer, "mg"),
        ("mag=nT", Sensor::Magnetometer, "nT"),
        ("mag=G", Sensor::Magnetometer, "G"),
    ] {
        let other = written_in(rec, units);
        let found = findings(&other, "");
        assert_eq!(found.len(), 1, "{} in {units}: {found:?}", rec.name);
        assert_eq!(found[0].sensor, sensor, "{} in {units}", rec.name);
        assert_eq!(
            found[0].likely.map(|u| u.to_string()).as_deref(),
            Some(likely),
            "{} in {units}: {}",
            rec.name,
            found[0]
        );
        assert_eq!(
            findings(&other, units),
            [],
            "{} in {units}, declared",
            rec.name
        );
    }
    // Declared in another unit than the data's: named the other way round. A gyroscope in
    // rad/s declared as deg/s is told only from tilting (its rates are plausible either way):
    // a recording of little rotation leaves it undecided, never named wrong.
    let found = findings(rec, "gyro=deg/s,acc=g");
    assert!(
        found.iter().any(|f| f.sensor == Sensor::Accelerometer),
        "{}: {found:?}",
        rec.name
    );
    for f in &found {
        assert!(f.likely.unwrap().is_si(), "{}: {f}", rec.name);
    }
}

#[test]
fn simulated_motion_in_other_units_is_named() {
    let rec = rootfuse_eval::sim::scenario("slow-rotation", 3, 60.0, 100.0).unwrap();
    every_unit_is_named(&rec);
}

#[test]
fn a_long_recording_is_decided_early_and_still_named() {
    // 40,000 samples of motion: the check decides after DECIDED_SAMPLES (and enough tilting)
    // and ignores the rest, with the same findings as the short recordings give.
    let rec = rootfuse_eval::sim::scenario("slow-rotation", 4, 400.0, 100.0).unwrap();
    let check = checked(&rec, "");
    assert!(
        check.samples() >= DECIDED_SAMPLES && check.samples() < rec.len() as u64 / 2,
        "decided after {} of {} samples",
        check.samples(),
        rec.len()
    );
    every_unit_is_named(&rec);
    // At rest the gyroscope test never sees its tilting: the check goes on to the end.
    let rest = rootfuse_eval::sim::scenario("static", 4, 150.0, 100.0).unwrap();
    assert_eq!(checked(&rest, "").samples(), rest.len() as u64);
}

#[test]
fn raw_counts_and_dead_sensors_are_named() {
    let rec = rootfuse_eval::sim::scenario("slow-rotation", 3, 30.0, 100.0).unwrap();
    // An accelerometer in counts of a 16-bit ±2 g range (16384 per g): no named unit fits.
    let counts = written_in(&rec, "acc=0.000598550415");
    let found = findings(&counts, "");
    assert_eq!(found.len(), 1);
    assert_eq!(
        (found[0].sensor, found[0].likely),
        (Sensor::Accelerometer, None)
    );
    assert_eq!(found[0].declaration(), "acc=<factor to m/s2>");
    assert!(
        found[0].to_string().contains("no unit fits (raw counts?)"),
        "{}",
        found[0]
    );
    // Declared as counts, nothing to say.
    assert_eq!(findings(&counts, "acc=0.000598550415"), []);
    // An accelerometer that reads zero throughout.
    let mut dead = rec.clone();
    dead.acc.iter_mut().for_each(|a| *a = *a * 0.0);
    let found = findings(&dead, "");
    assert_eq!(found.len(), 1);
    assert!(
        found[0]
            .to_string()
            .contains("every reading checked (3000) is zero"),
        "{}",
        found[0]
    );
}

/// Turns about the vertical hardly tilt the gravity direction; with a magnetometer, the
/// field's turning tells a gyroscope in °/s all the same (decisive: the run is refused), and
/// says nothing against rad/s. Without one, the limit of the check stands (pinned).
#[test]
fn yaw_motion_is_judged_by_the_magnetic_field() {
    for seed in 0..3 {
        let rec = rootfuse_eval::sim::scenario("vehicle", seed, 120.0, 100.0).unwrap();
        assert_eq!(findings(&rec, ""), [], "vehicle {seed}, rad/s");
        let deg = written_in(&rec, "gyro=deg/s");
        let found = findings(&deg, "");
        assert_eq!(found.len(), 1, "vehicle {seed} in deg/s: {found:?}");
        assert!(
            found[0].decisive && found[0].evidence.contains("magnetic field direction"),
            "vehicle {seed} in deg/s: {}",
            found[0]
        );
        assert_eq!(findings(&deg, "gyro=deg/s"), [], "vehicle {seed}, declared");
        // Without a magnetometer the check's limit stands: gravity hardly turns, so a
        // gyroscope in °/s is not told from the motion (at most from rates, as a warning).
        let six = rootfuse_eval::sim::scenario("vehicle-6d", seed, 120.0, 100.0).unwrap();
        let found = findings(&written_in(&six, "gyro=deg/s"), "");
        assert!(
            found.iter().all(|f| !f.decisive),
            "vehicle-6d {seed}: {found:?}"
        );
    }
}

#[test]
fn at_rest_the_gyroscope_unit_is_not_guessed() {
    // No tilting, nothing to compare the gyroscope with: no finding either way.
    let rec = rootfuse_eval::sim::scenario("static", 3, 30.0, 100.0).unwrap();
    assert_eq!(findings(&written_in(&rec, "gyro=deg/s"), ""), []);
}

#[cfg_attr(
    not(broad_data),
    ignore = "BROAD recordings not found (../shared/broad_csv or ROOTFUSE_BROAD_DIR)"
)]
#[test]
fn every_broad_trial_in_other_units_is_named() {
    let Some(dir) = broad_dir() else { return };
    for rec in rootfuse_io::read_dir(&dir).unwrap() {
        every_unit_is_named(&rec);
        // Against the motion (gravity's turning or, where linear acceleration leaves that
        // undecided, the field's), not only by rates no gyroscope measures.
        let found = findings(&written_in(&rec, "gyro=deg/s"), "");
        assert!(found[0].decisive, "{}: {}", rec.name, found[0]);
    }
}
