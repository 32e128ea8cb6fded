//! A deterministic, seeded IMU simulator.
//!
//! A [`Simulation`] is a [`Trajectory`] (the true motion: composable segments whose
//! orientation is known in closed form, see [`trajectory`]), a [`SensorModel`] (noise, biases,
//! scale and coupling errors, magnetometer hard/soft iron and disturbances, saturation, see
//! [`sensor`]), a [`Timing`] (rate, jitter, dropped samples) and a seed. [`Simulation::run`]
//! produces a [`Recording`] with the true orientation (sensor to earth, ENU) and a use mask,
//! plus the hidden true biases for tests.
//!
//! The same configuration and seed give bit-identical output on the same platform: all
//! randomness comes from ChaCha8 streams of the seed (not from the OS or thread-local RNGs),
//! and Gaussian draws use `rand_distr`'s ziggurat.
//!
//! Named presets for tests, benches and the CLI: [`scenario`], [`SCENARIOS`].
//!
//! Earth frame ENU (x east, y north, z up), gravity [`GRAVITY`] m/s² (the accelerometer reads
//! `+g` along earth-up at rest), magnetic field by default 50 µT with a dip of 64°.
//!
//! ```
//! use rootfuse_eval::{metrics, sim};
//! // 10 s of smooth rotation sampled at 100 Hz, seed 7.
//! let rec = sim::scenario("slow-rotation", 7, 10.0, 100.0).unwrap();
//! assert_eq!(rec.len(), 1000);
//! // At rest (the first 10 %) the accelerometer, rotated to earth by the truth, points up.
//! let q = rec.truth.as_ref().unwrap()[0];
//! assert!((q.rotate(rec.acc[0]).z - sim::GRAVITY).abs() < 0.2);
//! // The truth scores zero against itself with the BROAD metrics.
//! let truth = rec.truth.clone().unwrap();
//! let err = metrics::evaluate(&rec, &truth, metrics::Alignment::NineD).unwrap();
//! assert!(err.total < 1e-9 && err.n_used == 1000);
//! ```

mod scenario;
pub mod sensor;
pub mod trajectory;

pub use scenario::{SCENARIOS, scenario, scenario_batch, scenario_names, scenario_simulation};
pub use sensor::{
    BiasStep, EarthField, Frame, IDENTITY, InertialSensor, MagDisturbance, Magnetometer, Mat3,
    SensorModel, Timing,
};
pub use trajectory::{MotionState, Oscillation, Rotation, Segment, Trajectory, Vibration};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rootfuse_attitude::Quat;
use rootfuse_attitude::Recording;
use rootfuse_attitude::Vec3;
use std::string::String;
use std::vec;
use std::vec::Vec;

/// Gravity used by the presets, m/s² (the value the project's docs state: 9.81, up).
pub const GRAVITY: f64 = 9.81;

/// The largest number of samples one simulation may produce (guards against a typo in a
/// duration or rate exhausting memory).
pub const MAX_SAMPLES: usize = 50_000_000;

/// Why a simulation could not be set up.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A scenario name that is not in [`SCENARIOS`].
    #[error("unknown scenario `{name}` (known: {known})")]
    UnknownScenario {
        /// The name asked for.
        name: String,
        /// The known names, comma separated.
        known: String,
    },
    /// A parameter is out of its valid range.
    #[error("invalid {name}: {value}")]
    InvalidParameter {
        /// Which parameter.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A trajectory segment is invalid.
    #[error("trajectory segment {index}: {what}")]
    InvalidSegment {
        /// 0-based segment index.
        index: usize,
        /// What is wrong.
        what: &'static str,
    },
    /// A sensor's parameters are not finite / out of range.
    #[error("{sensor}: parameters must be finite (noise and walk >= 0, range > 0)")]
    InvalidSensor {
        /// Which sensor.
        sensor: &'static str,
    },
    /// Duration × rate exceeds [`MAX_SAMPLES`].
    #[error("{samples} samples requested; at most {MAX_SAMPLES} per simulation")]
    TooManySamples {
        /// Requested number of samples.
        samples: f64,
    },
}

