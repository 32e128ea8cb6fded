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

pub use scenario::{
    HARD_CASES, SCENARIOS, scenario, scenario_batch, scenario_names, scenario_simulation,
    scenario_stream,
};
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

    /// The samples one by one, without holding the recording: a fleet of long recordings
    /// written to a file (`rootfuse simulate`) needs memory for a block, not for the fleet.
    /// [`run`](Self::run) is this stream collected, so both give the same bits. Errors only on
    /// an invalid set-up.
    pub fn stream(&self) -> Result<SimStream, SimError> {
        self.timing.validate()?;
        self.sensor.validate()?;
        let n = self.nominal_samples()?;
        let s = &self.sensor;
        let tm = &self.timing;
        let mut gsteps = s.gyro.bias_steps.clone();
        let mut asteps = s.acc.bias_steps.clone();
        gsteps.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        asteps.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
        Ok(SimStream {
            n,
            k: 0,
            timing: (tm.jitter_std_s != 0.0 || tm.drop_prob != 0.0)
                .then(|| rng(self.seed, STREAM_TIMING)),
            noise: rng(self.seed, STREAM_NOISE),
            gb: s.gyro.bias,
            ab: s.acc.bias,
            gstep: 0,
            astep: 0,
            gsteps,
            asteps,
            m_earth: s.mag.as_ref().map(|mg| mg.field.vector()),
            prev_t: 0.0,
            sim: self.clone(),
        })
    }

    /// Runs the simulation. Errors only on an invalid set-up (never on the random draws).
    pub fn run(&self) -> Result<SimOutput, SimError> {
        let stream = self.stream()?;
        let m = stream.size_hint().1.unwrap_or(0);
        let has_mag = self.sensor.mag.is_some();
        let mut rec = Recording {
            name: self.name.clone(),
            t: Vec::with_capacity(m),
            gyr: Vec::with_capacity(m),
            acc: Vec::with_capacity(m),
            mag: has_mag.then(|| Vec::with_capacity(m)),
            truth: None,
            use_mask: None,
        };
        let mut out_gb = Vec::with_capacity(m);
        let mut out_ab = Vec::with_capacity(m);
        let mut disturbed = Vec::with_capacity(m);
        let mut truth = Vec::with_capacity(m);
        for x in stream {
            if let (Some(out), Some(y)) = (&mut rec.mag, x.mag) {
                out.push(y);
            }
            rec.t.push(x.t);
            rec.gyr.push(x.gyr);
            rec.acc.push(x.acc);
            truth.push(x.truth);
            out_gb.push(x.gyro_bias);
            out_ab.push(x.acc_bias);
            disturbed.push(x.mag_disturbed);
        }
        rec.use_mask = Some(vec![true; rec.t.len()]);
        rec.truth = Some(truth);
        Ok(SimOutput {
            recording: rec,
            gyro_bias: out_gb,
            acc_bias: out_ab,
            mag_disturbed: disturbed,
        })
    }
}

/// One sample of a [`SimStream`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SimSample {
    /// Time stamp, s.
    pub t: f64,
    /// Gyroscope reading, rad/s.
    pub gyr: Vec3<f64>,
    /// Accelerometer reading, m/s².
    pub acc: Vec3<f64>,
    /// Magnetometer reading (`None` for a sensor without one).
    pub mag: Option<Vec3<f64>>,
    /// True orientation, sensor to earth (ENU), scalar part non-negative.
    pub truth: Quat<f64>,
    /// True gyroscope bias, rad/s, sensor frame.
    pub gyro_bias: Vec3<f64>,
    /// True accelerometer bias, m/s², sensor frame.
    pub acc_bias: Vec3<f64>,
    /// Whether a magnetic disturbance is active.
    pub mag_disturbed: bool,
}

/// The samples of a [`Simulation`] in time order ([`Simulation::stream`]); ends after the
/// last one (and stays ended).
#[derive(Clone, Debug)]
pub struct SimStream {
    sim: Simulation,
    /// Nominal sample instants, and the next one.
    n: usize,
    k: usize,
    /// Jitter and drops (`None`: regular timing, no draws).
    timing: Option<ChaCha8Rng>,
    noise: ChaCha8Rng,
    gb: Vec3<f64>,
    ab: Vec3<f64>,
    gstep: usize,
    astep: usize,
    gsteps: Vec<BiasStep>,
    asteps: Vec<BiasStep>,
    m_earth: Option<Vec3<f64>>,
    prev_t: f64,
}

impl SimStream {
    /// The next sample instant: nominal `k / rate` plus clipped jitter, dropped samples
    /// skipped.
    fn next_time(&mut self) -> Option<f64> {
        let tm = &self.sim.timing;
        let dt = 1.0 / tm.rate_hz;
        let clip = 0.45 * dt;
        while self.k < self.n {
            let k = self.k;
            self.k += 1;
            let nominal = k as f64 * dt;
            let Some(r) = &mut self.timing else {
                return Some(nominal);
            };
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
            return Some(nominal + jitter);
        }
        None
    }
}

impl Iterator for SimStream {
    type Item = SimSample;

    fn next(&mut self) -> Option<SimSample> {
        let t = self.next_time()?;
        let s = &self.sim.sensor;
        let noise = &mut self.noise;
        // Bias random walk over the actual interval (dropped samples widen it).
        let dt = (t - self.prev_t).max(0.0);
        self.prev_t = t;
        if dt > 0.0 {
            if s.gyro.bias_walk > 0.0 {
                self.gb += normal3(noise) * (s.gyro.bias_walk * dt.sqrt());
            }
            if s.acc.bias_walk > 0.0 {
                self.ab += normal3(noise) * (s.acc.bias_walk * dt.sqrt());
            }
        }
        while self.gstep < self.gsteps.len() && self.gsteps[self.gstep].time_s <= t {
            self.gb += self.gsteps[self.gstep].delta;
            self.gstep += 1;
        }
        while self.astep < self.asteps.len() && self.asteps[self.astep].time_s <= t {
            self.ab += self.asteps[self.astep].delta;
            self.astep += 1;
        }

        let st = self.sim.trajectory.state_at(t);
        let gyr = s.gyro.sensitivity(st.omega) + self.gb + noise_of(noise, s.gyro.noise_std);
        let acc = s.acc.sensitivity(st.specific_force(s.gravity))
            + self.ab
            + noise_of(noise, s.acc.noise_std);
        let mut any_dist = false;
        let mut mag = None;
        if let (Some(mg), Some(me)) = (&s.mag, self.m_earth) {
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
                + noise_of(noise, mg.noise_std);
            mag = Some(sensor::saturate(y, mg.range));
        }
        Some(SimSample {
            t,
            gyr: sensor::saturate(gyr, s.gyro.range),
            acc: sensor::saturate(acc, s.acc.range),
            mag,
            truth: canonical(st.q),
            gyro_bias: self.gb,
            acc_bias: self.ab,
            mag_disturbed: any_dist,
        })
    }

    /// At most the nominal instants left (dropped samples make it fewer).
    fn size_hint(&self) -> (usize, Option<usize>) {
        let left = self.n - self.k;
        (if self.timing.is_some() { 0 } else { left }, Some(left))
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
