//! [`throughput`]: scalar loops against lanes against lanes on all cores, in one run.

use crate::interleaves;
use rayon::prelude::*;
use rootfuse_attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
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
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ModeResult {
    /// `scalar-f32`, `scalar-f64`, `lanes-f32x8`, `lanes-f64x4` or `lanes-f32x8-threads`.
    pub mode: &'static str,
    /// Channel-updates per second (one channel, one sample).
    pub updates_per_s: f64,
    /// Nanoseconds per channel-update.
    pub ns_per_update: f64,
}

/// The result of [`throughput`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
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
        // Plain strings and numbers only: serialisation cannot fail.
        serde_json::to_string(self).unwrap_or_default()
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

/// Scalar loop: every channel alone, all its samples, one after the other (the concrete
/// filter type, as an embedded user would run it: no enum dispatch per sample).
struct Scalar<'a> {
    pool: &'a [Vec<(ImuSample<f64>, f64)>],
    channels: usize,
    samples: usize,
}

impl<S: Lane> FilterVisitor<S> for Scalar<'_> {
    type Output = f64;
    fn visit<F: RegisteredFilter<S>>(self, spec: &FilterSpec) -> f64 {
        let data: Vec<Vec<(ImuSample<S>, S)>> = self
            .pool
            .iter()
            .map(|ch| ch.iter().map(convert::<S>).collect())
            .collect();
        let Some(fresh) = F::from_spec(spec) else {
            return f64::NAN;
        };
        let start = Instant::now();
        for c in 0..self.channels {
            let mut f = fresh.clone();
            run_steps(&mut f, &data[c % POOL_CHANNELS], self.samples);
            black_box(f.quat());
        }
        start.elapsed().as_secs_f64()
    }
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

/// The synthetic pool packed into chunks of `L` (not timed): `POOL_CHANNELS / LANES` chunks
/// of `POOL_STEPS` steps.
fn pack<L: Lane>(pool: &[Vec<(ImuSample<f64>, f64)>]) -> Vec<Vec<(ImuSample<L>, L)>> {
    (0..POOL_CHANNELS / L::LANES)
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
        .collect()
}

/// How the lane modes walk channels and steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// Chunk by chunk: each chunk runs all its samples before the next starts, so its state
    /// stays in registers and L1 (offline processing of whole recordings).
    ChunkMajor,
    /// Tick by tick: every chunk advances one sample, then the next sample (real-time
    /// streaming of many sensors): each chunk's state is loaded and stored once per sample.
    Tick,
}

/// Lanes on one thread or spread over the rayon pool, in the given order.
struct Lanes<'a> {
    pool: &'a [Vec<(ImuSample<f64>, f64)>],
    channels: usize,
    samples: usize,
    threads: bool,
    order: Order,
}

impl<L: Lane> FilterVisitor<L> for Lanes<'_> {
    type Output = f64;
    fn visit<F: RegisteredFilter<L>>(self, spec: &FilterSpec) -> f64 {
        let data = pack::<L>(self.pool);
        let pool_chunks = data.len();
        let chunks = self.channels.div_ceil(L::LANES);
        let Some(fresh) = F::from_spec(spec) else {
            return f64::NAN;
        };
        let samples = self.samples;
        if self.order == Order::Tick {
            let mut filters = vec![fresh; chunks];
            let start = Instant::now();
            let tick = |k: usize, c: usize, f: &mut F| {
                let (s, dt) = &black_box(&data[c % pool_chunks])[k % POOL_STEPS];
                f.update(s, *dt);
            };
            for k in 0..samples {
                if self.threads {
                    filters
                        .par_iter_mut()
                        .enumerate()
                        .for_each(|(c, f)| tick(k, c, f));
                } else {
                    for (c, f) in filters.iter_mut().enumerate() {
                        tick(k, c, f);
                    }
                }
            }
            let secs = start.elapsed().as_secs_f64();
            for f in &filters {
                black_box(f.quat());
            }
            return secs;
        }
        let run = |c: usize| {
            let mut f = fresh.clone();
            run_steps(&mut f, &data[c % pool_chunks], samples);
            black_box(f.quat());
        };
        let start = Instant::now();
        if self.threads {
            (0..chunks).into_par_iter().for_each(run);
        } else {
            (0..chunks).for_each(run);
        }
        start.elapsed().as_secs_f64()
    }
}

