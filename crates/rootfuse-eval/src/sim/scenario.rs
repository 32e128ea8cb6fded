//! Named scenario presets: a seeded trajectory and a consumer-grade 9D IMU model.
//!
//! Every preset scales to any duration and rate: motion is laid out in fractions of the
//! duration (typically 10 % rest, 80 % motion in pieces of about 5 s, 10 % rest). The seed
//! draws the initial orientation (uniform over SO(3)), the sensor's biases, scale and coupling
//! errors, and the motion; the same `(name, seed, duration, rate)` gives the same recording.
//!
//! The sensor of every preset (except `noise-free`), drawn per seed:
//! - gyroscope: noise density 1.2e-4 rad/s/√Hz (per-sample std = density·√rate), bias
//!   N(0, 0.005 rad/s) per axis, bias walk 5e-5 rad/s/√s, scale N(0, 0.3 %), coupling
//!   N(0, 0.001), range ±34.9 rad/s (2000 °/s);
//! - accelerometer: noise density 2e-3 m/s²/√Hz, bias N(0, 0.03 m/s²), bias walk
//!   1e-4 m/s²/√s, scale N(0, 0.3 %), coupling N(0, 0.001), range ±16 g;
//! - magnetometer (µT): earth field 50 µT, dip 64°, noise 0.2 µT per sample, residual hard iron
//!   N(0, 0.5 µT), soft iron I + N(0, 0.005) per element, range ±4900 µT.

use super::sensor::{
    BiasStep, EarthField, Frame, IDENTITY, InertialSensor, MagDisturbance, Magnetometer,
    SensorModel, Timing,
};
use super::trajectory::{Oscillation, Segment, Trajectory, Vibration};
use super::{GRAVITY, MAX_SAMPLES, STREAM_SETUP, SimError, SimStream, Simulation, rng};
use core::f64::consts::PI;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rootfuse_attitude::Quat;
use rootfuse_attitude::Recording;
use rootfuse_attitude::Vec3;
use std::string::ToString;
use std::vec;
use std::vec::Vec;

/// The preset names with a one-line description each.
pub const SCENARIOS: &[(&str, &str)] = &[
    (
        "static",
        "rest at a random orientation for the whole duration (bias and noise only)",
    ),
    (
        "slow-rotation",
        "10% rest, smooth random rotation up to ~1 rad/s (0.1-0.4 Hz) in ~5 s pieces, 10% rest",
    ),
    (
        "fast-rotation",
        "10% rest, alternating smooth rotation up to ~6 rad/s and constant-rate turns at 3-6 rad/s about random axes (0.3 s ramps), 10% rest",
    ),
    (
        "translation",
        "slow rotation (~0.5 rad/s) with linear acceleration of 2-5 m/s² horizontal, 1-3 m/s² vertical at 0.5-2 Hz",
    ),
    (
        "magnetic-disturbance",
        "slow rotation; a 30 µT room-fixed disturbance from 30% to 55% of the duration, a 20 µT body-fixed one from 65% to 80%",
    ),
    (
        "bias-step",
        "slow rotation; the gyro bias jumps by 0.02 rad/s (random direction) at half the duration",
    ),
    (
        "long-rest",
        "5% rest, 15% slow rotation, then rest for the remaining 80%",
    ),
    (
        "irregular-dt",
        "slow rotation sampled with time jitter (std 0.2/rate, clipped at 0.45/rate) and 3% dropped samples",
    ),
    (
        "vibration",
        "slow rotation with vibration throughout: 1-3 m/s² sensor-frame acceleration and 2 mrad wobble at min(0.3·rate, 50) Hz",
    ),
    (
        "gyro-saturation",
        "10% rest, constant-rate turns at 12 rad/s with the gyroscope clipped at ±8.73 rad/s (500 °/s), 10% rest",
    ),
    (
        "noise-free",
        "the slow-rotation motion measured by an ideal 9D IMU (no noise, bias or other error)",
    ),
    (
        "pendulum",
        "10% rest, pendulum swings of 30-70° at 0.3-1 Hz in ~10 s pieces, the sensor at the bob (lever g/ω²: centripetal up to 1.5 g, tangential up to 1.2 g), 10% rest",
    ),
    ("pendulum-6d", "pendulum without a magnetometer"),
    (
        "pendulum-disturbed",
        "pendulum with the magnetic disturbances of magnetic-disturbance",
    ),
    (
        "vehicle",
        "10% rest, ~8 s pieces alternating turns about the vertical at 0.1-0.4 rad/s with a sustained centripetal acceleration of 1-4 m/s² and straight acceleration or braking at 1-3 m/s², 10% rest",
    ),
    ("vehicle-6d", "vehicle without a magnetometer"),
    (
        "vehicle-disturbed",
        "vehicle with the magnetic disturbances of magnetic-disturbance",
    ),
    (
        "handheld-translation",
        "10% rest, back-and-forth motion along a random line at 3-8 m/s², 0.5-2 Hz, with slow rotation (~0.3 rad/s), 10% rest",
    ),
    (
        "handheld-translation-6d",
        "handheld-translation without a magnetometer",
    ),
    (
        "handheld-translation-disturbed",
        "handheld-translation with the magnetic disturbances of magnetic-disturbance",
    ),
];

