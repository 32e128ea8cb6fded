//! The IMU simulator: determinism, every preset, noise statistics, exact truth (closed forms and
//! gyro integration), gravity and magnetic field geometry, disturbances, timing, saturation.
use rootfuse_attitude::{Quat, Recording, Vec3};
use rootfuse_eval::sim::{
    self, BiasStep, EarthField, Frame, InertialSensor, MagDisturbance, Magnetometer, Oscillation,
    Rotation, SCENARIOS, Segment, SensorModel, SimError, Simulation, Timing, Trajectory, Vibration,
};

const G: f64 = sim::GRAVITY;

fn ideal_sim(trajectory: Trajectory, rate_hz: f64) -> Simulation {
    Simulation {
        name: "test".into(),
        trajectory,
        sensor: SensorModel::ideal(),
        timing: Timing::regular(rate_hz),
        seed: 1,
    }
}

fn tilted() -> Quat<f64> {
    Quat::from_euler_zyx(0.8, -0.4, 1.1)
}

/// Mean and (population) standard deviation.
fn stats(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let v: Vec<f64> = v.collect();
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    (mean, var.sqrt())
}

#[test]
fn same_seed_same_output_different_seed_different() {
    for &(name, _) in SCENARIOS {
        let a = sim::scenario(name, 42, 3.0, 100.0).unwrap();
        let b = sim::scenario(name, 42, 3.0, 100.0).unwrap();
        assert_eq!(a, b, "{name}");
        if name != "noise-free" {
            let c = sim::scenario(name, 43, 3.0, 100.0).unwrap();
            assert_ne!(a.gyr, c.gyr, "{name}");
        }
    }
}

#[test]
fn batch_equals_single_runs() {
    let seeds = [5, 1, 99, 5, 7];
    let batch = sim::scenario_batch("fast-rotation", &seeds, 1.0, 100.0).unwrap();
    assert_eq!(batch.len(), seeds.len());
    for (r, &seed) in batch.iter().zip(&seeds) {
        assert_eq!(
            *r,
            sim::scenario("fast-rotation", seed, 1.0, 100.0).unwrap()
        );
    }
    assert!(
        sim::scenario_batch("static", &[], 1.0, 100.0)
            .unwrap()
            .is_empty()
    );
    assert!(sim::scenario_batch("nope", &[1, 2], 1.0, 100.0).is_err());
}

#[test]
fn every_preset_is_well_formed() {
    for &(name, description) in SCENARIOS {
        assert!(!description.is_empty());
        let out = sim::scenario_simulation(name, 7, 12.0, 200.0)
            .unwrap()
            .run()
            .unwrap();
        let r: &Recording = &out.recording;
        assert_eq!(r.name, name);
        let n = r.len();
        let nominal = 12.0 * 200.0;
        if name == "irregular-dt" {
            assert!(n < nominal as usize && n as f64 > 0.9 * nominal, "{n}");
        } else {
            assert_eq!(n, nominal as usize, "{name}");
        }
        assert!(
            r.t.windows(2).all(|w| w[1] > w[0]),
            "{name}: time increases"
        );
        if name.ends_with("-6d") {
            assert!(r.mag.is_none(), "{name}: no magnetometer");
            continue;
        }
        assert!(r.mag.as_ref().is_some_and(|m| m.len() == n));
        assert_eq!(r.use_mask.as_ref().map(Vec::len), Some(n));
        assert_eq!(out.gyro_bias.len(), n);
        let truth = r.truth.as_ref().unwrap();
        for i in 0..n {
            assert!((truth[i].norm() - 1.0).abs() < 1e-12, "{name}: unit truth");
            assert!(truth[i].w >= 0.0);
            let s = r.sample(i);
            assert!(s.gyr.x.is_finite() && s.acc.y.is_finite() && s.mag.z.is_finite());
        }
        // A sane IMU: |acc| near g on average (a pendulum's bob feels up to 2.5 g), |mag|
        // near 50 µT.
        let (acc_mean, _) = stats(r.acc.iter().map(|a| a.norm()));
        let spread = if name.starts_with("pendulum") {
            4.0
        } else {
            1.5
        };
        assert!(
            (acc_mean - G).abs() < spread,
            "{name}: mean |acc| = {acc_mean}"
        );
        let (mag_mean, _) = stats(r.mag.as_ref().unwrap().iter().map(|m| m.norm()));
        assert!(
            (mag_mean - 50.0).abs() < 15.0,
            "{name}: mean |mag| = {mag_mean}"
        );
    }
}

