//! [`throughput`]: scalar loops against lanes against lanes on all cores, in one run.

use rayon::prelude::*;
use rootfuse_attitude::registry::FilterSpec;
use rootfuse_attitude::{ImuSample, Lane, OrientationFilter, Quat, Vec3};
use rootfuse_lane::X2;
use rootfuse_lane::wide::{f32x8, f64x4};
use std::hint::black_box;
use std::string::String;
use std::time::Instant;

/// Distinct synthetic channels generated; channel `c` replays channel `c % POOL_CHANNELS`.
/// A multiple of every lane width; the pool (with [`POOL_STEPS`]) is about 1.3 MB in any
/// precision, so it measures the filters, not the memory bus.
const POOL_CHANNELS: usize = 512;
/// Distinct steps per synthetic channel; step `k` replays step `k % POOL_STEPS`.
const POOL_STEPS: usize = 64;
/// Timed runs per mode; the fastest counts (see [`throughput`]).
pub const ROUNDS: usize = 3;

/// One measured mode.
#[derive(Clone, Debug, PartialEq)]
pub struct ModeResult {
    /// `scalar-f32`, `scalar-f64`, `lanes-f32x8`, `lanes-f64x4` or `lanes-f32x8-threads`.
    pub mode: &'static str,
    /// Channel-updates per second (one channel, one sample).
    pub updates_per_s: f64,
    /// Nanoseconds per channel-update.
    pub ns_per_update: f64,
}

/// The result of [`throughput`].
#[derive(Clone, Debug, PartialEq)]
pub struct ThroughputReport {
    /// Filter name.
    pub filter: String,
    /// Channels run.
    pub channels: usize,
    /// Samples per channel.
    pub samples: usize,
    /// One entry per mode, in the order listed in [`ModeResult::mode`].
    pub results: Vec<ModeResult>,
}

impl ThroughputReport {
    /// The result of one mode.
    pub fn mode(&self, mode: &str) -> Option<&ModeResult> {
        self.results.iter().find(|r| r.mode == mode)
    }

    /// `updates_per_s` of mode `a` over that of mode `b`.
    pub fn ratio(&self, a: &str, b: &str) -> Option<f64> {
        Some(self.mode(a)?.updates_per_s / self.mode(b)?.updates_per_s)
    }

    /// The JSON object `{"filter", "channels", "samples", "results": [{"mode",
    /// "updates_per_s", "ns_per_update"}]}` on one line (non-finite numbers as `null`).
    pub fn to_json(&self) -> String {
        fn num(x: f64) -> String {
            if x.is_finite() {
                format!("{x}")
            } else {
                "null".into()
            }
        }
        fn string(s: &str) -> String {
            let mut out = String::from("\"");
            for c in s.chars() {
                match c {
                    '"' => out.push_str("\\\""),
                    '\\' => out.push_str("\\\\"),
                    c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
                    c => out.push(c),
                }
            }
            out.push('"');
            out
        }
        let results: Vec<String> = self
            .results
            .iter()
            .map(|r| {
                format!(
                    "{{\"mode\":{},\"updates_per_s\":{},\"ns_per_update\":{}}}",
                    string(r.mode),
                    num(r.updates_per_s),
                    num(r.ns_per_update)
                )
            })
            .collect();
        format!(
            "{{\"filter\":{},\"channels\":{},\"samples\":{},\"results\":[{}]}}",
            string(&self.filter),
            self.channels,
            self.samples,
            results.join(",")
        )
    }
}

/// A small deterministic generator (64-bit LCG, top bits) for the synthetic data: uniform in
/// `[-1, 1)`.
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }
}

/// The synthetic pool: `POOL_CHANNELS` channels of `POOL_STEPS` samples of a sensor turning
/// slowly (about 0.5 rad/s) with noisy gravity and field, and 100 Hz steps with jitter. Every
/// sample is usable, so the filters run their full correction paths.
fn pool() -> Vec<Vec<(ImuSample<f64>, f64)>> {
    let field = Vec3::new(0.0, 0.44, -0.9);
    let up = Vec3::new(0.0, 0.0, 9.81);
    (0..POOL_CHANNELS)
        .map(|c| {
            let mut rng = Lcg(c as u64 * 7919 + 17);
            let w = Vec3::new(rng.next(), rng.next(), rng.next()) * 0.5;
            let mut q = Quat::from_euler_zyx(rng.next() * 3.0, rng.next(), rng.next());
            (0..POOL_STEPS)
                .map(|_| {
                    let dt = 0.01 + 0.001 * rng.next();
                    q = (q * Quat::from_rotation_vector(w * dt)).normalize();
                    let mut noise = || Vec3::new(rng.next(), rng.next(), rng.next());
                    let gyr = w + noise() * 0.01;
                    let acc = q.rotate_inverse(up) + noise() * 0.05;
                    let mag = q.rotate_inverse(field) + noise() * 0.01;
                    (ImuSample::new(gyr, acc, mag), dt)
                })
                .collect()
        })
        .collect()
}

fn convert<S: Lane>(s: &(ImuSample<f64>, f64)) -> (ImuSample<S>, S) {
    let c = |v: Vec3<f64>| Vec3::from_f64([v.x, v.y, v.z]);
    (
        ImuSample::new(c(s.0.gyr), c(s.0.acc), c(s.0.mag)),
        S::from_f64(s.1),
    )
}