/// The hard cases for inclination and for the reported covariance: a pendulum, a vehicle and a
/// handheld translation, each without a magnetometer (`-6d`) and with a disturbed field
/// (`-disturbed`, 9D). The accuracy tests and `benches/python/accuracy_peers.py` run VQF
/// beside the flagship on them; docs/accuracy.md scores both there.
///
/// ```
/// use rootfuse_eval::sim::{HARD_CASES, scenario_names};
/// assert!(HARD_CASES.iter().all(|h| scenario_names().any(|n| n == *h)));
/// ```
pub const HARD_CASES: [&str; 6] = [
    "pendulum-6d",
    "pendulum-disturbed",
    "vehicle-6d",
    "vehicle-disturbed",
    "handheld-translation-6d",
    "handheld-translation-disturbed",
];

/// The preset names, in the order of [`SCENARIOS`].
pub fn scenario_names() -> impl Iterator<Item = &'static str> {
    SCENARIOS.iter().map(|(n, _)| *n)
}

/// Runs the named preset (see [`SCENARIOS`]) and returns the recording (truth = sensor to
/// earth, ENU; use mask all true).
///
/// `duration_s` and `rate_hz` must be finite and positive, with at most [`MAX_SAMPLES`]
/// samples.
pub fn scenario(
    name: &str,
    seed: u64,
    duration_s: f64,
    rate_hz: f64,
) -> Result<Recording, SimError> {
    Ok(scenario_simulation(name, seed, duration_s, rate_hz)?
        .run()?
        .recording)
}

/// The named preset's samples one at a time ([`Simulation::stream`]): the same samples as
/// [`scenario`] without holding the recording.
pub fn scenario_stream(
    name: &str,
    seed: u64,
    duration_s: f64,
    rate_hz: f64,
) -> Result<SimStream, SimError> {
    scenario_simulation(name, seed, duration_s, rate_hz)?.stream()
}

/// Runs the named preset once per seed (one channel each), spread over the available cores
/// with scoped threads; the result is in seed order and identical to calling [`scenario`] for
/// each seed.
pub fn scenario_batch(
    name: &str,
    seeds: &[u64],
    duration_s: f64,
    rate_hz: f64,
) -> Result<Vec<Recording>, SimError> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, seeds.len().max(1));
    let chunk = seeds.len().div_ceil(threads).max(1);
    std::thread::scope(|scope| {
        let handles: Vec<_> = seeds
            .chunks(chunk)
            .map(|part| {
                scope.spawn(move || {
                    part.iter()
                        .map(|&seed| scenario(name, seed, duration_s, rate_hz))
                        .collect::<Result<Vec<_>, _>>()
                })
            })
            .collect();
        let mut out = Vec::with_capacity(seeds.len());
        for h in handles {
            // A worker only panics on a bug; hand that panic on unchanged.
            let part = h.join().unwrap_or_else(|e| std::panic::resume_unwind(e))?;
            out.extend(part);
        }
        Ok(out)
    })
}

