//! The online hard-iron estimator: it does not learn a disturbance, it brings a 9D filter
//! with 30 % hard iron back to the accuracy of perfect calibration, and it leaves calibrated
//! real data alone.
use crate::common::broad_dir;
use rootfuse_attitude::calibration::{MagCalibrated, OnlineHardIron, OnlineHardIronParams};
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::{Dof, Recording, Vec3};
use rootfuse_eval::metrics::{Alignment, evaluate};
use rootfuse_eval::sim::{self, IDENTITY};

const HARD: [f64; 3] = [12.0, -7.0, 6.0];

fn with_iron(name: &str, seed: u64, duration: f64, hard: [f64; 3]) -> sim::SimOutput {
    let mut s = sim::scenario_simulation(name, seed, duration, 100.0).unwrap();
    let m = s.sensor.mag.as_mut().unwrap();
    m.hard_iron = Vec3::from_array(hard);
    m.soft_iron = IDENTITY;
    s.run().unwrap()
}

/// Offsets applied over a recording, one per sample.
fn applied(params: OnlineHardIronParams, mag: &[Vec3<f64>]) -> Vec<Vec3<f64>> {
    let mut est = OnlineHardIron::<f64>::new(params).unwrap();
    mag.iter()
        .map(|m| {
            est.update(*m);
            est.applied_offset()
        })
        .collect()
}

/// The `magnetic-disturbance` preset (a 30 µT room-fixed field from 30 % to 55 % of the
/// duration, a 20 µT body-fixed one from 65 % to 80 %) with 30 % hard iron: the applied
/// offset converges to the hard iron before the first disturbance and stays there through
/// both. Without the learning and consistency gates the same estimator learns the
/// disturbance.
#[test]
fn online_estimator_does_not_learn_a_disturbance() {
    let out = with_iron("magnetic-disturbance", 21, 240.0, HARD);
    let mag = out.recording.mag.as_ref().unwrap();
    let truth = Vec3::from_array(HARD);
    let worst = |offsets: &[Vec3<f64>]| {
        // From just before the first disturbance to the end.
        offsets[(0.29 * mag.len() as f64) as usize..]
            .iter()
            .map(|h| (*h - truth).norm() / 50.0)
            .fold(0.0, f64::max)
    };
    let gated = applied(OnlineHardIronParams::default(), mag);
    let ungated = applied(
        OnlineHardIronParams {
            gate_sigmas: f64::INFINITY,
            max_residual_rms: f64::INFINITY,
            ..OnlineHardIronParams::default()
        },
        mag,
    );
    let (g, u) = (worst(&gated), worst(&ungated));
    eprintln!("worst offset error after convergence: gated {g:.4}, ungated {u:.4} of the field");
    assert!(g < 0.02, "gated estimator moved by {g} of the field");
    assert!(
        u > 2.0 * g && u > 0.03,
        "the test must be able to fail: ungated {u}"
    );
}

/// Heading RMSE (degrees) of the flagship after `from_s` seconds.
fn heading_after(rec: &Recording, from_s: f64, online: bool) -> f64 {
    let mut spec = FilterSpec::new("sqrt-eskf").unwrap();
    spec.set_dof(Dof::Nine).unwrap();
    let est = if online {
        let mut f =
            MagCalibrated::new(spec.build::<f64>(), OnlineHardIronParams::default()).unwrap();
        rec.estimate(&mut f)
    } else {
        rec.estimate(&mut spec.build::<f64>())
    };
    let mut rec = rec.clone();
    rec.use_mask = Some(rec.t.iter().map(|&t| t >= from_s).collect());
    evaluate(&rec, &est, Alignment::NineD).unwrap().heading
}

/// The goal: after 60 s of varied motion, the flagship's 9D heading error with 30 %
/// hard iron and online calibration is within 10 % of the run with perfect calibration
/// (the same recording without hard iron). Without online calibration it is far off. (On
/// seed 31 the correction is validated after 37 s of motion; from then on the heading RMSE
/// is 0.44°, 0.54°, 0.21° over 90–120 s, 120–200 s, 200–300 s.)
#[test]
fn online_calibration_restores_the_flagship_heading() {
    for seed in [31, 32, 33] {
        let biased = with_iron("slow-rotation", seed, 300.0, HARD).recording;
        let perfect = with_iron("slow-rotation", seed, 300.0, [0.0; 3]).recording;
        // The preset rests for the first 10 % (30 s): 60 s of varied motion end at 90 s.
        let from = 90.0;
        let reference = heading_after(&perfect, from, false);
        let calibrated = heading_after(&biased, from, true);
        let raw = heading_after(&biased, from, false);
        eprintln!(
            "seed {seed}: heading RMSE after {from} s: perfect {reference:.3}°, online {calibrated:.3}°, uncalibrated {raw:.3}°"
        );
        assert!(
            calibrated <= 1.1 * reference,
            "online {calibrated} vs perfect {reference}"
        );
        assert!(raw > 2.0 * reference, "the hard iron must matter: {raw}");
    }
}