#[test]
fn bad_arguments_are_typed_errors() {
    let e = sim::scenario("nope", 1, 1.0, 100.0).unwrap_err();
    assert!(matches!(e, SimError::UnknownScenario { .. }));
    assert!(e.to_string().contains("slow-rotation"), "{e}");
    for (d, f) in [
        (0.0, 100.0),
        (-1.0, 100.0),
        (f64::NAN, 100.0),
        (1.0, 0.0),
        (1.0, f64::INFINITY),
    ] {
        assert!(matches!(
            sim::scenario("static", 1, d, f),
            Err(SimError::InvalidParameter { .. })
        ));
    }
    assert!(matches!(
        sim::scenario("static", 1, 1e9, 1e3),
        Err(SimError::TooManySamples { .. })
    ));
    assert!(matches!(
        Trajectory::new(
            Quat::identity(),
            vec![Segment::rotate(1.0, Vec3::zero(), 1.0)]
        ),
        Err(SimError::InvalidSegment { index: 0, .. })
    ));
    assert!(matches!(
        Trajectory::new(
            Quat::identity(),
            vec![Segment::rest(1.0), Segment::rest(f64::NAN)]
        ),
        Err(SimError::InvalidSegment { index: 1, .. })
    ));
    let mut s = ideal_sim(
        Trajectory::new(Quat::identity(), vec![Segment::rest(1.0)]).unwrap(),
        100.0,
    );
    s.sensor.gyro.noise_std = -1.0;
    assert!(matches!(s.run(), Err(SimError::InvalidSensor { .. })));
}

#[test]
fn noise_and_bias_statistics_match_parameters() {
    // 40 000 samples at rest: the sample std of white noise is within 3 % (≈ 8 standard
    // errors of a std estimate, 1/sqrt(2n) = 0.35 %) and the mean within 5 standard errors
    // of the configured bias.
    let traj = Trajectory::new(tilted(), vec![Segment::rest(200.0)]).unwrap();
    let mut s = ideal_sim(traj, 200.0);
    s.sensor.gyro.noise_std = 0.01;
    s.sensor.gyro.bias = Vec3::new(0.02, -0.01, 0.005);
    s.sensor.acc.noise_std = 0.05;
    let mag = s.sensor.mag.as_mut().unwrap();
    mag.noise_std = 0.3;
    let out = s.run().unwrap();
    let r = &out.recording;
    let n = r.len() as f64;
    let acc_true = tilted().rotate_inverse(Vec3::new(0.0, 0.0, G));
    let mag_true = tilted().rotate_inverse(EarthField::default().vector());
    let checks: [(&str, Vec<f64>, f64, f64); 9] = [
        ("gx", r.gyr.iter().map(|v| v.x).collect(), 0.02, 0.01),
        ("gy", r.gyr.iter().map(|v| v.y).collect(), -0.01, 0.01),
        ("gz", r.gyr.iter().map(|v| v.z).collect(), 0.005, 0.01),
        ("ax", r.acc.iter().map(|v| v.x).collect(), acc_true.x, 0.05),
        ("ay", r.acc.iter().map(|v| v.y).collect(), acc_true.y, 0.05),
        ("az", r.acc.iter().map(|v| v.z).collect(), acc_true.z, 0.05),
        (
            "mx",
            r.mag.as_ref().unwrap().iter().map(|v| v.x).collect(),
            mag_true.x,
            0.3,
        ),
        (
            "my",
            r.mag.as_ref().unwrap().iter().map(|v| v.y).collect(),
            mag_true.y,
            0.3,
        ),
        (
            "mz",
            r.mag.as_ref().unwrap().iter().map(|v| v.z).collect(),
            mag_true.z,
            0.3,
        ),
    ];
    for (name, v, mean_true, std_true) in checks {
        let (mean, std) = stats(v.into_iter());
        assert!(
            (std / std_true - 1.0).abs() < 0.03,
            "{name}: std {std} vs {std_true}"
        );
        assert!(
            (mean - mean_true).abs() < 5.0 * std_true / n.sqrt(),
            "{name}: mean {mean} vs {mean_true}"
        );
    }

    // Bias random walk: increments over dt have std walk·sqrt(dt) (within 3 %).
    let traj = Trajectory::new(Quat::identity(), vec![Segment::rest(200.0)]).unwrap();
    let mut s = ideal_sim(traj, 200.0);
    s.sensor.gyro.bias_walk = 1e-3;
    s.sensor.acc.bias_walk = 2e-3;
    let out = s.run().unwrap();
    let dt: f64 = 1.0 / 200.0;
    for (b, walk) in [(&out.gyro_bias, 1e-3), (&out.acc_bias, 2e-3)] {
        let (_, std) = stats(b.windows(2).map(|w| w[1].y - w[0].y));
        assert!(
            (std / (walk * dt.sqrt()) - 1.0).abs() < 0.03,
            "walk std {std}"
        );
    }
    // The gyro reads exactly the true bias (ideal otherwise, at rest).
    assert_eq!(out.recording.gyr[1000], out.gyro_bias[1000]);
}

