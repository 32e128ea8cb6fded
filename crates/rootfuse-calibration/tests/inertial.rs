//! Gyroscope bias and the accelerometer's six-position calibration from rest phases.
use core::f64::consts::{FRAC_PI_2, PI};
use rootfuse_attitude::{Quat, Recording, Vec3};
use rootfuse_calibration::{
    FitOptions, FittedModel, RestOptions, RestPhase, accelerometer, gyro_bias, rest_phases,
};
use rootfuse_eval::sim::{self, Segment, Simulation, Timing, Trajectory};

const ACC_SCALE: [f64; 3] = [0.02, -0.01, 0.015];
const ACC_BIAS: [f64; 3] = [0.1, -0.05, 0.08];
const GYRO_BIAS: [f64; 3] = [0.01, -0.02, 0.005];

/// Rest in seven orientations (z up, the y axis down and up, z down, z up again, x up and
/// down), turned in between.
fn six_positions() -> Simulation {
    let turn = |axis: Vec3<f64>, angle: f64| Segment::smooth(2.0, axis * angle, Vec::new());
    let (x, y) = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0));
    let mut segments = vec![Segment::rest(4.0)];
    for _ in 0..4 {
        segments.push(turn(x, FRAC_PI_2));
        segments.push(Segment::rest(4.0));
    }
    segments.push(turn(y, FRAC_PI_2));
    segments.push(Segment::rest(4.0));
    segments.push(turn(y, PI));
    segments.push(Segment::rest(4.0));
    let mut sensor = sim::scenario_simulation("slow-rotation", 11, 10.0, 100.0)
        .unwrap()
        .sensor;
    sensor.acc.scale = Vec3::from_array(ACC_SCALE);
    sensor.acc.bias = Vec3::from_array(ACC_BIAS);
    sensor.acc.misalignment = [[0.0; 3]; 3];
    sensor.acc.bias_walk = 0.0;
    sensor.gyro.bias = Vec3::from_array(GYRO_BIAS);
    sensor.gyro.bias_walk = 0.0;
    Simulation {
        name: "six-position".into(),
        trajectory: Trajectory::new(Quat::identity(), segments).unwrap(),
        sensor,
        timing: Timing::regular(100.0),
        seed: 11,
    }
}

/// The rest phases of a recording with the default options, its magnetometer included.
fn rests(rec: &Recording) -> Vec<RestPhase> {
    rest_phases(
        &rec.t,
        &rec.gyr,
        &rec.acc,
        rec.mag.as_deref(),
        &RestOptions::default(),
    )
}

#[test]
fn six_position_method_recovers_offset_and_scale() {
    let rec = six_positions().run().unwrap().recording;
    let phases = rests(&rec);
    assert_eq!(phases.len(), 7, "{phases:?}");
    let acc = accelerometer(&rec.acc, &phases, sim::GRAVITY, &FitOptions::default()).unwrap();
    let fit = &acc.fit;
    eprintln!("{:?} {:?} {:?}", fit.model, fit.refused, fit.calibration);
    // Seven clusters cannot pin the six cross terms: offset and per-axis scale, said so.
    assert_eq!(fit.model, FittedModel::DiagonalScale);
    assert_eq!(fit.refused[0].model, FittedModel::Full);
    let h = fit.calibration.offset - Vec3::from_array(ACC_BIAS);
    assert!(h.norm() < 0.005, "offset error {h:?}");
    for k in 0..3 {
        let s = fit.calibration.matrix.m[k][k];
        let truth = 1.0 / (1.0 + ACC_SCALE[k]);
        assert!((s / truth - 1.0).abs() < 5e-4, "axis {k}: {s} vs {truth}");
    }
    assert!(fit.quality.residual_rms_relative < 0.005);
    assert_eq!(fit.calibration.norm, sim::GRAVITY);
}

#[test]
fn gyro_bias_is_the_rest_mean() {
    let rec = six_positions().run().unwrap().recording;
    let phases = rests(&rec);
    let fit = gyro_bias(&rec.gyr, &phases).unwrap();
    let err = (fit.calibration.offset - Vec3::from_array(GYRO_BIAS)).norm();
    // Noise 1.2e-3 rad/s per sample over about 3000 samples: a few 1e-5.
    assert!(err < 1e-4, "bias error {err}");
    assert!(fit.std_error.x < 5e-5 && fit.phase_spread < 1e-3);
    // Too few rest phases for the accelerometer: refused.
    assert!(accelerometer(&rec.acc, &phases[..3], sim::GRAVITY, &FitOptions::default()).is_err());
    assert!(gyro_bias(&rec.gyr, &[]).is_err());
}

/// A turntable: 4 s of rest, then 30 s of a steady turn about the vertical. The gyroscope and
/// the accelerometer are as steady as at rest; the rate (above any plausible bias) and the
/// turning field tell the turn from rest, so the bias comes from the 4 s of rest (steadiness
/// alone takes the turn for rest and writes its whole rate as the "bias").
#[test]
fn a_steady_turn_is_not_rest() {
    let z = Vec3::new(0.0, 0.0, 1.0);
    let mut sim = six_positions();
    for (rate, bias_limited) in [(0.5, true), (0.08, false)] {
        sim.trajectory = Trajectory::new(
            Quat::identity(),
            vec![Segment::rest(4.0), Segment::rotate(30.0, z, rate)],
        )
        .unwrap();
        let rec = sim.run().unwrap().recording;
        let phases = rests(&rec);
        let rest_end = phases.iter().map(|p| rec.t[p.end - 1]).fold(0.0, f64::max);
        assert!(
            rest_end < 4.3,
            "rate {rate}: rest found until {rest_end} s: {phases:?}"
        );
        let fit = gyro_bias(&rec.gyr, &phases).unwrap();
        let err = (fit.calibration.offset - Vec3::from_array(GYRO_BIAS)).norm();
        // The slow turn is seen by the field only once it has turned 0.5° (less the dip's
        // share about the vertical): one block of it joins the rest, a tenth of the rate
        // in the bias instead of all of it.
        let limit = if bias_limited { 2e-3 } else { 0.1 * rate };
        assert!(err < limit, "rate {rate}: bias error {err}");
        // Without the magnetometer only the rate limit is left: it catches the fast turn,
        // and a turn slower than a bias can be is not told from rest.
        let blind = rest_phases(&rec.t, &rec.gyr, &rec.acc, None, &RestOptions::default());
        let blind_end = blind.iter().map(|p| rec.t[p.end - 1]).fold(0.0, f64::max);
        assert_eq!(blind_end < 4.3, bias_limited, "rate {rate}: {blind_end}");
    }
}
