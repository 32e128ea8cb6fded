//! The batch engine: many IMU channels of one filter, [`Lane::LANES`] channels per SIMD
//! vector (`f32x8`: 8, `f64x4`: 4), chunks of lanes spread over cores with rayon.
//!
//! Every registered filter of `rootfuse-attitude` runs here through
//! [`AnyFilter<L>`](rootfuse_attitude::registry::AnyFilter): the same code as a scalar run,
//! so each channel's result equals running it alone through `spec.build::<f32>()` (or `f64`)
//! bit for bit (tested for every registered filter in the workspace's `tests/batch.rs`).
//!
//! ```
//! use rootfuse_attitude::registry::FilterSpec;
//! use rootfuse_attitude::sim::scenario;
//! use rootfuse_batch::{Precision, run_recordings};
//!
//! let mut spec = FilterSpec::new("ekf").unwrap();
//! spec.set_dof(6).unwrap();
//! let recs: Vec<_> = (0..3).map(|seed| scenario("static", seed, 1.0, 100.0).unwrap()).collect();
//! let out = run_recordings(&spec, &recs, Precision::F64);
//! assert!(out.iter().all(|o| o.quat.len() == 100 && o.rejections.dt == 0));
//! ```
//!
//! # Layout
//! Channel `c` is lane `c % LANES` of chunk `c / LANES` ([`Batch`], [`Chunk`]). Parameters
//! are shared by all channels of a batch (one [`FilterSpec`]); per-channel parameters would
//! need the filters to hold them in lanes, which they already do internally (every gain is a
//! `T`), so it is a constructor away, not a layout change. State, time steps and rejection
//! counters are per channel.
//!
//! # Tail lanes and masking
//! The last chunk's lanes past the last channel are fed [`pad_sample`] (gyro zero, gravity
//! `[0, 0, 9.81]`, field `[0, 0.44, -0.9]`, consistent with the identity orientation) with a
//! valid step [`PAD_DT`]: they run the ordinary code path on a sensor at rest, never a
//! degenerate one, and are never reported. A channel without a sample at a step (its
//! recording has ended, or [`Chunk::update_masked`] leaves it out) gets the padding sample
//! with `dt = 0`: the shared input screening skips such a sample entirely for that lane (state
//! untouched, see `rootfuse_attitude::filters`), and the one `dt` rejection it counts is
//! subtracted again when counters are reported. The tests check for every registered filter
//! that a channel with masked steps equals a scalar run without them, bit for bit.
//!
//! # Memory and streaming
//! The state of a channel is `size_of::<AnyFilter<L>>() / LANES` bytes
//! ([`state_bytes_per_channel`]); `AnyFilter` is an enum, so every filter costs as much as the
//! largest one (the EKF with its 7×7 covariance). Measured with `target-cpu=native` (the
//! enum size, then the filter's own struct):
//!
//! | lanes | `AnyFilter` per channel | gyro | complementary | mahony | madgwick | ekf | sqrt-eskf |
//! |---|---|---|---|---|---|---|---|
//! | `f32x8` | 376 | 64 | 72 | 92 | 84 | 296 | 376 |
//! | `f64x4` | 712 | 88 | 104 | 144 | 128 | 552 | 712 |
//!
//! (A scalar `Mahony<f32>` is 104 bytes, `Ekf<f32>` 312: the per-lane `u64` rejection
//! counters are the same, the shared parameters are amortised over the lanes.) At 4096
//! channels of Mahony in `f32x8` that is 1.5 MB of state (376 B each, because of the enum),
//! which no longer fits in L2; [`throughput`] runs chunk by chunk, each chunk's state staying
//! in registers for all its samples, so the state size matters for streaming blocks, not
//! within one.
//!
//! Nothing is allocated per update: [`Chunk::update`] works on the SIMD state in place, and
//! array-of-structs input ([`Batch::run_channels`], [`run_recordings`]) is packed into lanes
//! one step at a time through a `LANES`-entry buffer made once per chunk and call. Input is
//! streamed in blocks: [`Batch::run_soa`] and [`Batch::run_channels`] take one block (any
//! number of steps) and keep the state for the next, so memory stays flat for recordings of
//! any length; [`Chunk::run_sources`] runs any step range of any [`ChannelSource`]. Only
//! [`run_recordings`] holds whole recordings, because its output is the whole estimate.
//!
//! # Threads
//! Chunks are independent; rayon spreads them over its pool and each chunk runs its steps in
//! order on one thread, so results do not depend on the thread count (tested with 1 and 2
//! threads).
//!
//! # Throughput
//! [`throughput`] measures scalar `f32`/`f64` loops, `f32x8`/`f64x4` lanes on one core and
//! `f32x8` lanes on all cores in one run (the CLI's `rootfuse throughput`).
//!
//! [`Lane::LANES`]: rootfuse_lane::Lane::LANES
//! [`FilterSpec`]: rootfuse_attitude::registry::FilterSpec
#![warn(missing_docs)]

mod batch;
mod recordings;
mod throughput;

/// The rayon this crate spreads chunks with (configure its pools, e.g. the thread count).
pub use rayon;

pub use batch::{Batch, Channel, ChannelSource, Chunk, PAD_DT, RejectionTotals, pad_sample};
pub use recordings::{
    ChannelOutput, Columns, Precision, flag, run_recordings, run_recordings_with, run_sources,
    run_sources_with,
};
pub use throughput::{ModeResult, ROUNDS, ThroughputReport, throughput};

/// State bytes per channel of a batch over lanes `L`: `size_of::<AnyFilter<L>>() / LANES`
/// (the chunk's masking bookkeeping adds `size_of::<L::Counts>() / LANES + 2 × 8` bytes of
/// `u64` counters and bits, plus a padding sample of `10 × size_of::<L>() / LANES`).
pub fn state_bytes_per_channel<L: rootfuse_lane::Lane>() -> usize {
    core::mem::size_of::<rootfuse_attitude::registry::AnyFilter<L>>() / L::LANES
}