#[test]
fn accelerometer_at_rest_reads_g_along_sensor_up() {
    let traj = Trajectory::new(tilted(), vec![Segment::rest(1.0)]).unwrap();
    let r = ideal_sim(traj, 100.0).run().unwrap().recording;
    let truth = r.truth.as_ref().unwrap();
    for i in 0..r.len() {
        // Sensor-up = earth-up seen in the sensor frame; rotating the reading by the truth
        // gives +g along earth-up.
        let up_sensor = truth[i].rotate_inverse(Vec3::new(0.0, 0.0, 1.0));
        assert!((r.acc[i] - up_sensor * G).norm() < 1e-12);
        assert!((truth[i].rotate(r.acc[i]) - Vec3::new(0.0, 0.0, G)).norm() < 1e-12);
    }
    // In every noise-free preset motion without translation the specific force rotated to
    // earth is exactly +g up (the rotation never adds a linear acceleration).
    let r = sim::scenario("noise-free", 5, 10.0, 100.0).unwrap();
    let truth = r.truth.as_ref().unwrap();
    for i in 0..r.len() {
        assert!((truth[i].rotate(r.acc[i]) - Vec3::new(0.0, 0.0, G)).norm() < 1e-10);
    }
}

#[test]
fn constant_rate_truth_matches_closed_form() {
    let q0 = tilted();
    let axis = Vec3::new(1.0, -2.0, 0.5);
    let unit = axis * (1.0 / axis.norm());
    let rate = 2.3;
    let traj = Trajectory::new(
        q0,
        vec![
            Segment::rest(0.5),
            Segment::rotate(3.0, axis, rate),
            Segment::rest(0.5),
        ],
    )
    .unwrap();
    let r = ideal_sim(traj, 250.0).run().unwrap().recording;
    let truth = r.truth.as_ref().unwrap();
    for i in 0..r.len() {
        let t = r.t[i];
        let angle = rate * (t - 0.5).clamp(0.0, 3.0);
        let expect = q0 * Quat::from_axis_angle(unit, angle);
        assert!(truth[i].angle_to(expect) < 1e-12, "t = {t}");
        let w = if (0.5..3.5).contains(&t) {
            unit * rate
        } else {
            Vec3::zero()
        };
        assert!((r.gyr[i] - w).norm() < 1e-12, "t = {t}");
    }

    // With ramps: the plateau angle is rate·(T − ramp), reached at the end.
    let ramped = Segment {
        rotation: Rotation::ConstantRate {
            axis,
            rate,
            ramp_s: 0.4,
        },
        ..Segment::rest(3.0)
    };
    let traj = Trajectory::new(q0, vec![ramped, Segment::rest(1.0)]).unwrap();
    let end = traj.state_at(3.5);
    let expect = q0 * Quat::from_axis_angle(unit, rate * (3.0 - 0.4));
    assert!(end.q.angle_to(expect) < 1e-12);
    assert!((traj.state_at(0.2).omega.norm() - rate * 0.5).abs() < 1e-12);
}