/// The set-up of the named preset, to inspect, modify (for example drop the magnetometer with
/// `sensor.mag = None`) or run for the hidden truth ([`super::SimOutput`]).
pub fn scenario_simulation(
    name: &str,
    seed: u64,
    duration_s: f64,
    rate_hz: f64,
) -> Result<Simulation, SimError> {
    check_size(duration_s, rate_hz)?;

    let r = &mut rng(seed, STREAM_SETUP);
    let d = duration_s;
    // Fixed draw order: sensor, initial orientation, motion, extras.
    let mut sensor = consumer_imu(r, rate_hz);
    let q0 = random_orientation(r);
    let mut timing = Timing::regular(rate_hz);
    let slow = |r: &mut ChaCha8Rng| {
        framed(
            d,
            0.1,
            0.1,
            pieces(r, 0.8 * d, |r, t| smooth(r, t, 1.0, 0.1, 0.4)),
        )
    };

    // The hard cases' variants: without a magnetometer, or with a disturbed field.
    let (base, variant) = match name.rsplit_once('-') {
        Some((base, v @ ("6d" | "disturbed")))
            if matches!(base, "pendulum" | "vehicle" | "handheld-translation") =>
        {
            (base, v)
        }
        _ => (name, ""),
    };
    let up = q0.rotate_inverse(Vec3::new(0.0, 0.0, 1.0));
    let segments = match base {
        "static" => vec![Segment::rest(d)],
        "pendulum" => pendulum(r, d, q0, up),
        "vehicle" => vehicle(r, d, q0, up),
        "handheld-translation" => handheld(r, d),
        "slow-rotation" | "noise-free" => slow(r),
        "fast-rotation" => fast_rotation(r, d),
        "translation" => translation(r, d),
        "magnetic-disturbance" => {
            let segs = slow(r);
            disturb(r, &mut sensor, d);
            segs
        }
        "bias-step" => {
            let segs = slow(r);
            sensor.gyro.bias_steps.push(BiasStep {
                time_s: 0.5 * d,
                delta: random_unit(r) * 0.02,
            });
            segs
        }
        "long-rest" => framed(
            d,
            0.05,
            0.8,
            pieces(r, 0.15 * d, |r, t| smooth(r, t, 1.0, 0.1, 0.4)),
        ),
        "irregular-dt" => {
            timing.jitter_std_s = 0.2 / rate_hz;
            timing.drop_prob = 0.03;
            slow(r)
        }
        "vibration" => {
            let f = (0.3 * rate_hz).min(50.0);
            let vib = Vibration {
                angle: vec![Oscillation {
                    amplitude: Vec3::new(0.002, 0.002, 0.002),
                    freq_hz: f,
                    phase: random_phase(r),
                }],
                acc: vec![Oscillation {
                    amplitude: Vec3::new(
                        uniform(r, 1.0, 3.0),
                        uniform(r, 1.0, 3.0),
                        uniform(r, 1.0, 3.0),
                    ),
                    freq_hz: f,
                    phase: random_phase(r),
                }],
            };
            slow(r)
                .into_iter()
                .map(|s| s.with_vibration(vib.clone()))
                .collect()
        }
        "gyro-saturation" => {
            sensor.gyro.range = 500.0_f64.to_radians();
            framed(
                d,
                0.1,
                0.1,
                pieces(r, 0.8 * d, |r, t| turn(r, t, 12.0, 12.0)),
            )
        }
        _ => {
            return Err(SimError::UnknownScenario {
                name: name.to_string(),
                known: scenario_names().collect::<Vec<_>>().join(", "),
            });
        }
    };
    if name == "noise-free" {
        sensor = SensorModel::ideal();
    }
    match variant {
        "6d" => sensor.mag = None,
        "disturbed" => disturb(r, &mut sensor, d),
        _ => {}
    }
    Ok(Simulation {
        name: name.to_string(),
        trajectory: Trajectory::new(q0, segments)?,
        sensor,
        timing,
        seed,
    })
}