/// A complete simulation set-up.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    /// Name given to the recording.
    pub name: String,
    /// The true motion.
    pub trajectory: Trajectory,
    /// The IMU's error model.
    pub sensor: SensorModel,
    /// Sampling.
    pub timing: Timing,
    /// Seed of the noise, jitter and drop streams.
    pub seed: u64,
}

/// Output of [`Simulation::run`]: the recording and the hidden truth a test may want.
#[derive(Clone, Debug, PartialEq)]
pub struct SimOutput {
    /// The samples, truth (sensor to earth, ENU) and use mask (all samples count).
    pub recording: Recording,
    /// True gyroscope bias at each sample, rad/s, sensor frame.
    pub gyro_bias: Vec<Vec3<f64>>,
    /// True accelerometer bias at each sample, m/s², sensor frame.
    pub acc_bias: Vec<Vec3<f64>>,
    /// Whether a magnetic disturbance is active at each sample.
    pub mag_disturbed: Vec<bool>,
}

/// ChaCha stream numbers: set-up draws (presets), timing, sensor noise. Separate streams keep
/// the noise the same when only jitter or drops change.
pub(crate) const STREAM_SETUP: u64 = 0;
const STREAM_TIMING: u64 = 1;
const STREAM_NOISE: u64 = 2;

/// A ChaCha8 generator for `seed` on `stream`.
pub(crate) fn rng(seed: u64, stream: u64) -> ChaCha8Rng {
    let mut r = ChaCha8Rng::seed_from_u64(seed);
    r.set_stream(stream);
    r
}

#[inline]
fn normal3(r: &mut ChaCha8Rng) -> Vec3<f64> {
    Vec3::new(
        r.sample(StandardNormal),
        r.sample(StandardNormal),
        r.sample(StandardNormal),
    )
}

impl Simulation {
    /// Number of nominal sample instants: `round(duration·rate)`, at least 1.
    fn nominal_samples(&self) -> Result<usize, SimError> {
        let n = (self.trajectory.duration() * self.timing.rate_hz).round();
        if n.is_nan() || n > MAX_SAMPLES as f64 {
            return Err(SimError::TooManySamples { samples: n });
        }
        Ok((n as usize).max(1))
    }

    /// The sample instants: nominal `k / rate` plus clipped jitter, minus dropped samples.
    fn sample_times(&self, n: usize) -> Vec<f64> {
        let tm = &self.timing;
        let dt = 1.0 / tm.rate_hz;
        let clip = 0.45 * dt;
        if tm.jitter_std_s == 0.0 && tm.drop_prob == 0.0 {
            return (0..n).map(|k| k as f64 * dt).collect();
        }
        let mut r = rng(self.seed, STREAM_TIMING);
        let mut t = Vec::with_capacity(n);
        for k in 0..n {
            let nominal = k as f64 * dt;
            // Draw both numbers for every sample so that the jitter of sample k does not
            // depend on whether earlier samples were dropped.
            let z: f64 = r.sample(StandardNormal);
            let u: f64 = r.random();
            if k > 0 && u < tm.drop_prob {
                continue;
            }
            let jitter = if k == 0 {
                0.0
            } else {
                (z * tm.jitter_std_s).clamp(-clip, clip)
            };
            t.push(nominal + jitter);
        }
        t
    }