/// Integrates the ideal gyro of a recording with the trapezoidal rate (second order) and
/// returns the largest angle to the truth, rad.
fn gyro_integration_error(r: &Recording) -> f64 {
    let truth = r.truth.as_ref().unwrap();
    let mut q = truth[0];
    let mut worst: f64 = 0.0;
    for i in 1..r.len() {
        let dt = r.t[i] - r.t[i - 1];
        let w = (r.gyr[i - 1] + r.gyr[i]) * 0.5;
        q = (q * Quat::from_rotation_vector(w * dt)).normalize();
        worst = worst.max(q.angle_to(truth[i]));
    }
    worst
}

#[test]
fn gyro_integrates_to_the_truth() {
    // The smooth segments state their truth in closed form and their rate through the SO(3)
    // Jacobian: integrating the rate must reproduce the truth (a wrong Jacobian is off by
    // degrees). Tolerances are the integrator's second-order error at these rates.
    let r = sim::scenario("noise-free", 9, 20.0, 1000.0).unwrap();
    let err = gyro_integration_error(&r);
    eprintln!("noise-free: gyro integration vs truth {err:.1e} rad");
    assert!(err < 1e-5, "noise-free: {err}");
    // Fast rotation and vibration, ideal sensor.
    for (name, rate, tol) in [("fast-rotation", 2000.0, 2e-5), ("vibration", 4000.0, 1e-4)] {
        let mut s = sim::scenario_simulation(name, 9, 6.0, rate).unwrap();
        s.sensor = SensorModel::ideal();
        let r = s.run().unwrap().recording;
        let err = gyro_integration_error(&r);
        eprintln!("{name}: gyro integration vs truth {err:.1e} rad");
        assert!(err < tol, "{name}: {err}");
    }
    // A hand-made smooth segment with a large rotation vector (|r| near 2.5 rad).
    let seg = Segment::smooth(
        4.0,
        Vec3::new(1.5, -1.0, 1.2),
        vec![Oscillation {
            amplitude: Vec3::new(0.4, 0.3, 0.45),
            freq_hz: 0.7,
            phase: Vec3::new(0.1, 1.0, 2.0),
        }],
    );
    let traj = Trajectory::new(tilted(), vec![seg.clone()]).unwrap();
    let r = ideal_sim(traj, 2000.0).run().unwrap().recording;
    assert!(gyro_integration_error(&r) < 1e-5);
    // Segment ends: starts and ends at rest and at exp(end/2).
    let traj = Trajectory::new(tilted(), vec![seg, Segment::rest(1.0)]).unwrap();
    assert!(traj.state_at(0.0).omega.norm() < 1e-12);
    assert!(traj.state_at(4.0).omega.norm() < 1e-12);
    let expect = tilted() * Quat::from_rotation_vector(Vec3::new(1.5, -1.0, 1.2));
    assert!(traj.state_at(4.5).q.angle_to(expect) < 1e-12);
}

#[test]
fn magnetometer_direction_matches_dip() {
    for dip in [64.0, -30.0, 0.0] {
        let traj = Trajectory::new(
            tilted(),
            vec![Segment::rotate(2.0, Vec3::new(0.3, 1.0, -0.2), 1.5)],
        )
        .unwrap();
        let mut s = ideal_sim(traj, 100.0);
        s.sensor.mag.as_mut().unwrap().field = EarthField {
            magnitude: 48.0,
            dip_deg: dip,
        };
        let r = s.run().unwrap().recording;
        let truth = r.truth.as_ref().unwrap();
        for (q, m) in truth.iter().zip(r.mag.as_ref().unwrap()) {
            let e = q.rotate(*m);
            // North is +y (no east component), dip below the horizon, magnitude kept.
            assert!(e.x.abs() < 1e-12);
            assert!(e.y > 0.0);
            let measured = (-e.z).atan2(e.y).to_degrees();
            assert!((measured - dip).abs() < 1e-9, "{measured} vs {dip}");
            assert!((e.norm() - 48.0).abs() < 1e-9);
        }
    }
    // The consumer sensor of the presets: dip within 1° on average at rest.
    let r = sim::scenario("static", 3, 10.0, 100.0).unwrap();
    let q = r.truth.as_ref().unwrap()[0];
    let (dip, _) = stats(r.mag.as_ref().unwrap().iter().map(|m| {
        let e = q.rotate(*m);
        (-e.z).atan2(e.x.hypot(e.y)).to_degrees()
    }));
    assert!((dip - 64.0).abs() < 1.0, "{dip}");
}