/// A positive, finite duration and rate whose product fits [`MAX_SAMPLES`].
fn check_size(duration_s: f64, rate_hz: f64) -> Result<(), SimError> {
    if !(duration_s.is_finite() && duration_s > 0.0) {
        return Err(SimError::InvalidParameter {
            name: "duration_s",
            value: duration_s,
        });
    }
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(SimError::InvalidParameter {
            name: "rate_hz",
            value: rate_hz,
        });
    }
    let samples = duration_s * rate_hz;
    // Two finite inputs can still overflow to infinity; that is caught here too.
    if samples.is_nan() || samples > MAX_SAMPLES as f64 {
        return Err(SimError::TooManySamples { samples });
    }
    Ok(())
}

/// Swings of 30–70° at 0.3–1 Hz about horizontal axes, the sensor a pendulum's length below
/// the pivot (centripetal and tangential acceleration to about 1 g).
fn pendulum(r: &mut ChaCha8Rng, d: f64, q0: Quat<f64>, up: Vec3<f64>) -> Vec<Segment> {
    let motion = pieces_of(r, 0.8 * d, 10.0, |r, t| {
        let freq = uniform(r, 0.3, 1.0);
        let amplitude = uniform(r, 30.0, 70.0).to_radians();
        let heading = uniform(r, 0.0, 2.0 * PI);
        let axis = q0.rotate_inverse(Vec3::new(heading.cos(), heading.sin(), 0.0));
        // The length of a simple pendulum of that frequency, hanging below the pivot.
        let length = GRAVITY / (2.0 * PI * freq).powi(2);
        Segment::swing(t, axis, amplitude, freq, up * -length)
    });
    framed(d, 0.1, 0.1, motion)
}

/// Turns with a car's lateral acceleration and straight stretches of forward acceleration.
fn vehicle(r: &mut ChaCha8Rng, d: f64, q0: Quat<f64>, up: Vec3<f64>) -> Vec<Segment> {
    // Forward and left are fixed in the vehicle, so in the sensor frame.
    let forward = q0.rotate_inverse(Vec3::new(1.0, 0.0, 0.0));
    let left = up.cross(forward);
    let constant = |v: Vec3<f64>| Oscillation {
        amplitude: v,
        freq_hz: 0.0,
        phase: Vec3::new(0.5 * PI, 0.5 * PI, 0.5 * PI),
    };
    let mut k = 0usize;
    let motion = pieces_of(r, 0.8 * d, 8.0, |r, t| {
        k += 1;
        let (rotation, acc) = if k % 2 == 1 {
            // A car's lateral acceleration of 1-4 m/s² (speed = that / rate).
            let rate = uniform(r, 0.1, 0.4) * sign(r);
            let speed = uniform(r, 1.0, 4.0) / rate.abs();
            let mut turn = Segment::rotate(t, up, rate);
            if let super::Rotation::ConstantRate { ramp_s, .. } = &mut turn.rotation {
                *ramp_s = 0.1;
            }
            // Toward the centre of the turn: left for a positive (counter-clockwise)
            // rate.
            (turn, left * (speed * rate))
        } else {
            (Segment::rest(t), forward * (uniform(r, 1.0, 3.0) * sign(r)))
        };
        rotation.with_vibration(Vibration {
            angle: Vec::new(),
            acc: vec![constant(acc)],
        })
    });
    framed(d, 0.1, 0.1, motion)
}

/// Slow rotation with back-and-forth translation of 0.5–2 Hz.
fn handheld(r: &mut ChaCha8Rng, d: f64) -> Vec<Segment> {
    let motion = pieces(r, 0.8 * d, |r, t| {
        let seg = smooth(r, t, 0.3, 0.1, 0.3);
        seg.with_translation(Oscillation {
            amplitude: random_unit(r) * uniform(r, 3.0, 8.0),
            freq_hz: uniform(r, 0.5, 2.0),
            phase: Vec3::zero(),
        })
    });
    framed(d, 0.1, 0.1, motion)
}