/// On the BROAD trials (magnetometers already calibrated) online calibration changes no
/// trial's 9D total RMSE of the flagship by more than 2 %.
#[test]
#[cfg_attr(
    not(broad_data),
    ignore = "BROAD data not found (../shared/broad_csv or $ROOTFUSE_BROAD_DIR)"
)]
fn online_calibration_leaves_calibrated_broad_trials_alone() {
    let Some(dir) = broad_dir() else { return };
    let mut trials: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.extension().is_some_and(|e| e == "csv")
                && p.file_name().is_some_and(|n| n != "index.csv")
        })
        .collect();
    trials.sort();
    assert_eq!(trials.len(), 14, "the 14 shared trials");
    let mut spec = FilterSpec::new("sqrt-eskf").unwrap();
    spec.set_dof(Dof::Nine).unwrap();
    let mut failures = Vec::new();
    for path in &trials {
        let rec = rootfuse_io::read_csv(path).unwrap();
        let plain = evaluate(
            &rec,
            &rec.estimate(&mut spec.build::<f64>()),
            Alignment::NineD,
        )
        .unwrap()
        .total;
        let mut f =
            MagCalibrated::new(spec.build::<f64>(), OnlineHardIronParams::default()).unwrap();
        let online = evaluate(&rec, &rec.estimate(&mut f), Alignment::NineD)
            .unwrap()
            .total;
        let change = (online - plain) / plain;
        eprintln!(
            "{:<40} plain {plain:.3}°, online {online:.3}° ({:+.2} %), offset {:?}, active {}",
            rec.name,
            100.0 * change,
            f.calibration().applied_offset(),
            f.calibration().active()
        );
        if change.abs() > 0.02 {
            failures.push(format!("{}: {:+.2} %", rec.name, 100.0 * change));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Lane-generic: four channels in `f64x4` lanes give exactly the four scalar runs, and a
/// reading that is NaN (or wildly off) in one lane changes nothing in the others.
#[test]
fn lanes_equal_scalar_runs_and_bad_lanes_stay_local() {
    use wide::f64x4;
    let recs: Vec<_> = (0..4)
        .map(|k| {
            with_iron(
                "slow-rotation",
                40 + k,
                60.0,
                [HARD[0] * k as f64 / 3.0, HARD[1], HARD[2]],
            )
            .recording
            .mag
            .unwrap()
        })
        .collect();
    // Lane 2 gets NaN and huge readings now and then.
    let reading = |k: usize, i: usize| {
        let m = recs[k][i];
        match (k, i % 97) {
            (2, 0) => Vec3::new(f64::NAN, m.y, m.z),
            (2, 1) => m * 1e30,
            _ => m,
        }
    };
    let params = OnlineHardIronParams::default();
    let mut lanes = OnlineHardIron::<f64x4>::new(params).unwrap();
    let mut scalars: Vec<_> = (0..4)
        .map(|_| OnlineHardIron::<f64>::new(params).unwrap())
        .collect();
    for i in 0..recs[0].len() {
        let out = lanes.update(Vec3::from_lanes(|k| reading(k, i)));
        for (k, s) in scalars.iter_mut().enumerate() {
            let o = s.update(reading(k, i));
            let l = out.lane(k);
            for (a, b) in [(o.x, l.x), (o.y, l.y), (o.z, l.z)] {
                assert!(
                    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()),
                    "sample {i} lane {k}"
                );
            }
        }
    }
    for (k, s) in scalars.iter().enumerate() {
        assert_eq!(s.applied_offset(), lanes.applied_offset().lane(k));
        assert_eq!(s.rejected().as_ref()[0], lanes.rejected().as_ref()[k]);
    }
}