#[test]
fn magnetic_disturbances_and_bias_steps_happen_when_configured() {
    let d = 20.0;
    let out = sim::scenario_simulation("magnetic-disturbance", 4, d, 100.0)
        .unwrap()
        .run()
        .unwrap();
    let r = &out.recording;
    let truth = r.truth.as_ref().unwrap();
    let mag = r.mag.as_ref().unwrap();
    let field = EarthField::default().vector();
    for i in 0..r.len() {
        let t = r.t[i];
        let inside = (0.3 * d < t && t < 0.55 * d) || (0.65 * d < t && t < 0.8 * d);
        assert_eq!(out.mag_disturbed[i], inside, "t = {t}");
        let dev = (truth[i].rotate(mag[i]) - field).norm();
        // Undisturbed: only noise and residual iron (≲ 3 µT); fully disturbed: 20-30 µT.
        let mid = (0.35 * d < t && t < 0.5 * d) || (0.7 * d < t && t < 0.75 * d);
        if !inside {
            assert!(dev < 4.0, "t = {t}: {dev}");
        } else if mid {
            assert!(dev > 12.0, "t = {t}: {dev}");
        }
    }

    let out = sim::scenario_simulation("bias-step", 4, d, 100.0)
        .unwrap()
        .run()
        .unwrap();
    let t = &out.recording.t;
    let k = t.iter().position(|&x| x >= 0.5 * d).unwrap();
    let jump = (out.gyro_bias[k] - out.gyro_bias[k - 1]).norm();
    assert!((jump - 0.02).abs() < 1e-3, "{jump}");

    // Hand-made: a sensor-frame disturbance with ramps, exact values.
    let traj = Trajectory::new(tilted(), vec![Segment::rest(3.0)]).unwrap();
    let mut s = ideal_sim(traj, 100.0);
    s.sensor
        .mag
        .as_mut()
        .unwrap()
        .disturbances
        .push(MagDisturbance {
            start_s: 1.0,
            end_s: 2.0,
            field: Vec3::new(10.0, 0.0, 0.0),
            frame: Frame::Sensor,
            ramp_s: 0.2,
        });
    let r = s.run().unwrap().recording;
    let base = r.mag.as_ref().unwrap()[0];
    let at = |t: f64| r.mag.as_ref().unwrap()[(t * 100.0).round() as usize] - base;
    assert!((at(1.5) - Vec3::new(10.0, 0.0, 0.0)).norm() < 1e-9);
    assert!(
        (at(1.1).x - 5.0).abs() < 1e-9,
        "half-way up the smoothstep ramp"
    );
    assert!(at(2.5).norm() < 1e-12);

    // Hand-made bias step on the accelerometer.
    let traj = Trajectory::new(Quat::identity(), vec![Segment::rest(2.0)]).unwrap();
    let mut s = ideal_sim(traj, 100.0);
    s.sensor.acc.bias_steps.push(BiasStep {
        time_s: 1.0,
        delta: Vec3::new(0.0, 0.5, 0.0),
    });
    let r = s.run().unwrap().recording;
    assert_eq!(r.acc[99].y, 0.0);
    assert_eq!(r.acc[100].y, 0.5);
}