/// Fast smooth rotation alternating with fast turns.
fn fast_rotation(r: &mut ChaCha8Rng, d: f64) -> Vec<Segment> {
    let mut k = 0usize;
    let motion = pieces(r, 0.8 * d, |r, t| {
        k += 1;
        if k % 2 == 1 {
            smooth(r, t, 6.0, 0.5, 1.5)
        } else {
            turn(r, t, 3.0, 6.0)
        }
    });
    framed(d, 0.1, 0.1, motion)
}

/// Slow rotation with two translations on each piece.
fn translation(r: &mut ChaCha8Rng, d: f64) -> Vec<Segment> {
    let motion = pieces(r, 0.8 * d, |r, t| {
        let mut seg = smooth(r, t, 0.5, 0.1, 0.3);
        for _ in 0..2 {
            let amp = Vec3::new(
                uniform(r, 2.0, 5.0) * sign(r),
                uniform(r, 2.0, 5.0) * sign(r),
                uniform(r, 1.0, 3.0) * sign(r),
            ) * 0.5;
            seg = seg.with_translation(Oscillation {
                amplitude: amp,
                freq_hz: uniform(r, 0.5, 2.0),
                phase: random_phase(r),
            });
        }
        seg
    });
    framed(d, 0.1, 0.1, motion)
}

/// The consumer-grade 9D IMU of the presets (see the module docs), errors drawn from `r`.
fn consumer_imu(r: &mut ChaCha8Rng, rate_hz: f64) -> SensorModel {
    let sqrt_rate = rate_hz.sqrt();
    let inertial = |r: &mut ChaCha8Rng, density: f64, bias: f64, walk: f64, range: f64| {
        let mut misalignment = [[0.0; 3]; 3];
        for (i, row) in misalignment.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                if i != j {
                    *v = 0.001 * normal(r);
                }
            }
        }
        InertialSensor {
            noise_std: density * sqrt_rate,
            bias: normal3(r) * bias,
            bias_walk: walk,
            bias_steps: Vec::new(),
            scale: normal3(r) * 0.003,
            misalignment,
            range,
        }
    };
    let gyro = inertial(r, 1.2e-4, 0.005, 5e-5, 2000.0_f64.to_radians());
    let acc = inertial(r, 2e-3, 0.03, 1e-4, 16.0 * GRAVITY);
    let mut soft_iron = IDENTITY;
    for v in soft_iron.iter_mut().flatten() {
        *v += 0.005 * normal(r);
    }
    let mag = Magnetometer {
        field: EarthField::default(),
        noise_std: 0.2,
        hard_iron: normal3(r) * 0.5,
        soft_iron,
        disturbances: Vec::new(),
        range: 4900.0,
    };
    SensorModel {
        gyro,
        acc,
        mag: Some(mag),
        gravity: GRAVITY,
    }
}

/// `lead` and `tail` fractions of rest around `motion`.
fn framed(d: f64, lead: f64, tail: f64, motion: Vec<Segment>) -> Vec<Segment> {
    let mut v = Vec::with_capacity(motion.len() + 2);
    v.push(Segment::rest(lead * d));
    v.extend(motion);
    v.push(Segment::rest(tail * d));
    v
}

/// Fills `span` seconds with pieces of about 5 s (equal length, at least one piece).
fn pieces(
    r: &mut ChaCha8Rng,
    span: f64,
    make: impl FnMut(&mut ChaCha8Rng, f64) -> Segment,
) -> Vec<Segment> {
    pieces_of(r, span, 5.0, make)
}

/// Fills `span` seconds with pieces of about `length` seconds (equal length, at least one).
fn pieces_of(
    r: &mut ChaCha8Rng,
    span: f64,
    length: f64,
    mut make: impl FnMut(&mut ChaCha8Rng, f64) -> Segment,
) -> Vec<Segment> {
    let n = ((span / length).round() as usize).clamp(1, 100_000);
    (0..n).map(|_| make(r, span / n as f64)).collect()
}