    /// Runs the simulation. Errors only on an invalid set-up (never on the random draws).
    pub fn run(&self) -> Result<SimOutput, SimError> {
        self.timing.validate()?;
        self.sensor.validate()?;
        let n = self.nominal_samples()?;
        let times = self.sample_times(n);
        let m = times.len();
        let s = &self.sensor;
        let mut noise = rng(self.seed, STREAM_NOISE);

        let mut rec = Recording {
            name: self.name.clone(),
            t: Vec::with_capacity(m),
            gyr: Vec::with_capacity(m),
            acc: Vec::with_capacity(m),
            mag: s.mag.as_ref().map(|_| Vec::with_capacity(m)),
            truth: Some(Vec::with_capacity(m)),
            use_mask: Some(vec![true; m]),
        };
        let mut out_gb = Vec::with_capacity(m);
        let mut out_ab = Vec::with_capacity(m);
        let mut disturbed = Vec::with_capacity(m);

        let mut gb = s.gyro.bias;
        let mut ab = s.acc.bias;
        let mut gstep = 0usize;
        let mut astep = 0usize;
        let mut gsteps = s.gyro.bias_steps.clone();
        let mut asteps = s.acc.bias_steps.clone();
        gsteps.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        asteps.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        let m_earth = s.mag.as_ref().map(|mg| mg.field.vector());
        let mut truth = Vec::with_capacity(m);
        let mut prev_t = 0.0;

        for &t in &times {
            // Bias random walk over the actual interval (dropped samples widen it).
            let dt = (t - prev_t).max(0.0);
            prev_t = t;
            if dt > 0.0 {
                if s.gyro.bias_walk > 0.0 {
                    gb += normal3(&mut noise) * (s.gyro.bias_walk * dt.sqrt());
                }
                if s.acc.bias_walk > 0.0 {
                    ab += normal3(&mut noise) * (s.acc.bias_walk * dt.sqrt());
                }
            }
            while gstep < gsteps.len() && gsteps[gstep].time_s <= t {
                gb += gsteps[gstep].delta;
                gstep += 1;
            }
            while astep < asteps.len() && asteps[astep].time_s <= t {
                ab += asteps[astep].delta;
                astep += 1;
            }

            let st = self.trajectory.state_at(t);
            let gyr = s.gyro.sensitivity(st.omega) + gb + noise_of(&mut noise, s.gyro.noise_std);
            let acc = s.acc.sensitivity(st.specific_force(s.gravity))
                + ab
                + noise_of(&mut noise, s.acc.noise_std);
            let mut any_dist = false;
            if let (Some(mg), Some(me), Some(out)) = (&s.mag, m_earth, &mut rec.mag) {
                let mut earth = me;
                let mut body = Vec3::zero();
                for d in &mg.disturbances {
                    let e = d.envelope(t);
                    if e > 0.0 {
                        any_dist = true;
                        match d.frame {
                            Frame::Earth => earth += d.field * e,
                            Frame::Sensor => body += d.field * e,
                        }
                    }
                }
                let y = sensor::mat_vec(&mg.soft_iron, st.q.rotate_inverse(earth))
                    + mg.hard_iron
                    + body
                    + noise_of(&mut noise, mg.noise_std);
                out.push(sensor::saturate(y, mg.range));
            }
            rec.t.push(t);
            rec.gyr.push(sensor::saturate(gyr, s.gyro.range));
            rec.acc.push(sensor::saturate(acc, s.acc.range));
            truth.push(canonical(st.q));
            out_gb.push(gb);
            out_ab.push(ab);
            disturbed.push(any_dist);
        }
        rec.truth = Some(truth);
        Ok(SimOutput {
            recording: rec,
            gyro_bias: out_gb,
            acc_bias: out_ab,
            mag_disturbed: disturbed,
        })
    }
}

/// White noise of standard deviation `std` per axis; no draw for a noise-free sensor, so an
/// ideal sensor costs nothing.
#[inline]
fn noise_of(r: &mut ChaCha8Rng, std: f64) -> Vec3<f64> {
    if std > 0.0 {
        normal3(r) * std
    } else {
        Vec3::zero()
    }
}

/// `q` with a non-negative scalar part (a fixed sign makes truth files diff-friendly).
fn canonical(q: Quat<f64>) -> Quat<f64> {
    if q.w < 0.0 { -q } else { q }
}