#[test]
fn scale_misalignment_iron_and_saturation() {
    let traj = Trajectory::new(
        Quat::identity(),
        vec![Segment::rotate(1.0, Vec3::new(0.0, 0.0, 1.0), 10.0)],
    )
    .unwrap();
    let mut s = ideal_sim(traj, 100.0);
    s.sensor.gyro = InertialSensor {
        scale: Vec3::new(0.0, 0.0, 0.02),
        misalignment: [[0.0, 0.0, 0.01], [0.0, 0.0, -0.02], [0.0, 0.0, 0.0]],
        range: 10.1,
        ..InertialSensor::ideal()
    };
    let mut m = Magnetometer::ideal();
    m.hard_iron = Vec3::new(1.0, 2.0, 3.0);
    m.soft_iron = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    s.sensor.mag = Some(m);
    let r = s.run().unwrap().recording;
    let g = r.gyr[50];
    // z reads 10·1.02 = 10.2, clipped to 10.1; the coupling puts 1 % and −2 % of 10.2 on x, y.
    assert!((g.z - 10.1).abs() < 1e-12);
    assert!((g.x - 0.102).abs() < 1e-12 && (g.y + 0.204).abs() < 1e-12);
    let m0 = r.mag.as_ref().unwrap()[0];
    let f = EarthField::default().vector();
    assert!((m0 - Vec3::new(2.0 * f.x + 1.0, f.y + 2.0, f.z + 3.0)).norm() < 1e-12);

    // The saturation preset clips at 500 °/s and actually reaches the limit.
    let r = sim::scenario("gyro-saturation", 1, 10.0, 200.0).unwrap();
    let limit = 500.0_f64.to_radians();
    let peak = r
        .gyr
        .iter()
        .map(|g| g.x.abs().max(g.y.abs()).max(g.z.abs()))
        .fold(0.0, f64::max);
    assert!(peak <= limit && peak > limit - 1e-9, "{peak}");
}

#[test]
fn irregular_timing() {
    let rate = 200.0;
    let r = sim::scenario("irregular-dt", 11, 50.0, rate).unwrap();
    let dts: Vec<f64> = r.t.windows(2).map(|w| w[1] - w[0]).collect();
    let min = dts.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(
        min >= 0.1 / rate - 1e-12,
        "jitter clipped at ±0.45 dt: {min}"
    );
    let gaps = dts.iter().filter(|&&d| d > 1.6 / rate).count();
    let n = 50.0 * rate;
    // 3 % dropped: about 300 of 10 000 samples (binomial std ≈ 17).
    let dropped = n as usize - r.len();
    assert!((200..400).contains(&dropped), "{dropped}");
    assert!(gaps > 150, "{gaps}");
    let (_, jitter) = stats(
        r.t.iter()
            .enumerate()
            .filter(|(i, _)| *i < 50)
            .map(|(_, &t)| {
                let k = (t * rate).round();
                t - k / rate
            }),
    );
    assert!(jitter > 0.1 / rate && jitter < 0.3 / rate, "{jitter}");
    // The truth is evaluated at the jittered instants: the ideal gyro still integrates to it.
    let mut s = sim::scenario_simulation("irregular-dt", 11, 10.0, 1000.0).unwrap();
    s.sensor = SensorModel {
        mag: None,
        ..SensorModel::ideal()
    };
    let r = s.run().unwrap().recording;
    assert!(r.mag.is_none());
    assert!(gyro_integration_error(&r) < 1e-4);
}

#[test]
fn vibration_and_translation_reach_the_accelerometer() {
    let traj = Trajectory::new(
        Quat::identity(),
        vec![
            Segment::rest(2.0)
                .with_translation(Oscillation {
                    amplitude: Vec3::new(3.0, 0.0, 0.0),
                    freq_hz: 1.0,
                    phase: Vec3::zero(),
                })
                .with_vibration(Vibration {
                    angle: vec![],
                    acc: vec![Oscillation {
                        amplitude: Vec3::new(0.0, 0.0, 0.5),
                        freq_hz: 20.0,
                        phase: Vec3::zero(),
                    }],
                }),
        ],
    )
    .unwrap();
    let r = ideal_sim(traj.clone(), 1000.0).run().unwrap().recording;
    // At t = 0.25 s: earth x acceleration 3·sin(π/2) = 3; vibration 0.5·sin(10π) = 0.
    let a = r.acc[250];
    assert!((a.x - 3.0).abs() < 1e-9 && (a.z - G).abs() < 1e-9, "{a:?}");
    // At t = 1.0125 s: vibration 0.5·sin(2π·20·1.0125) = 0.5·sin(40.5π) = 0.5, and
    // translation 3·sin(2.025π) along x.
    let a = traj.state_at(1.0125).specific_force(G);
    let ax = 3.0 * (2.0 * std::f64::consts::PI * 1.0125).sin();
    assert!(
        (a.z - G - 0.5).abs() < 1e-12 && (a.x - ax).abs() < 1e-12,
        "{a:?}"
    );
}