/// The field disturbances of `magnetic-disturbance`: a 30 µT room-fixed one from 30 % to
/// 55 % of the duration `d`, a 20 µT body-fixed one from 65 % to 80 %.
fn disturb(r: &mut ChaCha8Rng, sensor: &mut SensorModel, d: f64) {
    let ramp = (0.02 * d).min(1.0);
    let (earth, body) = (random_unit(r) * 30.0, random_unit(r) * 20.0);
    if let Some(m) = &mut sensor.mag {
        m.disturbances = vec![
            MagDisturbance {
                start_s: 0.30 * d,
                end_s: 0.55 * d,
                field: earth,
                frame: Frame::Earth,
                ramp_s: ramp,
            },
            MagDisturbance {
                start_s: 0.65 * d,
                end_s: 0.80 * d,
                field: body,
                frame: Frame::Sensor,
                ramp_s: ramp,
            },
        ];
    }
}

/// A smooth random rotation with body rate up to about `peak_rate` rad/s, wobble frequencies
/// in `[f_lo, f_hi]` Hz, and a net rotation of 0.3–1.2 rad about a random axis.
fn smooth(r: &mut ChaCha8Rng, duration: f64, peak_rate: f64, f_lo: f64, f_hi: f64) -> Segment {
    let end = random_unit(r) * uniform(r, 0.3, 1.2);
    let wobble = (0..2)
        .map(|_| {
            let f = uniform(r, f_lo, f_hi);
            // Two harmonics on three axes: each axis gets a share so the norm stays near the
            // peak; capped so |r| stays below π (far from the Jacobian's singularity at 2π).
            let a = (peak_rate / (2.0 * PI * f * 2.0 * 3.0_f64.sqrt())).min(0.45);
            Oscillation {
                amplitude: Vec3::new(
                    a * uniform(r, 0.5, 1.0),
                    a * uniform(r, 0.5, 1.0),
                    a * uniform(r, 0.5, 1.0),
                ),
                freq_hz: f,
                phase: random_phase(r),
            }
        })
        .collect();
    Segment::smooth(duration, end, wobble)
}

/// A constant-rate turn about a random axis at a rate in `[lo, hi]` rad/s (random sign),
/// with 0.3 s ramps.
fn turn(r: &mut ChaCha8Rng, duration: f64, lo: f64, hi: f64) -> Segment {
    let mut s = Segment::rotate(duration, random_unit(r), uniform(r, lo, hi) * sign(r));
    if let super::Rotation::ConstantRate { ramp_s, .. } = &mut s.rotation {
        *ramp_s = 0.3;
    }
    s
}

fn normal(r: &mut ChaCha8Rng) -> f64 {
    r.sample(StandardNormal)
}
fn normal3(r: &mut ChaCha8Rng) -> Vec3<f64> {
    Vec3::new(normal(r), normal(r), normal(r))
}
fn uniform(r: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * r.random::<f64>()
}
fn sign(r: &mut ChaCha8Rng) -> f64 {
    if r.random::<bool>() { 1.0 } else { -1.0 }
}
fn random_phase(r: &mut ChaCha8Rng) -> Vec3<f64> {
    Vec3::new(
        uniform(r, 0.0, 2.0 * PI),
        uniform(r, 0.0, 2.0 * PI),
        uniform(r, 0.0, 2.0 * PI),
    )
}
/// A uniformly distributed unit vector (normalised Gaussian; redrawn in the practically
/// impossible case of a tiny norm).
fn random_unit(r: &mut ChaCha8Rng) -> Vec3<f64> {
    loop {
        let v = normal3(r);
        let n = v.norm();
        if n > 1e-6 {
            return v * (1.0 / n);
        }
    }
}
/// A uniformly distributed orientation (normalised 4D Gaussian), scalar part ≥ 0.
fn random_orientation(r: &mut ChaCha8Rng) -> Quat<f64> {
    loop {
        let q = Quat::new(normal(r), normal(r), normal(r), normal(r));
        let n = q.norm();
        if n > 1e-6 {
            let q = q.scale(1.0 / n);
            return if q.w < 0.0 { -q } else { q };
        }
    }
}