/// Scalar loop: every channel alone, all its samples, one after the other.
fn scalar<S: Lane>(
    spec: &FilterSpec,
    pool: &[Vec<(ImuSample<f64>, f64)>],
    channels: usize,
    samples: usize,
) -> f64 {
    let data: Vec<Vec<(ImuSample<S>, S)>> = pool
        .iter()
        .map(|ch| ch.iter().map(convert::<S>).collect())
        .collect();
    let start = Instant::now();
    for c in 0..channels {
        let mut f = spec.build::<S>();
        let ch = &data[c % POOL_CHANNELS];
        run_steps(&mut f, ch, samples);
        black_box(f.quat());
    }
    start.elapsed().as_secs_f64()
}

/// Runs `samples` steps of `data` (replayed cyclically) through `f`.
#[inline]
fn run_steps<T: Lane, F: OrientationFilter<T>>(
    f: &mut F,
    data: &[(ImuSample<T>, T)],
    samples: usize,
) {
    let mut left = samples;
    while left > 0 {
        let n = left.min(data.len());
        for (s, dt) in black_box(&data[..n]) {
            f.update(s, *dt);
        }
        left -= n;
    }
}

/// Lanes: chunk by chunk (each chunk's state stays in registers and L1 for all its samples),
/// on one thread or spread over the rayon pool.
fn lanes<L: Lane>(
    spec: &FilterSpec,
    pool: &[Vec<(ImuSample<f64>, f64)>],
    channels: usize,
    samples: usize,
    threads: bool,
) -> f64 {
    let pool_chunks = POOL_CHANNELS / L::LANES;
    let data: Vec<Vec<(ImuSample<L>, L)>> = (0..pool_chunks)
        .map(|c| {
            (0..POOL_STEPS)
                .map(|k| {
                    let lane = |i: usize| convert::<L::Scalar>(&pool[c * L::LANES + i][k]);
                    let sample = ImuSample::new(
                        Vec3::from_lanes(|i| lane(i).0.gyr),
                        Vec3::from_lanes(|i| lane(i).0.acc),
                        Vec3::from_lanes(|i| lane(i).0.mag),
                    );
                    (sample, L::from_fn(|i| lane(i).1))
                })
                .collect()
        })
        .collect();
    let chunks = channels.div_ceil(L::LANES);
    let run = |c: usize| {
        let mut f = spec.build::<L>();
        run_steps(&mut f, &data[c % pool_chunks], samples);
        black_box(f.quat());
    };
    let start = Instant::now();
    if threads {
        (0..chunks).into_par_iter().for_each(run);
    } else {
        (0..chunks).for_each(run);
    }
    start.elapsed().as_secs_f64()
}

/// Measures, in one run, `channels` channels of `samples` samples each of the filter `spec` in
/// the modes `scalar-f32`, `scalar-f64`, `lanes-f32x8`, `lanes-f64x4` and
/// `lanes-f32x8-threads` (the rayon global pool, i.e. all cores unless configured).
///
/// The input is synthetic (a slowly turning sensor with noise, every sample usable), generated
/// once and not timed: 512 distinct channels of 64 steps, replayed cyclically, so the data
/// stays in cache and the filters are what is measured. A channel-update is one sample of one
/// channel; lane modes count real channels only (tail lanes are overhead).
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// let report = rootfuse_batch::throughput(&FilterSpec::new("gyro").unwrap(), 16, 10);
/// assert_eq!(report.results.len(), 5);
/// assert!(report.to_json().starts_with("{\"filter\":\"gyro\""));
/// ```
pub fn throughput(spec: &FilterSpec, channels: usize, samples: usize) -> ThroughputReport {
    let pool = pool();
    let updates = (channels * samples) as f64;
    let single = std::env::var("RF_SINGLE").is_ok();
    let modes: [(&'static str, &dyn Fn() -> f64); 5] = [
        ("scalar-f32", &|| {
            scalar::<f32>(spec, &pool, channels, samples)
        }),
        ("scalar-f64", &|| {
            scalar::<f64>(spec, &pool, channels, samples)
        }),
        ("lanes-f32x8", &|| {
            if single {
                lanes::<f32x8>(spec, &pool, channels, samples, false)
            } else {
                lanes::<X2<f32x8>>(spec, &pool, channels, samples, false)
            }
        }),
        ("lanes-f64x4", &|| {
            if single {
                lanes::<f64x4>(spec, &pool, channels, samples, false)
            } else {
                lanes::<X2<f64x4>>(spec, &pool, channels, samples, false)
            }
        }),
        ("lanes-f32x8-threads", &|| {
            lanes::<X2<f32x8>>(spec, &pool, channels, samples, true)
        }),
    ];
    // Best of ROUNDS, the modes taking turns: a machine shared with other work slows single
    // runs down, never speeds them up, so the fastest run is the closest to the code's cost.
    let mut best = [f64::INFINITY; 5];
    for _ in 0..ROUNDS {
        for (b, (_, run)) in best.iter_mut().zip(&modes) {
            *b = b.min(run());
        }
    }
    let timed = modes
        .iter()
        .zip(best)
        .map(|((mode, _), secs)| (*mode, secs));
    ThroughputReport {
        filter: spec.kind().name().into(),
        channels,
        samples,
        results: timed
            .map(|(mode, secs)| ModeResult {
                mode,
                updates_per_s: updates / secs,
                ns_per_update: secs * 1e9 / updates,
            })
            .collect(),
    }
}