/// The hard cases for inclination (issue 35): a pendulum whose bob feels about 1 g of
/// centripetal and tangential acceleration, a vehicle's sustained acceleration in long turns,
/// a hand moving back and forth; exact truth (the ideal gyro integrates to it), the
/// acceleration they promise, and their 6D and disturbed-field variants.
#[test]
fn hard_case_scenarios_accelerate_as_described() {
    // Non-gravitational specific force |f − R(q)ᵀ·g·z|, m/s², per sample.
    let linear = |r: &Recording| -> Vec<f64> {
        let truth = r.truth.as_ref().unwrap();
        r.acc
            .iter()
            .zip(truth)
            .map(|(a, q)| (*a - q.rotate_inverse(Vec3::new(0.0, 0.0, G))).norm())
            .collect()
    };
    for (name, peak_at_least, mean_at_least) in [
        ("pendulum", 0.9 * G, 2.0),
        ("vehicle", 2.0, 1.0),
        ("handheld-translation", 3.0, 1.0),
    ] {
        for seed in 0..3 {
            let mut s = sim::scenario_simulation(name, seed, 60.0, 400.0).unwrap();
            s.sensor = SensorModel::ideal();
            let r = s.run().unwrap().recording;
            let lin = linear(&r);
            let peak = lin.iter().copied().fold(0.0, f64::max);
            let (mean, _) = stats(lin.iter().copied());
            assert!(peak >= peak_at_least, "{name} {seed}: peak {peak} m/s²");
            assert!(mean >= mean_at_least, "{name} {seed}: mean {mean} m/s²");
            let err = gyro_integration_error(&r);
            assert!(err < 1e-4, "{name} {seed}: gyro integration {err} rad");
        }
        let six = sim::scenario(&format!("{name}-6d"), 1, 20.0, 100.0).unwrap();
        assert!(six.mag.is_none());
        let plain = sim::scenario_simulation(name, 1, 20.0, 100.0).unwrap();
        let disturbed =
            sim::scenario_simulation(&format!("{name}-disturbed"), 1, 20.0, 100.0).unwrap();
        assert!(plain.sensor.mag.as_ref().unwrap().disturbances.is_empty());
        assert_eq!(disturbed.sensor.mag.as_ref().unwrap().disturbances.len(), 2);
    }
    assert!(sim::scenario("pendulum-9d", 1, 1.0, 100.0).is_err());
}

/// A pendulum of length g/ω² swinging 10° at 0.5 Hz is a simple pendulum: where the swing is
/// at full amplitude, the specific force points along the string to the pivot, within the
/// small-angle error (tangential g·|θ − sin θ| ≤ 9e-4·g at 10°).
#[test]
fn pendulum_force_points_to_the_pivot() {
    let freq = 0.5;
    let w = 2.0 * std::f64::consts::PI * freq;
    // Sensor frame = earth at rest, the bob g/ω² below the pivot, swinging about x.
    let lever = Vec3::new(0.0, 0.0, -G / (w * w));
    let swing = Segment::swing(
        20.0,
        Vec3::new(1.0, 0.0, 0.0),
        10f64.to_radians(),
        freq,
        lever,
    );
    let traj = Trajectory::new(Quat::identity(), vec![swing]).unwrap();
    let r = ideal_sim(traj, 200.0).run().unwrap().recording;
    let mut checked = 0;
    for (t, f) in r.t.iter().zip(&r.acc) {
        if (2.5..17.5).contains(t) {
            assert!(f.x.abs() < 1e-9, "t {t}: {f:?}");
            assert!(f.y.abs() < 9e-4 * G, "t {t}: tangential {} m/s²", f.y);
            assert!(f.z > 0.9 * G, "t {t}: {f:?}");
            checked += 1;
        }
    }
    assert_eq!(checked, 3000);
    assert!(gyro_integration_error(&r) < 1e-5);
}