/// One lane mode: `L` or `X2<L>` by [`interleaves`], concrete filter type by
/// [`FilterSpec::visit`].
fn lanes<L: Lane>(spec: &FilterSpec, lanes: Lanes<'_>) -> f64
where
    X2<L>: Lane,
{
    if interleaves::<L>(spec) {
        spec.visit::<X2<L>, _>(lanes)
    } else {
        spec.visit::<L, _>(lanes)
    }
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
/// use rootfuse_attitude::registry::{FilterSpec, FilterVisitor, RegisteredFilter};
/// let report = rootfuse_batch::throughput(&FilterSpec::new("gyro").unwrap(), 16, 10);
/// assert_eq!(report.results.len(), 5);
/// assert!(report.to_json().starts_with("{\"filter\":\"gyro\""));
/// ```
pub fn throughput(spec: &FilterSpec, channels: usize, samples: usize) -> ThroughputReport {
    let pool = pool();
    let updates = (channels * samples) as f64;
    let lane = |threads: bool| Lanes {
        pool: &pool,
        channels,
        samples,
        threads,
        order: Order::ChunkMajor,
    };
    let scalar = || Scalar {
        pool: &pool,
        channels,
        samples,
    };
    let modes: [(&'static str, &dyn Fn() -> f64); 5] = [
        ("scalar-f32", &|| spec.visit::<f32, _>(scalar())),
        ("scalar-f64", &|| spec.visit::<f64, _>(scalar())),
        ("lanes-f32x8", &|| lanes::<f32x8>(spec, lane(false))),
        ("lanes-f64x4", &|| lanes::<f64x4>(spec, lane(false))),
        ("lanes-f32x8-threads", &|| lanes::<f32x8>(spec, lane(true))),
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

/// One point of [`sweep`]: `f32x8` lanes on one core at one channel count.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SweepPoint {
    /// Channels run.
    pub channels: usize,
    /// Samples per channel.
    pub samples: usize,
    /// Bytes of filter state of all channels (`size_of` of the filter over the lane type
    /// the engine uses, times the chunks).
    pub state_bytes: usize,
    /// Channel-updates per second, [`Order::ChunkMajor`].
    #[serde(rename = "chunk_major_updates_per_s")]
    pub chunk_major: f64,
    /// Channel-updates per second, [`Order::Tick`].
    #[serde(rename = "tick_updates_per_s")]
    pub tick: f64,
}

/// Bytes of one chunk's filter state for `spec` over the lane type [`lanes`] picks for `L`.
fn chunk_state<L: Lane>(spec: &FilterSpec) -> (usize, usize)
where
    X2<L>: Lane,
{
    struct Size;
    impl<L: Lane> FilterVisitor<L> for Size {
        type Output = usize;
        fn visit<F: RegisteredFilter<L>>(self, _: &FilterSpec) -> usize {
            core::mem::size_of::<F>()
        }
    }
    if interleaves::<L>(spec) {
        (spec.visit::<X2<L>, _>(Size), 2 * L::LANES)
    } else {
        (spec.visit::<L, _>(Size), L::LANES)
    }
}

/// Throughput of `f32x8` lanes on one core against the number of channels, in both
/// [`Order`]s, each point run for about `seconds` (samples per channel scaled from a short
/// calibration run, at least 8). Best of [`ROUNDS`] per point and order.
///
/// ```
/// use rootfuse_attitude::registry::FilterSpec;
/// let points = rootfuse_batch::sweep(&FilterSpec::new("gyro").unwrap(), &[8, 64], 0.001);
/// assert_eq!(points.len(), 2);
/// assert!(points[1].state_bytes > points[0].state_bytes);
/// ```
pub fn sweep(spec: &FilterSpec, channel_counts: &[usize], seconds: f64) -> Vec<SweepPoint> {
    let pool = pool();
    let run = |channels: usize, samples: usize, order: Order| {
        let secs = (0..ROUNDS)
            .map(|_| {
                lanes::<f32x8>(
                    spec,
                    Lanes {
                        pool: &pool,
                        channels,
                        samples,
                        threads: false,
                        order,
                    },
                )
            })
            .fold(f64::INFINITY, f64::min);
        (channels * samples) as f64 / secs
    };
    let rate = run(4096, POOL_STEPS, Order::ChunkMajor);
    let (chunk_bytes, lanes_per_chunk) = chunk_state::<f32x8>(spec);
    channel_counts
        .iter()
        .map(|&channels| {
            let samples = ((seconds * rate / channels as f64).ceil() as usize).max(8);
            SweepPoint {
                channels,
                samples,
                state_bytes: channels.div_ceil(lanes_per_chunk) * chunk_bytes,
                chunk_major: run(channels, samples, Order::ChunkMajor),
                tick: run(channels, samples, Order::Tick),
            }
        })
        .collect()
}
